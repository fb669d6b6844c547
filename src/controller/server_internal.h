/* Private to the controller server's files (server.c: lifetime, the paced loop thread and its
 * supervisor, read-outs; server_net.c: the socket and the host's session;
 * server_dispatch.c: a host's requests checked, applied and answered): the server's state, shared
 * constants and the functions one file calls in another. See server.c's opening comment. */
#ifndef RTHS_SERVER_INTERNAL_H
#define RTHS_SERVER_INTERNAL_H

#include "rths/server.h"

#include "controller/server_engine.h"
#include "controller/spsc.h"
#include "rths/controller.h"
#include "rths/protocol.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <string.h>
#include <time.h>

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

static inline int64_t mono_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static inline uint64_t dbits(double x) {
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

static inline double bitsd(uint64_t u) {
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

static inline double ctl_time(rths_server *s) {
    return bitsd(atomic_load_explicit(&s->time_bits, memory_order_relaxed));
}

/* server_net.c (network thread) */
void *server_net_main(void *arg);
int server_bind_listen(rths_server *s, rths_error *err);
void server_notice(rths_server *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
int server_queue_frame(rths_server *s, rths_msg *m, int reply);
void server_drop_client(rths_server *s, const char *why);

/* server_dispatch.c (network thread, but the names are read from any thread) */
void server_handle_request(rths_server *s, const rths_msg *m);
void server_send_error(rths_server *s, uint16_t seq, int code, int req_type, const char *msg);
void server_fill_status(rths_server *s, rths_proto_status_msg *st);
const char *server_fault_name(int f);
void server_fault_text(rths_server *s, int fault, char *out, size_t cap);
const char *server_disarm_reason_name(int r);

#endif
