/* Remote rig: the rig interface over a TCP connection to `rths controller` (docs/protocol.md).
 *
 * One blocking request/reply at a time; frames the controller pushes unasked (PERIOD, TRACE,
 * STATUS) are taken in whenever the client reads, periods into a queue that run_periods drains.
 * This is host-side code: it may allocate and block, unlike the controller's loop. */
#include "rths/rig_remote.h"

#include "rths/protocol.h"

#include <errno.h>
#include <math.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

_Static_assert(RTHS_PROTO_HARMONICS == RTHS_MAX_HARMONICS,
               "PERIOD frames carry exactly the rig's harmonics");
_Static_assert(RTHS_PROTO_MAX_DOFS == RTHS_MAX_INTERFACE_DOFS,
               "frames carry every interface DoF a rig drives");

/* 1 MiB: with the injected link delay the host holds what arrived during the delay (a trace
 * stream of 4 DoFs is about 0.6 MB/s) */
#define RX_CAP (1024 * 1024)
/* arrival marks of the received bytes (the injected link delay): chunks beyond merge */
#define RX_MARKS 4096

typedef struct remote {
    char uri[300];
    char host[256];
    int port;
    rths_remote_options opt;
    char client_name[RTHS_PROTO_MAX_TEXT + 1];
    int fd;
    uint16_t seq;
    uint8_t rx[RX_CAP];
    size_t rx_len;
    /* the test hook's one-way delay (rths_remote_options.link_delay_s): the time each received
     * chunk of rx arrived, chunk i ending at rx offset mark_end[i] */
    double delay_s;
    int sent_last; /* the last thing done on the link was a send: the next one travels with it */
    size_t mark_end[RX_MARKS];
    double mark_time[RX_MARKS];
    int marks;
    /* controller facts from HELLO_REPLY */
    double h, watchdog_s, noise_m;
    int interface_dofs; /* the controller's: every target and record has this many */
    char controller_name[RTHS_PROTO_MAX_TEXT + 1];
    /* periods received and not yet handed out (ring, grows) */
    rths_proto_period *q;
    size_t q_cap, q_head, q_len;
    double valid_from_s; /* periods starting before this ran under an older setting */
    double last_time_s;
    int armed;
    double last_sent_s; /* any frame to the controller feeds its watchdog */
    rths_rig_fault fault;
    char fault_msg[512];
    /* the last settings, replayed after a reconnect */
    int have_forcing;
    double frequency_hz, amplitude_n;
    /* SET_FORCING goes out without waiting for its ACK, so the target set next follows it on the
     * wire with no round trip between them (docs/protocol.md, "Which periods follow a change"):
     * forcing_seq is its outstanding request (0: none), prev_* what to restore if it is refused;
     * a refusal (forcing_rc, forcing_err) is returned by every operation that runs the forcing
     * until the next set_forcing */
    uint16_t forcing_seq;
    int prev_have_forcing, forcing_rc;
    double prev_frequency_hz, prev_amplitude_n;
    rths_error forcing_err;
    int harmonics; /* DoF d's coefficients at ta[d * harmonics + k - 1] */
    double ta[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_HARMONICS];
    double tb[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_HARMONICS];
    /* trace collection in progress */
    int tracing;
    rths_trace_sample *trace_out;
    int trace_max, trace_n;
    double trace_t0, trace_t1;
} remote;

void rths_remote_options_defaults(rths_remote_options *opt) {
    opt->connect_timeout_s = 5.0;
    opt->reply_timeout_s = 5.0;
    opt->stall_timeout_s = 10.0;
    opt->client_name = "rths host";
    opt->link_delay_s = 0.0;
}

int rths_rig_uri_is_remote(const char *uri) {
    return uri && !strncmp(uri, "tcp://", 6);
}

int rths_remote_parse_uri(const char *uri, char *host, size_t host_cap, int *port,
                          rths_error *err) {
    if (!rths_rig_uri_is_remote(uri))
        return rths_error_set(err, RTHS_EINPUT, "rig '%s': expected tcp://HOST:PORT",
                              uri ? uri : "(null)");
    const char *p = uri + 6, *colon;
    size_t hl;
    if (*p == '[') {
        const char *close = strchr(p, ']');
        if (!close || close[1] != ':')
            return rths_error_set(err, RTHS_EINPUT, "rig '%s': expected tcp://[IPV6]:PORT", uri);
        p++;
        hl = (size_t)(close - p);
        colon = close + 1;
    } else {
        colon = strrchr(p, ':');
        if (!colon) return rths_error_set(err, RTHS_EINPUT, "rig '%s': missing :PORT", uri);
        hl = (size_t)(colon - p);
        if (memchr(p, ':', hl))
            return rths_error_set(err, RTHS_EINPUT, "rig '%s': an IPv6 address must be in brackets",
                                  uri);
    }
    if (hl == 0 || hl >= host_cap)
        return rths_error_set(err, RTHS_EINPUT, "rig '%s': missing or overlong host", uri);
    char *end;
    errno = 0;
    long v = strtol(colon + 1, &end, 10);
    if (errno || end == colon + 1 || *end || v < 1 || v > 65535)
        return rths_error_set(err, RTHS_EINPUT, "rig '%s': port must be 1..65535", uri);
    memcpy(host, p, hl);
    host[hl] = '\0';
    *port = (int)v;
    return RTHS_OK;
}

