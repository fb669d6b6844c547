/* The truth of a nonlinear run (rths_truth_compute: shooting, RK4 with 1024 steps per period,
 * pseudo-arclength through the folds) against harmonic balance (rths_hb_solve), an independent
 * method, on examples/two_interface_duffing.yaml (a Duffing spring on the numerical side of the
 * two-interface building, through both folds): at every point of the curve, harmonic balance with
 * 15 harmonics started from the shooting point's harmonics converges to the same interface
 * amplitude within 1e-5 (measured 2.1e-6), and 30 harmonics move it by less than 1e-9 (the
 * truncation). So a hybrid run within 0.5 % of truth.csv is within 0.5 % of the harmonic-balance
 * truth (tests/cli/frf_duffing_two_interface.sh). */
#include "testlib.h"

#include "rths/harmonic_balance.h"
#include "rths/setup.h"
#include "rths/truth.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* interface DoF iface's fundamental amplitude of an HB solution with H harmonics */
static double hb_amplitude(const double *coef, int n, int iface) {
    return hypot(coef[iface + n], coef[iface + 2 * n]);
}

static void test_shooting_truth_is_harmonic_balance(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (rths_config_load(rths_test_source_path("examples/two_interface_duffing.yaml"), NULL, 0,
                         &cfg, &err) ||
        rths_setup_read(cfg, &s, &err))
        fail_msg("%s", err.msg);
    const int n = s.assembly.n, iface = s.split.int_dofs[0];
    rths_shooting_options opt = {.start_hz = 13.5,
                                 .end_hz = 13.65,
                                 .steps_per_period = 1024,
                                 .max_step = 0.02,
                                 .max_points = 4000};
    rths_periodic_point *pp = NULL;
    int count = 0;
    if (rths_nonlinear_frf(&s.assembly, s.n_nonlinear, s.nonlinear, s.static_force, s.force, &opt,
                           &pp, &count, &err))
        fail_msg("%s", err.msg);
    rths_truth_curve t;
    if (rths_truth_compute(&s, 13.5, 13.65, &t, &err)) fail_msg("%s", err.msg);
    assert_int_equal(t.n, count);
    rths_hb_options h15, h30;
    rths_hb_defaults(&h15);
    h30 = h15;
    h30.harmonics = 30;
    h30.samples = 512;
    const int nb15 = 2 * h15.harmonics + 1, nb30 = 2 * h30.harmonics + 1;
    double *c15 = calloc((size_t)n * nb15, sizeof(double));
    double *c30 = calloc((size_t)n * nb30, sizeof(double));
    assert_non_null(c15);
    assert_non_null(c30);
    int folds = 0, unstable = 0;
    double worst = 0, worst_trunc = 0;
    for (int j = 0; j < count; j++) {
        /* the truth.csv amplitude is this shooting point's */
        double shoot = hypot(pp[j].cos_m[iface + n], pp[j].sin_m[iface + n]);
        assert_close(t.amp_m[j], shoot, 1e-15 * shoot);
        /* and truth.csv's per-DoF columns the shooting point's interface DoFs' */
        assert_int_equal(t.dofs, 2);
        for (int d = 0; d < 2; d++) {
            int dof = s.split.int_dofs[d];
            double a = hypot(pp[j].cos_m[dof + n], pp[j].sin_m[dof + n]);
            assert_close(t.amp_dof_m[d * t.n + j], a, 1e-15 * a);
        }
        if (j >= 2) {
            double f0 = pp[j - 2].omega_rad_s, f1 = pp[j - 1].omega_rad_s, f2 = pp[j].omega_rad_s;
            folds += (f1 - f0) * (f2 - f1) < 0;
        }
        unstable += !pp[j].stable;
        /* harmonic balance from the shooting point's harmonics 0..3 */
        memset(c15, 0, sizeof(double) * (size_t)n * nb15);
        for (int i = 0; i < n; i++) {
            c15[i] = pp[j].cos_m[i];
            for (int k = 1; k <= RTHS_PERIODIC_HARMONICS; k++) {
                c15[i + n * (2 * k - 1)] = pp[j].cos_m[i + k * n];
                c15[i + n * (2 * k)] = pp[j].sin_m[i + k * n];
            }
        }
        memset(c30, 0, sizeof(double) * (size_t)n * nb30);
        memcpy(c30, c15, sizeof(double) * (size_t)n * nb15);
        int it;
        if (rths_hb_solve(&s.assembly, s.n_nonlinear, s.nonlinear, s.static_force, s.force,
                          pp[j].omega_rad_s, &h15, c15, &it, &err) ||
            rths_hb_solve(&s.assembly, s.n_nonlinear, s.nonlinear, s.static_force, s.force,
                          pp[j].omega_rad_s, &h30, c30, &it, &err))
            fail_msg("point %d (%.6f Hz): %s", j, pp[j].omega_rad_s / (2 * M_PI), err.msg);
        double a15 = hb_amplitude(c15, n, iface), a30 = hb_amplitude(c30, n, iface);
        worst = fmax(worst, fabs(a15 - shoot) / a15);
        worst_trunc = fmax(worst_trunc, fabs(a30 - a15) / a30);
    }
    print_message("%d points, %d folds, %d unstable: shooting vs harmonic balance %.2e, 15 vs 30 "
                  "harmonics %.2e\n",
                  count, folds, unstable, worst, worst_trunc);
    assert_int_equal(folds, 2); /* the curve passes both folds */
    assert_true(unstable > 0);
    assert_true(worst < 1e-5); /* measured 2.1e-6: the shooting's own tolerance, 500x below 0.5 % */
    assert_true(worst_trunc < 1e-9);
    free(c15);
    free(c30);
    rths_truth_free(&t);
    rths_periodic_points_free(pp, count);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_shooting_truth_is_harmonic_balance),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
