/* live.json (report/live.c): what a watched run writes after every evaluation. The numbers are
 * checked against closed forms: the residual is |phys - num| over the matched harmonics, the trace
 * is the Fourier series of the given coefficients, the observing rig forwards every call and
 * publishes the last period of each evaluation. */
#include "rths/continuation.h"
#include "rths/live.h"
#include "rths/rig_virtual.h"
#include "testlib.h"

#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct {
    char dir[64];
    char path[128];
} scratch;

static int setup(void **state) {
    scratch *s = calloc(1, sizeof *s);
    snprintf(s->dir, sizeof s->dir, "/tmp/rths-test-live-XXXXXX");
    if (!mkdtemp(s->dir)) return -1;
    snprintf(s->path, sizeof s->path, "%s/live.json", s->dir);
    *state = s;
    return 0;
}

static int teardown(void **state) {
    scratch *s = *state;
    char tmp[160];
    remove(s->path);
    snprintf(tmp, sizeof tmp, "%s.tmp", s->path);
    remove(tmp);
    rmdir(s->dir);
    free(s);
    return 0;
}

static json_object *read_live(const scratch *s) {
    json_object *o = json_object_from_file(s->path);
    assert_non_null(o);
    return o;
}

static double num(json_object *o, const char *key) {
    json_object *v;
    assert_true(json_object_object_get_ex(o, key, &v));
    return json_object_get_double(v);
}

static json_object *get(json_object *o, const char *key) {
    json_object *v = NULL;
    assert_true(json_object_object_get_ex(o, key, &v));
    return v;
}

/* phys: 3 + 2 cos + 1 sin + 0.5 cos 2wt; num differs by (0.3, -0.4) in harmonic 1 and 7 in
 * harmonic 2 (not matched when harmonics = 1). */
static rths_live_evaluation example(void) {
    rths_live_evaluation ev = {.frequency_hz = 10, .harmonics = 1, .rig_time_s = 42.5};
    ev.target_a_m[0] = 1e-5;
    ev.target_b_m[0] = -2e-5;
    ev.phys.a[0] = 3;
    ev.phys.a[1] = 2;
    ev.phys.b[1] = 1;
    ev.phys.a[2] = 0.5;
    ev.num = ev.phys;
    ev.num.a[1] += 0.3;
    ev.num.b[1] -= 0.4;
    ev.num.a[2] += 7;
    return ev;
}

static void residual_and_trace(void **state) {
    scratch *s = *state;
    rths_live *live;
    rths_error err;
    assert_int_equal(rths_live_open(s->dir, &live, &err), RTHS_OK);
    rths_live_set_interval(live, 0);
    rths_live_evaluation ev = example();
    assert_int_equal(rths_live_evaluation_done(live, &ev, &err), RTHS_OK);
    json_object *o = read_live(s);
    /* |(0.3, -0.4)| = 0.5 exactly; harmonic 2 is not matched, so it does not count */
    assert_close(num(o, "residual_m"), 0.5, 1e-9);
    assert_close(num(o, "frequency_hz"), 10, 0);
    assert_close(num(o, "rig_time_s"), 42.5, 1e-9);
    assert_int_equal((int)num(o, "iteration"), 1);
    assert_string_equal(json_object_get_string(get(o, "state")), "running");
    json_object *trace = get(o, "trace");
    json_object *t = get(trace, "time_s"), *p = get(trace, "physical_m"),
                *q = get(trace, "numerical_m");
    int n = (int)json_object_array_length(t);
    assert_int_equal(n, RTHS_LIVE_TRACE_SAMPLES);
    /* the series at t = 0: a0 + sum a_k; at the end of the period (t = 0.1 s) the same */
    assert_close(json_object_get_double(json_object_array_get_idx(p, 0)), 3 + 2 + 0.5, 1e-8);
    assert_close(json_object_get_double(json_object_array_get_idx(t, n - 1)), 0.1, 1e-9);
    assert_close(json_object_get_double(json_object_array_get_idx(p, n - 1)), 5.5, 1e-7);
    /* at i = 21 of 63 the phase is 2 pi / 3: cos = -1/2, sin = sqrt(3)/2, cos 2x = -1/2 */
    double c = -0.5, sn = sqrt(3) / 2;
    assert_close(json_object_get_double(json_object_array_get_idx(p, 21)),
                 3 + 2 * c + 1 * sn + 0.5 * c, 1e-7);
    assert_close(json_object_get_double(json_object_array_get_idx(q, 21)),
                 3 + 2.3 * c + 0.6 * sn + 7.5 * c, 1e-7);
    json_object *phys = get(o, "physical");
    assert_close(json_object_get_double(json_object_array_get_idx(get(phys, "a_m"), 2)), 0.5, 0);
    json_object *target = get(o, "target");
    assert_close(json_object_get_double(json_object_array_get_idx(get(target, "b_m"), 0)), -2e-5,
                 0);
    json_object_put(o);
    /* no temporary left behind: the file was renamed into place */
    char tmp[160];
    snprintf(tmp, sizeof tmp, "%s.tmp", s->path);
    assert_int_not_equal(access(tmp, F_OK), 0);
    rths_live_close(live);
    o = read_live(s);
    assert_string_equal(json_object_get_string(get(o, "state")), "ended");
    json_object_put(o);
}

