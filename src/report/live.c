/* live.json: the state of a run in progress, replaced after every evaluation (see live.h). */
#include "rths/live.h"
#include "rths/report.h"

#include <errno.h>
#include <fcntl.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* Two trace series and a 64-entry history of %.17g numbers, coefficients and the rest stay well
 * under this; an overflow (which cannot happen with these limits) skips the write. */
#define LIVE_BUFFER_BYTES 32768

struct rths_live {
    char *path, *tmp;
    char *buf;
    size_t len;
    int overflow;
    locale_t c_locale;
    double opened_s;
    /* what live.json shows */
    int have_evaluation;
    rths_live_evaluation ev;
    double trace_t[RTHS_LIVE_TRACE_SAMPLES], trace_p[RTHS_LIVE_TRACE_SAMPLES],
        trace_n[RTHS_LIVE_TRACE_SAMPLES];
    int trace_n_samples, trace_measured;
    double history[RTHS_LIVE_HISTORY];
    int history_n; /* evaluations of the current point (the ring keeps the last 64) */
    int points_accepted, evaluations_total, new_point;
    double residual_m;
    int have_link_stats;
    long overruns;
    double worst_lateness_s;
    int ended;
    double min_interval_s, last_write_s;
    int dirty;                      /* recorded but not yet written (inside the minimum interval) */
    struct observing_rig *observer; /* the observing rig on this live, if any */
    /* cos and sin of k * 2 pi i / (n - 1) for the reconstructed trace, computed once */
    double cos_table[RTHS_MAX_HARMONICS][RTHS_LIVE_TRACE_SAMPLES];
    double sin_table[RTHS_MAX_HARMONICS][RTHS_LIVE_TRACE_SAMPLES];
};

/* The observing rig (rths_live_wrap_rig). */
typedef struct observing_rig {
    rths_live *live; /* NULL once live is closed */
    rths_rig *inner;
    rths_live_evaluation ev; /* the evaluation in progress */
    int periods;             /* periods run since the last publication */
} observing_rig;
static void publish_if_done(observing_rig *o);

/* ---- the text ---- */

