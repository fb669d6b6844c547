/* The true assembly's periodic response by shooting: reduces to the analytic FRF when the leg is
 * linear; with the seed's bilinear leg and preload, the static point sits on the stiff side, and a
 * few newtons of forcing near the second mode give a fold pair with an unstable middle branch. */
#include "testlib.h"

#include "rths/model.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>

static const double seed_m[4] = {5.37, 5.37, 5.37, 10.74};
static const double seed_c[4] = {4.4062, 3.7979, 3.7421, 3.7421};
static const double seed_k[4] = {53048, 45724, 45052, 45052};

static void test_linear_leg_matches_analytic_frf(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, &a, &err), RTHS_OK);
    rths_bilinear_leg leg = {.lower_dof = 1, .upper_dof = 2, .stiffness_n_per_m = seed_k[2], .ratio = 1.0};
    double fs[4] = {0, 0, -5.0, 0}, f[4] = {0, 0, 0, 1.0};
    rths_shooting_options opt = {.start_hz = 12.0, .end_hz = 14.0, .steps_per_period = 2048,
                                 .max_step = 0.05, .max_points = 400};
    rths_periodic_point *pts;
    int n;
    assert_int_equal(rths_bilinear_frf(&a, &leg, fs, f, &opt, &pts, &n, &err), RTHS_OK);
    assert_true(n > 10);
    assert_close(pts[n - 1].omega_rad_s / (2 * M_PI), 14.0, 0.2);
    for (int p = 0; p < n; p++) {
        double complex X[4];
        assert_int_equal(rths_frf(4, a.mass, a.damping, a.stiffness, f, pts[p].omega_rad_s, X, &err), RTHS_OK);
        for (int i = 0; i < 4; i++) {
            /* RK4 with 2048 steps per period: (w_max h)^4 ~ 1e-9; 1e-6 relative is a safe bound */
            assert_close(pts[p].cos_m[i + 4], creal(X[i]), 1e-6 * cabs(X[i]));
            assert_close(pts[p].sin_m[i + 4], -cimag(X[i]), 1e-6 * cabs(X[i]));
        }
        /* static term = K^{-1} fs: storey 3's leg carries the 5 N */
        assert_close(pts[p].cos_m[2] - pts[p].cos_m[1], -5.0 / seed_k[2], 1e-9);
        assert_true(pts[p].stable);
    }
    rths_periodic_points_free(pts, n);
    rths_assembly_free(&a);
}

static void test_bilinear_static_point(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, &a, &err), RTHS_OK);
    rths_bilinear_leg leg = {.lower_dof = 1, .upper_dof = 2, .stiffness_n_per_m = seed_k[2], .ratio = 2.0};
    double fs[4] = {0, 0, -26.68, 0}, q[4];
    assert_int_equal(rths_bilinear_static(&a, &leg, fs, q, &err), RTHS_OK);
    /* the leg below storey 3 carries the whole preload on its stiff (compression) side */
    assert_close(q[2] - q[1], -26.68 / (2 * seed_k[2]), 1e-12);
    assert_close(q[0], -26.68 / seed_k[0], 1e-12);
    double fs2[4] = {0, 0, 26.68, 0};
    assert_int_equal(rths_bilinear_static(&a, &leg, fs2, q, &err), RTHS_OK);
    assert_close(q[2] - q[1], 26.68 / seed_k[2], 1e-12);
    rths_assembly_free(&a);
}

static void test_bilinear_folds(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, &a, &err), RTHS_OK);
    rths_bilinear_leg leg = {.lower_dof = 1, .upper_dof = 2, .stiffness_n_per_m = seed_k[2], .ratio = 2.0};
    double amp = getenv("RTHS_TEST_FORCE") ? atof(getenv("RTHS_TEST_FORCE")) : 3.0;
    double lo = getenv("RTHS_TEST_LO") ? atof(getenv("RTHS_TEST_LO")) : 13.0;
    double hi = getenv("RTHS_TEST_HI") ? atof(getenv("RTHS_TEST_HI")) : 16.0;
    double fs[4] = {0, 0, -26.68, 0}, f[4] = {0, 0, 0, amp};
    rths_shooting_options opt = {.start_hz = lo, .end_hz = hi, .steps_per_period = 1024,
                                 .max_step = 0.02, .max_points = 2000};
    rths_periodic_point *pts;
    int n;
    assert_int_equal(rths_bilinear_frf(&a, &leg, fs, f, &opt, &pts, &n, &err), RTHS_OK);
    int folds = 0, unstable = 0;
    for (int p = 1; p + 1 < n; p++) {
        double d0 = pts[p].omega_rad_s - pts[p - 1].omega_rad_s;
        double d1 = pts[p + 1].omega_rad_s - pts[p].omega_rad_s;
        if (d0 * d1 < 0) folds++;
        if (!pts[p].stable) unstable++;
        if (getenv("RTHS_TEST_VERBOSE"))
            print_message("%g %g %g %d\n", pts[p].omega_rad_s / (2 * M_PI),
                          hypot(pts[p].cos_m[2 + 4], pts[p].sin_m[2 + 4]), pts[p].max_floquet,
                          pts[p].stable);
    }
    assert_int_equal(folds, 2);
    assert_true(unstable > 0);
    rths_periodic_points_free(pts, n);
    rths_assembly_free(&a);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_linear_leg_matches_analytic_frf),
        cmocka_unit_test(test_bilinear_static_point),
        cmocka_unit_test(test_bilinear_folds),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