/* ---- link ---- */

/* The injected delay's bookkeeping: when the bytes now ending rx arrived. */
static void mark_arrival(remote *r) {
    if (r->marks == RX_MARKS) { /* merge the two oldest chunks: the later time holds for both */
        memmove(r->mark_end, r->mark_end + 1, sizeof r->mark_end[0] * (RX_MARKS - 1));
        memmove(r->mark_time + 1, r->mark_time + 2, sizeof r->mark_time[0] * (RX_MARKS - 2));
        r->marks--;
    }
    r->mark_end[r->marks] = r->rx_len;
    r->mark_time[r->marks++] = rths_monotonic_s();
}

/* Waits until the monotonic clock reads until_s (the injected delay only), taking in whatever
 * arrives meanwhile with its arrival time, as the kernel would on a long link: frames are
 * delayed by the link, never by the host being busy waiting. A closed or failed socket is left
 * for the next read to report. */
static void wait_receiving(remote *r, double until_s) {
    for (double left; (left = until_s - rths_monotonic_s()) > 0;) {
        if (r->fd < 0 || r->rx_len == RX_CAP) {
            struct timespec ts = {(time_t)left, (long)((left - (double)(time_t)left) * 1e9)};
            nanosleep(&ts, NULL);
            continue;
        }
        struct pollfd pfd = {r->fd, POLLIN, 0};
        int pr = poll(&pfd, 1, (int)ceil(left * 1000.0));
        if (pr <= 0) continue;
        ssize_t k = recv(r->fd, r->rx + r->rx_len, RX_CAP - r->rx_len, MSG_DONTWAIT);
        if (k > 0) {
            r->rx_len += (size_t)k;
            mark_arrival(r);
        } else if (k == 0 || (errno != EINTR && errno != EAGAIN)) {
            struct timespec ts = {(time_t)left, (long)((left - (double)(time_t)left) * 1e9)};
            nanosleep(&ts, NULL); /* the read after the wait finds the failure */
        }
    }
}

