/* The controller process: wall-clock paced loop thread + network thread (see server.h).
 *
 * Everything the loop touches is allocated before it starts: the command ring (network -> loop),
 * the trace ring (loop -> network), the lateness and step-cost histograms, and the published
 * state, all atomics. The step's own period ring (loop -> network) lives in the engine. The
 * network thread owns the socket and the protocol; it never blocks on a client (non-blocking
 * sends from a bounded transmit buffer; stream frames are dropped, never waited for). */
#include "rths/server.h"

#include "controller/server_engine.h"
#include "controller/spsc.h"
#include "rths/controller.h"
#include "rths/protocol.h"

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

#if defined(__SANITIZE_ADDRESS__)
#define RTHS_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RTHS_ASAN 1
#endif
#endif

#define CMD_RING 64           /* commands in flight; the network waits for each, so few */
#define MAX_CMDS_PER_SAMPLE 4 /* commands the loop applies per sample, at most */
#define TRACE_RING 16384      /* trace samples between network-thread wake-ups */
#define SCOPE_RING 8192       /* decimated samples for a viewer (rths_server_scope_pop) */
#define LAT_BINS 50000        /* lateness histogram: 1 us bins up to 50 ms, then overflow */
#define STEP_BINS 10000       /* step cost histogram: 0.1 us bins up to 1 ms, then overflow */
#define RX_CAP 8192
#define TX_CAP (256 * 1024)
#define TX_RESERVE (32 * 1024) /* room kept for replies: stream frames never take it */
#define NOTICE_BURST 10        /* connection notices per NOTICE_WINDOW_NS; the rest are counted */
#define NOTICE_WINDOW_NS 1000000000

/* ---- state ---- */

enum { CMD_ARM = 1, CMD_DISARM, CMD_FORCING, CMD_TARGET, CMD_RESET };

typedef struct loop_cmd {
    uint32_t id;
    int type;
    int reason; /* CMD_DISARM: rths_disarm_reason */
    double frequency_hz, amplitude_n;
    int dofs, harmonics; /* CMD_TARGET: DoF d's coefficients at a[d * harmonics + k - 1] */
    double a[RTHS_PROTO_MAX_DOFS * RTHS_PROTO_HARMONICS],
        b[RTHS_PROTO_MAX_DOFS * RTHS_PROTO_HARMONICS];
} loop_cmd;

typedef struct client {
    int fd;
    int hello;
    char peer[80];
    uint8_t rx[RX_CAP];
    size_t rx_len;
    uint8_t *tx;
    size_t tx_len;
    int sub_periods, sub_traces;
    rths_proto_trace_sample batch[RTHS_PROTO_MAX_TRACE_BATCH];
    int batch_n;
    int last_armed, last_fault; /* state last reported, for pushed STATUS frames */
} client;

struct rths_server {
    rths_server_options opt;
    rths_engine *engine;
    rths_engine_info info;
    int listen_fd;
    int port;
    int64_t period_ns;
    pthread_t loop_thread, net_thread, supervisor_thread;
    int loop_started, net_started, supervisor_started;
    atomic_int supervisor_stop;
    /* The supervisor's view of the loop: the monotonic time the sample in progress started (0
     * while the loop sleeps); set by the supervisor once it found the loop stalled, with how
     * long that sample had run. loop_abandoned: rths_server_stop gave up joining a stuck loop
     * thread, so nothing it may still touch is freed. */
    _Atomic int64_t busy_since_ns;
    _Atomic int64_t stalled_ns;
    atomic_int loop_tid; /* the loop thread's kernel id, for its state in /proc */
    int loop_abandoned;
    int hw_watchdog; /* the plug-in's hardware watchdog is armed */
    char hw_watchdog_why[200];
    atomic_int stop;
    atomic_int loop_ready;

    rths_spsc cmds, traces, scope;
    void *cmd_storage, *trace_storage, *scope_storage;
    uint32_t next_cmd_id; /* network thread */
    _Atomic uint32_t applied_id;
    atomic_int applied_result;
    _Atomic uint64_t applied_time_bits; /* controller time at which the command took effect */

    /* published by the loop */
    _Atomic uint64_t samples, overruns, resyncs, worst_late_ns, worst_step_ns, step_sum_ns;
    atomic_int armed, fault, last_disarm, rt_flags;
    atomic_int rt_fifo_errno, rt_pin_errno, rt_cpu; /* why SCHED_FIFO, pinning were refused */
    /* what latched the fault (rths_fault_detail), published by the loop (or the supervisor) */
    atomic_int fault_cause, fault_channel;
    _Atomic uint64_t fault_value_bits, fault_limit_bits;
    _Atomic uint64_t freq_bits, amp_bits;
    _Atomic uint64_t time_bits;                        /* controller time after the last step, s */
    _Atomic uint64_t engine_dropped;                   /* periods the step's ring dropped */
    _Atomic uint64_t demand_bits[RTHS_PROTO_MAX_DOFS]; /* every actuator's demand, V */
    _Atomic uint32_t *lat_hist;                        /* LAT_BINS + 1 */
    _Atomic uint32_t *step_hist;                       /* STEP_BINS + 1 */

    /* the viewer's scope: decimation set by the viewer (0: off), the ring filled by the loop */
    _Atomic uint32_t scope_decimation;
    _Atomic uint64_t scope_dropped;
    atomic_int client_connected; /* written by the network thread, read by a viewer */

    /* written by the network thread, read by the loop */
    _Atomic int64_t last_rx_ns;
    atomic_int trace_on;
    _Atomic uint32_t trace_decimation;

    /* network thread only */
    client c;
    int note_armed, note_fault; /* state last announced on stderr */
    int64_t notice_window_start_ns;
    int notices_in_window, notices_suppressed;
    rths_proto_period latest;
    int have_latest;
    _Atomic uint64_t periods_dropped;
};

