/* rths_run_frf, the whole FRF test as a library call: a short noise-free sweep of the linear
 * example ends completed with every point reported through on_point and within 0.5 % of the
 * analytic FRF (the tolerance is 1e-4 relative; the transient left by the steady-state test adds
 * ~1e-3 at most); cancelled after three points it saves exactly those three (journal, frf.csv,
 * summary.json saying so) and a resume continues to the end; bad input writes nothing. */
#include "fixture_seed_rig.h"
#include "testlib.h"

#include "rths/rig_virtual.h"
#include "rths/run.h"
#include "rths/truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *const sets[] = {"rig.noise=false", "continuation.start_hz=12.6",
                                   "continuation.end_hz=12.9"};

typedef struct {
    int points, updates, cancel_after;
    int fail_at; /* > 0: the callback stops the run at this point index with status 7 */
    double max_error;
    const rths_setup *setup;
    const char *extra[4]; /* further overrides after sets */
    /* > 0: measure on a caller's rig (rths_run_frf_options.rig) that wraps the virtual rig and
     * reports integrity counts in the periods it delivers (fake_rig below) */
    int fake_rig;
    long fake_first, fake_last; /* periods [first, last) delivered carry the counts */
    int fake_late, fake_clipped, fake_saturated;
    long delivered, late_sent, clipped_sent, saturated_sent;     /* what the fake rig delivered */
    long point_late[64], point_clipped[64], point_saturated[64]; /* as on_point saw them */
} watcher;

static int watch_point(void *user, const rths_point *pt, int is_update) {
    watcher *w = user;
    if (is_update) {
        w->updates++;
        return RTHS_OK;
    }
    assert_int_equal(pt->index, w->points);
    if (w->fail_at > 0 && pt->index == w->fail_at) return 7;
    if (pt->index < 64) {
        w->point_late[pt->index] = pt->residual.eval.late_samples;
        w->point_clipped[pt->index] = pt->residual.eval.clipped_demand_samples;
        w->point_saturated[pt->index] = pt->residual.eval.saturated_sensor_samples;
    }
    w->points++;
    double truth = rths_truth_linear_amplitude_m(w->setup, pt->sol.frequency_hz);
    w->max_error = fmax(w->max_error, fabs(pt->sol.amplitude_m - truth) / truth);
    return RTHS_OK;
}

static int cancel_now(void *user) {
    watcher *w = user;
    return w->cancel_after > 0 && w->points >= w->cancel_after;
}

/* A caller's rig: the virtual rig, whose periods [fake_first, fake_last) report integrity
 * counts as a controller process would (late samples, clipped demand, saturated sensors). */
typedef struct {
    rths_rig *inner;
    watcher *w;
} fake_rig;

static int f_set_forcing(void *self, double f, double a, rths_error *err) {
    return rths_rig_set_forcing(((fake_rig *)self)->inner, f, a, err);
}
static int f_set_target(void *self, int h, const double *a, const double *b, rths_error *err) {
    return rths_rig_set_target(((fake_rig *)self)->inner, h, a, b, err);
}
static int f_run_periods(void *self, int count, rths_period *out, rths_error *err) {
    fake_rig *r = self;
    int rc = rths_rig_run_periods(r->inner, count, out, err);
    for (int i = 0; i < count && !rc; i++, r->w->delivered++)
        if (r->w->delivered >= r->w->fake_first && r->w->delivered < r->w->fake_last) {
            out[i].late_samples = r->w->fake_late;
            out[i].clipped_demand_samples = r->w->fake_clipped;
            out[i].saturated_sensor_samples = r->w->fake_saturated;
            r->w->late_sent += r->w->fake_late;
            r->w->clipped_sent += r->w->fake_clipped;
            r->w->saturated_sent += r->w->fake_saturated;
        }
    return rc;
}
static int f_record_trace(void *self, double d, int m, rths_trace_sample *out, int *n,
                          rths_error *err) {
    return rths_rig_record_trace(((fake_rig *)self)->inner, d, m, out, n, err);
}
static double f_time_s(void *self) {
    return rths_rig_time_s(((fake_rig *)self)->inner);
}
static rths_rig_fault f_fault(void *self) {
    return rths_rig_get_fault(((fake_rig *)self)->inner);
}
static int f_reset_fault(void *self, rths_error *err) {
    return rths_rig_reset_fault(((fake_rig *)self)->inner, err);
}
static double f_noise(void *self) {
    return rths_rig_noise_level_m(((fake_rig *)self)->inner);
}
static void f_destroy(void *self) {
    fake_rig *r = self;
    rths_rig_destroy(r->inner);
    free(r);
}
static const rths_rig_ops fake_ops = {.set_forcing = f_set_forcing,
                                      .set_target = f_set_target,
                                      .run_periods = f_run_periods,
                                      .record_trace = f_record_trace,
                                      .time_s = f_time_s,
                                      .fault = f_fault,
                                      .reset_fault = f_reset_fault,
                                      .noise_level_m = f_noise,
                                      .destroy = f_destroy};

