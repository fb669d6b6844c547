/* The controller process's page (rths_server_view_start, view.h): a collector thread drains the
 * loop's scope ring (server.h) into a window of the last second, the HTTP threads turn that
 * window, the lateness histogram and the loop's published state into JSON. Nothing here is on
 * the loop's side: the loop only ever pushes to its ring and bumps its counters. */
#include "view/view_internal.h"

#include <json-c/json.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum {
    SCOPE_WINDOW = 4096, /* samples kept (4 s at 1 kHz); the page gets the last SCOPE_SHOWN_S */
    COLLECT_BATCH = 512,
};
#define SCOPE_RATE_HZ 1000.0 /* the scope's sample rate after decimation, about */
#define SCOPE_SHOWN_S 1.0    /* seconds of signal the page draws */
#define COLLECT_EVERY_S 0.02 /* the collector's period: the ring holds 8 s at 1 kHz */

/* Lateness bins of the page: whole microseconds (the loop's own bins are 1 us wide). */
static const double lateness_edges_s[] = {0,      1e-6,   2e-6, 5e-6, 10e-6, 20e-6, 50e-6, 100e-6,
                                          200e-6, 500e-6, 1e-3, 2e-3, 5e-3,  10e-3, 20e-3, 50e-3};
enum { N_LATENESS = sizeof lateness_edges_s / sizeof lateness_edges_s[0] };

struct rths_server_view {
    rths_server *server;
    rths_view *view;
    int decimation;
    pthread_t collector;
    int collector_started;
    atomic_int stop;
    pthread_mutex_t lock; /* the window, between the collector and the HTTP threads only */
    rths_server_scope_sample window[SCOPE_WINDOW];
    int head, count; /* next slot to write; samples held */
    uint64_t collected;
    char host[256]; /* the address served on */
};

static void *collect_main(void *arg) {
    rths_server_view *sv = arg;
    rths_server_scope_sample batch[COLLECT_BATCH];
    while (!atomic_load(&sv->stop)) {
        int n;
        while ((n = rths_server_scope_pop(sv->server, batch, COLLECT_BATCH)) > 0) {
            pthread_mutex_lock(&sv->lock);
            for (int i = 0; i < n; i++) {
                sv->window[sv->head] = batch[i];
                sv->head = (sv->head + 1) % SCOPE_WINDOW;
            }
            sv->count = sv->count + n < SCOPE_WINDOW ? sv->count + n : SCOPE_WINDOW;
            sv->collected += (uint64_t)n;
            pthread_mutex_unlock(&sv->lock);
        }
        struct timespec ts = {0, (long)(COLLECT_EVERY_S * 1e9)};
        nanosleep(&ts, NULL);
    }
    return NULL;
}

/* ---- JSON ---- */

typedef struct text {
    char *s;
    size_t len, cap;
    int failed;
} text;

static void put(text *t, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(text *t, const char *fmt, ...) {
    for (int pass = 0; !t->failed && pass < 2; pass++) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(t->s ? t->s + t->len : NULL, t->s ? t->cap - t->len : 0, fmt, ap);
        va_end(ap);
        if (n < 0) t->failed = 1;
        if (n < 0 || (t->s && t->len + (size_t)n < t->cap)) {
            if (n >= 0) t->len += (size_t)n;
            return;
        }
        size_t cap = t->cap ? t->cap : 65536;
        while (cap <= t->len + (size_t)n)
            cap *= 2;
        char *grown = realloc(t->s, cap);
        if (!grown) t->failed = 1;
        t->s = grown ? grown : t->s;
        t->cap = grown ? cap : t->cap;
    }
}

/* A number JSON can hold: non-finite values (a faulted signal) become null. */
static void put_number(text *t, const char *fmt, double x) {
    if (isfinite(x))
        put(t, fmt, x);
    else
        put(t, "null");
}

static const char *watchdog_state(const rths_server_stats *st, const rths_server_watch *w) {
    if (st->fault == 6) return "tripped: host silent too long (RESET_FAULT, then ARM)";
    if (!st->armed) return "idle (disarmed)";
    return w->host_silence_s > 0.5 * w->watchdog_s ? "watching: host slow" : "watching: host ok";
}

