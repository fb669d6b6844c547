/* rths server: the real-time controller process (`rths controller`), controller module.
 *
 * Two threads. The loop thread runs the per-sample step (controller + plant behind the per-sample
 * I/O seam) paced by the wall clock with absolute deadlines (clock_nanosleep TIMER_ABSTIME on
 * CLOCK_MONOTONIC), under SCHED_FIFO, with locked memory and pinned to a CPU when permitted; it
 * never allocates, blocks, locks or does I/O. The network thread serves one host over TCP
 * (docs/protocol.md) and talks to the loop only through preallocated single-producer
 * single-consumer rings and atomics. Safety (explicit arm, latched limits with a ramp to zero,
 * the host watchdog, disarm on loss of the controlling connection) is enforced on the loop side.
 * It drives every interface DoF of the configuration's split (1 to RTHS_PROTO_MAX_DOFS, one
 * actuator each) and speaks protocol version 3, which carries them all and each period's integrity
 * counts. */
#ifndef RTHS_SERVER_H
#define RTHS_SERVER_H

#include "rths/config.h"

#include <stdint.h>

typedef struct rths_server_options {
    char host[256];             /* listen address; default "127.0.0.1" (loopback only) */
    int port;                   /* 0: an ephemeral port, see rths_server_port() */
    double watchdog_s;          /* server.watchdog_s: host silence that trips the watchdog */
    int realtime;               /* server.realtime: try SCHED_FIFO, mlockall, CPU pinning */
    int priority;               /* server.priority: SCHED_FIFO priority 1..99 */
    int cpu;                    /* server.cpu: CPU for the loop thread, -1: the last one */
    double max_frequency_hz;    /* server.max_frequency_hz: SET_FORCING above is refused */
    double max_amplitude_n;     /* server.max_amplitude_n: |amplitude| above is refused */
    double stall_margin_s;      /* server.stall_margin_s: a sample running longer than its period
                                   plus this is a stalled loop (the supervisor drives the device's
                                   safe state); 0.05 */
    double hardware_watchdog_s; /* server.hardware_watchdog_s: the timeout a plug-in's hardware
                                   watchdog is armed with (io.h); 0.1 */
    int quiet;                  /* no notices on stderr (tests, bench) */
} rths_server_options;

void rths_server_options_defaults(rths_server_options *opt);

/* Reads the `server` section over the defaults already in opt. */
int rths_server_config_read(rths_config *cfg, rths_server_options *opt, rths_error *err);

typedef struct rths_server rths_server;

/* Builds the step and the plant from the configuration (every section they read) and binds the
 * listening socket. Nothing runs until rths_server_start. */
int rths_server_create(rths_config *cfg, const rths_server_options *opt, rths_server **out,
                       rths_error *err);
int rths_server_port(const rths_server *s); /* the bound port (useful after port 0) */
double rths_server_sample_period_s(const rths_server *s);
/* Time the step takes to ramp demand, forcing and target to zero after a disarm or fault, s. */
double rths_server_ramp_time_s(const rths_server *s);

/* Starts the loop and network threads. */
int rths_server_start(rths_server *s, rths_error *err);
/* Disarms (ramp to zero), stops and joins the threads. Safe to call twice. A loop thread stuck
 * in the device (rths_server_loop_stalled) is not waited for: the supervisor has driven the
 * device's safe state, and the thread is left to end with the process (rths_server_destroy then
 * frees nothing it may touch). */
void rths_server_stop(rths_server *s);
/* 1 when the supervisor found the loop stalled (ran_s: how long the stuck sample had run when
 * it was found, s); the process should exit once stopped. */
int rths_server_loop_stalled(rths_server *s, double *ran_s);
void rths_server_destroy(rths_server *s);

typedef struct rths_server_stats {
    uint64_t samples;  /* loop cycles run */
    uint64_t overruns; /* cycles woken after the next deadline had already passed */
    uint64_t resyncs;  /* times the loop gave up catching up and restarted its clock */
    double worst_lateness_s;
    double lateness_p50_s, lateness_p90_s, lateness_p99_s, lateness_p999_s; /* 1 us bins */
    double step_mean_s, step_p50_s, step_p99_s, step_max_s;                 /* 0.1 us bins */
    int rt_fifo, rt_mlock, rt_pinned;
    int armed;
    int fault;       /* rths_rig_fault numbering */
    int last_disarm; /* rths_disarm_reason (protocol.h) */
} rths_server_stats;

void rths_server_get_stats(rths_server *s, rths_server_stats *out);

/* `rths controller --latency-test SECONDS`: the loop's pacing alone, no device and no step, for
 * seconds at rate_hz, with the real-time set-up of opt (SCHED_FIFO, mlockall, CPU) reported on
 * stderr unless quiet: fills the lateness and overrun fields of out (and rt_*), like
 * cyclictest's wake-up latency. Blocks for the duration. */
int rths_server_latency_test(const rths_server_options *opt, double rate_hz, double seconds,
                             rths_server_stats *out, rths_error *err);

/* ---- watching the process without disturbing the loop (a web page: rths_server_view_start in
 * view.h). The loop publishes every decimation-th sample into a preallocated single-producer
 * single-consumer ring (never waited for: a full ring drops the sample, counted) and its lateness
 * into histogram bins, all lock-free; the functions below read them from another thread. ---- */

/* One decimated loop sample, of the first interface DoF. */
typedef struct rths_server_scope_sample {
    double time_s;   /* controller (rig) time, s */
    double x_phys_m; /* physical interface displacement (measured) */
    double x_num_m;  /* numerical interface displacement */
    double target_m; /* the host's target for the interface */
    double force_n;  /* interface force (load cell) */
    double demand_v; /* actuator demand */
} rths_server_scope_sample;

/* Publishes every decimation-th sample from now on (0: none, the default). Any thread. */
void rths_server_scope_enable(rths_server *s, int decimation);
/* Pops up to max published samples, oldest first; returns how many. Exactly one thread may call
 * it (the ring's single consumer); the ring holds 8192 samples. */
int rths_server_scope_pop(rths_server *s, rths_server_scope_sample *out, int max);

typedef struct rths_server_watch {
    double time_s;       /* controller time, s */
    double frequency_hz; /* forcing in effect */
    double amplitude_n;
    double sample_period_s;
    double watchdog_s;           /* server.watchdog_s */
    double host_silence_s;       /* since the host's last frame (the watchdog's clock) */
    double ramp_time_s;          /* ramp to zero after a disarm or fault */
    double displacement_limit_m; /* controller.limits.displacement_m */
    int host_connected;          /* a host holds the connection */
    int scope_decimation;        /* as enabled, 0: off */
    uint64_t scope_dropped;      /* scope samples lost to a full ring */
    uint64_t periods_dropped;    /* whole periods the host did not get */
} rths_server_watch;

void rths_server_get_watch(rths_server *s, rths_server_watch *out);
/* The loop's wake-up lateness so far: counts[i] = samples late by edges_s[i] <= lateness <
 * edges_s[i + 1] (the last: and beyond). edges_s ascending from 0, resolved to whole
 * microseconds (the loop's bins). Any thread. */
void rths_server_lateness_histogram(rths_server *s, const double *edges_s, int n_edges,
                                    uint64_t *counts);
/* Names of the rths_rig_fault numbering and of rths_disarm_reason (protocol.h). */
const char *rths_server_fault_name(int fault);
const char *rths_server_disarm_reason_name(int reason);

#endif