static int link_fail(remote *r, rths_error *err, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static int link_fail(remote *r, rths_error *err, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(r->fault_msg, sizeof r->fault_msg, fmt, ap);
    va_end(ap);
    if (r->fd >= 0) close(r->fd);
    r->fd = -1;
    r->rx_len = 0;
    r->marks = 0;
    r->armed = 0;
    r->forcing_seq = 0; /* the lost link answers nothing more */
    r->fault = RTHS_RIG_FAULT_LINK;
    return rths_error_set(err, RTHS_EFAIL, "controller %s: link lost: %s", r->uri, r->fault_msg);
}

static int send_msg(remote *r, rths_msg *m, rths_error *err) {
    uint8_t buf[RTHS_PROTO_MAX_FRAME];
    size_t n = rths_proto_encode(m, buf, sizeof buf);
    if (!n)
        return rths_error_set(err, RTHS_EINPUT, "cannot encode %s (values not finite?)",
                              rths_msg_type_name(m->type));
    /* the test hook: the frame reaches the controller delay_s later, as over a long link; one
     * sent right behind another (nothing read between: SET_TARGET behind SET_FORCING) was ready
     * with it and travels with it, its delay spent in the wait for the first */
    if (r->delay_s > 0 && !r->sent_last) wait_receiving(r, rths_monotonic_s() + r->delay_s);
    r->sent_last = 1;
    size_t off = 0;
    while (off < n) {
        ssize_t k = send(r->fd, buf + off, n - off, MSG_NOSIGNAL);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return link_fail(r, err, "send: %s", strerror(errno));
        off += (size_t)k;
    }
    r->last_sent_s = rths_monotonic_s();
    return RTHS_OK;
}

static void queue_period(remote *r, const rths_proto_period *p) {
    /* Half a sample of slack: start and ACK times are both sample counts times h. */
    if (p->start_time_s < r->valid_from_s - 0.5 * r->h) return;
    if (r->q_len == r->q_cap) {
        size_t cap = r->q_cap ? 2 * r->q_cap : 64;
        rths_proto_period *nq = malloc(cap * sizeof *nq);
        if (!nq) return; /* dropped; run_periods will wait for the next one */
        for (size_t i = 0; i < r->q_len; i++)
            nq[i] = r->q[(r->q_head + i) % r->q_cap];
        free(r->q);
        r->q = nq;
        r->q_cap = cap;
        r->q_head = 0;
    }
    r->q[(r->q_head + r->q_len) % r->q_cap] = *p;
    r->q_len++;
}

/* Takes in an unsolicited frame. */
static void absorb(remote *r, const rths_msg *m) {
    switch (m->type) {
    case RTHS_MSG_PERIOD:
        if (m->u.period.end_time_s > r->last_time_s) r->last_time_s = m->u.period.end_time_s;
        queue_period(r, &m->u.period);
        break;
    case RTHS_MSG_TRACE:
        for (int i = 0; i < m->u.trace.count; i++) {
            const rths_proto_trace_sample *s = &m->u.trace.s[i];
            if (s->time_s > r->last_time_s) r->last_time_s = s->time_s;
            if (!r->tracing || s->time_s < r->trace_t0 - 0.5 * r->h || r->trace_n >= r->trace_max ||
                s->time_s > r->trace_t1 + 0.5 * r->h)
                continue;
            rths_trace_sample t = {.time_s = s->time_s,
                                   .x_phys_m = s->x_phys_m,
                                   .x_num_m = s->x_num_m,
                                   .target_m = s->target_m,
                                   .force_n = s->force_n,
                                   .demand = s->demand};
            if (m->u.trace.dofs > 1) { /* every interface DoF's signals */
                t.dofs = m->u.trace.dofs;
                for (int d = 0; d < t.dofs; d++) {
                    t.x_phys_dof_m[d] = s->x_phys_dof_m[d];
                    t.x_num_dof_m[d] = s->x_num_dof_m[d];
                    t.target_dof_m[d] = s->target_dof_m[d];
                    t.force_dof_n[d] = s->force_dof_n[d];
                    t.demand_dof_v[d] = s->demand_dof[d];
                }
            }
            r->trace_out[r->trace_n++] = t;
        }
        break;
    case RTHS_MSG_STATUS:
        r->last_time_s = m->u.status.time_s;
        r->armed = (m->u.status.flags & RTHS_STATUS_ARMED) != 0;
        if (m->u.status.fault && r->fault == RTHS_RIG_OK) {
            r->fault = (rths_rig_fault)m->u.status.fault;
            /* the controller's own account names the channel, the value and the limit; shown
             * to the operator, so printable text only */
            char detail[RTHS_PROTO_MAX_TEXT + 4];
            rths_proto_printable(m->u.status.fault_detail, RTHS_PROTO_MAX_TEXT, detail,
                                 sizeof detail);
            if (detail[0])
                snprintf(r->fault_msg, sizeof r->fault_msg, "controller latched a %s fault: %s",
                         rths_rig_fault_name(r->fault), detail);
            else
                snprintf(r->fault_msg, sizeof r->fault_msg, "controller latched a %s fault",
                         rths_rig_fault_name(r->fault));
        }
        break;
    default:
        break;
    }
}

/* A frame of another protocol version: the link is unusable; the message names both versions
 * and, when the controller's frame is an ERROR (its layout is the same in every version), what
 * the controller said. */
static int version_fail(remote *r, rths_error *err) {
    char why[RTHS_PROTO_MAX_TEXT + 1];
    rths_proto_version_message(why, sizeof why, rths_proto_frame_version(r->rx, r->rx_len));
    rths_msg m;
    size_t used;
    if (rths_proto_decode_error_any_version(r->rx, r->rx_len, &m, &used) == RTHS_PROTO_OK)
        return link_fail(r, err, "%s (the controller says: %s)", why, m.u.error.message);
    return link_fail(r, err, "%s", why);
}

/* When byte used - 1 of rx arrived (now when unmarked). */
static double arrival_s(const remote *r, size_t used) {
    for (int i = 0; i < r->marks; i++)
        if (r->mark_end[i] >= used) return r->mark_time[i];
    return rths_monotonic_s();
}
static void consume_marks(remote *r, size_t used) {
    int keep = 0;
    for (int i = 0; i < r->marks; i++)
        if (r->mark_end[i] > used) {
            r->mark_end[keep] = r->mark_end[i] - used;
            r->mark_time[keep++] = r->mark_time[i];
        }
    r->marks = keep;
}

/* Reads one frame, waiting at most timeout_s. RTHS_OK with *got = 1 (frame in m) or 0 (timeout). */
static int read_frame(remote *r, double timeout_s, rths_msg *m, int *got, rths_error *err) {
    double deadline = rths_monotonic_s() + timeout_s;
    *got = 0;
    r->sent_last = 0;
    for (;;) {
        size_t used = 0;
        int st = rths_proto_decode(r->rx, r->rx_len, m, &used);
        if (st == RTHS_PROTO_OK && r->delay_s > 0) {
            /* the test hook: a frame is read delay_s after its last byte arrived */
            double ready = arrival_s(r, used) + r->delay_s;
            if (ready > deadline) {
                wait_receiving(r, deadline);
                return RTHS_OK;
            }
            wait_receiving(r, ready);
        }
        if (st == RTHS_PROTO_OK) {
            memmove(r->rx, r->rx + used, r->rx_len - used);
            r->rx_len -= used;
            consume_marks(r, used);
            *got = 1;
            return RTHS_OK;
        }
        if (st == RTHS_PROTO_EVERSION) return version_fail(r, err);
        if (st != RTHS_PROTO_INCOMPLETE)
            return link_fail(r, err, "bad frame from the controller: %s%s%s",
                             rths_proto_status_name(st), m->problem[0] ? ": " : "", m->problem);
        double left = deadline - rths_monotonic_s();
        if (left <= 0) return RTHS_OK;
        struct pollfd pfd = {r->fd, POLLIN, 0};
        int pr = poll(&pfd, 1, (int)ceil(left * 1000.0));
        if (pr < 0 && errno == EINTR) continue;
        if (pr < 0) return link_fail(r, err, "poll: %s", strerror(errno));
        if (pr == 0) continue;
        ssize_t k = recv(r->fd, r->rx + r->rx_len, RX_CAP - r->rx_len, 0);
        if (k < 0 && (errno == EINTR || errno == EAGAIN)) continue;
        if (k == 0) return link_fail(r, err, "the controller closed the connection");
        if (k < 0) return link_fail(r, err, "recv: %s", strerror(errno));
        r->rx_len += (size_t)k;
        if (r->delay_s > 0) mark_arrival(r);
    }
}

/* The outstanding SET_FORCING's reply: an ACK says from when periods run the new forcing (a
 * target set since cannot make an earlier one valid), and everything queued ran the old; an
 * ERROR restores the forcing before it and is kept for the operations that would run it. */
static void forcing_reply(remote *r, const rths_msg *reply) {
    r->forcing_seq = 0;
    if (reply->type == RTHS_MSG_ACK) {
        if (reply->u.ack.time_s > r->valid_from_s) r->valid_from_s = reply->u.ack.time_s;
        r->q_len = 0;
        return;
    }
    r->frequency_hz = r->prev_frequency_hz;
    r->amplitude_n = r->prev_amplitude_n;
    r->have_forcing = r->prev_have_forcing;
    r->forcing_rc =
        rths_error_set(&r->forcing_err, RTHS_EFAIL, "controller %s refused SET_FORCING: %s (%s)",
                       r->uri, reply->u.error.message, rths_proto_status_name(reply->u.error.code));
}

static int is_forcing_reply(const remote *r, const rths_msg *m) {
    return r->forcing_seq && m->seq == r->forcing_seq &&
           (m->type == RTHS_MSG_ACK || m->type == RTHS_MSG_ERROR);
}

/* Sends a request and waits for its reply (frames pushed meanwhile are absorbed, an outstanding
 * SET_FORCING's reply taken on the way). An ERROR reply returns RTHS_EFAIL with the
 * controller's message (the link stays up). */
static int request(remote *r, rths_msg *req, int want_type, rths_msg *reply, rths_error *err) {
    if (r->fd < 0)
        return rths_error_set(err, RTHS_EFAIL, "controller %s: not connected (%s)", r->uri,
                              r->fault_msg);
    if (++r->seq == 0) r->seq = 1;
    req->seq = r->seq;
    int rc = send_msg(r, req, err);
    if (rc) return rc;
    double deadline = rths_monotonic_s() + r->opt.reply_timeout_s;
    for (;;) {
        int got;
        double left = deadline - rths_monotonic_s();
        if (left <= 0)
            return link_fail(r, err, "no reply to %s within %.3g s", rths_msg_type_name(req->type),
                             r->opt.reply_timeout_s);
        if ((rc = read_frame(r, left, reply, &got, err))) return rc;
        if (!got) continue;
        if (is_forcing_reply(r, reply)) {
            forcing_reply(r, reply);
            continue;
        }
        if (reply->seq != req->seq || (reply->type != want_type && reply->type != RTHS_MSG_ERROR)) {
            if (reply->seq == 0 && reply->type == RTHS_MSG_ERROR)
                /* unsolicited: the controller refuses the connection (busy) or closes it */
                return link_fail(r, err, "%s (%s)", reply->u.error.message,
                                 rths_proto_status_name(reply->u.error.code));
            if (reply->seq == 0) {
                absorb(r, reply);
                continue;
            }
            return link_fail(r, err, "unexpected %s (seq %u) in reply to %s",
                             rths_msg_type_name(reply->type), reply->seq,
                             rths_msg_type_name(req->type));
        }
        if (r->forcing_seq) /* replies come in the order sent: SET_FORCING's was lost */
            return link_fail(r, err, "no reply to SET_FORCING (seq %u) before the reply to %s",
                             r->forcing_seq, rths_msg_type_name(req->type));
        if (reply->type == RTHS_MSG_ERROR)
            return rths_error_set(err, RTHS_EFAIL, "controller %s refused %s: %s (%s)", r->uri,
                                  rths_msg_type_name(req->type), reply->u.error.message,
                                  rths_proto_status_name(reply->u.error.code));
        if (reply->type == RTHS_MSG_ACK && reply->u.ack.time_s > r->last_time_s)
            r->last_time_s = reply->u.ack.time_s;
        if (reply->type == RTHS_MSG_STATUS) absorb(r, reply);
        return RTHS_OK;
    }
}

static int simple(remote *r, int type, rths_msg *reply, rths_error *err) {
    rths_msg m;
    rths_msg_init(&m, type, 0);
    return request(r, &m, RTHS_MSG_ACK, reply, err);
}

static int subscribe(remote *r, unsigned flags, uint32_t decimation, rths_msg *reply,
                     rths_error *err) {
    rths_msg m;
    rths_msg_init(&m, RTHS_MSG_SUBSCRIBE, 0);
    m.u.subscribe.flags = (uint8_t)flags;
    m.u.subscribe.trace_decimation = decimation;
    return request(r, &m, RTHS_MSG_ACK, reply, err);
}

/* Waits for the outstanding SET_FORCING's reply (a PING behind it: its reply comes after), then
 * says whether the forcing stands. */
static int forcing_outcome(remote *r, rths_error *err) {
    if (r->forcing_seq) {
        rths_msg reply;
        int rc = simple(r, RTHS_MSG_PING, &reply, err);
        if (rc) return rc;
    }
    if (r->forcing_rc && err) *err = r->forcing_err;
    return r->forcing_rc;
}

/* Sends SET_FORCING of r's forcing, its reply left outstanding (forcing_reply takes it; none may
 * be outstanding already); prev_* are restored if it is refused. */
static int send_forcing(remote *r, double prev_frequency_hz, double prev_amplitude_n,
                        int prev_have_forcing, rths_error *err) {
    if (r->fd < 0)
        return rths_error_set(err, RTHS_EFAIL, "controller %s: not connected (%s)", r->uri,
                              r->fault_msg);
    int rc;
    r->forcing_rc = 0;
    rths_msg m;
    rths_msg_init(&m, RTHS_MSG_SET_FORCING, 0);
    m.u.forcing.frequency_hz = r->frequency_hz;
    m.u.forcing.amplitude_n = r->amplitude_n;
    if (++r->seq == 0) r->seq = 1;
    m.seq = r->seq;
    if ((rc = send_msg(r, &m, err))) return rc;
    r->forcing_seq = m.seq;
    r->prev_frequency_hz = prev_frequency_hz;
    r->prev_amplitude_n = prev_amplitude_n;
    r->prev_have_forcing = prev_have_forcing;
    return RTHS_OK;
}

static int send_target(remote *r, rths_error *err) {
    rths_msg m, reply;
    rths_msg_init(&m, RTHS_MSG_SET_TARGET, 0);
    m.u.target.dofs = r->interface_dofs;
    m.u.target.harmonics = r->harmonics;
    for (int i = 0; i < r->interface_dofs * r->harmonics; i++) {
        m.u.target.a[i] = r->ta[i];
        m.u.target.b[i] = r->tb[i];
    }
    int rc = request(r, &m, RTHS_MSG_ACK, &reply, err);
    if (rc) return rc;
    if (reply.u.ack.time_s > r->valid_from_s) r->valid_from_s = reply.u.ack.time_s;
    r->q_len = 0;
    return RTHS_OK;
}

static int connect_and_hello(remote *r, rths_error *err) {
    char port[16];
    snprintf(port, sizeof port, "%d", r->port);
    struct addrinfo hints = {0}, *res = NULL;
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    int gai = getaddrinfo(r->host, port, &hints, &res);
    if (gai)
        return rths_error_set(err, RTHS_EFAIL, "controller %s: cannot resolve '%s': %s", r->uri,
                              r->host, gai_strerror(gai));
    int fd = -1;
    char why[256] = "no address";
    for (struct addrinfo *ai = res; ai && fd < 0; ai = ai->ai_next) {
        fd = socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, ai->ai_protocol);
        if (fd < 0) continue;
        int ok = connect(fd, ai->ai_addr, ai->ai_addrlen) == 0;
        if (!ok && errno == EINPROGRESS) {
            struct pollfd pfd = {fd, POLLOUT, 0};
            int pr = poll(&pfd, 1, (int)(r->opt.connect_timeout_s * 1000.0));
            int soerr = 0;
            socklen_t sl = sizeof soerr;
            if (pr == 1 && !getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &sl) && !soerr)
                ok = 1;
            else
                snprintf(why, sizeof why, "%s", pr == 0 ? "connect timed out" : strerror(soerr));
        } else if (!ok) {
            snprintf(why, sizeof why, "%s", strerror(errno));
        }
        if (!ok) {
            close(fd);
            fd = -1;
        }
    }
    freeaddrinfo(res);
    if (fd < 0)
        return rths_error_set(err, RTHS_EFAIL, "controller %s: cannot connect: %s", r->uri, why);
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    /* Back to blocking sends (bounded by a timeout); reads always go through poll. */
    struct timeval tv = {(time_t)r->opt.reply_timeout_s, 0};
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    r->fd = fd;
    r->rx_len = 0;
    r->marks = 0;
    r->q_len = 0;
    r->armed = 0;
    r->valid_from_s = 0.0;
    r->last_time_s = 0.0;
    r->forcing_seq = 0;

    rths_msg m, reply;
    rths_msg_init(&m, RTHS_MSG_HELLO, 0);
    m.u.hello.version = RTHS_PROTO_VERSION;
    snprintf(m.u.hello.name, sizeof m.u.hello.name, "%s", r->client_name);
    int rc = request(r, &m, RTHS_MSG_HELLO_REPLY, &reply, err);
    if (rc) {
        if (r->fd >= 0) close(r->fd);
        r->fd = -1;
        return rc;
    }
    if (reply.u.hello_reply.version != RTHS_PROTO_VERSION ||
        !(reply.u.hello_reply.sample_period_s > 0)) {
        close(r->fd);
        r->fd = -1;
        char why[RTHS_PROTO_MAX_TEXT + 1];
        rths_proto_version_message(why, sizeof why, reply.u.hello_reply.version);
        return rths_error_set(err, RTHS_EFAIL, "controller %s: %s; sample period %g s", r->uri, why,
                              reply.u.hello_reply.sample_period_s);
    }
    if (r->interface_dofs && reply.u.hello_reply.interface_dofs != r->interface_dofs) {
        /* a reconnection to a controller configured otherwise: the host's targets would not fit */
        int had = r->interface_dofs;
        close(r->fd);
        r->fd = -1;
        return rths_error_set(err, RTHS_EFAIL,
                              "controller %s now drives %d interface DoF(s); this run drives %d",
                              r->uri, reply.u.hello_reply.interface_dofs, had);
    }
    r->interface_dofs = reply.u.hello_reply.interface_dofs;
    r->h = reply.u.hello_reply.sample_period_s;
    r->watchdog_s = reply.u.hello_reply.watchdog_s;
    r->noise_m = reply.u.hello_reply.noise_level_m;
    rths_proto_printable(reply.u.hello_reply.name, RTHS_PROTO_MAX_TEXT - 3, r->controller_name,
                         sizeof r->controller_name);
    if ((rc = subscribe(r, RTHS_SUBSCRIBE_PERIODS, 1, &reply, err))) return rc;
    rths_msg_init(&m, RTHS_MSG_GET_STATUS, 0);
    if ((rc = request(r, &m, RTHS_MSG_STATUS, &reply, err))) return rc;
    return RTHS_OK;
}

