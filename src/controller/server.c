/* The controller process: wall-clock paced loop thread + network thread (see server.h).
 *
 * Everything the loop touches is allocated before it starts: the command ring (network -> loop),
 * the trace ring (loop -> network), the lateness and step-cost histograms, and the published
 * state, all atomics. The step's own period ring (loop -> network) lives in the engine. The
 * network thread owns the socket and the protocol; it never blocks on a client (non-blocking
 * sends from a bounded transmit buffer; stream frames are dropped, never waited for).
 *
 * This file: the server's lifetime (create, start, stop, destroy), the paced loop thread and its
 * supervisor, and what other threads read of it (statistics, scope, watch, names, the latency
 * test). The network thread is in server_net.c and server_dispatch.c (server_internal.h). */
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

/* ---- the loop thread ---- */

static void apply_cmd(rths_server *s, const loop_cmd *c) {
    int result = 0;
    rths_engine *e = s->engine;
    double applied_time_s = -1; /* the ACK's time: when it took effect, unless said otherwise */
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
        /* from when the host may keep periods: a change may take over the period the last
         * sample opened, or wait for the next boundary (docs/protocol.md) */
        applied_time_s = rths_engine_forcing_valid_from_s(e);
        atomic_store_explicit(&s->freq_bits, dbits(c->frequency_hz), memory_order_relaxed);
        atomic_store_explicit(&s->amp_bits, dbits(c->amplitude_n), memory_order_relaxed);
        break;
    case CMD_TARGET:
        rths_engine_set_target(e, c->dofs, c->harmonics, c->a, c->b);
        /* a target that follows a forcing change keeps that change's periods */
        applied_time_s = rths_engine_target_valid_from_s(e);
        break;
    case CMD_RESET:
        /* a stalled loop's device is in its safe state for good: only a restart clears it */
        if (!atomic_load_explicit(&s->stalled_ns, memory_order_relaxed)) rths_engine_reset_fault(e);
        break;
    }
    atomic_store_explicit(&s->applied_result, result, memory_order_relaxed);
    if (applied_time_s < 0) applied_time_s = rths_engine_time_s(e);
    atomic_store_explicit(&s->applied_time_bits, dbits(applied_time_s), memory_order_relaxed);
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
    if ((rc = server_bind_listen(s, err))) {
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
    if ((e = pthread_create(&s->net_thread, NULL, server_net_main, s))) {
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
    return server_fault_name(fault);
}

const char *rths_server_disarm_reason_name(int reason) {
    return server_disarm_reason_name(reason);
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