static void put(rths_live *l, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(rths_live *l, const char *fmt, ...) {
    if (l->overflow) return;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(l->buf + l->len, LIVE_BUFFER_BYTES - l->len, fmt, ap);
    va_end(ap);
    if (n < 0 || (size_t)n >= LIVE_BUFFER_BYTES - l->len)
        l->overflow = 1;
    else
        l->len += (size_t)n;
}

/* JSON has no NaN or infinity: those become null. */
static void put_number(rths_live *l, const char *fmt, double x) {
    if (isfinite(x))
        put(l, fmt, x);
    else
        put(l, "null");
}

/* key and value: the text before the number, the number (or null), the text after it */
static void put_value(rths_live *l, const char *before, const char *fmt, double x,
                      const char *after) {
    put(l, "%s", before);
    put_number(l, fmt, x);
    put(l, "%s", after);
}

static void put_array(rths_live *l, const char *key, const double *x, int n, const char *fmt) {
    put(l, "\"%s\": [", key);
    for (int i = 0; i < n; i++) {
        if (i) put(l, ", ");
        put_number(l, fmt, x[i]);
    }
    put(l, "]");
}

static void put_fourier(rths_live *l, const char *key, const rths_fourier *f) {
    put(l, "  \"%s\": {", key);
    put_array(l, "a_m", f->a, RTHS_MAX_HARMONICS + 1, "%.17g");
    put(l, ", ");
    put_array(l, "b_m", f->b, RTHS_MAX_HARMONICS + 1, "%.17g");
    put(l, "},\n");
}

static void put_history(rths_live *l) {
    int n = l->history_n < RTHS_LIVE_HISTORY ? l->history_n : RTHS_LIVE_HISTORY;
    int first = l->history_n - n; /* oldest kept evaluation */
    put(l, "  \"residual_history_m\": [");
    for (int i = 0; i < n; i++) {
        if (i) put(l, ", ");
        put_number(l, "%.9g", l->history[(first + i) % RTHS_LIVE_HISTORY]);
    }
    put(l, "],\n");
}

static void put_health(rths_live *l) {
    const rths_live_evaluation *ev = &l->ev;
    put(l, "  \"health\": {\"fault\": \"%s\", \"fault_code\": %d, \"remote\": %s, ",
        rths_rig_fault_name(ev->fault), (int)ev->fault, l->have_link_stats ? "true" : "false");
    if (l->have_link_stats) {
        put(l, "\"link_stats\": true, \"overruns\": %ld, ", l->overruns);
        put_value(l, "\"worst_lateness_s\": ", "%.9g", l->worst_lateness_s, "}\n");
    } else {
        put(l, "\"link_stats\": false, \"overruns\": null, \"worst_lateness_s\": null}\n");
    }
}

static void format_text(rths_live *l) {
    const rths_live_evaluation *ev = &l->ev;
    l->len = 0;
    l->overflow = 0;
    locale_t previous = uselocale(l->c_locale);
    struct timespec now;
    clock_gettime(CLOCK_REALTIME, &now);
    int iteration = l->new_point ? 0 : l->history_n;
    put(l, "{\n  \"format\": 1,\n  \"state\": \"%s\",\n  \"point\": %d,\n",
        l->ended ? "ended" : "running", l->points_accepted);
    put(l, "  \"points_accepted\": %d,\n  \"iteration\": %d,\n  \"evaluations_total\": %d,\n",
        l->points_accepted, iteration, l->evaluations_total);
    put_value(l, "  \"frequency_hz\": ", "%.17g", ev->frequency_hz, ",\n");
    put_value(l, "  \"residual_m\": ", "%.9g", l->residual_m, ",\n");
    put_history(l);
    put(l, "  \"harmonics\": %d,\n  \"target\": {", ev->harmonics);
    put_array(l, "a_m", ev->target_a_m, ev->harmonics, "%.17g");
    put(l, ", ");
    put_array(l, "b_m", ev->target_b_m, ev->harmonics, "%.17g");
    put(l, "},\n");
    put_fourier(l, "physical", &ev->phys);
    put_fourier(l, "numerical", &ev->num);
    put_value(l, "  \"period_s\": ", "%.17g", ev->frequency_hz > 0 ? 1 / ev->frequency_hz : NAN,
              ",\n");
    put(l, "  \"trace\": {\"source\": \"%s\", ",
        l->trace_measured ? "measured" : "reconstructed from the latest period's harmonics");
    put_array(l, "time_s", l->trace_t, l->trace_n_samples, "%.9g");
    put(l, ", ");
    put_array(l, "physical_m", l->trace_p, l->trace_n_samples, "%.9g");
    put(l, ", ");
    put_array(l, "numerical_m", l->trace_n, l->trace_n_samples, "%.9g");
    put(l, "},\n");
    put_value(l, "  \"rig_time_s\": ", "%.9g", ev->rig_time_s, ",\n");
    put(l, "  \"wall_time_s\": %.6f,\n  \"unix_time_s\": %.3f,\n", rths_monotonic_s() - l->opened_s,
        (double)now.tv_sec + 1e-9 * (double)now.tv_nsec);
    put_health(l);
    put(l, "}\n");
    uselocale(previous);
}

/* ---- the file ---- */

/* temp + rename: readers see a whole file. No fsync (a display, see live.h). */
static int write_text(rths_live *l, rths_error *err) {
    l->dirty = 0;
    l->last_write_s = rths_monotonic_s();
    format_text(l);
    if (l->overflow) return rths_error_set(err, RTHS_EFAIL, "live.json: text too long");
    int fd = open(l->tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0)
        return rths_error_set(err, RTHS_EFAIL, "cannot write %s: %s", l->tmp, strerror(errno));
    size_t done = 0;
    while (done < l->len) {
        ssize_t n = write(fd, l->buf + done, l->len - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        done += (size_t)n;
    }
    int e = errno;
    if (close(fd) != 0 || done != l->len || rename(l->tmp, l->path) != 0) {
        unlink(l->tmp);
        return rths_error_set(err, RTHS_EFAIL, "cannot write %s: %s", l->path, strerror(e));
    }
    return RTHS_OK;
}

int rths_live_open(const char *dir, rths_live **out, rths_error *err) {
    *out = NULL;
    rths_live *l = calloc(1, sizeof *l);
    if (!l) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    l->path = rths_path_join(dir, "live.json");
    l->tmp = rths_path_join(dir, "live.json.tmp");
    l->buf = malloc(LIVE_BUFFER_BYTES);
    l->c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
    if (!l->path || !l->tmp || !l->buf || !l->c_locale) {
        rths_live_close(l);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    l->buf[0] = 0;
    l->opened_s = rths_monotonic_s();
    l->min_interval_s = 0.1;
    l->last_write_s = -1e300;
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++)
        for (int i = 0; i < RTHS_LIVE_TRACE_SAMPLES; i++) {
            double phase = 2 * M_PI * k * i / (RTHS_LIVE_TRACE_SAMPLES - 1);
            l->cos_table[k - 1][i] = cos(phase);
            l->sin_table[k - 1][i] = sin(phase);
        }
    *out = l;
    return RTHS_OK;
}

void rths_live_close(rths_live *l) {
    if (!l) return;
    if (l->have_evaluation && l->buf && l->c_locale && !l->ended) {
        l->ended = 1;
        rths_error ignored;
        (void)write_text(l, &ignored);
    }
    if (l->observer) l->observer->live = NULL; /* the rig may outlive live: it then just forwards */
    if (l->c_locale) freelocale(l->c_locale);
    free(l->path);
    free(l->tmp);
    free(l->buf);
    free(l);
}

const char *rths_live_text(const rths_live *l) {
    return l->buf;
}

/* ---- what is shown ---- */

/* |physical - numerical| over the matched harmonics, m: what the corrector drives to zero. */
static double mismatch_m(const rths_live_evaluation *ev) {
    double s = 0;
    for (int k = 1; k <= ev->harmonics && k <= RTHS_MAX_HARMONICS; k++) {
        double da = ev->phys.a[k] - ev->num.a[k], db = ev->phys.b[k] - ev->num.b[k];
        s += da * da + db * db;
    }
    return sqrt(s);
}

static void reconstruct_trace(rths_live *l) {
    const rths_live_evaluation *ev = &l->ev;
    int n = RTHS_LIVE_TRACE_SAMPLES;
    double period = ev->frequency_hz > 0 ? 1 / ev->frequency_hz : 0;
    for (int i = 0; i < n; i++) {
        double t = period * i / (n - 1), p = ev->phys.a[0], q = ev->num.a[0];
        for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
            double c = l->cos_table[k - 1][i], s = l->sin_table[k - 1][i];
            p += ev->phys.a[k] * c + ev->phys.b[k] * s;
            q += ev->num.a[k] * c + ev->num.b[k] * s;
        }
        l->trace_t[i] = t;
        l->trace_p[i] = p;
        l->trace_n[i] = q;
    }
    l->trace_n_samples = n;
    l->trace_measured = 0;
}

static void copy_trace(rths_live *l, const rths_live_evaluation *ev) {
    int n =
        ev->trace_samples < RTHS_LIVE_TRACE_SAMPLES ? ev->trace_samples : RTHS_LIVE_TRACE_SAMPLES;
    /* decimate evenly when more samples than kept are given */
    for (int i = 0; i < n; i++) {
        int j = (int)((long)i * ev->trace_samples / n);
        l->trace_t[i] = ev->trace_time_s[j];
        l->trace_p[i] = ev->trace_phys_m[j];
        l->trace_n[i] = ev->trace_num_m[j];
    }
    l->trace_n_samples = n;
    l->trace_measured = 1;
}

/* At most one file per min_interval_s: the page polls 4 times a second, so faster writes would
 * cost the run without showing anything more (the residual history keeps every evaluation). */
static int write_if_due(rths_live *l, rths_error *err) {
    l->dirty = 1;
    if (rths_monotonic_s() - l->last_write_s < l->min_interval_s) return RTHS_OK;
    return write_text(l, err);
}

void rths_live_set_interval(rths_live *l, double min_interval_s) {
    if (l) l->min_interval_s = min_interval_s > 0 ? min_interval_s : 0;
}

void rths_live_flush(rths_live *l) {
    rths_error ignored;
    if (l && l->dirty && l->have_evaluation) (void)write_text(l, &ignored);
}

int rths_live_evaluation_done(rths_live *l, const rths_live_evaluation *ev, rths_error *err) {
    if (ev->harmonics < 0 || ev->harmonics > RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT, "live: %d harmonics (at most %d)", ev->harmonics,
                              RTHS_MAX_HARMONICS);
    if (l->new_point) {
        l->history_n = 0;
        l->new_point = 0;
    }
    l->ev = *ev;
    l->ev.trace_time_s = l->ev.trace_phys_m = l->ev.trace_num_m = NULL;
    if (ev->trace_samples > 0 && ev->trace_time_s && ev->trace_phys_m && ev->trace_num_m)
        copy_trace(l, ev);
    else
        reconstruct_trace(l);
    l->residual_m = mismatch_m(ev);
    l->history[l->history_n % RTHS_LIVE_HISTORY] = l->residual_m;
    l->history_n++;
    l->evaluations_total++;
    l->have_evaluation = 1;
    return write_if_due(l, err);
}

void rths_live_progress(rths_live *l, int point, double frequency_hz, double residual_m,
                        int accepted) {
    (void)frequency_hz;
    (void)residual_m;
    if (!l) return;
    /* the evaluation that decided this attempt belongs to the point it decided */
    if (l->observer) publish_if_done(l->observer);
    int points_accepted = point + (accepted ? 1 : 0);
    int changed = points_accepted != l->points_accepted;
    l->points_accepted = points_accepted;
    if (accepted) l->new_point = 1;
    rths_error ignored;
    if (changed && l->have_evaluation) (void)write_if_due(l, &ignored);
}

void rths_live_link_stats(rths_live *l, long overruns, double worst_lateness_s) {
    if (!l) return;
    l->have_link_stats = 1;
    l->overruns = overruns;
    l->worst_lateness_s = worst_lateness_s;
}

/* ---- the observing rig ---- */

/* An evaluation ends when the host changes forcing or target after running periods. */
static void publish_if_done(observing_rig *o) {
    if (o->periods == 0 || !o->live) return;
    o->ev.rig_time_s = rths_rig_time_s(o->inner);
    o->ev.fault = rths_rig_get_fault(o->inner);
    rths_error ignored;
    (void)rths_live_evaluation_done(o->live, &o->ev, &ignored);
    o->periods = 0;
}

static int obs_set_forcing(void *self, double frequency_hz, double amplitude_n, rths_error *err) {
    observing_rig *o = self;
    publish_if_done(o);
    o->ev.frequency_hz = frequency_hz;
    return rths_rig_set_forcing(o->inner, frequency_hz, amplitude_n, err);
}

/* The target the live record shows (the first interface DoF's harmonics). */
static void remember_target(observing_rig *o, int harmonics, const double *a, const double *b) {
    o->ev.harmonics = harmonics;
    for (int k = 0; k < harmonics; k++) {
        o->ev.target_a_m[k] = a[k];
        o->ev.target_b_m[k] = b[k];
    }
}

static int obs_set_target(void *self, int harmonics, const double *a, const double *b,
                          rths_error *err) {
    observing_rig *o = self;
    publish_if_done(o);
    int rc = rths_rig_set_target(o->inner, harmonics, a, b, err);
    if (!rc) remember_target(o, harmonics, a, b);
    return rc;
}

/* Several interface DoFs: forwarded; the live record shows the first DoF's target. */
static int obs_set_target_dofs(void *self, int dofs, int harmonics, const double *a,
                               const double *b, rths_error *err) {
    observing_rig *o = self;
    publish_if_done(o);
    int rc = rths_rig_set_target_dofs(o->inner, dofs, harmonics, a, b, err);
    if (!rc) remember_target(o, harmonics, a, b); /* the first DoF's come first */
    return rc;
}

static int obs_interface_dofs(void *self) {
    return rths_rig_interface_dofs(((observing_rig *)self)->inner);
}

static int obs_run_periods(void *self, int count, rths_period *out, rths_error *err) {
    observing_rig *o = self;
    int rc = rths_rig_run_periods(o->inner, count, out, err);
    if (!rc && count > 0) {
        o->ev.phys = out[count - 1].phys;
        o->ev.num = out[count - 1].num;
        o->ev.frequency_hz = out[count - 1].frequency_hz;
        o->periods += count;
    }
    return rc;
}

static int obs_record_trace(void *self, double duration_s, int max_samples, rths_trace_sample *out,
                            int *n_out, rths_error *err) {
    observing_rig *o = self;
    return rths_rig_record_trace(o->inner, duration_s, max_samples, out, n_out, err);
}

static double obs_time_s(void *self) {
    return rths_rig_time_s(((observing_rig *)self)->inner);
}

static rths_rig_fault obs_fault(void *self) {
    return rths_rig_get_fault(((observing_rig *)self)->inner);
}

static int obs_reset_fault(void *self, rths_error *err) {
    return rths_rig_reset_fault(((observing_rig *)self)->inner, err);
}

static double obs_noise_level_m(void *self) {
    return rths_rig_noise_level_m(((observing_rig *)self)->inner);
}

static void obs_destroy(void *self) {
    observing_rig *o = self;
    publish_if_done(o);
    if (o->live) o->live->observer = NULL;
    rths_rig_destroy(o->inner);
    free(o);
}

static const rths_rig_ops observing_ops = {
    .set_forcing = obs_set_forcing,
    .set_target = obs_set_target,
    .run_periods = obs_run_periods,
    .record_trace = obs_record_trace,
    .time_s = obs_time_s,
    .fault = obs_fault,
    .reset_fault = obs_reset_fault,
    .noise_level_m = obs_noise_level_m,
    .destroy = obs_destroy,
    .set_target_dofs = obs_set_target_dofs,
    .interface_dofs = obs_interface_dofs,
};

int rths_live_wrap_rig(rths_live *live, rths_rig *inner, rths_rig **out, rths_error *err) {
    /* *out may alias inner (rig = wrap(rig)): it is only set on success, so a failure leaves the
     * caller's rig as it was */
    observing_rig *o = calloc(1, sizeof *o);
    rths_rig *rig = o ? rths_rig_create(&observing_ops, o, rths_rig_description(inner)) : NULL;
    if (!rig) {
        free(o);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    o->live = live;
    o->inner = inner;
    live->observer = o;
    *out = rig;
    return RTHS_OK;
}