static void history_per_point(void **state) {
    scratch *s = *state;
    rths_live *live;
    rths_error err;
    assert_int_equal(rths_live_open(s->dir, &live, &err), RTHS_OK);
    rths_live_set_interval(live, 0);
    rths_live_evaluation ev = example();
    for (int i = 0; i < 3; i++) {
        ev.num.b[1] = ev.phys.b[1] - 0.4 / (i + 1); /* residual sqrt(0.09 + 0.16/(i+1)^2) */
        assert_int_equal(rths_live_evaluation_done(live, &ev, &err), RTHS_OK);
    }
    json_object *o = read_live(s);
    json_object *h = get(o, "residual_history_m");
    assert_int_equal((int)json_object_array_length(h), 3);
    for (int i = 0; i < 3; i++)
        assert_close(json_object_get_double(json_object_array_get_idx(h, i)),
                     hypot(0.3, 0.4 / (i + 1)), 1e-8);
    json_object_put(o);
    /* the point is accepted: the next evaluation starts the next point's history */
    rths_live_progress(live, 0, 10, 0.1, 1); /* point 0 accepted */
    assert_int_equal(rths_live_evaluation_done(live, &ev, &err), RTHS_OK);
    o = read_live(s);
    assert_int_equal((int)num(o, "point"), 1);
    assert_int_equal((int)num(o, "evaluations_total"), 4);
    assert_int_equal((int)json_object_array_length(get(o, "residual_history_m")), 1);
    json_object_put(o);
    /* a long point keeps the last RTHS_LIVE_HISTORY evaluations, latest last */
    for (int i = 0; i < RTHS_LIVE_HISTORY + 6; i++) {
        ev.num.a[1] = ev.phys.a[1] + 0.001 * i;
        ev.num.b[1] = ev.phys.b[1];
        assert_int_equal(rths_live_evaluation_done(live, &ev, &err), RTHS_OK);
    }
    o = read_live(s);
    h = get(o, "residual_history_m");
    assert_int_equal((int)json_object_array_length(h), RTHS_LIVE_HISTORY);
    assert_close(json_object_get_double(json_object_array_get_idx(h, RTHS_LIVE_HISTORY - 1)),
                 0.001 * (RTHS_LIVE_HISTORY + 5), 1e-9);
    json_object_put(o);
    rths_live_close(live);
}

static void nan_is_null_and_interval_holds_back(void **state) {
    scratch *s = *state;
    rths_live *live;
    rths_error err;
    assert_int_equal(rths_live_open(s->dir, &live, &err), RTHS_OK);
    rths_live_set_interval(live, 3600); /* only the first write goes out */
    rths_live_evaluation ev = example();
    ev.rig_time_s = NAN;
    assert_int_equal(rths_live_evaluation_done(live, &ev, &err), RTHS_OK);
    json_object *o = read_live(s);
    assert_true(json_object_is_type(get(o, "rig_time_s"), json_type_null));
    json_object_put(o);
    ev.rig_time_s = 7;
    assert_int_equal(rths_live_evaluation_done(live, &ev, &err), RTHS_OK);
    o = read_live(s);
    assert_true(json_object_is_type(get(o, "rig_time_s"), json_type_null)); /* held back */
    json_object_put(o);
    rths_live_flush(live);
    o = read_live(s);
    assert_close(num(o, "rig_time_s"), 7, 0);
    assert_int_equal((int)num(o, "evaluations_total"), 2);
    json_object_put(o);
    ev.harmonics = RTHS_MAX_HARMONICS + 1;
    assert_int_equal(rths_live_evaluation_done(live, &ev, &err), RTHS_EINPUT);
    rths_live_close(live);
}

