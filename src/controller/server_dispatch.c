/* The controller server's request dispatch (network thread): each request of the host checked,
 * turned into a loop command or a reply, and answered (ACK, STATUS, ERROR); the fault and
 * disarm names. */
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

void server_send_error(rths_server *s, uint16_t seq, int code, int req_type, const char *msg) {
    rths_msg m;
    rths_msg_error(&m, seq, code, req_type, "%s", msg);
    server_queue_frame(s, &m, 1);
}

/* Posts a command and waits (a few samples) for the loop to apply it. */
static int run_cmd(rths_server *s, loop_cmd *cmd, double *applied_time) {
    cmd->id = ++s->next_cmd_id;
    if (atomic_load(&s->stalled_ns)) return RTHS_PROTO_ESTATE; /* a stuck loop applies nothing */
    int64_t give_up = mono_ns() + 2000000000;
    while (!rths_spsc_push(&s->cmds, cmd)) {
        if (mono_ns() > give_up) return RTHS_PROTO_ESTATE;
        struct timespec ts = {0, 50000};
        nanosleep(&ts, NULL);
    }
    while ((int32_t)(atomic_load_explicit(&s->applied_id, memory_order_acquire) - cmd->id) < 0) {
        if (mono_ns() > give_up || atomic_load(&s->stop)) return RTHS_PROTO_ESTATE;
        struct timespec ts = {0, 50000};
        nanosleep(&ts, NULL);
    }
    *applied_time = bitsd(atomic_load_explicit(&s->applied_time_bits, memory_order_relaxed));
    return atomic_load_explicit(&s->applied_result, memory_order_relaxed);
}

void server_fill_status(rths_server *s, rths_proto_status_msg *st) {
    memset(st, 0, sizeof *st);
    st->time_s = ctl_time(s);
    int flags = atomic_load(&s->rt_flags);
    if (atomic_load(&s->armed)) flags |= RTHS_STATUS_ARMED;
    if (s->c.fd >= 0) flags |= RTHS_STATUS_CLIENT_OWNS;
    st->flags = (uint8_t)flags;
    st->fault = (uint8_t)atomic_load(&s->fault);
    st->last_disarm = (uint8_t)atomic_load(&s->last_disarm);
    st->frequency_hz = bitsd(atomic_load(&s->freq_bits));
    st->amplitude_n = bitsd(atomic_load(&s->amp_bits));
    st->samples = atomic_load(&s->samples);
    st->overruns = atomic_load(&s->overruns);
    st->worst_lateness_s = (double)atomic_load(&s->worst_late_ns) * 1e-9;
    st->periods_dropped = atomic_load(&s->periods_dropped) + atomic_load(&s->engine_dropped);
    int bin = 0;
    for (int i = 0; i <= LAT_BINS; i++) {
        /* fine bin i covers [i, i+1) us; coarse edges are whole microseconds */
        while (bin < RTHS_PROTO_LATENCY_BINS - 1 &&
               i >= (int)(rths_proto_latency_edges_s[bin] * 1e6 + 0.5))
            bin++;
        st->latency_hist[bin] += atomic_load_explicit(&s->lat_hist[i], memory_order_relaxed);
    }
    server_fault_text(s, st->fault, st->fault_detail, sizeof st->fault_detail);
    st->demand_v.n = s->info.interface_dofs;
    for (int d = 0; d < s->info.interface_dofs; d++)
        st->demand_v.v[d] = bitsd(atomic_load_explicit(&s->demand_bits[d], memory_order_relaxed));
}

/* The shared names (signals.h), with "no" for none as the controller page's API has it. */
const char *server_fault_name(int f) {
    return f == RTHS_RIG_OK ? "no" : rths_rig_fault_name((rths_rig_fault)f);
}

/* The latched fault's text naming the channel, the value and the limit (empty without one). */
void server_fault_text(rths_server *s, int fault, char *out, size_t cap) {
    out[0] = '\0';
    if (!fault) return;
    rths_fault_detail d = {.fault = fault};
    d.cause = atomic_load_explicit(&s->fault_cause, memory_order_acquire);
    d.channel = atomic_load_explicit(&s->fault_channel, memory_order_relaxed);
    d.value = bitsd(atomic_load_explicit(&s->fault_value_bits, memory_order_relaxed));
    d.limit = bitsd(atomic_load_explicit(&s->fault_limit_bits, memory_order_relaxed));
    rths_fault_detail_format(&d, out, cap);
}

static void reply_ack(rths_server *s, const rths_msg *req, double t) {
    rths_msg m;
    rths_msg_init(&m, RTHS_MSG_ACK, req->seq);
    m.u.ack.acked_type = req->type;
    m.u.ack.time_s = t;
    server_queue_frame(s, &m, 1);
}