/* The loop's state as flat fields: also /api/status's "process" (the run page shows them). */
static void put_state(text *t, rths_server_view *sv) {
    rths_server_stats st;
    rths_server_watch w;
    rths_server_get_stats(sv->server, &st);
    rths_server_get_watch(sv->server, &w);
    put(t, "\"armed\": %s, \"limit_state\": \"%s\", \"fault\": \"%s\", \"last_disarm\": \"%s\", ",
        st.armed ? "true" : "false", st.fault ? "latched" : "none latched",
        rths_server_fault_name(st.fault), rths_server_disarm_reason_name(st.last_disarm));
    put(t, "\"controller_time_s\": %.9g, \"forcing_hz\": %.9g, \"forcing_amplitude_n\": %.9g, ",
        w.time_s, w.frequency_hz, w.amplitude_n);
    put(t, "\"host_connected\": %s, \"host_silence_s\": %.4g, \"watchdog_s\": %.6g, ",
        w.host_connected ? "true" : "false", w.host_silence_s, w.watchdog_s);
    put(t, "\"watchdog\": \"%s\", \"displacement_limit_m\": %.9g, \"sample_period_s\": %.9g, ",
        watchdog_state(&st, &w), w.displacement_limit_m, w.sample_period_s);
    put(t, "\"samples\": %llu, \"overruns\": %llu, \"resyncs\": %llu, ",
        (unsigned long long)st.samples, (unsigned long long)st.overruns,
        (unsigned long long)st.resyncs);
    put(t, "\"worst_lateness_s\": %.6g, \"lateness_p50_s\": %.6g, \"lateness_p99_s\": %.6g, ",
        st.worst_lateness_s, st.lateness_p50_s, st.lateness_p99_s);
    put(t, "\"step_mean_s\": %.6g, \"step_max_s\": %.6g, ", st.step_mean_s, st.step_max_s);
    put(t, "\"realtime\": \"%s%s%s\", ", st.rt_fifo ? "SCHED_FIFO " : "",
        st.rt_mlock ? "mlock " : "", st.rt_pinned ? "pinned" : "");
    put(t, "\"periods_dropped\": %llu, \"scope_dropped\": %llu",
        (unsigned long long)w.periods_dropped, (unsigned long long)w.scope_dropped);
}

static void put_column(text *t, const char *name, const rths_server_scope_sample *s, int n,
                       size_t offset, const char *fmt) {
    put(t, "\"%s\": [", name);
    for (int i = 0; i < n; i++) {
        if (i) put(t, ",");
        put_number(t, fmt, *(const double *)((const char *)&s[i] + offset));
    }
    put(t, "]");
}

/* The last SCOPE_SHOWN_S of the window, oldest first, as columns. */
static void put_scope(text *t, rths_server_view *sv, double sample_period_s) {
    int want = (int)ceil(SCOPE_SHOWN_S / (sample_period_s * sv->decimation));
    if (want > SCOPE_WINDOW) want = SCOPE_WINDOW;
    rths_server_scope_sample *s = malloc(sizeof *s * (size_t)want);
    if (!s) {
        t->failed = 1;
        return;
    }
    pthread_mutex_lock(&sv->lock);
    int n = sv->count < want ? sv->count : want;
    for (int i = 0; i < n; i++)
        s[i] = sv->window[(sv->head - n + i + SCOPE_WINDOW) % SCOPE_WINDOW];
    uint64_t collected = sv->collected;
    pthread_mutex_unlock(&sv->lock);
    put(t, "\"scope\": {\"decimation\": %d, \"sample_period_s\": %.9g, \"collected\": %llu, ",
        sv->decimation, sample_period_s * sv->decimation, (unsigned long long)collected);
    put_column(t, "time_s", s, n, offsetof(rths_server_scope_sample, time_s), "%.9g");
    put(t, ", ");
    put_column(t, "x_phys_m", s, n, offsetof(rths_server_scope_sample, x_phys_m), "%.7g");
    put(t, ", ");
    put_column(t, "x_num_m", s, n, offsetof(rths_server_scope_sample, x_num_m), "%.7g");
    put(t, ", ");
    put_column(t, "target_m", s, n, offsetof(rths_server_scope_sample, target_m), "%.7g");
    put(t, ", ");
    put_column(t, "force_n", s, n, offsetof(rths_server_scope_sample, force_n), "%.7g");
    put(t, "}");
    free(s);
}