/* ---- rig operations ---- */

static int check_usable(remote *r, rths_error *err) {
    if (r->fault != RTHS_RIG_OK)
        return rths_error_set(err, RTHS_EFAIL, "controller %s: rig fault '%s' latched: %s", r->uri,
                              rths_rig_fault_name(r->fault), r->fault_msg);
    return RTHS_OK;
}

static int ensure_armed(remote *r, rths_error *err) {
    if (r->armed) return RTHS_OK;
    rths_msg reply;
    int rc = simple(r, RTHS_MSG_ARM, &reply, err);
    if (rc) return rc;
    r->armed = 1;
    if (reply.u.ack.time_s > r->valid_from_s) r->valid_from_s = reply.u.ack.time_s;
    r->q_len = 0;
    return RTHS_OK;
}

static double ping_interval(const remote *r) {
    double p = 0.25 * r->watchdog_s;
    return p > 0 && p < 0.5 ? p : 0.5;
}

/* Waits for frames for up to `wait` seconds, pinging to keep the watchdog fed (the last frame
 * sent counts, across calls: a host calling run_periods(1) in a loop is not silent). */
static int pump(remote *r, double wait, rths_error *err) {
    rths_msg m;
    int got, rc;
    if (rths_monotonic_s() - r->last_sent_s >= ping_interval(r)) {
        rths_msg reply;
        if ((rc = simple(r, RTHS_MSG_PING, &reply, err))) return rc;
    }
    if ((rc = read_frame(r, wait, &m, &got, err))) return rc;
    if (got && is_forcing_reply(r, &m)) {
        forcing_reply(r, &m);
    } else if (got) {
        if (m.seq != 0)
            return link_fail(r, err, "unexpected %s (seq %u) with no request outstanding",
                             rths_msg_type_name(m.type), m.seq);
        absorb(r, &m);
    }
    return check_usable(r, err);
}

