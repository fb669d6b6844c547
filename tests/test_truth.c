/* The truth curves a hybrid test is judged against: the analytic FRF equals an independent
 * complex solve of (K - w^2 M + i w C) x = F; its peak sits at the second mode; the distance
 * measure is the vertical log-error on a flat curve and zero on it; the shooting curve of the
 * bilinear example changes stability exactly at its turning points (saddle-node folds). */
#include "testlib.h"

#include "rths/truth.h"

#include <complex.h>
#include <math.h>
#include <string.h>

static void load(const char *example, rths_config **cfg, rths_setup *s) {
    rths_error err;
    if (rths_config_load(rths_test_source_path(example), NULL, 0, cfg, &err) ||
        rths_setup_read(*cfg, s, &err))
        fail_msg("%s", err.msg);
}

/* |x_iface| of (K - w^2 M + i w C) x = F by complex Gaussian elimination (row-major copy). */
static double direct_amplitude(const rths_setup *s, double f_hz) {
    enum { NMAX = 16 };
    int n = s->assembly.n;
    assert_true(n <= NMAX);
    double w = 2 * M_PI * f_hz;
    double complex a[NMAX][NMAX + 1];
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++)
            a[i][j] = s->assembly.stiffness[i + j * n] - w * w * s->assembly.mass[i + j * n] +
                      I * w * s->assembly.damping[i + j * n];
        a[i][n] = s->force[i];
    }
    for (int k = 0; k < n; k++)
        for (int i = k + 1; i < n; i++) {
            double complex f = a[i][k] / a[k][k];
            for (int j = k; j <= n; j++)
                a[i][j] -= f * a[k][j];
        }
    double complex x[NMAX];
    for (int k = n - 1; k >= 0; k--) {
        x[k] = a[k][n];
        for (int j = k + 1; j < n; j++)
            x[k] -= a[k][j] * x[j];
        x[k] /= a[k][k];
    }
    return cabs(x[s->split.int_dofs[0]]);
}

/* Linear example: the analytic amplitude to 1e-10 (two solves of a well-conditioned 4 x 4
 * system away from resonance differ by rounding), the curve's peak within 0.01 Hz of mode 2
 * (13.4731 Hz, 0.35 % damping: a half-power bandwidth of 0.095 Hz), relative errors exact. */