static void put_lateness(text *t, rths_server_view *sv) {
    uint64_t counts[N_LATENESS];
    rths_server_lateness_histogram(sv->server, lateness_edges_s, N_LATENESS, counts);
    put(t, "\"lateness\": {\"edges_s\": [");
    for (int i = 0; i < N_LATENESS; i++)
        put(t, "%s%.6g", i ? "," : "", lateness_edges_s[i]);
    put(t, "], \"counts\": [");
    for (int i = 0; i < N_LATENESS; i++)
        put(t, "%s%llu", i ? "," : "", (unsigned long long)counts[i]);
    put(t, "]}");
}

char *rths_server_view_process_json(rths_server_view *sv) {
    text t = {0};
    rths_server_watch w;
    rths_server_get_watch(sv->server, &w);
    /* the histogram before the state: its counts never exceed the state's samples (+1, the
     * wake-up being binned) */
    put(&t, "{");
    put_lateness(&t, sv);
    put(&t, ", \"state\": {");
    put_state(&t, sv);
    put(&t, "}, ");
    put_scope(&t, sv, w.sample_period_s);
    put(&t, "}");
    if (t.failed) {
        free(t.s);
        return NULL;
    }
    return t.s;
}

static char *process_json(void *user) {
    return rths_server_view_process_json(user);
}

static int snapshot(void *user, char *buf, size_t cap) {
    text t = {0};
    put(&t, "{");
    put_state(&t, user);
    put(&t, "}");
    int n = t.failed || t.len >= cap ? -1 : (int)t.len;
    if (n > 0) memcpy(buf, t.s, t.len + 1);
    free(t.s);
    return n;
}

/* ---- lifetime ---- */

/* Empties the scope ring; only while no collector runs (the ring has one consumer). */
static void drain(rths_server *server) {
    rths_server_scope_sample stale[COLLECT_BATCH];
    while (rths_server_scope_pop(server, stale, COLLECT_BATCH) > 0) {
    }
}

int rths_server_view_start(rths_server *server, const char *listen, rths_server_view **out,
                           rths_error *err) {
    *out = NULL;
    rths_view_options opt;
    rths_view_options_defaults(&opt);
    int rc = view_parse_listen_as("--view", listen ? listen : "", opt.host, sizeof opt.host,
                                  &opt.port, err);
    if (rc) return rc;
    rths_server_view *sv = calloc(1, sizeof *sv);
    if (!sv) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    sv->server = server;
    snprintf(sv->host, sizeof sv->host, "%s", opt.host);
    pthread_mutex_init(&sv->lock, NULL);
    double h = rths_server_sample_period_s(server);
    sv->decimation = (int)fmax(1.0, round(1.0 / (SCOPE_RATE_HZ * h)));
    opt.snapshot = snapshot;
    opt.snapshot_user = sv;
    opt.process = process_json;
    opt.process_user = sv;
    opt.page = "controller.html";
    int e;
    if ((rc = rths_view_start(&opt, &sv->view, err)) == RTHS_OK) {
        drain(server); /* what a previous page may have left is old */
        rths_server_scope_enable(server, sv->decimation);
        if ((e = pthread_create(&sv->collector, NULL, collect_main, sv)) == 0)
            sv->collector_started = 1;
        else
            rc = rths_error_set(err, RTHS_EFAIL, "cannot start the view's collector: %s",
                                strerror(e));
    }
    if (rc) {
        rths_server_view_stop(sv);
        return rc;
    }
    *out = sv;
    return RTHS_OK;
}

int rths_server_view_port(const rths_server_view *sv) {
    return rths_view_port(sv->view);
}

const char *rths_server_view_host(const rths_server_view *sv) {
    return sv->host;
}

void rths_server_view_stop(rths_server_view *sv) {
    if (!sv) return;
    rths_view_stop(sv->view); /* no request runs after this */
    rths_server_scope_enable(sv->server, 0);
    atomic_store(&sv->stop, 1);
    if (sv->collector_started) pthread_join(sv->collector, NULL);
    drain(sv->server); /* the next page starts from the present */
    pthread_mutex_destroy(&sv->lock);
    free(sv);
}