static int run_once(const char *out, int resume, const char *strategy, watcher *w,
                    rths_run_frf_result *r, rths_error *err) {
    rths_config *cfg;
    rths_setup setup;
    const char *all[8];
    int n_sets = 0;
    for (int i = 0; i < 3; i++)
        all[n_sets++] = sets[i];
    for (int i = 0; i < 4 && w->extra[i]; i++)
        all[n_sets++] = w->extra[i];
    rths_fixture_setup("examples/four_storey_linear.yaml", all, n_sets, &cfg, &setup);
    w->setup = &setup;
    rths_run_frf_options opt = {.cfg = cfg,
                                .setup = &setup,
                                .out_dir = out,
                                .strategy = strategy,
                                .resume = resume,
                                .overrides = all,
                                .n_overrides = n_sets};
    if (w->fake_rig) {
        fake_rig *f = calloc(1, sizeof *f);
        assert_non_null(f);
        f->w = w;
        if (rths_virtual_rig_create(cfg, &setup, 0, 0, &f->inner, err)) fail_msg("%s", err->msg);
        opt.rig = rths_rig_create(&fake_ops, f, "fake rig");
        assert_non_null(opt.rig);
    }
    rths_run_callbacks cb = {.on_point = watch_point, .should_cancel = cancel_now, .user = w};
    int rc = rths_run_frf(&opt, &cb, r, err);
    rths_setup_free(&setup);
    rths_config_free(cfg);
    return rc;
}

static int exists(const char *dir, const char *name) {
    char path[1024];
    struct stat st;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return stat(path, &st) == 0;
}

static int csv_rows(const char *dir) {
    char path[1024], line[4096];
    snprintf(path, sizeof path, "%s/frf.csv", dir);
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    int rows = -1; /* header */
    while (fgets(line, sizeof line, f))
        rows++;
    fclose(f);
    return rows;
}

static int file_has(const char *dir, const char *name, const char *text) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    static char buf[1 << 20];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = 0;
    fclose(f);
    return strstr(buf, text) != NULL;
}

static void remove_tree(const char *dir) {
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
}

/* frf.csv's column `name` as numbers (rows rows at most); returns the rows read */
static int csv_column(const char *dir, const char *name, double *values, int rows) {
    char path[1024];
    static char line[1 << 16];
    snprintf(path, sizeof path, "%s/frf.csv", dir);
    FILE *f = fopen(path, "r");
    if (!f || !fgets(line, sizeof line, f)) fail_msg("cannot read %s", path);
    int col = -1, c = 0;
    for (char *tok = strtok(line, ",\n"); tok; tok = strtok(NULL, ",\n"), c++)
        if (!strcmp(tok, name)) col = c;
    if (col < 0) fail_msg("frf.csv has no column %s", name);
    int n = 0;
    while (n < rows && fgets(line, sizeof line, f)) {
        char *p = line;
        for (int k = 0; k < col; k++)
            p = strchr(p, ',') + 1;
        values[n++] = strtod(p, NULL);
    }
    fclose(f);
    return n;
}

/* A JSON integer "key": N after the first occurrence of `after` in summary.json */
static long summary_long(const char *dir, const char *after, const char *key) {
    char path[1024];
    static char buf[1 << 20];
    snprintf(path, sizeof path, "%s/summary.json", dir);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = 0;
    fclose(f);
    const char *p = strstr(buf, after);
    assert_non_null(p);
    char pattern[128];
    snprintf(pattern, sizeof pattern, "\"%s\": ", key);
    p = strstr(p, pattern);
    assert_non_null(p);
    return strtol(p + strlen(pattern), NULL, 10);
}

static void test_completed(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_run_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char out[600];
    snprintf(out, sizeof out, "%s/run", dir);
    watcher w = {0};
    rths_run_frf_result r;
    rths_error err;
    if (run_once(out, 0, NULL, &w, &r, &err)) fail_msg("%s", err.msg);
    assert_int_equal(r.status, RTHS_RUN_COMPLETED);
    assert_true(r.outputs_written);
    assert_int_equal(r.points, w.points);
    assert_int_equal(r.converged_points, r.points);
    assert_true(r.points >= 6); /* 0.3 Hz in steps of at most 0.05 Hz */
    assert_int_equal(csv_rows(out), r.points);
    assert_true(w.max_error < 5e-3);
    assert_true(r.max_relative_error_vs_truth < 5e-3);
    assert_true(exists(out, "summary.json") && exists(out, "truth.csv") &&
                exists(out, "journal.jsonl") && exists(out, "config.yaml"));
    /* the run released the folder: no stale run.lock (issue 24.16) */
    assert_false(exists(out, "run.lock"));
    remove_tree(dir);
}

