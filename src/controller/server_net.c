/* The controller server's network thread: the listening socket, the one host session (accept,
 * read and decode, bounded non-blocking transmit), the period and trace streams, and the
 * operator's notices on stderr. Requests are passed to server_dispatch.c. */
#include "controller/server_internal.h"

#include <errno.h>
#include <math.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

/* ---- the network thread ---- */

/* Connection notices on stderr (network thread), at most NOTICE_BURST per second: a storm of
 * connections must not flood the operator's terminal or log. What is held back is counted and
 * reported once the second is over (notices_flush). */
static void notices_flush(rths_server *s, int64_t now) {
    if (now - s->notice_window_start_ns < NOTICE_WINDOW_NS) return;
    if (s->notices_suppressed && !s->opt.quiet)
        fprintf(stderr, "rths controller: %d more connection notices suppressed\n",
                s->notices_suppressed);
    s->notice_window_start_ns = now;
    s->notices_in_window = s->notices_suppressed = 0;
}

void server_notice(rths_server *s, const char *fmt, ...) {
    if (s->opt.quiet) return;
    notices_flush(s, mono_ns());
    if (s->notices_in_window >= NOTICE_BURST) {
        s->notices_suppressed++;
        return;
    }
    s->notices_in_window++;
    va_list ap;
    va_start(ap, fmt);
    fputs("rths controller: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

/* Queues a frame; stream frames (replies == 0) only when the reply reserve stays free. */
int server_queue_frame(rths_server *s, rths_msg *m, int reply) {
    client *c = &s->c;
    if (c->fd < 0) return 0;
    size_t room = TX_CAP - c->tx_len;
    if (!reply) room = room > TX_RESERVE ? room - TX_RESERVE : 0;
    size_t n = rths_proto_encode(m, c->tx + c->tx_len, room);
    if (!n) return 0;
    c->tx_len += n;
    return 1;
}

static int flush_tx(rths_server *s);

/* Sends what the socket takes now; -1 when the connection is broken. */
static int flush_tx(rths_server *s) {
    client *c = &s->c;
    while (c->fd >= 0 && c->tx_len) {
        ssize_t k = send(c->fd, c->tx, c->tx_len, MSG_DONTWAIT | MSG_NOSIGNAL);
        if (k < 0 && errno == EINTR) continue;
        if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return 0;
        if (k <= 0) {
            c->tx_len = 0;
            return -1;
        }
        memmove(c->tx, c->tx + k, c->tx_len - (size_t)k);
        c->tx_len -= (size_t)k;
    }
    return 0;
}

void server_drop_client(rths_server *s, const char *why) {
    client *c = &s->c;
    if (c->fd < 0) return;
    (void)flush_tx(s); /* best effort: a final ERROR frame may still get out */
    close(c->fd);
    c->fd = -1;
    atomic_store(&s->client_connected, 0);
    atomic_store(&s->trace_on, 0);
    server_notice(s, "client %s disconnected (%s)", c->peer, why);
    if (atomic_load(&s->armed)) {
        /* Loss of the controlling connection disarms: excitation and target ramp to zero. */
        loop_cmd cmd = {.id = ++s->next_cmd_id, .type = CMD_DISARM, .reason = RTHS_DISARM_LINK};
        rths_spsc_push(&s->cmds, &cmd);
    }
}

/* A frame of another protocol version: the refusal names both versions, framed in the peer's
 * version when this build can write it (the ERROR layout is the same in every version), so an
 * older host reads why; then the connection closes (the stream cannot be read). */
static void refuse_version(rths_server *s, const uint8_t *frame, size_t len) {
    client *c = &s->c;
    int peer = rths_proto_frame_version(frame, len);
    char why[RTHS_PROTO_MAX_TEXT + 1];
    rths_proto_version_message(why, sizeof why, peer);
    rths_msg m;
    rths_msg_error(&m, 0, RTHS_PROTO_EVERSION, 0, "%s; closing the connection", why);
    size_t room = TX_CAP - c->tx_len;
    size_t n = rths_proto_encode_error_as(&m, peer, c->tx + c->tx_len, room);
    if (!n) n = rths_proto_encode(&m, c->tx + c->tx_len, room);
    c->tx_len += n;
    server_drop_client(s, why);
}

static void read_client(rths_server *s) {
    client *c = &s->c;
    ssize_t k = recv(c->fd, c->rx + c->rx_len, RX_CAP - c->rx_len, MSG_DONTWAIT);
    if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return;
    if (k <= 0) {
        server_drop_client(s, k == 0 ? "closed by the host" : strerror(errno));
        return;
    }
    c->rx_len += (size_t)k;
    size_t off = 0;
    while (c->fd >= 0) {
        rths_msg m;
        size_t used = 0;
        int st = rths_proto_decode(c->rx + off, c->rx_len - off, &m, &used);
        if (st == RTHS_PROTO_INCOMPLETE) break;
        if (st == RTHS_PROTO_EVERSION) {
            refuse_version(s, c->rx + off, c->rx_len - off);
            return;
        }
        if (rths_proto_status_is_fatal(st)) {
            char why[160];
            snprintf(why, sizeof why, "%s; closing the connection", rths_proto_status_name(st));
            server_send_error(s, 0, st, 0, why);
            server_drop_client(s, rths_proto_status_name(st));
            return;
        }
        off += used;
        atomic_store_explicit(&s->last_rx_ns, mono_ns(), memory_order_relaxed);
        if (st != RTHS_PROTO_OK) {
            char why[160];
            if (st == RTHS_PROTO_ETYPE)
                snprintf(why, sizeof why, "unknown message type 0x%02x", m.type);
            else
                snprintf(why, sizeof why, "%s for %s (type 0x%02x)%s%s", rths_proto_status_name(st),
                         rths_msg_type_name(m.type), m.type, m.problem[0] ? ": " : "", m.problem);
            server_send_error(s, m.seq, st, m.type, why);
            continue;
        }
        server_handle_request(s, &m);
    }
    if (c->fd >= 0) {
        memmove(c->rx, c->rx + off, c->rx_len - off);
        c->rx_len -= off;
    }
}

static void accept_client(rths_server *s) {
    struct sockaddr_storage sa;
    socklen_t sl = sizeof sa;
    int fd = accept4(s->listen_fd, (struct sockaddr *)&sa, &sl, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;
    char host[64] = "?", serv[16] = "?";
    getnameinfo((struct sockaddr *)&sa, sl, host, sizeof host, serv, sizeof serv,
                NI_NUMERICHOST | NI_NUMERICSERV);
    if (s->c.fd >= 0 && atomic_load(&s->armed)) {
        /* One controlling client: the armed session is never disturbed by a newcomer. */
        uint8_t buf[RTHS_PROTO_MAX_FRAME];
        rths_msg m;
        rths_msg_error(&m, 0, RTHS_PROTO_EBUSY, 0, "controller armed by %s; try later", s->c.peer);
        size_t n = rths_proto_encode(&m, buf, sizeof buf);
        ssize_t sent = send(fd, buf, n, MSG_DONTWAIT | MSG_NOSIGNAL);
        (void)sent;
        close(fd);
        server_notice(s, "refused %s:%s (busy, armed by %s)", host, serv, s->c.peer);
        return;
    }
    if (s->c.fd >= 0) server_drop_client(s, "replaced by a new connection");
    client *c = &s->c;
    c->fd = fd;
    c->hello = 0;
    c->rx_len = 0;
    c->tx_len = 0;
    c->sub_periods = c->sub_traces = 0;
    c->batch_n = 0;
    c->last_armed = atomic_load(&s->armed);
    c->last_fault = atomic_load(&s->fault);
    snprintf(c->peer, sizeof c->peer, "%s:%s", host, serv);
    atomic_store(&s->client_connected, 1);
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    atomic_store(&s->last_rx_ns, mono_ns());
}

static void pump_streams(rths_server *s) {
    client *c = &s->c;
    rths_msg m;
    rths_proto_period p;
    while (rths_engine_pop_period(s->engine, &p)) {
        s->latest = p;
        s->have_latest = 1;
        if (c->fd >= 0 && c->hello && c->sub_periods) {
            rths_msg_init(&m, RTHS_MSG_PERIOD, 0);
            m.u.period = p;
            if (!server_queue_frame(s, &m, 0)) atomic_fetch_add(&s->periods_dropped, 1);
        }
    }
    rths_proto_trace_sample ts;
    while (rths_spsc_pop(&s->traces, &ts)) {
        if (c->fd < 0 || !c->sub_traces) continue;
        c->batch[c->batch_n++] = ts;
        if (c->batch_n == RTHS_PROTO_MAX_TRACE_BATCH) {
            rths_msg_init(&m, RTHS_MSG_TRACE, 0);
            m.u.trace.count = c->batch_n;
            m.u.trace.dofs = s->info.interface_dofs; /* every interface DoF's signals */
            memcpy(m.u.trace.s, c->batch, sizeof c->batch);
            server_queue_frame(s, &m, 0);
            c->batch_n = 0;
        }
    }
    /* A partial batch goes out at once: the host may be waiting for its last samples. */
    if (c->fd >= 0 && c->batch_n) {
        rths_msg_init(&m, RTHS_MSG_TRACE, 0);
        m.u.trace.count = c->batch_n;
        m.u.trace.dofs = s->info.interface_dofs;
        memcpy(m.u.trace.s, c->batch, sizeof c->batch[0] * (size_t)c->batch_n);
        server_queue_frame(s, &m, 0);
        c->batch_n = 0;
    }
    if (c->fd >= 0 && c->hello) {
        int armed = atomic_load(&s->armed), fault = atomic_load(&s->fault);
        if (armed != c->last_armed || fault != c->last_fault) {
            rths_msg_init(&m, RTHS_MSG_STATUS, 0);
            server_fill_status(s, &m.u.status);
            server_queue_frame(s, &m, 1);
            c->last_armed = armed;
            c->last_fault = fault;
        }
    }
}

/* Operator notices on stderr for every change of the armed state or the fault (network thread:
 * the loop never prints). */
static void announce(rths_server *s) {
    int armed = atomic_load(&s->armed), fault = atomic_load(&s->fault);
    if (s->opt.quiet || (armed == s->note_armed && fault == s->note_fault)) return;
    double ramp = s->info.ramp_time_s;
    if (fault && fault != s->note_fault) {
        char why[RTHS_PROTO_MAX_TEXT + 1];
        server_fault_text(s, fault, why, sizeof why);
        if (atomic_load(&s->stalled_ns))
            fprintf(stderr,
                    "rths controller: t = %.3f s: fault latched: %s; the loop does not resume "
                    "(restart the controller)\n",
                    ctl_time(s), why);
        else
            fprintf(stderr,
                    "rths controller: t = %.3f s: fault latched: %s; demand, forcing and target "
                    "ramp to zero over %g s (RESET_FAULT, then ARM, to resume)\n",
                    ctl_time(s), why, ramp);
    }
    if (armed && !s->note_armed)
        fprintf(stderr, "rths controller: t = %.3f s: armed by %s\n", ctl_time(s), s->c.peer);
    if (!armed && s->note_armed)
        fprintf(stderr,
                "rths controller: t = %.3f s: disarmed (%s); forcing and target ramp to zero over "
                "%g s\n",
                ctl_time(s), server_disarm_reason_name(atomic_load(&s->last_disarm)), ramp);
    s->note_armed = armed;
    s->note_fault = fault;
}

void *server_net_main(void *arg) {
    rths_server *s = arg;
    while (!atomic_load(&s->stop)) {
        struct pollfd pfd[2] = {{s->listen_fd, POLLIN, 0}, {s->c.fd, POLLIN, 0}};
        if (s->c.fd >= 0 && s->c.tx_len) pfd[1].events |= POLLOUT;
        int n = poll(pfd, s->c.fd >= 0 ? 2 : 1, 1);
        if (n > 0 && (pfd[0].revents & POLLIN)) accept_client(s);
        if (n > 0 && s->c.fd >= 0 && pfd[1].fd == s->c.fd &&
            (pfd[1].revents & (POLLIN | POLLERR | POLLHUP)))
            read_client(s);
        pump_streams(s);
        if (flush_tx(s)) server_drop_client(s, "send failed");
        announce(s);
        notices_flush(s, mono_ns());
    }
    server_drop_client(s, "controller stopping");
    return NULL;
}

/* ---- lifetime ---- */

int server_bind_listen(rths_server *s, rths_error *err) {
    char port[16];
    snprintf(port, sizeof port, "%d", s->opt.port);
    struct addrinfo hints = {0}, *res = NULL;
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    int gai = getaddrinfo(s->opt.host, port, &hints, &res);
    if (gai)
        return rths_error_set(err, RTHS_EINPUT, "listen address '%s': %s", s->opt.host,
                              gai_strerror(gai));
    int fd = -1;
    char why[200] = "no usable address";
    for (struct addrinfo *ai = res; ai; ai = ai->ai_next) {
        fd = socket(ai->ai_family, ai->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, ai->ai_protocol);
        if (fd < 0) continue;
        int one = 1;
        /* A restarted controller must get its port back while old connections sit in TIME_WAIT. */
        setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        if (!bind(fd, ai->ai_addr, ai->ai_addrlen) && !listen(fd, SOMAXCONN)) {
            struct sockaddr_storage sa;
            socklen_t sl = sizeof sa;
            getsockname(fd, (struct sockaddr *)&sa, &sl);
            char serv[16];
            getnameinfo((struct sockaddr *)&sa, sl, NULL, 0, serv, sizeof serv, NI_NUMERICSERV);
            s->port = atoi(serv);
            break;
        }
        snprintf(why, sizeof why, "%s", strerror(errno));
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd < 0)
        return rths_error_set(err, RTHS_EFAIL, "cannot listen on %s:%d: %s", s->opt.host,
                              s->opt.port, why);
    s->listen_fd = fd;
    return RTHS_OK;
}
