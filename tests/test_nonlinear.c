/* The true assembly's periodic response by shooting: reduces to the analytic FRF when the leg is
 * linear; with the seed's bilinear leg and preload, the static point sits on the stiff side, and a
 * few newtons of forcing near the second mode give a fold pair with an unstable middle branch. */
#include "testlib.h"

#include "rths/model.h"
#include "rths/harmonic_balance.h"
#include "rths/nonlinear.h"

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
    rths_bilinear_leg leg = {
        .lower_dof = 1, .upper_dof = 2, .stiffness_n_per_m = seed_k[2], .ratio = 1.0};
    double fs[4] = {0, 0, -5.0, 0}, f[4] = {0, 0, 0, 1.0};
    rths_shooting_options opt = {.start_hz = 12.0,
                                 .end_hz = 14.0,
                                 .steps_per_period = 2048,
                                 .max_step = 0.05,
                                 .max_points = 400};
    rths_periodic_point *pts;
    int n;
    assert_int_equal(rths_bilinear_frf(&a, &leg, fs, f, &opt, &pts, &n, &err), RTHS_OK);
    assert_true(n > 10);
    assert_close(pts[n - 1].omega_rad_s / (2 * M_PI), 14.0, 0.2);
    for (int p = 0; p < n; p++) {
        double complex X[4];
        assert_int_equal(
            rths_frf(4, a.mass, a.damping, a.stiffness, f, pts[p].omega_rad_s, X, &err), RTHS_OK);
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
    rths_bilinear_leg leg = {
        .lower_dof = 1, .upper_dof = 2, .stiffness_n_per_m = seed_k[2], .ratio = 2.0};
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
    rths_bilinear_leg leg = {
        .lower_dof = 1, .upper_dof = 2, .stiffness_n_per_m = seed_k[2], .ratio = 2.0};
    double amp = getenv("RTHS_TEST_FORCE") ? atof(getenv("RTHS_TEST_FORCE")) : 3.0;
    double lo = getenv("RTHS_TEST_LO") ? atof(getenv("RTHS_TEST_LO")) : 13.0;
    double hi = getenv("RTHS_TEST_HI") ? atof(getenv("RTHS_TEST_HI")) : 16.0;
    double fs[4] = {0, 0, -26.68, 0}, f[4] = {0, 0, 0, amp};
    rths_shooting_options opt = {.start_hz = lo,
                                 .end_hz = hi,
                                 .steps_per_period = 1024,
                                 .max_step = 0.02,
                                 .max_points = 2000};
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

/* ---- issue 27: elements of every kind, anywhere ---- */

/* A Duffing oscillator's static point k q + k3 q^3 = F, against the cubic's root by bisection. */
static void test_cubic_static_point(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    const double m[1] = {1}, c[1] = {1}, k[1] = {1e4};
    assert_int_equal(rths_assembly_from_chain(1, m, c, k, &a, &err), RTHS_OK);
    rths_nl_element e = {.type = RTHS_NL_CUBIC, .dof_i = 0, .dof_j = -1, .k = 1e10};
    double fs[1] = {-20.0}, q[1];
    assert_int_equal(rths_nonlinear_static(&a, 1, &e, fs, q, &err), RTHS_OK);
    double lo = -1, hi = 0; /* f(q) = k q + k3 q^3 - F, increasing */
    for (int it = 0; it < 200; it++) {
        double mid = 0.5 * (lo + hi);
        if (1e4 * mid + 1e10 * mid * mid * mid - fs[0] > 0)
            hi = mid;
        else
            lo = mid;
    }
    assert_close(q[0], 0.5 * (lo + hi), 1e-15);
    assert_true(q[0] > -20.0 / 1e4); /* stiffer than the linear spring */
    rths_assembly_free(&a);
}

/* Independent RK4 of M q'' + C q' + K q + g = f cos(w t) from rest, many periods, with its own
 * force evaluation (the shooting code's is not used): the steady fundamental and third harmonic
 * of every DoF over the last period. */
static void brute_force(const rths_assembly *a, const double *f, double w, int periods, int steps,
                        double k3, double slip, double vreg, double *c1, double *s1, double *c3,
                        double *s3) {
    enum { N = 2 };
    double x[2 * N] = {0}, k1[2 * N], k2[2 * N], k3s[2 * N], k4[2 * N], t[2 * N];
    double h = 2 * M_PI / w / steps;
    double minv[N * N];
    double det = a->mass[0] * a->mass[3] - a->mass[1] * a->mass[2];
    minv[0] = a->mass[3] / det, minv[3] = a->mass[0] / det;
    minv[1] = -a->mass[1] / det, minv[2] = -a->mass[2] / det;
    for (int i = 0; i < N; i++)
        c1[i] = s1[i] = c3[i] = s3[i] = 0;
#define RHS(T, X, D)                                                                               \
    do {                                                                                           \
        double force[N];                                                                           \
        double d = (X)[1] - (X)[0], g = k3 * d * d * d, gf = slip * tanh((X)[N] / vreg);           \
        for (int i = 0; i < N; i++) {                                                              \
            force[i] = f[i] * cos(w * (T));                                                        \
            for (int j = 0; j < N; j++)                                                            \
                force[i] -= a->stiffness[i + j * N] * (X)[j] + a->damping[i + j * N] * (X)[N + j]; \
        }                                                                                          \
        force[1] -= g, force[0] += g, force[0] -= gf;                                              \
        for (int i = 0; i < N; i++) {                                                              \
            (D)[i] = (X)[N + i];                                                                   \
            (D)[N + i] = minv[i] * force[0] + minv[i + N] * force[1];                              \
        }                                                                                          \
    } while (0)
    for (int p = 0; p < periods; p++)
        for (int st = 0; st < steps; st++) {
            double time = h * ((double)p * steps + st);
            if (p == periods - 1)
                for (int i = 0; i < N; i++) {
                    double wt = w * time;
                    c1[i] += 2.0 / steps * cos(wt) * x[i], s1[i] += 2.0 / steps * sin(wt) * x[i];
                    c3[i] += 2.0 / steps * cos(3 * wt) * x[i];
                    s3[i] += 2.0 / steps * sin(3 * wt) * x[i];
                }
            RHS(time, x, k1);
            for (int i = 0; i < 2 * N; i++)
                t[i] = x[i] + 0.5 * h * k1[i];
            RHS(time + 0.5 * h, t, k2);
            for (int i = 0; i < 2 * N; i++)
                t[i] = x[i] + 0.5 * h * k2[i];
            RHS(time + 0.5 * h, t, k3s);
            for (int i = 0; i < 2 * N; i++)
                t[i] = x[i] + h * k3s[i];
            RHS(time + h, t, k4);
            for (int i = 0; i < 2 * N; i++)
                x[i] += h / 6 * (k1[i] + 2 * k2[i] + 2 * k3s[i] + k4[i]);
        }
#undef RHS
}

/* A cubic spring between two DoFs and a regularised friction element to the ground: the
 * shooting solution's harmonics equal a long brute-force simulation's. */
static void test_cubic_and_friction_match_simulation(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    const double m[2] = {1, 1}, c[2] = {2, 2}, k[2] = {1e4, 1e4};
    assert_int_equal(rths_assembly_from_chain(2, m, c, k, &a, &err), RTHS_OK);
    const double k3 = 1e10, slip = 0.2, vreg = 1e-2;
    rths_nl_element el[2] = {
        {.type = RTHS_NL_CUBIC, .dof_i = 1, .dof_j = 0, .k = k3},
        {.type = RTHS_NL_FRICTION, .dof_i = 0, .dof_j = -1, .force_n = slip, .v_reg_m_s = vreg}};
    double fs[2] = {0, 0}, f[2] = {0, 2.0};
    rths_shooting_options opt = {.start_hz = 8.0,
                                 .end_hz = 8.05,
                                 .steps_per_period = 2048,
                                 .max_step = 0.05,
                                 .max_points = 50};
    rths_periodic_point *pts;
    int n;
    assert_int_equal(rths_nonlinear_frf(&a, 2, el, fs, f, &opt, &pts, &n, &err), RTHS_OK);
    assert_close(pts[0].omega_rad_s, 2 * M_PI * 8.0, 1e-9);
    double c1[2], s1[2], c3[2], s3[2];
    brute_force(&a, f, pts[0].omega_rad_s, 150, 2048, k3, slip, vreg, c1, s1, c3, s3);
    for (int i = 0; i < 2; i++) {
        double amp = hypot(c1[i], s1[i]);
        print_message("DoF %d: fundamental %g m (shooting %g), 3rd %g m\n", i + 1, amp,
                      hypot(pts[0].cos_m[i + 2], pts[0].sin_m[i + 2]), hypot(c3[i], s3[i]));
        /* the transient's decay over 150 periods (damping ratio >= 1.6 %) is far below 1e-6 */
        assert_close(pts[0].cos_m[i + 2], c1[i], 1e-6 * amp);
        assert_close(pts[0].sin_m[i + 2], s1[i], 1e-6 * amp);
        assert_close(pts[0].cos_m[i + 6], c3[i], 1e-6 * amp);
        assert_close(pts[0].sin_m[i + 6], s3[i], 1e-6 * amp);
    }
    /* the elements matter: the cubic's 3rd harmonic is well above the integration's error */
    assert_true(hypot(c3[1], s3[1]) > 1e-3 * hypot(c1[1], s1[1]));
    assert_true(pts[0].stable);
    rths_periodic_points_free(pts, n);
    rths_assembly_free(&a);
}

/* A hardening Duffing oscillator bends its peak to the right: two folds, the branch between them
 * unstable (Floquet multiplier above 1), the branches outside stable. */
static void test_duffing_folds_and_stability(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    const double m[1] = {1}, c[1] = {1}, k[1] = {1e4};
    assert_int_equal(rths_assembly_from_chain(1, m, c, k, &a, &err), RTHS_OK);
    /* peak ~ F / (c w0) = 0.02 m, where 3/4 k3 A^2 / k ~ 0.9: the backbone reaches ~22 Hz */
    rths_nl_element e = {.type = RTHS_NL_CUBIC, .dof_i = 0, .dof_j = -1, .k = 3e7};
    double fs[1] = {0}, f[1] = {2.0};
    rths_shooting_options opt = {.start_hz = 14.0,
                                 .end_hz = 26.0,
                                 .steps_per_period = 256,
                                 .max_step = 0.05,
                                 .max_points = 3000};
    rths_periodic_point *pts;
    int n;
    assert_int_equal(rths_nonlinear_frf(&a, 1, &e, fs, f, &opt, &pts, &n, &err), RTHS_OK);
    int folds = 0, changes = 0;
    for (int p = 1; p + 1 < n; p++) {
        double d0 = pts[p].omega_rad_s - pts[p - 1].omega_rad_s;
        double d1 = pts[p + 1].omega_rad_s - pts[p].omega_rad_s;
        folds += d0 * d1 < 0;
        changes += pts[p].stable != pts[p - 1].stable;
        /* on the unstable branch the frequency runs backwards */
        if (!pts[p].stable) assert_true(d0 < 0 || d1 < 0);
    }
    assert_int_equal(folds, 2);
    assert_int_equal(changes, 2);
    assert_true(pts[0].stable && pts[n - 1].stable);
    rths_periodic_points_free(pts, n);
    rths_assembly_free(&a);
}

/* Harmonic balance (AFT, exact Jacobian) against shooting at one frequency: the 2-DoF chain with
 * a cubic spring and regularised friction at 8 Hz, and the hardening Duffing oscillator at 14 Hz;
 * the truncation checked by doubling the harmonics. */
static void hb_against_shooting(const rths_assembly *a, int count, const rths_nl_element *el,
                                const double *f, double f_hz, double tol) {
    rths_error err;
    int n = a->n;
    double fs[2] = {0, 0};
    rths_shooting_options opt = {.start_hz = f_hz,
                                 .end_hz = f_hz + 0.01,
                                 .steps_per_period = 2048,
                                 .max_step = 0.05,
                                 .max_points = 3};
    rths_periodic_point *pts;
    int np;
    assert_int_equal(rths_nonlinear_frf(a, count, el, fs, f, &opt, &pts, &np, &err), RTHS_OK);
    rths_hb_options ho;
    rths_hb_defaults(&ho);
    double *x = calloc((size_t)n * (2 * ho.harmonics + 1), sizeof(double));
    int it = 0;
    assert_int_equal(rths_hb_solve(a, count, el, fs, f, pts[0].omega_rad_s, &ho, x, &it, &err),
                     RTHS_OK);
    rths_hb_options h2 = ho;
    h2.harmonics = 2 * ho.harmonics;
    h2.samples = 2 * ho.samples;
    double *x2 = calloc((size_t)n * (2 * h2.harmonics + 1), sizeof(double));
    assert_int_equal(rths_hb_solve(a, count, el, fs, f, pts[0].omega_rad_s, &h2, x2, NULL, &err),
                     RTHS_OK);
    for (int i = 0; i < n; i++) {
        double amp = hypot(x[i + n], x[i + 2 * n]);
        print_message("DoF %d at %g Hz: HB %g m (%d Newton steps), shooting %g m, 3rd %g m\n",
                      i + 1, f_hz, amp, it, hypot(pts[0].cos_m[i + n], pts[0].sin_m[i + n]),
                      hypot(x[i + 5 * n], x[i + 6 * n]));
        /* shooting's sin_m is the sin(w t) coefficient, as the series' */
        assert_close(x[i + n], pts[0].cos_m[i + n], tol * amp);
        assert_close(x[i + 2 * n], pts[0].sin_m[i + n], tol * amp);
        assert_close(x[i + 5 * n], pts[0].cos_m[i + 3 * n], tol * amp);
        assert_close(x[i + 6 * n], pts[0].sin_m[i + 3 * n], tol * amp);
        /* doubling the harmonics moves nothing beyond the tolerance */
        assert_close(x2[i + n], x[i + n], tol * amp);
        assert_close(x2[i + 2 * n], x[i + 2 * n], tol * amp);
    }
    free(x), free(x2);
    rths_periodic_points_free(pts, np);
}

static void test_harmonic_balance_matches_shooting(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    const double m[2] = {1, 1}, c[2] = {2, 2}, k[2] = {1e4, 1e4};
    assert_int_equal(rths_assembly_from_chain(2, m, c, k, &a, &err), RTHS_OK);
    rths_nl_element el[2] = {
        {.type = RTHS_NL_CUBIC, .dof_i = 1, .dof_j = 0, .k = 1e10},
        {.type = RTHS_NL_FRICTION, .dof_i = 0, .dof_j = -1, .force_n = 0.2, .v_reg_m_s = 1e-2}};
    double f[2] = {0, 2.0};
    hb_against_shooting(&a, 2, el, f, 8.0, 1e-6);
    rths_assembly_free(&a);
    const double m1[1] = {1}, c1[1] = {1}, k1[1] = {1e4};
    assert_int_equal(rths_assembly_from_chain(1, m1, c1, k1, &a, &err), RTHS_OK);
    rths_nl_element duffing = {.type = RTHS_NL_CUBIC, .dof_i = 0, .dof_j = -1, .k = 3e7};
    double f1[2] = {2.0, 0};
    hb_against_shooting(&a, 1, &duffing, f1, 14.0, 1e-6);
    rths_assembly_free(&a);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_linear_leg_matches_analytic_frf),
        cmocka_unit_test(test_bilinear_static_point),
        cmocka_unit_test(test_bilinear_folds),
        cmocka_unit_test(test_cubic_static_point),
        cmocka_unit_test(test_cubic_and_friction_match_simulation),
        cmocka_unit_test(test_duffing_folds_and_stability),
        cmocka_unit_test(test_harmonic_balance_matches_shooting),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