/* ---- the observing rig over a scripted rig ---- */

typedef struct {
    int set_forcing, set_target, runs, destroyed;
    double frequency_hz, time_s;
    int harmonics;
} fake;

static int fake_set_forcing(void *self, double f, double a, rths_error *err) {
    (void)a;
    (void)err;
    fake *k = self;
    k->set_forcing++;
    k->frequency_hz = f;
    return RTHS_OK;
}

static int fake_set_target(void *self, int harmonics, const double *a, const double *b,
                           rths_error *err) {
    (void)a;
    (void)b;
    (void)err;
    fake *k = self;
    k->set_target++;
    k->harmonics = harmonics;
    return RTHS_OK;
}

/* period p of the run: phys a1 = 1, num a1 = 1 + 1/(p+1), so the last period's mismatch is known */
static int fake_run(void *self, int count, rths_period *out, rths_error *err) {
    (void)err;
    fake *k = self;
    for (int i = 0; i < count; i++) {
        memset(&out[i], 0, sizeof out[i]);
        out[i].frequency_hz = k->frequency_hz;
        out[i].phys.a[1] = 1;
        out[i].num.a[1] = 1 + 1.0 / (k->runs + 1);
        k->runs++;
        k->time_s += 1 / k->frequency_hz;
    }
    return RTHS_OK;
}

static double fake_time(void *self) {
    return ((fake *)self)->time_s;
}

static void fake_destroy(void *self) {
    ((fake *)self)->destroyed++;
}

static const rths_rig_ops fake_ops = {.set_forcing = fake_set_forcing,
                                      .set_target = fake_set_target,
                                      .run_periods = fake_run,
                                      .time_s = fake_time,
                                      .destroy = fake_destroy};

static void observing_rig(void **state) {
    scratch *s = *state;
    fake k = {0};
    rths_live *live;
    rths_rig *rig;
    rths_error err;
    assert_int_equal(rths_live_open(s->dir, &live, &err), RTHS_OK);
    rths_live_set_interval(live, 0);
    assert_int_equal(rths_live_wrap_rig(live, rths_rig_create(&fake_ops, &k, "fake"), &rig, &err),
                     RTHS_OK);
    double a = 1e-3, b = 2e-3;
    rths_period p[4];
    /* evaluation 1: 4 periods at 5 Hz */
    assert_int_equal(rths_rig_set_forcing(rig, 5, 1, &err), RTHS_OK);
    assert_int_equal(rths_rig_set_target(rig, 1, &a, &b, &err), RTHS_OK);
    assert_int_equal(rths_rig_run_periods(rig, 4, p, &err), RTHS_OK);
    assert_int_equal(access(s->path, F_OK), -1); /* not published while it runs */
    /* evaluation 2 begins: evaluation 1 is published with its last period (run 3: 1/4) */
    assert_int_equal(rths_rig_set_forcing(rig, 5, 1, &err), RTHS_OK);
    json_object *o = read_live(s);
    assert_close(num(o, "residual_m"), 0.25, 1e-9);
    assert_close(num(o, "rig_time_s"), 0.8, 1e-9);
    assert_close(num(o, "frequency_hz"), 5, 0);
    json_object_put(o);
    assert_int_equal(rths_rig_set_target(rig, 1, &a, &b, &err), RTHS_OK);
    assert_int_equal(rths_rig_run_periods(rig, 1, p, &err), RTHS_OK);
    /* the corrector accepts: progress publishes the deciding evaluation (run 4: 1/5) first */
    rths_live_progress(live, 0, 5, 0.2, 1);
    o = read_live(s);
    assert_close(num(o, "residual_m"), 0.2, 1e-9);
    assert_int_equal((int)json_object_array_length(get(o, "residual_history_m")), 2);
    assert_int_equal((int)num(o, "points_accepted"), 1);
    json_object_put(o);
    /* every call reached the rig once */
    assert_int_equal(k.set_forcing, 2);
    assert_int_equal(k.set_target, 2);
    assert_int_equal(k.runs, 5);
    assert_close(rths_rig_time_s(rig), 1.0, 1e-12);
    rths_rig_destroy(rig);
    assert_int_equal(k.destroyed, 1);
    rths_live_close(live);
}