static void test_linear_truth(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load("examples/four_storey_linear.yaml", &cfg, &s);
    for (double f = 12.0; f <= 14.0; f += 0.25)
        assert_rel(rths_truth_linear_amplitude_m(&s, f), direct_amplitude(&s, f), 1e-10);
    rths_truth_curve t;
    rths_error err;
    assert_int_equal(rths_truth_compute(&s, 12.0, 14.0, &t, &err), RTHS_OK);
    assert_true(t.exact);
    assert_true(t.n > 20);
    int peak = 0;
    for (int j = 0; j < t.n; j++) {
        assert_int_equal(t.stable[j], 1);
        assert_true(t.freq_hz[j] >= 12.0 - 1e-9 && t.freq_hz[j] <= 14.0 + 1e-9);
        if (t.amp_m[j] > t.amp_m[peak]) peak = j;
    }
    assert_close(t.freq_hz[peak], 13.4731, 0.01);
    double truth = rths_truth_linear_amplitude_m(&s, 12.5);
    assert_close(rths_truth_relative_error(&s, &t, 12.5, 1.02 * truth), 0.02, 1e-12);
    rths_truth_free(&t);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* On a flat curve the distance is the vertical log-error, ln(1.01) for 1 % high; a point on the
 * curve is at distance 0; on a folded (multi-valued) curve the nearest branch counts; a point
 * without a positive frequency and amplitude is infinitely far. */
static void test_curve_distance(void **state) {
    (void)state;
    double f[4] = {10, 11, 12, 11}, a[4] = {1, 1, 1, 3};
    rths_truth_curve t = {.n = 3, .freq_hz = f, .amp_m = a};
    assert_close(rths_truth_curve_distance(&t, 11, 1.01), log(1.01), 1e-12);
    assert_close(rths_truth_curve_distance(&t, 11.3, 1.0), 0, 1e-12);
    t.n = 4; /* the curve turns back at 12 Hz and climbs to 3 m at 11 Hz */
    assert_close(rths_truth_curve_distance(&t, 11, 1.01), log(1.01), 1e-12);
    double on_upper = rths_truth_curve_distance(&t, 11.0, 3.0);
    assert_close(on_upper, 0, 1e-12);
    assert_true(isinf(rths_truth_curve_distance(&t, 0, 1)));
    assert_true(isinf(rths_truth_curve_distance(&t, 11, 0)));
}

/* Bilinear example over its test range with the usual 10 % margin: the shooting curve turns back
 * in frequency, and its stability flips exactly twice, each time next to a turn (a saddle-node
 * fold), to within one continuation step. */
static void test_bilinear_truth_folds(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load("examples/four_storey_bilinear.yaml", &cfg, &s);
    rths_truth_curve t;
    rths_error err;
    assert_int_equal(rths_truth_compute(&s, 13.39, 14.71, &t, &err), RTHS_OK);
    assert_false(t.exact);
    int flips = 0, turns = 0;
    for (int j = 1; j + 1 < t.n; j++) {
        int turn = (t.freq_hz[j] - t.freq_hz[j - 1]) * (t.freq_hz[j + 1] - t.freq_hz[j]) < 0;
        turns += turn;
        if (t.stable[j] != t.stable[j - 1]) {
            flips++;
            /* the flip is next to a turn of the frequency */
            int near = 0;
            for (int q = j - 2; q <= j + 1; q++)
                if (q >= 1 && q + 1 < t.n)
                    near |=
                        (t.freq_hz[q] - t.freq_hz[q - 1]) * (t.freq_hz[q + 1] - t.freq_hz[q]) < 0;
            assert_true(near);
        }
    }
    assert_int_equal(flips, 2);
    assert_true(turns >= 2); /* the two folds (plus any jitter of a near-vertical stretch) */
    /* the largest Floquet modulus on each branch between the folds (13.91-14.006 Hz): asked with
     * a branch's own amplitude, the value interpolated on that branch's piece, above 1 on the
     * unstable one only; none outside the curve */
    assert_non_null(t.max_floquet);
    const double f = 13.95;
    int branches = 0, unstable = 0;
    for (int j = 0; j + 1 < t.n; j++) {
        double f0 = t.freq_hz[j], f1 = t.freq_hz[j + 1];
        if (!((f0 - f) * (f1 - f) <= 0) || f0 == f1) continue;
        int st;
        double a = rths_truth_branch_amplitude_m(&s, &t, f, t.amp_m[j], &st);
        double mu = rths_truth_branch_max_floquet(&t, f, a);
        double lo = fmin(t.max_floquet[j], t.max_floquet[j + 1]),
               hi = fmax(t.max_floquet[j], t.max_floquet[j + 1]);
        assert_true(mu >= lo - 1e-12 && mu <= hi + 1e-12);
        assert_int_equal(mu < 1, st);
        branches++;
        unstable += !st;
    }
    assert_int_equal(branches, 3);
    assert_int_equal(unstable, 1);
    assert_true(isnan(rths_truth_branch_max_floquet(&t, 20.0, 1e-3)));
    rths_truth_free(&t);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* A branch's amplitude between the curve's points follows the cubic through the four nearest on
 * the same monotone piece: on a resonance peak A(f) = 1 / sqrt((f0^2 - f^2)^2 + (2 zeta f0 f)^2)
 * (zeta = 1 %, a half-power band of 0.28 Hz) sampled every 0.02 Hz (the shooting truth's spacing),
 * the cubic is within 2e-4 of the exact value and ten times closer than the straight line
 * (measured: cubic 7.9e-5, line 2.5e-3). */
static void test_branch_interpolation(void **state) {
    (void)state;
    enum { N = 61 };
    double freq[N], amp[N];
    int stable[N];
    const double f0 = 14.0, zeta = 0.01;
    for (int i = 0; i < N; i++) {
        freq[i] = 13.4 + 0.02 * i;
        double f = freq[i];
        amp[i] = 1.0 / sqrt(pow(f0 * f0 - f * f, 2) + pow(2 * zeta * f0 * f, 2));
        stable[i] = 1;
    }
    rths_truth_curve t = {.n = N, .freq_hz = freq, .amp_m = amp, .stable = stable};
    rths_setup s = {.has_bilinear = 1}; /* a curve, not the analytic FRF */
    double worst_cubic = 0, worst_line = 0;
    for (int k = 0; k < 200; k++) {
        double f = 13.45 + 0.005 * k + 0.0013;
        double exact = 1.0 / sqrt(pow(f0 * f0 - f * f, 2) + pow(2 * zeta * f0 * f, 2));
        double got = rths_truth_branch_amplitude_m(&s, &t, f, exact, NULL);
        worst_cubic = fmax(worst_cubic, fabs(got / exact - 1));
        int j = (int)((f - 13.4) / 0.02);
        double line = amp[j] + (f - freq[j]) / 0.02 * (amp[j + 1] - amp[j]);
        worst_line = fmax(worst_line, fabs(line / exact - 1));
    }
    print_message("branch interpolation: cubic %.2e, straight line %.2e relative\n", worst_cubic,
                  worst_line);
    assert_true(isnan(rths_truth_branch_max_floquet(&t, 14.0, 1.0))); /* no multipliers given */
    assert_true(worst_cubic < 2e-4);
    assert_true(worst_cubic < 0.1 * worst_line);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_linear_truth),
        cmocka_unit_test(test_curve_distance),
        cmocka_unit_test(test_bilinear_truth_folds),
        cmocka_unit_test(test_branch_interpolation),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