static void handle_hello(rths_server *s, const rths_msg *m) {
    client *c = &s->c;
    if (m->u.hello.version != RTHS_PROTO_VERSION) {
        char msg[RTHS_PROTO_MAX_TEXT + 1];
        rths_proto_version_message(msg, sizeof msg, m->u.hello.version);
        server_send_error(s, m->seq, RTHS_PROTO_EVERSION, m->type, msg);
        server_drop_client(s, msg);
        return;
    }
    c->hello = 1;
    rths_msg r;
    rths_msg_init(&r, RTHS_MSG_HELLO_REPLY, m->seq);
    r.u.hello_reply.version = RTHS_PROTO_VERSION;
    r.u.hello_reply.max_harmonics = (uint8_t)s->info.max_harmonics;
    r.u.hello_reply.interface_dofs = (uint8_t)s->info.interface_dofs;
    r.u.hello_reply.sample_period_s = s->info.sample_period_s;
    r.u.hello_reply.watchdog_s = s->opt.watchdog_s;
    r.u.hello_reply.noise_level_m = s->info.noise_level_m;
    snprintf(r.u.hello_reply.name, sizeof r.u.hello_reply.name, "%s", s->info.description);
    server_queue_frame(s, &r, 1);
    /* the client names itself: shown to the operator only as printable text (a newline would
     * forge a console line, an escape reach the terminal) */
    char name[64 + 4];
    rths_proto_printable(m->u.hello.name, 64, name, sizeof name);
    server_notice(s, "client %s says hello (%s)", c->peer, name);
}

/* SET_FORCING and SET_TARGET within the configured limits, else ERROR 10 naming the keys; an
 * accepted one becomes the loop command cmd. Returns 0 when accepted. */
static int check_forcing(rths_server *s, const rths_msg *m, loop_cmd *cmd) {
    const double f = m->u.forcing.frequency_hz, amp = m->u.forcing.amplitude_n;
    /* at least 4 samples per period, as the in-process rig requires: the step's phase and
     * Fourier sums assume omega h < pi / 2 */
    const double f_max = fmin(s->opt.max_frequency_hz, 0.25 / s->info.sample_period_s);
    if (!(f >= s->info.min_frequency_hz) || f > s->opt.max_frequency_hz ||
        !(f < 0.25 / s->info.sample_period_s) || fabs(amp) > s->opt.max_amplitude_n) {
        char msg[RTHS_PROTO_MAX_TEXT + 1];
        snprintf(msg, sizeof msg,
                 "forcing %g Hz, %g N outside [%g, %g] Hz, |amplitude| <= %g N "
                 "(controller.min_frequency_hz, server.max_frequency_hz < rate/4, "
                 "server.max_amplitude_n)",
                 f, amp, s->info.min_frequency_hz, f_max, s->opt.max_amplitude_n);
        server_send_error(s, m->seq, RTHS_PROTO_ERANGE, m->type, msg);
        return -1;
    }
    cmd->type = CMD_FORCING;
    cmd->frequency_hz = f;
    cmd->amplitude_n = amp;
    return 0;
}

static int check_target(rths_server *s, const rths_msg *m, loop_cmd *cmd) {
    const rths_proto_target *t = &m->u.target;
    char msg[RTHS_PROTO_MAX_TEXT + 1];
    if (t->harmonics > s->info.max_harmonics) {
        snprintf(msg, sizeof msg, "target with %d harmonics; this controller runs at most %d",
                 t->harmonics, s->info.max_harmonics);
        server_send_error(s, m->seq, RTHS_PROTO_ERANGE, m->type, msg);
        return -1;
    }
    const int dofs = t->dofs ? t->dofs : 1;
    if (dofs != s->info.interface_dofs) {
        snprintf(msg, sizeof msg, "target for %d interface DoF(s); this controller drives %d", dofs,
                 s->info.interface_dofs);
        server_send_error(s, m->seq, RTHS_PROTO_ERANGE, m->type, msg);
        return -1;
    }
    for (int d = 0; d < dofs; d++) {
        const int off = d * t->harmonics;
        double peak = rths_target_peak_bound_m(t->harmonics, t->a + off, t->b + off);
        if (peak > s->info.displacement_limit_m) {
            snprintf(msg, sizeof msg,
                     "target of up to %g m (interface DoF %d) is beyond the displacement limit "
                     "%g m (controller.limits.displacement_m)",
                     peak, d + 1, s->info.displacement_limit_m);
            server_send_error(s, m->seq, RTHS_PROTO_ERANGE, m->type, msg);
            return -1;
        }
    }
    cmd->type = CMD_TARGET;
    cmd->dofs = dofs;
    cmd->harmonics = t->harmonics;
    memcpy(cmd->a, t->a, sizeof cmd->a);
    memcpy(cmd->b, t->b, sizeof cmd->b);
    return 0;
}