static void test_cancel_and_resume(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_run_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char out[600];
    snprintf(out, sizeof out, "%s/run", dir);
    watcher w = {.cancel_after = 3};
    rths_run_frf_result r;
    rths_error err;
    assert_int_equal(run_once(out, 0, NULL, &w, &r, &err), RTHS_OK);
    assert_int_equal(r.status, RTHS_RUN_CANCELLED);
    assert_int_equal(r.points, 3);
    assert_int_equal(csv_rows(out), 3);
    /* the user stopped it, and the log says so with the status the command exits with (issue
     * 24.16: it said "cancelled by the caller" and "finished with status 0") */
    assert_true(file_has(out, "summary.json", "stopped by the user after 3 points"));
    assert_true(file_has(out, "run.log", "finished: stopped by the user (exit 130)"));
    assert_false(file_has(out, "run.log", "finished with status 0"));
    assert_false(exists(out, "trace.csv")); /* no rig time spent after a cancel */
    assert_false(exists(out, "run.lock"));

    watcher again = {.points = 3}; /* the new points' indices follow the journal's */
    assert_int_equal(run_once(out, 1, NULL, &again, &r, &err), RTHS_OK);
    assert_int_equal(r.status, RTHS_RUN_COMPLETED);
    assert_int_equal(r.resumed_points, 3);
    assert_true(r.points > 3);
    assert_int_equal(again.points, r.points); /* on_point saw every new point */
    assert_int_equal(csv_rows(out), r.points);
    /* the points measured after the resume are marked (issue 24.10: the resumed rig starts from
     * rest with a fresh noise stream; docs/journal.md, "What a resume restores"), the journal's
     * are not, and summary.json counts them */
    double resumed[64];
    assert_int_equal(csv_column(out, "resumed", resumed, 64), r.points);
    for (int i = 0; i < r.points && i < 64; i++)
        assert_true(resumed[i] == (i >= 3 ? 1.0 : 0.0));
    assert_int_equal(summary_long(out, "\"resumed_points\"", "points_measured_after_resume"),
                     r.points - 3);
    /* the mark survives a further resume (kept in the journal) */
    watcher third = {.points = r.points};
    int before = r.points;
    assert_int_equal(run_once(out, 1, NULL, &third, &r, &err), RTHS_OK);
    assert_int_equal(r.points, before);
    assert_int_equal(summary_long(out, "\"resumed_points\"", "points_measured_after_resume"),
                     before - 3);
    remove_tree(dir);
}

/* An occupied folder without resume, a resume of nothing, an unknown strategy: RTHS_EINPUT and
 * nothing written. */
static void test_bad_input_writes_nothing(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_run_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char out[600];
    snprintf(out, sizeof out, "%s/run", dir);
    watcher w = {0};
    rths_run_frf_result r;
    rths_error err;
    assert_int_equal(run_once(out, 1, NULL, &w, &r, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "no journal.jsonl"));
    assert_int_equal(run_once(out, 0, "fastest", &w, &r, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "fastest"));
    assert_false(exists(dir, "run"));
    assert_false(r.outputs_written);
    mkdir(out, 0755);
    char journal[700];
    snprintf(journal, sizeof journal, "%s/journal.jsonl", out);
    FILE *f = fopen(journal, "w");
    fclose(f);
    assert_int_equal(run_once(out, 0, NULL, &w, &r, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "already holds a run"));
    assert_false(exists(out, "run.log"));
    remove_tree(dir);
}

/* The point handler stopping the run: the stop reason says what failed (here the caller's
 * callback; a failed journal write takes the same path with its errno text), not "stopped by the
 * point handler" (issue 24.16). */
static void test_handler_failure_named(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_run_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char out[600];
    snprintf(out, sizeof out, "%s/run", dir);
    watcher w = {.fail_at = 2};
    rths_run_frf_result r;
    rths_error err = {0};
    assert_int_equal(run_once(out, 0, NULL, &w, &r, &err), 7); /* the callback's status */
    assert_non_null(strstr(err.msg, "the point callback stopped the run (status 7)"));
    assert_int_equal(r.status, RTHS_RUN_FAILED);
    assert_non_null(strstr(r.stop_reason, "the point callback stopped the run (status 7)"));
    assert_true(file_has(out, "summary.json", "the point callback stopped the run (status 7)"));
    assert_false(file_has(out, "summary.json", "stopped by the point handler"));
    assert_false(exists(out, "run.lock"));
    remove_tree(dir);
}

/* A sweep the controller would refuse to force (below controller.min_frequency_hz) is bad input
 * before anything is written (issue 24.16: it failed at run time with status 1). */