static int64_t mono_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static uint64_t dbits(double x) {
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

static double bitsd(uint64_t u) {
    double x;
    memcpy(&x, &u, sizeof x);
    return x;
}

/* Loop-thread-only counters: a plain load + store (no locked instruction) is enough because
 * there is one writer; readers on other threads see a consistent value of each word. */
static inline void bump32(_Atomic uint32_t *p) {
    atomic_store_explicit(p, atomic_load_explicit(p, memory_order_relaxed) + 1,
                          memory_order_relaxed);
}

static inline void add64(_Atomic uint64_t *p, uint64_t v) {
    atomic_store_explicit(p, atomic_load_explicit(p, memory_order_relaxed) + v,
                          memory_order_relaxed);
}

static inline void max64(_Atomic uint64_t *p, uint64_t v) {
    if (v > atomic_load_explicit(p, memory_order_relaxed))
        atomic_store_explicit(p, v, memory_order_relaxed);
}

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

static void notice(rths_server *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void notice(rths_server *s, const char *fmt, ...) {
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

/* ---- options and configuration ---- */

void rths_server_options_defaults(rths_server_options *opt) {
    memset(opt, 0, sizeof *opt);
    snprintf(opt->host, sizeof opt->host, "127.0.0.1");
    opt->port = 7400;
    opt->watchdog_s = 2.0;
    opt->realtime = 1;
    opt->priority = 80;
    opt->cpu = -1;
    opt->max_frequency_hz = 100.0;
    opt->max_amplitude_n = 20.0;
    opt->stall_margin_s = 0.05;
    opt->hardware_watchdog_s = 0.1;
}

/* ---- the loop thread ---- */

static void apply_cmd(rths_server *s, const loop_cmd *c) {
    int result = 0;
    rths_engine *e = s->engine;
    switch (c->type) {
    case CMD_ARM:
        result = rths_engine_arm(e);
        break;
    case CMD_DISARM:
        if (rths_engine_armed(e)) atomic_store(&s->last_disarm, c->reason);
        rths_engine_disarm(e);
        break;
    case CMD_FORCING:
        rths_engine_set_forcing(e, c->frequency_hz, c->amplitude_n);
        atomic_store_explicit(&s->freq_bits, dbits(c->frequency_hz), memory_order_relaxed);
        atomic_store_explicit(&s->amp_bits, dbits(c->amplitude_n), memory_order_relaxed);
        break;
    case CMD_TARGET:
        rths_engine_set_target(e, c->dofs, c->harmonics, c->a, c->b);
        break;
    case CMD_RESET:
        /* a stalled loop's device is in its safe state for good: only a restart clears it */
        if (!atomic_load_explicit(&s->stalled_ns, memory_order_relaxed)) rths_engine_reset_fault(e);
        break;
    }
    atomic_store_explicit(&s->applied_result, result, memory_order_relaxed);
    atomic_store_explicit(&s->applied_time_bits, dbits(rths_engine_time_s(e)),
                          memory_order_relaxed);
    atomic_store_explicit(&s->applied_id, c->id, memory_order_release);
}

static void rt_setup(rths_server *s) {
    int flags = 0;
    if (s->opt.realtime) {
        long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
        int cpu = s->opt.cpu >= 0 ? s->opt.cpu : (int)(ncpu > 0 ? ncpu - 1 : 0);
        atomic_store(&s->rt_cpu, cpu);
        cpu_set_t set;
        CPU_ZERO(&set);
        CPU_SET(cpu, &set);
        int e = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
        if (!e)
            flags |= RTHS_STATUS_RT_PINNED;
        else
            atomic_store(&s->rt_pin_errno, e);
        struct sched_param sp = {.sched_priority = s->opt.priority};
        e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
        if (!e)
            flags |= RTHS_STATUS_RT_FIFO;
        else
            atomic_store(&s->rt_fifo_errno, e);
        /* Pre-fault a stack reserve so the first deep call does not page-fault mid-loop. */
        volatile unsigned char stack[64 * 1024];
        for (size_t i = 0; i < sizeof stack; i += 4096)
            stack[i] = 0;
    }
    atomic_fetch_or(&s->rt_flags, flags);
}

/* Sleeps to the next absolute deadline and records how late the wake-up was; returns now, ns.
 * *late: the wake-up came after the following sample's deadline had passed (an overrun: the
 * sample's I/O runs at least a whole sample late). */
static int64_t wait_next_sample(rths_server *s, struct timespec *next, int *overrun) {
    const int64_t period = s->period_ns;
    next->tv_nsec += period;
    while (next->tv_nsec >= 1000000000) {
        next->tv_nsec -= 1000000000;
        next->tv_sec++;
    }
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, next, NULL) == EINTR) {
    }
    int64_t now = mono_ns();
    int64_t deadline = (int64_t)next->tv_sec * 1000000000 + next->tv_nsec;
    int64_t late = now - deadline;
    if (late < 0) late = 0;
    uint64_t bin = (uint64_t)late / 1000u;
    bump32(&s->lat_hist[bin < LAT_BINS ? bin : LAT_BINS]);
    max64(&s->worst_late_ns, (uint64_t)late);
    *overrun = late >= period;
    if (*overrun) add64(&s->overruns, 1);
    if (late > 100000000) { /* 0.1 s behind at any rate: catching up would only burst */
        next->tv_sec = now / 1000000000;
        next->tv_nsec = now % 1000000000;
        add64(&s->resyncs, 1);
    }
    return now;
}

/* Host commands (a bounded number per sample: a flood cannot stretch one sample) and the
 * watchdog. */
static void serve_host(rths_server *s, int64_t now, int64_t watchdog_ns) {
    loop_cmd c;
    for (int k = 0; k < MAX_CMDS_PER_SAMPLE && rths_spsc_pop(&s->cmds, &c); k++)
        apply_cmd(s, &c);
    const int64_t silent = now - atomic_load_explicit(&s->last_rx_ns, memory_order_relaxed);
    if (rths_engine_armed(s->engine) && silent > watchdog_ns) {
        atomic_store(&s->last_disarm, RTHS_DISARM_WATCHDOG);
        rths_engine_trip_watchdog(s->engine, (double)silent * 1e-9, s->opt.watchdog_s);
    }
}

/* One step, timed into the step-cost histogram. */
static void timed_step(rths_server *s, rths_proto_trace_sample *sig) {
    int64_t t0 = mono_ns();
    rths_engine_step(s->engine, sig);
    int64_t cost = mono_ns() - t0;
    uint64_t c = (uint64_t)(cost > 0 ? cost : 0);
    uint64_t sb = c / 100u;
    bump32(&s->step_hist[sb < STEP_BINS ? sb : STEP_BINS]);
    add64(&s->step_sum_ns, c);
    max64(&s->worst_step_ns, c);
}

/* Every scope_decimation-th sample into the viewer's ring; a full ring drops the sample (counted),
 * never waits. One relaxed load per sample when nobody watches. */
static void publish_scope(rths_server *s, const rths_proto_trace_sample *sig, uint32_t *count) {
    uint32_t d = atomic_load_explicit(&s->scope_decimation, memory_order_acquire);
    if (!d) {
        *count = 0;
        return;
    }
    if (++*count < d) return;
    *count = 0;
    /* the ring holds what the viewer shows (the first DoF's six numbers), not the whole record */
    rths_server_scope_sample x = {sig->time_s,   sig->x_phys_m, sig->x_num_m,
                                  sig->target_m, sig->force_n,  sig->demand};
    if (!rths_spsc_push(&s->scope, &x)) add64(&s->scope_dropped, 1);
}

/* The fault's detail for other threads, when the fault changed (the loop; the supervisor only
 * while the loop is stuck). */
static void publish_fault_detail(rths_server *s, const rths_fault_detail *d) {
    atomic_store_explicit(&s->fault_channel, d->channel, memory_order_relaxed);
    atomic_store_explicit(&s->fault_value_bits, dbits(isfinite(d->value) ? d->value : 0.0),
                          memory_order_relaxed);
    atomic_store_explicit(&s->fault_limit_bits, dbits(d->limit), memory_order_relaxed);
    /* last, with release: a reader that sees the cause sees its numbers */
    atomic_store_explicit(&s->fault_cause, d->cause, memory_order_release);
}

/* The state other threads read, after every sample. */
static void publish_state(rths_server *s, int *prev_armed) {
    int armed = rths_engine_armed(s->engine);
    int fault = rths_engine_fault(s->engine);
    /* after a stall the supervisor's fault and words stand, whatever was latched before */
    if (atomic_load_explicit(&s->stalled_ns, memory_order_relaxed))
        fault = RTHS_RIG_FAULT_WATCHDOG;
    else if (fault != atomic_load_explicit(&s->fault, memory_order_relaxed)) {
        rths_fault_detail d;
        rths_engine_fault_detail(s->engine, &d);
        publish_fault_detail(s, &d);
    }
    if (*prev_armed && !armed && fault && atomic_load(&s->last_disarm) != RTHS_DISARM_WATCHDOG)
        atomic_store(&s->last_disarm, RTHS_DISARM_FAULT);
    *prev_armed = armed;
    atomic_store_explicit(&s->armed, armed, memory_order_relaxed);
    atomic_store_explicit(&s->fault, fault, memory_order_relaxed);
    atomic_store_explicit(&s->time_bits, dbits(rths_engine_time_s(s->engine)),
                          memory_order_relaxed);
    atomic_store_explicit(&s->engine_dropped, (uint64_t)rths_engine_dropped_periods(s->engine),
                          memory_order_relaxed);
    double demand_v[RTHS_PROTO_MAX_DOFS];
    rths_engine_demands(s->engine, demand_v);
    for (int d = 0; d < s->info.interface_dofs; d++)
        atomic_store_explicit(&s->demand_bits[d], dbits(demand_v[d]), memory_order_relaxed);
    add64(&s->samples, 1);
}

static void *loop_main(void *arg) {
    rths_server *s = arg;
    atomic_store(&s->loop_tid, (int)syscall(SYS_gettid));
    rt_setup(s);
    atomic_store(&s->loop_ready, 1);
    const int64_t watchdog_ns = (int64_t)(s->opt.watchdog_s * 1e9);
    /* After a stop request the loop keeps stepping, disarmed, long enough for the step's ramp to
     * bring the demand to zero: a real rig must not be left with a held demand. */
    int64_t shutdown_left = -1;
    uint32_t decim_count = 0, scope_count = 0;
    int prev_armed = 0;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    int stall_latched = 0;
    for (;;) {
        atomic_store_explicit(&s->busy_since_ns, 0, memory_order_relaxed);
        int overrun = 0;
        int64_t now = wait_next_sample(s, &next, &overrun);
        /* the supervisor watches how long this sample runs (docs/io-plugins.md, stalls) */
        atomic_store_explicit(&s->busy_since_ns, now, memory_order_relaxed);
        int64_t stalled = atomic_load_explicit(&s->stalled_ns, memory_order_relaxed);
        if (stalled && !stall_latched) {
            /* back from a stall the supervisor already answered: the fault it published is
             * latched in the step too, so the loop never resumes excitation */
            rths_fault_detail why = {.fault = RTHS_RIG_FAULT_WATCHDOG,
                                     .cause = RTHS_FAULT_CAUSE_LOOP_STALLED,
                                     .value = (double)stalled * 1e-9,
                                     .limit = bitsd(atomic_load(&s->fault_limit_bits))};
            rths_engine_trip(s->engine, &why);
            stall_latched = 1;
        }
        if (overrun) rths_engine_mark_late(s->engine);
        if (shutdown_left < 0 && atomic_load_explicit(&s->stop, memory_order_relaxed)) {
            if (rths_engine_armed(s->engine)) atomic_store(&s->last_disarm, RTHS_DISARM_SHUTDOWN);
            rths_engine_disarm(s->engine);
            /* the whole ramp to zero (controller.ramp_time_s, up to 60 s) and half a second */
            shutdown_left = (int64_t)((s->info.ramp_time_s + 0.5) * 1e9 / (double)s->period_ns) + 1;
        }
        if (shutdown_left < 0)
            serve_host(s, now, watchdog_ns);
        else if (shutdown_left-- == 0)
            break;

        rths_proto_trace_sample sig;
        timed_step(s, &sig);
        if (atomic_load_explicit(&s->trace_on, memory_order_relaxed)) {
            uint32_t d = atomic_load_explicit(&s->trace_decimation, memory_order_relaxed);
            if (++decim_count >= d) {
                decim_count = 0;
                rths_spsc_push(&s->traces, &sig); /* full: the sample is lost, never waited for */
            }
        } else {
            decim_count = 0;
        }
        publish_scope(s, &sig, &scope_count);
        publish_state(s, &prev_armed);
    }
    atomic_store_explicit(&s->busy_since_ns, 0, memory_order_relaxed);
    atomic_store(&s->armed, 0);
    return NULL;
}

/* ---- the supervisor thread ---- */

/* The loop thread's scheduling state from /proc/self/task/TID/stat: 'R' running or runnable,
 * 'S' or 'D' waiting (inside a blocking call), ...; '?' when it cannot be read. */
static char thread_state(int tid) {
    char path[64], buf[512];
    snprintf(path, sizeof path, "/proc/self/task/%d/stat", tid);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return '?';
    ssize_t n = read(fd, buf, sizeof buf - 1);
    close(fd);
    if (n <= 0) return '?';
    buf[n] = '\0';
    const char *close_paren = strrchr(buf, ')'); /* the name may hold spaces and parentheses */
    return close_paren && close_paren[1] == ' ' && close_paren[2] ? close_paren[2] : '?';
}

static int64_t thread_cpu_ns(clockid_t cid) {
    struct timespec ts;
    if (clock_gettime(cid, &ts)) return -1;
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

/* Watches the loop from outside: when one sample has run longer than its sample period plus
 * server.stall_margin_s (a plug-in blocked in read or write, or spinning in them), it drives
 * the device's safe state itself, latches the watchdog fault naming the stall, and tells the
 * operator (through the network thread). Checks every fifth of the margin (at most 5 ms), so a
 * blocked loop's safe state follows the missed deadline within 1.2 margins. A loop thread that
 * is runnable but not running (preempted on a loaded machine without real-time priority) is not
 * stuck in the device: it is given time (its samples are late, and counted so), unless it also
 * uses the CPU for a whole margin (a device spinning) or stays behind by a second more. The
 * loop's lateness between samples is never a stall: those samples are counted late. */
static void *supervisor_main(void *arg) {
    rths_server *s = arg;
    const int64_t margin = (int64_t)(s->opt.stall_margin_s * 1e9);
    const int64_t allowed = s->period_ns + margin;
    int64_t poll_ns = margin / 5;
    if (poll_ns > 5000000) poll_ns = 5000000;
    if (poll_ns < 100000) poll_ns = 100000;
    clockid_t cpu_clock;
    int have_cpu_clock = !pthread_getcpuclockid(s->loop_thread, &cpu_clock);
    int64_t watched_since = 0, watch_start = 0, cpu_at_start = 0;
    while (!atomic_load(&s->supervisor_stop)) {
        struct timespec ts = {0, (long)poll_ns};
        nanosleep(&ts, NULL);
        if (atomic_load_explicit(&s->stalled_ns, memory_order_relaxed)) continue;
        int64_t since = atomic_load_explicit(&s->busy_since_ns, memory_order_relaxed);
        int64_t now = mono_ns(), ran = since ? now - since : 0;
        if (ran <= allowed) continue;
        if (thread_state(atomic_load(&s->loop_tid)) == 'R' && have_cpu_clock) {
            /* running or preempted: stuck only if it spins (CPU for half the time watched) */
            int64_t cpu = thread_cpu_ns(cpu_clock);
            if (watched_since != since) {
                watched_since = since, watch_start = now, cpu_at_start = cpu;
                continue;
            }
            int spinning = now - watch_start >= margin && cpu >= 0 &&
                           2 * (cpu - cpu_at_start) >= now - watch_start;
            if (!spinning && ran <= allowed + 1000000000) continue;
        }
        rths_engine_safe_state(s->engine);
        rths_fault_detail why = {.fault = RTHS_RIG_FAULT_WATCHDOG,
                                 .cause = RTHS_FAULT_CAUSE_LOOP_STALLED,
                                 .value = (double)ran * 1e-9,
                                 .limit = (double)allowed * 1e-9};
        /* the loop thread is stuck and publishes nothing: the supervisor does, once */
        publish_fault_detail(s, &why);
        if (atomic_load(&s->armed)) atomic_store(&s->last_disarm, RTHS_DISARM_FAULT);
        atomic_store(&s->fault, RTHS_RIG_FAULT_WATCHDOG);
        atomic_store(&s->armed, 0);
        atomic_store_explicit(&s->stalled_ns, ran, memory_order_release);
    }
    return NULL;
}

/* ---- the network thread ---- */

static void fault_text(rths_server *s, int fault, char *out, size_t cap);

static double ctl_time(rths_server *s) {
    return bitsd(atomic_load_explicit(&s->time_bits, memory_order_relaxed));
}

/* Queues a frame; stream frames (replies == 0) only when the reply reserve stays free. */
static int queue_frame(rths_server *s, rths_msg *m, int reply) {
    client *c = &s->c;
    if (c->fd < 0) return 0;
    size_t room = TX_CAP - c->tx_len;
    if (!reply) room = room > TX_RESERVE ? room - TX_RESERVE : 0;
    size_t n = rths_proto_encode(m, c->tx + c->tx_len, room);
    if (!n) return 0;
    c->tx_len += n;
    return 1;
}

static void send_error(rths_server *s, uint16_t seq, int code, int req_type, const char *msg) {
    rths_msg m;
    rths_msg_error(&m, seq, code, req_type, "%s", msg);
    queue_frame(s, &m, 1);
}

static int flush_tx(rths_server *s);

static void drop_client(rths_server *s, const char *why) {
    client *c = &s->c;
    if (c->fd < 0) return;
    (void)flush_tx(s); /* best effort: a final ERROR frame may still get out */
    close(c->fd);
    c->fd = -1;
    atomic_store(&s->client_connected, 0);
    atomic_store(&s->trace_on, 0);
    notice(s, "client %s disconnected (%s)", c->peer, why);
    if (atomic_load(&s->armed)) {
        /* Loss of the controlling connection disarms: excitation and target ramp to zero. */
        loop_cmd cmd = {.id = ++s->next_cmd_id, .type = CMD_DISARM, .reason = RTHS_DISARM_LINK};
        rths_spsc_push(&s->cmds, &cmd);
    }
}

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

static void fill_status(rths_server *s, rths_proto_status_msg *st) {
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
    fault_text(s, st->fault, st->fault_detail, sizeof st->fault_detail);
    st->demand_v.n = s->info.interface_dofs;
    for (int d = 0; d < s->info.interface_dofs; d++)
        st->demand_v.v[d] = bitsd(atomic_load_explicit(&s->demand_bits[d], memory_order_relaxed));
}

/* The shared names (signals.h), with "no" for none as the controller page's API has it. */
static const char *fault_name(int f) {
    return f == RTHS_RIG_OK ? "no" : rths_rig_fault_name((rths_rig_fault)f);
}

/* The latched fault's text naming the channel, the value and the limit (empty without one). */
static void fault_text(rths_server *s, int fault, char *out, size_t cap) {
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
    queue_frame(s, &m, 1);
}

static void handle_hello(rths_server *s, const rths_msg *m) {
    client *c = &s->c;
    if (m->u.hello.version != RTHS_PROTO_VERSION) {
        char msg[RTHS_PROTO_MAX_TEXT + 1];
        rths_proto_version_message(msg, sizeof msg, m->u.hello.version);
        send_error(s, m->seq, RTHS_PROTO_EVERSION, m->type, msg);
        drop_client(s, msg);
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
    queue_frame(s, &r, 1);
    /* the client names itself: shown to the operator only as printable text (a newline would
     * forge a console line, an escape reach the terminal) */
    char name[64 + 4];
    rths_proto_printable(m->u.hello.name, 64, name, sizeof name);
    notice(s, "client %s says hello (%s)", c->peer, name);
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
        send_error(s, m->seq, RTHS_PROTO_ERANGE, m->type, msg);
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
        send_error(s, m->seq, RTHS_PROTO_ERANGE, m->type, msg);
        return -1;
    }
    const int dofs = t->dofs ? t->dofs : 1;
    if (dofs != s->info.interface_dofs) {
        snprintf(msg, sizeof msg, "target for %d interface DoF(s); this controller drives %d", dofs,
                 s->info.interface_dofs);
        send_error(s, m->seq, RTHS_PROTO_ERANGE, m->type, msg);
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
            send_error(s, m->seq, RTHS_PROTO_ERANGE, m->type, msg);
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
        fill_status(s, &r.u.status);
        queue_frame(s, &r, 1);
        c->last_armed = r.u.status.flags & RTHS_STATUS_ARMED ? 1 : 0;
        c->last_fault = r.u.status.fault;
    } else if (!s->have_latest) {
        send_error(s, m->seq, RTHS_PROTO_ENODATA, m->type, "no whole period yet");
    } else {
        rths_msg_init(&r, RTHS_MSG_PERIOD, m->seq);
        r.u.period = s->latest;
        queue_frame(s, &r, 1);
    }
}

static void handle(rths_server *s, const rths_msg *m) {
    char msg[RTHS_PROTO_MAX_TEXT + 1];
    if (!s->c.hello && m->type != RTHS_MSG_HELLO) {
        send_error(s, m->seq, RTHS_PROTO_ESTATE, m->type, "send HELLO first");
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
            fault_text(s, atomic_load(&s->fault), why, sizeof why);
            snprintf(msg, sizeof msg, "cannot arm: fault latched (%.120s); %s", why,
                     atomic_load(&s->stalled_ns) ? "restart the controller"
                                                 : "send RESET_FAULT first");
            send_error(s, m->seq, rc, m->type, msg);
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
        send_error(s, m->seq, RTHS_PROTO_ETYPE, m->type, msg);
        return;
    }
    reply_ack(s, m, t);
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
    drop_client(s, why);
}

static void read_client(rths_server *s) {
    client *c = &s->c;
    ssize_t k = recv(c->fd, c->rx + c->rx_len, RX_CAP - c->rx_len, MSG_DONTWAIT);
    if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return;
    if (k <= 0) {
        drop_client(s, k == 0 ? "closed by the host" : strerror(errno));
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
            send_error(s, 0, st, 0, why);
            drop_client(s, rths_proto_status_name(st));
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
            send_error(s, m.seq, st, m.type, why);
            continue;
        }
        handle(s, &m);
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
        notice(s, "refused %s:%s (busy, armed by %s)", host, serv, s->c.peer);
        return;
    }
    if (s->c.fd >= 0) drop_client(s, "replaced by a new connection");
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
            if (!queue_frame(s, &m, 0)) atomic_fetch_add(&s->periods_dropped, 1);
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
            queue_frame(s, &m, 0);
            c->batch_n = 0;
        }
    }
    /* A partial batch goes out at once: the host may be waiting for its last samples. */
    if (c->fd >= 0 && c->batch_n) {
        rths_msg_init(&m, RTHS_MSG_TRACE, 0);
        m.u.trace.count = c->batch_n;
        m.u.trace.dofs = s->info.interface_dofs;
        memcpy(m.u.trace.s, c->batch, sizeof c->batch[0] * (size_t)c->batch_n);
        queue_frame(s, &m, 0);
        c->batch_n = 0;
    }
    if (c->fd >= 0 && c->hello) {
        int armed = atomic_load(&s->armed), fault = atomic_load(&s->fault);
        if (armed != c->last_armed || fault != c->last_fault) {
            rths_msg_init(&m, RTHS_MSG_STATUS, 0);
            fill_status(s, &m.u.status);
            queue_frame(s, &m, 1);
            c->last_armed = armed;
            c->last_fault = fault;
        }
    }
}