/* ---- a real continuation run on the virtual rig, watched ---- */

typedef struct {
    rths_live *live;
    rths_point last;
} watched;

static int keep_point(void *user, const rths_point *pt, int is_update) {
    (void)is_update;
    ((watched *)user)->last = *pt;
    return 0;
}

static void progress(void *user, int points, double f, double r, int evaluations, int accepted) {
    (void)evaluations;
    rths_live_progress(((watched *)user)->live, points, f, r, accepted);
}

/* Every evaluation of the run is published (interval 0): live.json ends with the run's own counts
 * and the last point's frequency, and the run's results are those of an unwatched run. */
static void real_run(void **state) {
    scratch *s = *state;
    const char *ov[] = {"continuation.start_hz=12.9", "continuation.end_hz=13.05"};
    rths_config *cfg;
    rths_setup setup;
    rths_error err;
    assert_int_equal(rths_config_load(rths_test_source_path("examples/four_storey_linear.yaml"), ov,
                                      2, &cfg, &err),
                     RTHS_OK);
    assert_int_equal(rths_setup_read(cfg, &setup, &err), RTHS_OK);
    rths_settle_options so;
    rths_newton_options no;
    rths_continuation_options co;
    int harmonics = 1;
    rths_settle_defaults(&so, 0);
    rths_newton_defaults(&no, 0);
    rths_continuation_defaults(&co);
    co.model_predictor = 1;
    assert_int_equal(rths_iterate_config_read(cfg, &so, &no, &harmonics, &err), RTHS_OK);
    assert_int_equal(rths_continuation_config_read(cfg, &co, &err), RTHS_OK);
    rths_continuation_result res[2];
    watched w[2];
    for (int watch = 0; watch < 2; watch++) {
        rths_rig *rig;
        memset(&w[watch], 0, sizeof w[watch]);
        assert_int_equal(rths_virtual_rig_create(cfg, &setup, 0, 0, &rig, &err), RTHS_OK);
        if (watch) {
            assert_int_equal(rths_live_open(s->dir, &w[watch].live, &err), RTHS_OK);
            rths_live_set_interval(w[watch].live, 0);
            assert_int_equal(rths_live_wrap_rig(w[watch].live, rig, &rig, &err), RTHS_OK);
        }
        assert_int_equal(rths_continuation_run(
                             rig, &co, &so, &no, harmonics, setup.forcing_amplitude_n, NULL, 0,
                             keep_point, watch ? progress : NULL, &w[watch], &res[watch], &err),
                         RTHS_OK);
        rths_live_close(w[watch].live);
        rths_rig_destroy(rig);
    }
    /* the observing rig changes nothing: same evaluations, same last point, bit for bit */
    assert_int_equal(res[1].evaluations, res[0].evaluations);
    assert_int_equal(res[1].points, res[0].points);
    assert_true(w[1].last.sol.amplitude_m == w[0].last.sol.amplitude_m);
    json_object *o = read_live(s);
    assert_string_equal(json_object_get_string(get(o, "state")), "ended");
    assert_int_equal((int)num(o, "evaluations_total"), res[1].evaluations);
    assert_int_equal((int)num(o, "points_accepted"), res[1].points);
    assert_true(num(o, "frequency_hz") == w[1].last.sol.eval.frequency_hz);
    assert_true(num(o, "rig_time_s") > 0);
    json_object_put(o);
    rths_setup_free(&setup);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(residual_and_trace, setup, teardown),
        cmocka_unit_test_setup_teardown(history_per_point, setup, teardown),
        cmocka_unit_test_setup_teardown(nan_is_null_and_interval_holds_back, setup, teardown),
        cmocka_unit_test_setup_teardown(observing_rig, setup, teardown),
        cmocka_unit_test_setup_teardown(real_run, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