static void to_fourier(const rths_proto_fourier *in, rths_fourier *out) {
    for (int k = 0; k <= RTHS_MAX_HARMONICS; k++) {
        out->a[k] = in->a[k];
        out->b[k] = in->b[k];
    }
}

static int r_set_forcing(void *self, double frequency_hz, double amplitude_n, rths_error *err) {
    remote *r = self;
    int rc = check_usable(r, err);
    if (rc) return rc;
    if (!(frequency_hz > 0) || !isfinite(frequency_hz) || !isfinite(amplitude_n))
        return rths_error_set(err, RTHS_EINPUT, "forcing %g Hz, %g N: frequency must be > 0",
                              frequency_hz, amplitude_n);
    /* one SET_FORCING outstanding at a time: the last one's outcome first (a refusal restores
     * the forcing before it, which this one then replaces) */
    if (r->forcing_seq && (rc = forcing_outcome(r, err)) && r->fd < 0) return rc;
    double of = r->frequency_hz, oa = r->amplitude_n;
    int oh = r->have_forcing;
    r->frequency_hz = frequency_hz;
    r->amplitude_n = amplitude_n;
    r->have_forcing = 1;
    if ((rc = send_forcing(r, of, oa, oh, err))) {
        r->frequency_hz = of;
        r->amplitude_n = oa;
        r->have_forcing = oh;
    }
    return rc;
}

