/* The quadratic pseudo-arclength predictor (rths_newton_options.quadratic_predictor,
 * docs/method.md, "The fitted evaluation"): on a noise-free hardening Duffing oscillator with two
 * folds, the same run with the secant and with the quadratic predictor, both against the closed
 * form of the solution set. */
#include "testlib.h"

#include "rths/config.h"
#include "rths/continuation.h"
#include "rths/iterate.h"
#include "rths/rig.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* m y'' + c y' + k y + k3 y^3 = F cos(w t), one harmonic: (k + 3/4 k3 |y|^2 - m w^2 + i c w0) y =
 * F, the damping force scaled by the natural frequency (as in test_multi_interface.c) so the
 * solution set has a closed form. The residual is a displacement (divided by c w0). */
static const double d_m = 1.0, d_k = 3947.8417604357433, d_k3 = 3.3e6, d_cw0 = 78.956835, d_F = 1.0;

static double complex d_dyn(double w, double a) {
    return d_k + 0.75 * d_k3 * a * a - d_m * w * w + I * d_cw0;
}

static int d_eval(void *ctx, const double *u, double w, rths_residual *out, rths_error *err) {
    int *count = ctx;
    (void)err;
    (*count)++;
    double complex y = u[0] - I * u[1];
    double complex r = (d_dyn(w, cabs(y)) * y - d_F) / d_cw0;
    memset(out, 0, sizeof *out);
    out->n = 2;
    const double phi[2] = {creal(r), -cimag(r)};
    for (int i = 0; i < 2; i++) {
        out->phi[i] = phi[i];
        out->response[i] = u[i];
        out->reference[i] = u[i] - phi[i];
    }
    out->rig_time_s = 1.0;
    return RTHS_OK;
}

static rths_rig_fault d_fault(void *self) {
    (void)self;
    return RTHS_RIG_OK;
}

typedef struct {
    rths_point *pts;
    int n, cap;
} point_list;

static int keep_point(void *user, const rths_point *pt, int is_update) {
    (void)is_update;
    point_list *l = user;
    assert_true(pt->index < l->cap);
    l->pts[pt->index] = *pt;
    if (pt->index >= l->n) l->n = pt->index + 1;
    return RTHS_OK;
}

typedef struct {
    int points, evaluations, folds;
    double worst; /* largest relative deviation from |D(w, a)| a = F */
} sweep;

static sweep run_sweep(int quadratic) {
    static const rths_rig_ops ops = {.fault = d_fault};
    rths_rig *rig = rths_rig_create(&ops, NULL, "Duffing");
    int count = 0;
    rths_zero_problem problem = {.n = 2, .harmonics = 1, .eval = d_eval, .ctx = &count};
    rths_newton_options nw;
    rths_continuation_options co;
    rths_newton_defaults(&nw, 0);
    nw.quadratic_predictor = quadratic;
    rths_continuation_defaults(&co);
    co.method = RTHS_CONT_ARCLENGTH;
    co.start_hz = 8.0;
    co.end_hz = 13.0;
    co.max_step = 0.04;
    co.amplitude_scale_m = 0.01;
    enum { MAXP = 2000 };
    point_list l = {.pts = calloc(MAXP, sizeof(rths_point)), .cap = MAXP};
    rths_continuation_result res;
    rths_error err;
    if (rths_continuation_run_problem(&problem, rig, &co, &nw, 1, NULL, 0, keep_point, NULL, &l,
                                      &res, &err))
        fail_msg("%s", err.msg);
    assert_true(res.reached_end);
    sweep s = {.points = l.n, .evaluations = count, .folds = res.n_folds};
    for (int i = 0; i < l.n; i++) {
        const rths_solution *p = &l.pts[i].sol;
        double a = hypot(p->target_a[0], p->target_b[0]);
        s.worst = fmax(s.worst, fabs(cabs(d_dyn(p->omega_rad_s, a)) * a / d_F - 1));
    }
    free(l.pts);
    rths_rig_destroy(rig);
    return s;
}

/* Both predictors trace the branch through its two folds onto the solution set (within 0.5 %:
 * the corrector's relative tolerance 1e-3 on the mismatch, amplified at the peak); the quadratic
 * one, whose error is third order in the step where the secant's is second, needs fewer
 * evaluations over the same branch (measured: see the printed counts). */
static void test_quadratic_fewer_evaluations(void **state) {
    (void)state;
    sweep secant = run_sweep(0), quadratic = run_sweep(1);
    print_message("secant: %d points, %d evaluations (%.2f per point), worst %.4f %%\n",
                  secant.points, secant.evaluations, (double)secant.evaluations / secant.points,
                  100 * secant.worst);
    print_message("quadratic: %d points, %d evaluations (%.2f per point), worst %.4f %%\n",
                  quadratic.points, quadratic.evaluations,
                  (double)quadratic.evaluations / quadratic.points, 100 * quadratic.worst);
    assert_int_equal(secant.folds, 2);
    assert_int_equal(quadratic.folds, 2);
    assert_true(secant.worst < 0.005);
    assert_true(quadratic.worst < 0.005);
    assert_true((double)quadratic.evaluations / quadratic.points <
                0.9 * (double)secant.evaluations / secant.points);
}

/* iteration.quadratic_predictor: off by default with either strategy, on when set. */
static void test_quadratic_predictor_config(void **state) {
    (void)state;
    static const char *const cases[][2] = {
        {"iteration.settle.strategy=wait", NULL},
        {"iteration.settle.strategy=fit", NULL},
        {"iteration.settle.strategy=fit", "iteration.quadratic_predictor=true"},
        {"iteration.settle.strategy=wait", "iteration.quadratic_predictor=true"}};
    const int want[] = {0, 0, 1, 1};
    for (int c = 0; c < 4; c++) {
        rths_config *cfg = NULL;
        rths_error err;
        if (rths_config_load(NULL, cases[c], cases[c][1] ? 2 : 1, &cfg, &err))
            fail_msg("%s", err.msg);
        rths_settle_options st;
        rths_newton_options nw;
        rths_settle_defaults(&st, 0);
        rths_newton_defaults(&nw, 0);
        int harmonics = 1;
        if (rths_iterate_config_read(cfg, &st, &nw, &harmonics, &err)) fail_msg("%s", err.msg);
        assert_int_equal(nw.quadratic_predictor, want[c]);
        rths_config_free(cfg);
    }
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_quadratic_fewer_evaluations),
        cmocka_unit_test(test_quadratic_predictor_config),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