static const char *disarm_reason_name(int r) {
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

/* Operator notices on stderr for every change of the armed state or the fault (network thread:
 * the loop never prints). */
static void announce(rths_server *s) {
    int armed = atomic_load(&s->armed), fault = atomic_load(&s->fault);
    if (s->opt.quiet || (armed == s->note_armed && fault == s->note_fault)) return;
    double ramp = s->info.ramp_time_s;
    if (fault && fault != s->note_fault) {
        char why[RTHS_PROTO_MAX_TEXT + 1];
        fault_text(s, fault, why, sizeof why);
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
                ctl_time(s), disarm_reason_name(atomic_load(&s->last_disarm)), ramp);
    s->note_armed = armed;
    s->note_fault = fault;
}

static void *net_main(void *arg) {
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
        if (flush_tx(s)) drop_client(s, "send failed");
        announce(s);
        notices_flush(s, mono_ns());
    }
    drop_client(s, "controller stopping");
    return NULL;
}

/* ---- lifetime ---- */

static int bind_listen(rths_server *s, rths_error *err) {
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

int rths_server_create(rths_config *cfg, const rths_server_options *opt, rths_server **out,
                       rths_error *err) {
    *out = NULL;
    rths_server *s = calloc(1, sizeof *s);
    if (!s) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    s->opt = *opt;
    s->listen_fd = -1;
    s->c.fd = -1;
    int rc = rths_engine_create(cfg, &s->engine, &s->info, err);
    if (rc) {
        free(s);
        return rc;
    }
    s->period_ns = (int64_t)llround(s->info.sample_period_s * 1e9);
    s->c.tx = malloc(TX_CAP);
    s->lat_hist = calloc(LAT_BINS + 1, sizeof *s->lat_hist);
    s->step_hist = calloc(STEP_BINS + 1, sizeof *s->step_hist);
    if (!s->c.tx || !s->lat_hist || !s->step_hist ||
        !(s->cmd_storage = calloc(CMD_RING, sizeof(loop_cmd))) ||
        !(s->trace_storage = calloc(TRACE_RING, sizeof(rths_proto_trace_sample))) ||
        !(s->scope_storage = calloc(SCOPE_RING, sizeof(rths_server_scope_sample)))) {
        rths_server_destroy(s);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    rths_spsc_init(&s->cmds, s->cmd_storage, CMD_RING, sizeof(loop_cmd));
    rths_spsc_init(&s->traces, s->trace_storage, TRACE_RING, sizeof(rths_proto_trace_sample));
    rths_spsc_init(&s->scope, s->scope_storage, SCOPE_RING, sizeof(rths_server_scope_sample));
    if (s->period_ns < 1000) {
        rths_server_destroy(s);
        return rths_error_set(err, RTHS_EINPUT, "sample period %g s is below 1 us",
                              s->info.sample_period_s);
    }
    atomic_store(&s->freq_bits, dbits(0.0));
    atomic_store(&s->time_bits, dbits(0.0));
    atomic_store(&s->applied_time_bits, dbits(0.0));
    atomic_store(&s->amp_bits, dbits(0.0));
    atomic_store(&s->trace_decimation, 1);
    if ((rc = bind_listen(s, err))) {
        rths_server_destroy(s);
        return rc;
    }
    *out = s;
    return RTHS_OK;
}

int rths_server_port(const rths_server *s) {
    return s->port;
}
double rths_server_sample_period_s(const rths_server *s) {
    return s->info.sample_period_s;
}
double rths_server_ramp_time_s(const rths_server *s) {
    return s->info.ramp_time_s;
}

/* What the real-time set-up asked for and what it got, one plain line each (stderr). */
static void report_realtime(rths_server *s, int mlocked, const char *mlock_why) {
    int f = atomic_load(&s->rt_flags);
    if (!s->opt.realtime) {
        fprintf(stderr, "rths controller: notice: real-time features off (server.realtime: "
                        "false); loop timing is best effort\n");
        return;
    }
    if (f & RTHS_STATUS_RT_FIFO)
        fprintf(stderr, "rths controller: real time: SCHED_FIFO priority %d granted\n",
                s->opt.priority);
    else
        fprintf(stderr,
                "rths controller: real time: SCHED_FIFO priority %d NOT granted (%s); the loop "
                "runs at normal priority, timing best effort (needs CAP_SYS_NICE or an rtprio "
                "limit, e.g. ulimit -r 99)\n",
                s->opt.priority, strerror(atomic_load(&s->rt_fifo_errno)));
    if (mlocked)
        fprintf(stderr, "rths controller: real time: memory locked (mlockall) granted\n");
    else
        fprintf(stderr,
                "rths controller: real time: memory locking NOT granted (%s); page faults may "
                "delay the loop (needs CAP_IPC_LOCK or ulimit -l unlimited)\n",
                mlock_why);
    if (f & RTHS_STATUS_RT_PINNED)
        fprintf(stderr, "rths controller: real time: loop thread pinned to CPU %d granted\n",
                atomic_load(&s->rt_cpu));
    else
        fprintf(stderr, "rths controller: real time: pinning to CPU %d NOT granted (%s)\n",
                atomic_load(&s->rt_cpu), strerror(atomic_load(&s->rt_pin_errno)));
}

/* server.realtime: all memory locked (no page fault in the loop); 1 when granted, else why not
 * in why. Recorded in the status flags either way. */
static int lock_memory(rths_server *s, char *why, size_t cap) {
    int mlocked = 0;
    if (s->opt.realtime) {
#ifdef RTHS_ASAN
        snprintf(why, cap, "not with AddressSanitizer (its shadow memory)");
#else
        if (!mlockall(MCL_CURRENT | MCL_FUTURE))
            mlocked = 1;
        else
            snprintf(why, cap, "%s", strerror(errno));
#endif
    }
    if (mlocked) atomic_fetch_or(&s->rt_flags, RTHS_STATUS_RT_MLOCK);
    return mlocked;
}

int rths_server_start(rths_server *s, rths_error *err) {
    if (s->loop_started) return RTHS_OK;
    char mlock_why[160] = "";
    int mlocked = lock_memory(s, mlock_why, sizeof mlock_why);
    atomic_store(&s->last_rx_ns, mono_ns());
    /* the plug-in's hardware watchdog, when it has one: armed before the loop kicks it */
    rths_error werr;
    rths_error_clear(&werr);
    s->hw_watchdog = !rths_engine_watchdog_arm(s->engine, s->opt.hardware_watchdog_s, &werr);
    snprintf(s->hw_watchdog_why, sizeof s->hw_watchdog_why, "%.150s", werr.msg);
    int e = pthread_create(&s->loop_thread, NULL, loop_main, s);
    if (e) return rths_error_set(err, RTHS_EFAIL, "cannot start the loop thread: %s", strerror(e));
    s->loop_started = 1;
    while (!atomic_load(&s->loop_ready)) {
        struct timespec ts = {0, 100000};
        nanosleep(&ts, NULL);
    }
    if ((e = pthread_create(&s->supervisor_thread, NULL, supervisor_main, s))) {
        rths_server_stop(s);
        return rths_error_set(err, RTHS_EFAIL, "cannot start the supervisor thread: %s",
                              strerror(e));
    }
    s->supervisor_started = 1;
    if ((e = pthread_create(&s->net_thread, NULL, net_main, s))) {
        rths_server_stop(s);
        return rths_error_set(err, RTHS_EFAIL, "cannot start the network thread: %s", strerror(e));
    }
    s->net_started = 1;
    if (!s->opt.quiet) {
        report_realtime(s, mlocked, mlock_why);
        if (s->hw_watchdog)
            fprintf(stderr,
                    "rths controller: hardware watchdog armed: the device goes to its safe state "
                    "by itself %g s after the loop's last kick\n",
                    s->opt.hardware_watchdog_s);
        else
            fprintf(stderr, "rths controller: notice: no hardware watchdog: %s\n",
                    s->hw_watchdog_why);
    }
    return RTHS_OK;
}

void rths_server_stop(rths_server *s) {
    if (!s) return;
    atomic_store(&s->stop, 1);
    if (s->net_started) pthread_join(s->net_thread, NULL);
    if (s->loop_started) {
        /* The loop ramps down and ends by itself; a loop stuck in the device never does. Once the
         * supervisor has found it stalled (and driven the safe state) the thread is abandoned:
         * the process can still stop, on SIGTERM too. */
        while (pthread_tryjoin_np(s->loop_thread, NULL) == EBUSY) {
            if (atomic_load(&s->stalled_ns) && !s->loop_abandoned) {
                s->loop_abandoned = 1;
                break;
            }
            struct timespec ts = {0, 1000000};
            nanosleep(&ts, NULL);
        }
    }
    atomic_store(&s->supervisor_stop, 1);
    if (s->supervisor_started) pthread_join(s->supervisor_thread, NULL);
    s->net_started = s->loop_started = s->supervisor_started = 0;
    if (!s->loop_abandoned && (atomic_load(&s->rt_flags) & RTHS_STATUS_RT_MLOCK)) munlockall();
}

int rths_server_loop_stalled(rths_server *s, double *ran_s) {
    int64_t ran = atomic_load(&s->stalled_ns);
    if (ran_s) *ran_s = (double)ran * 1e-9;
    return ran != 0;
}

/* A server whose loop thread was abandoned (stuck in the device), kept reachable until exit. */
static rths_server *abandoned;

void rths_server_destroy(rths_server *s) {
    if (!s) return;
    rths_server_stop(s);
    if (s->c.fd >= 0) close(s->c.fd);
    if (s->listen_fd >= 0) close(s->listen_fd);
    /* an abandoned loop thread may still return into the engine and the rings: they stay (the
     * process is ending; closing the device under a thread inside it is not safe) */
    if (s->loop_abandoned) {
        abandoned = s; /* still referenced: what the stuck thread may touch is not a leak */
        return;
    }
    rths_engine_destroy(s->engine);
    free(s->c.tx);
    free(s->lat_hist);
    free(s->step_hist);
    free(s->cmd_storage);
    free(s->trace_storage);
    free(s->scope_storage);
    free(s);
}

static double hist_quantile(_Atomic uint32_t *h, int bins, double width_s, double q) {
    uint64_t total = 0;
    for (int i = 0; i <= bins; i++)
        total += atomic_load_explicit(&h[i], memory_order_relaxed);
    if (!total) return 0.0;
    uint64_t want = (uint64_t)ceil(q * (double)total), acc = 0;
    for (int i = 0; i <= bins; i++) {
        acc += atomic_load_explicit(&h[i], memory_order_relaxed);
        if (acc >= want) return (i + 1) * width_s; /* upper edge of the bin: conservative */
    }
    return (bins + 1) * width_s;
}

void rths_server_get_stats(rths_server *s, rths_server_stats *o) {
    memset(o, 0, sizeof *o);
    o->samples = atomic_load(&s->samples);
    o->overruns = atomic_load(&s->overruns);
    o->resyncs = atomic_load(&s->resyncs);
    o->worst_lateness_s = (double)atomic_load(&s->worst_late_ns) * 1e-9;
    o->lateness_p50_s = hist_quantile(s->lat_hist, LAT_BINS, 1e-6, 0.50);
    o->lateness_p90_s = hist_quantile(s->lat_hist, LAT_BINS, 1e-6, 0.90);
    o->lateness_p99_s = hist_quantile(s->lat_hist, LAT_BINS, 1e-6, 0.99);
    o->lateness_p999_s = hist_quantile(s->lat_hist, LAT_BINS, 1e-6, 0.999);
    o->step_mean_s =
        o->samples ? (double)atomic_load(&s->step_sum_ns) * 1e-9 / (double)o->samples : 0.0;
    o->step_p50_s = hist_quantile(s->step_hist, STEP_BINS, 1e-7, 0.50);
    o->step_p99_s = hist_quantile(s->step_hist, STEP_BINS, 1e-7, 0.99);
    o->step_max_s = (double)atomic_load(&s->worst_step_ns) * 1e-9;
    int f = atomic_load(&s->rt_flags);
    o->rt_fifo = (f & RTHS_STATUS_RT_FIFO) != 0;
    o->rt_mlock = (f & RTHS_STATUS_RT_MLOCK) != 0;
    o->rt_pinned = (f & RTHS_STATUS_RT_PINNED) != 0;
    o->armed = atomic_load(&s->armed);
    o->fault = atomic_load(&s->fault);
    o->last_disarm = atomic_load(&s->last_disarm);
}

/* ---- watching the process (the viewer's side; see server.h) ---- */

void rths_server_scope_enable(rths_server *s, int decimation) {
    atomic_store_explicit(&s->scope_decimation, (uint32_t)(decimation > 0 ? decimation : 0),
                          memory_order_release);
}

int rths_server_scope_pop(rths_server *s, rths_server_scope_sample *out, int max) {
    int n = 0;
    while (n < max && rths_spsc_pop(&s->scope, &out[n]))
        n++;
    return n;
}

void rths_server_get_watch(rths_server *s, rths_server_watch *o) {
    memset(o, 0, sizeof *o);
    o->time_s = ctl_time(s);
    o->frequency_hz = bitsd(atomic_load(&s->freq_bits));
    o->amplitude_n = bitsd(atomic_load(&s->amp_bits));
    o->sample_period_s = s->info.sample_period_s;
    o->watchdog_s = s->opt.watchdog_s;
    o->ramp_time_s = s->info.ramp_time_s;
    o->displacement_limit_m = s->info.displacement_limit_m;
    o->host_connected = atomic_load(&s->client_connected);
    int64_t silent = mono_ns() - atomic_load_explicit(&s->last_rx_ns, memory_order_relaxed);
    o->host_silence_s = silent > 0 ? (double)silent * 1e-9 : 0.0;
    o->scope_decimation = (int)atomic_load(&s->scope_decimation);
    o->scope_dropped = atomic_load(&s->scope_dropped);
    o->periods_dropped = atomic_load(&s->periods_dropped) + atomic_load(&s->engine_dropped);
}

void rths_server_lateness_histogram(rths_server *s, const double *edges_s, int n_edges,
                                    uint64_t *counts) {
    memset(counts, 0, sizeof *counts * (size_t)n_edges);
    int bin = -1;
    for (int i = 0; i <= LAT_BINS; i++) {
        /* fine bin i holds [i, i + 1) us (the last: everything beyond); it goes to the coarse bin
         * whose lower edge it has reached */
        while (bin + 1 < n_edges && (double)i * 1e-6 >= edges_s[bin + 1] - 1e-12)
            bin++;
        if (bin >= 0) counts[bin] += atomic_load_explicit(&s->lat_hist[i], memory_order_relaxed);
    }
}

const char *rths_server_fault_name(int fault) {
    return fault_name(fault);
}

const char *rths_server_disarm_reason_name(int reason) {
    return disarm_reason_name(reason);
}

/* ---- the latency test (rths controller --latency-test) ---- */

typedef struct {
    rths_server *s;
    uint64_t samples;
} latency_run;

static void *latency_main(void *arg) {
    latency_run *run = arg;
    rths_server *s = run->s;
    rt_setup(s);
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (uint64_t k = 0; k < run->samples; k++) {
        int overrun;
        wait_next_sample(s, &next, &overrun);
        add64(&s->samples, 1);
    }
    return NULL;
}

int rths_server_latency_test(const rths_server_options *opt, double rate_hz, double seconds,
                             rths_server_stats *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    if (!(rate_hz >= 1 && rate_hz <= 1e6) || !(seconds > 0 && seconds <= 1e6))
        return rths_error_set(err, RTHS_EINPUT,
                              "latency test: %g Hz for %g s; the rate must be in [1, 1e6] Hz and "
                              "the duration in (0, 1e6] s",
                              rate_hz, seconds);
    /* a server with only what the pacing touches: options, histograms, counters */
    rths_server *s = calloc(1, sizeof *s);
    if (!s) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    s->opt = *opt;
    s->period_ns = (int64_t)llround(1e9 / rate_hz);
    s->lat_hist = calloc(LAT_BINS + 1, sizeof *s->lat_hist);
    s->step_hist = calloc(STEP_BINS + 1, sizeof *s->step_hist);
    if (!s->lat_hist || !s->step_hist) {
        free(s->lat_hist), free(s->step_hist), free(s);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    char mlock_why[160] = "";
    int mlocked = lock_memory(s, mlock_why, sizeof mlock_why);
    latency_run run = {s, (uint64_t)llround(seconds * rate_hz)};
    pthread_t th;
    int e = pthread_create(&th, NULL, latency_main, &run);
    int rc = RTHS_OK;
    if (e)
        rc = rths_error_set(err, RTHS_EFAIL, "cannot start the loop thread: %s", strerror(e));
    else {
        pthread_join(th, NULL);
        if (!s->opt.quiet) report_realtime(s, mlocked, mlock_why);
        rths_server_get_stats(s, out);
    }
    if (mlocked) munlockall();
    free(s->lat_hist), free(s->step_hist), free(s);
    return rc;
}