static int r_set_target_dofs(void *self, int dofs, int harmonics, const double *a, const double *b,
                             rths_error *err) {
    remote *r = self;
    int rc = check_usable(r, err);
    if (rc) return rc;
    if (dofs != r->interface_dofs)
        return rths_error_set(err, RTHS_EINPUT,
                              "target for %d interface DoF(s); controller %s drives %d", dofs,
                              r->uri, r->interface_dofs);
    if (harmonics < 0 || harmonics > RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT, "%d harmonics: 0..%d supported", harmonics,
                              RTHS_MAX_HARMONICS);
    /* a refused target (e.g. beyond the displacement limit) must not be the one restored on
     * reconnection: keep the last accepted one */
    int old_harmonics = r->harmonics;
    double old_a[sizeof r->ta / sizeof r->ta[0]], old_b[sizeof r->tb / sizeof r->tb[0]];
    memcpy(old_a, r->ta, sizeof old_a);
    memcpy(old_b, r->tb, sizeof old_b);
    r->harmonics = harmonics;
    for (int i = 0; i < dofs * harmonics; i++) {
        r->ta[i] = a[i];
        r->tb[i] = b[i];
    }
    if ((rc = send_target(r, err))) {
        r->harmonics = old_harmonics;
        memcpy(r->ta, old_a, sizeof old_a);
        memcpy(r->tb, old_b, sizeof old_b);
        return rc;
    }
    /* the forcing sent just before was answered on the way: if it was refused, this target
     * runs under the one before, and the caller must know */
    return forcing_outcome(r, err);
}