static void test_range_below_controller_minimum(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_run_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char out[600];
    snprintf(out, sizeof out, "%s/run", dir);
    watcher w = {.extra = {"continuation.start_hz=0.001"}};
    rths_run_frf_result r;
    rths_error err = {0};
    assert_int_equal(run_once(out, 0, NULL, &w, &r, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "continuation.start_hz"));
    assert_non_null(strstr(err.msg, "controller.min_frequency_hz (0.1 Hz)"));
    watcher high = {.extra = {"controller.sample_rate_hz=100", "continuation.end_hz=30"}};
    assert_int_equal(run_once(out, 0, NULL, &high, &r, &err), RTHS_EINPUT);
    if (!strstr(err.msg, "continuation.end_hz")) fail_msg("%s", err.msg);
    assert_false(exists(dir, "run"));
    remove_tree(dir);
}

/* Integrity counts from the rig (issue 24.1): a rig whose periods 5..14 report 2 late, 1
 * clipped-demand and 3 saturated-sensor samples each; summary.json's totals over the rig's
 * periods equal what it delivered (20, 10, 30 over every period it ran), run.log says so, and
 * frf.csv's new last columns carry each accepted evaluation's counts as the point handler saw
 * them. Before this, nothing anywhere reported them. */
static void test_integrity_reported(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_run_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char out[600];
    snprintf(out, sizeof out, "%s/run", dir);
    watcher w = {.fake_rig = 1,
                 .fake_first = 5,
                 .fake_last = 15,
                 .fake_late = 2,
                 .fake_clipped = 1,
                 .fake_saturated = 3};
    rths_run_frf_result r;
    rths_error err = {0};
    if (run_once(out, 0, NULL, &w, &r, &err)) fail_msg("%s", err.msg);
    assert_int_equal(r.status, RTHS_RUN_COMPLETED);
    assert_int_equal(w.late_sent, 20);
    assert_int_equal(summary_long(out, "\"rig_this_run\"", "periods"), w.delivered);
    assert_int_equal(summary_long(out, "\"rig_this_run\"", "late_samples"), 20);
    assert_int_equal(summary_long(out, "\"rig_this_run\"", "clipped_demand_samples"), 10);
    assert_int_equal(summary_long(out, "\"rig_this_run\"", "saturated_sensor_samples"), 30);
    char line[200];
    snprintf(line, sizeof line, "integrity: the rig ran %ld periods", w.delivered);
    assert_true(file_has(out, "run.log", line));
    assert_true(file_has(out, "run.log", "20 late, 10 with a clipped demand, 30 with a saturated"));
    double late[64], clipped[64], saturated[64], resumed[64];
    assert_int_equal(csv_column(out, "late_samples", late, 64), r.points);
    assert_int_equal(csv_column(out, "clipped_demand_samples", clipped, 64), r.points);
    assert_int_equal(csv_column(out, "saturated_sensor_samples", saturated, 64), r.points);
    assert_int_equal(csv_column(out, "resumed", resumed, 64), r.points);
    long sum_late = 0;
    for (int i = 0; i < r.points && i < 64; i++) {
        assert_true(late[i] == (double)w.point_late[i]);
        assert_true(clipped[i] == (double)w.point_clipped[i]);
        assert_true(saturated[i] == (double)w.point_saturated[i]);
        assert_true(resumed[i] == 0);
        sum_late += w.point_late[i];
    }
    assert_int_equal(summary_long(out, "\"accepted_points\"", "late_samples"), sum_late);
    remove_tree(dir);
}

/* A rig reporting late samples in every period: the run either refuses its evaluations and
 * fails naming the counts, or (a controller.max_overrun_share that allows them) reports them;
 * never silent. */
static void test_integrity_failure_named(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_run_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char out[600];
    snprintf(out, sizeof out, "%s/run", dir);
    watcher w = {.fake_rig = 1, .fake_first = 0, .fake_last = 1L << 40, .fake_late = 5};
    rths_run_frf_result r;
    rths_error err = {0};
    int rc = run_once(out, 0, NULL, &w, &r, &err);
    if (rc) {
        assert_int_equal(rc, RTHS_EFAIL);
        char named[200];
        snprintf(named, sizeof named, "the rig reported %ld late", w.late_sent);
        if (!strstr(err.msg, named)) fail_msg("%s", err.msg);
    } else {
        assert_int_equal(summary_long(out, "\"rig_this_run\"", "late_samples"), w.late_sent);
    }
    assert_true(w.late_sent > 0);
    remove_tree(dir);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_completed),
        cmocka_unit_test(test_cancel_and_resume),
        cmocka_unit_test(test_bad_input_writes_nothing),
        cmocka_unit_test(test_handler_failure_named),
        cmocka_unit_test(test_range_below_controller_minimum),
        cmocka_unit_test(test_integrity_reported),
        cmocka_unit_test(test_integrity_failure_named),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