static void handle_subscribe(rths_server *s, const rths_msg *m) {
    client *c = &s->c;
    c->sub_periods = (m->u.subscribe.flags & RTHS_SUBSCRIBE_PERIODS) != 0;
    c->sub_traces = (m->u.subscribe.flags & RTHS_SUBSCRIBE_TRACES) != 0;
    /* Samples queued under the old subscription must not be mistaken for new ones. */
    atomic_store(&s->trace_on, 0);
    rths_proto_trace_sample junk;
    while (rths_spsc_pop(&s->traces, &junk)) {
    }
    c->batch_n = 0;
    atomic_store(&s->trace_decimation, m->u.subscribe.trace_decimation);
    atomic_store(&s->trace_on, c->sub_traces);
    reply_ack(s, m, ctl_time(s));
}

static void handle_query(rths_server *s, const rths_msg *m) {
    client *c = &s->c;
    rths_msg r;
    if (m->type == RTHS_MSG_GET_STATUS) {
        rths_msg_init(&r, RTHS_MSG_STATUS, m->seq);
        server_fill_status(s, &r.u.status);
        server_queue_frame(s, &r, 1);
        c->last_armed = r.u.status.flags & RTHS_STATUS_ARMED ? 1 : 0;
        c->last_fault = r.u.status.fault;
    } else if (!s->have_latest) {
        server_send_error(s, m->seq, RTHS_PROTO_ENODATA, m->type, "no whole period yet");
    } else {
        rths_msg_init(&r, RTHS_MSG_PERIOD, m->seq);
        r.u.period = s->latest;
        server_queue_frame(s, &r, 1);
    }
}

void server_handle_request(rths_server *s, const rths_msg *m) {
    char msg[RTHS_PROTO_MAX_TEXT + 1];
    if (!s->c.hello && m->type != RTHS_MSG_HELLO) {
        server_send_error(s, m->seq, RTHS_PROTO_ESTATE, m->type, "send HELLO first");
        return;
    }
    loop_cmd cmd;
    memset(&cmd, 0, sizeof cmd);
    double t = ctl_time(s);
    int rc;
    switch (m->type) {
    case RTHS_MSG_HELLO:
        handle_hello(s, m);
        return;
    case RTHS_MSG_ARM:
        cmd.type = CMD_ARM;
        if ((rc = run_cmd(s, &cmd, &t))) {
            char why[RTHS_PROTO_MAX_TEXT + 1];
            server_fault_text(s, atomic_load(&s->fault), why, sizeof why);
            snprintf(msg, sizeof msg, "cannot arm: fault latched (%.120s); %s", why,
                     atomic_load(&s->stalled_ns) ? "restart the controller"
                                                 : "send RESET_FAULT first");
            server_send_error(s, m->seq, rc, m->type, msg);
            return;
        }
        break;
    case RTHS_MSG_DISARM:
        cmd.type = CMD_DISARM;
        cmd.reason = RTHS_DISARM_COMMAND;
        run_cmd(s, &cmd, &t);
        break;
    case RTHS_MSG_SET_FORCING:
        if (check_forcing(s, m, &cmd)) return;
        run_cmd(s, &cmd, &t);
        break;
    case RTHS_MSG_SET_TARGET:
        if (check_target(s, m, &cmd)) return;
        run_cmd(s, &cmd, &t);
        break;
    case RTHS_MSG_GET_STATUS:
    case RTHS_MSG_GET_COEFFS:
        handle_query(s, m);
        return;
    case RTHS_MSG_SUBSCRIBE:
        handle_subscribe(s, m);
        return;
    case RTHS_MSG_RESET_FAULT:
        cmd.type = CMD_RESET;
        run_cmd(s, &cmd, &t);
        break;
    case RTHS_MSG_PING:
        break;
    default:
        /* Replies-only types sent to the controller. */
        snprintf(msg, sizeof msg, "%s is not a request", rths_msg_type_name(m->type));
        server_send_error(s, m->seq, RTHS_PROTO_ETYPE, m->type, msg);
        return;
    }
    reply_ack(s, m, t);
}

const char *server_disarm_reason_name(int r) {
    switch (r) {
    case RTHS_DISARM_COMMAND:
        return "host command";
    case RTHS_DISARM_FAULT:
        return "fault";
    case RTHS_DISARM_WATCHDOG:
        return "watchdog: host silent";
    case RTHS_DISARM_LINK:
        return "host connection lost";
    case RTHS_DISARM_SHUTDOWN:
        return "shutdown";
    }
    return "never armed";
}