static int r_set_target(void *self, int harmonics, const double *a, const double *b,
                        rths_error *err) {
    return r_set_target_dofs(self, 1, harmonics, a, b, err);
}

static int r_interface_dofs(void *self) {
    return ((remote *)self)->interface_dofs;
}

/* A PERIOD frame as the rig's record: every interface DoF, [0] repeating the first (signals.h). */
static void to_period(const rths_proto_period *p, rths_period *o) {
    memset(o, 0, sizeof *o);
    o->frequency_hz = p->frequency_hz;
    o->end_time_s = p->end_time_s;
    o->samples = (int)p->samples;
    o->late_samples = (int)p->late_samples;
    o->clipped_demand_samples = (int)p->clipped_demand_samples;
    o->saturated_sensor_samples = (int)p->saturated_sensor_samples;
    to_fourier(&p->phys, &o->phys);
    to_fourier(&p->num, &o->num);
    to_fourier(&p->force, &o->force);
    o->interface_dofs = p->interface_dofs > 1 ? p->interface_dofs : 1;
    o->phys_dof[0] = o->phys;
    o->num_dof[0] = o->num;
    o->force_dof[0] = o->force;
    for (int d = 1; d < o->interface_dofs; d++) {
        to_fourier(&p->phys_dof[d], &o->phys_dof[d]);
        to_fourier(&p->num_dof[d], &o->num_dof[d]);
        to_fourier(&p->force_dof[d], &o->force_dof[d]);
    }
    o->output_dofs = p->output_dofs;
    for (int j = 0; j < o->output_dofs; j++)
        to_fourier(&p->output_dof[j], &o->output_dof[j]);
}

static int r_run_periods(void *self, int count, rths_period *out, rths_error *err) {
    remote *r = self;
    int rc = check_usable(r, err);
    if (rc) return rc;
    if ((rc = forcing_outcome(r, err))) return rc;
    if (!r->have_forcing) return rths_error_set(err, RTHS_EINPUT, "run_periods before set_forcing");
    if ((rc = ensure_armed(r, err))) return rc;
    double last_progress = rths_monotonic_s();
    double stall = r->opt.stall_timeout_s + 2.0 / r->frequency_hz;
    int n = 0;
    while (n < count) {
        if (r->q_len) {
            to_period(&r->q[r->q_head], &out[n++]);
            r->q_head = (r->q_head + 1) % r->q_cap;
            r->q_len--;
            last_progress = rths_monotonic_s();
            continue;
        }
        if (rths_monotonic_s() - last_progress > stall)
            return link_fail(r, err, "no whole period from the controller for %.3g s", stall);
        if ((rc = pump(r, ping_interval(r), err))) return rc;
    }
    return RTHS_OK;
}

static int r_record_trace(void *self, double duration_s, int max_samples, rths_trace_sample *out,
                          int *n_out, rths_error *err) {
    remote *r = self;
    *n_out = 0;
    int rc = check_usable(r, err);
    if (rc) return rc;
    if (!(duration_s > 0) || max_samples < 1)
        return rths_error_set(err, RTHS_EINPUT, "trace of %g s with %d samples", duration_s,
                              max_samples);
    if ((rc = forcing_outcome(r, err))) return rc;
    if ((rc = ensure_armed(r, err))) return rc;
    double dec = ceil(duration_s / r->h / max_samples);
    if (dec < 1) dec = 1;
    if (dec > 4294967295.0) dec = 4294967295.0;
    rths_msg reply;
    r->tracing = 0;
    if ((rc = subscribe(r, RTHS_SUBSCRIBE_PERIODS | RTHS_SUBSCRIBE_TRACES, (uint32_t)dec, &reply,
                        err)))
        return rc;
    r->tracing = 1;
    r->trace_out = out;
    r->trace_max = max_samples;
    r->trace_n = 0;
    r->trace_t0 = reply.u.ack.time_s;
    r->trace_t1 = reply.u.ack.time_s + duration_s;
    double start = rths_monotonic_s();
    while (r->trace_n < max_samples && r->last_time_s < r->trace_t1) {
        if (rths_monotonic_s() - start > duration_s + r->opt.stall_timeout_s) {
            r->tracing = 0;
            return link_fail(r, err, "trace did not arrive within %.3g s",
                             duration_s + r->opt.stall_timeout_s);
        }
        if ((rc = pump(r, ping_interval(r), err))) {
            r->tracing = 0;
            *n_out = r->trace_n;
            return rc;
        }
    }
    r->tracing = 0;
    *n_out = r->trace_n;
    return subscribe(r, RTHS_SUBSCRIBE_PERIODS, 1, &reply, err);
}

static int refresh(remote *r) {
    if (r->fd < 0) return RTHS_EFAIL;
    rths_msg m, reply;
    rths_msg_init(&m, RTHS_MSG_GET_STATUS, 0);
    return request(r, &m, RTHS_MSG_STATUS, &reply, NULL);
}

static double r_time_s(void *self) {
    remote *r = self;
    refresh(r);
    return r->last_time_s;
}

static rths_rig_fault r_fault(void *self) {
    remote *r = self;
    if (r->fault == RTHS_RIG_OK) refresh(r);
    return r->fault;
}

static int r_reset_fault(void *self, rths_error *err) {
    remote *r = self;
    int rc;
    if (r->fd < 0) {
        if ((rc = connect_and_hello(r, err))) return rc;
        r->fault = RTHS_RIG_OK;
        r->fault_msg[0] = '\0';
    }
    rths_msg reply;
    if ((rc = simple(r, RTHS_MSG_RESET_FAULT, &reply, err))) return rc;
    r->fault = RTHS_RIG_OK;
    r->fault_msg[0] = '\0';
    r->armed = 0;
    /* the last forcing and target again; a refusal of a later forcing stays reported until the
     * next set_forcing (rig_remote.h) */
    const int refused_rc = r->forcing_rc;
    const rths_error refused = r->forcing_err;
    if (r->have_forcing) {
        if ((rc = send_forcing(r, r->frequency_hz, r->amplitude_n, r->have_forcing, err)))
            return rc;
        if ((rc = send_target(r, err)) || (rc = forcing_outcome(r, err))) return rc;
    } else if ((rc = send_target(r, err))) {
        return rc;
    }
    r->forcing_rc = refused_rc;
    r->forcing_err = refused;
    return RTHS_OK;
}

static double r_noise_level_m(void *self) {
    return ((remote *)self)->noise_m;
}

/* DISARM: the controller ramps forcing and target to zero (controller.ramp_time_s) and stays
 * disarmed; the next run_periods or record_trace arms it again. Without a link the controller
 * has disarmed itself already (loss of the controlling connection disarms it). */
static int r_disarm(void *self, rths_error *err) {
    remote *r = self;
    if (r->fd < 0) return RTHS_OK;
    rths_msg reply;
    int rc = simple(r, RTHS_MSG_DISARM, &reply, err);
    if (!rc) r->armed = 0;
    return rc;
}

static void r_destroy(void *self) {
    remote *r = self;
    if (r->fd >= 0) {
        rths_msg reply;
        r->opt.reply_timeout_s = 1.0;
        simple(r, RTHS_MSG_DISARM, &reply, NULL);
        if (r->fd >= 0) close(r->fd);
    }
    free(r->q);
    free(r);
}

static const rths_rig_ops remote_ops = {
    .set_forcing = r_set_forcing,
    .set_target = r_set_target,
    .run_periods = r_run_periods,
    .record_trace = r_record_trace,
    .time_s = r_time_s,
    .fault = r_fault,
    .reset_fault = r_reset_fault,
    .disarm = r_disarm,
    .noise_level_m = r_noise_level_m,
    .destroy = r_destroy,
    .set_target_dofs = r_set_target_dofs,
    .interface_dofs = r_interface_dofs,
};

int rths_remote_rig_known_fault(rths_rig *rig, rths_rig_fault *out) {
    remote *r = rths_rig_backend(rig, &remote_ops);
    if (!r) return 0;
    *out = r->fault;
    return 1;
}

int rths_remote_rig_create(const char *uri, const rths_remote_options *opt, rths_rig **out,
                           rths_error *err) {
    *out = NULL;
    remote *r = calloc(1, sizeof *r);
    if (!r) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    r->fd = -1;
    int rc = rths_remote_parse_uri(uri, r->host, sizeof r->host, &r->port, err);
    if (rc) {
        free(r);
        return rc;
    }
    snprintf(r->uri, sizeof r->uri, "%s", uri);
    if (opt)
        r->opt = *opt;
    else
        rths_remote_options_defaults(&r->opt);
    if (!(r->opt.connect_timeout_s > 0)) r->opt.connect_timeout_s = 5.0;
    if (!(r->opt.reply_timeout_s > 0)) r->opt.reply_timeout_s = 5.0;
    if (!(r->opt.stall_timeout_s > 0)) r->opt.stall_timeout_s = 10.0;
    /* the test hook (docs/protocol.md, "Injected link delay"): the environment's delay when the
     * options set none */
    const char *env = getenv("RTHS_TEST_LINK_DELAY_S");
    if (!(r->opt.link_delay_s > 0) && env && *env) {
        char *end;
        double d = strtod(env, &end);
        if (*end || !(d >= 0) || d > 60) {
            free(r);
            return rths_error_set(err, RTHS_EINPUT,
                                  "RTHS_TEST_LINK_DELAY_S='%.40s': expected seconds in [0, 60]",
                                  env);
        }
        r->opt.link_delay_s = d;
    }
    r->delay_s = r->opt.link_delay_s > 0 ? r->opt.link_delay_s : 0.0;
    /* a request waits for its reply over both ways of the link */
    if (r->opt.reply_timeout_s < 4 * r->delay_s + 1) r->opt.reply_timeout_s = 4 * r->delay_s + 1;
    snprintf(r->client_name, sizeof r->client_name, "%s",
             r->opt.client_name ? r->opt.client_name : "rths host");
    r->opt.client_name = NULL;
    if ((rc = connect_and_hello(r, err))) {
        if (r->fd >= 0) close(r->fd);
        free(r->q);
        free(r);
        return rc;
    }
    char desc[600];
    snprintf(desc, sizeof desc, "remote controller %.300s (%.200s)", r->uri, r->controller_name);
    *out = rths_rig_create(&remote_ops, r, desc);
    if (!*out) {
        r_destroy(r);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    return RTHS_OK;
}
