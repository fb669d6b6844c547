/* The fitted evaluation (docs/method.md, "One evaluation", "The fitted evaluation"): the steady
 * state of per-period coefficient series fitted together with their shared decaying terms
 * (src/iterate/transient_fit.c), its standard error against a known truth over many seeds, and
 * the evaluation strategy `fit` on mock rigs: a geometric transient (the fit stops early and is
 * right), a time-varying one (the fit is refused and the evaluation falls back to waiting). */
#include "testlib.h"

#include "iterate/transient_fit.h"
#include "rths/iterate.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* m series y_i(q) = a_i + Re(c_i z^q) + d_i r^q + noise: a complex pair (z = 0.85 e^{1.3 i},
 * a lightly damped mode ringing against the forcing) and a fast real pole (r = 0.3). */
enum { SERIES = 4 };
static void synthetic(int K, double sigma, rths_rng *rng, const double *a, double *y) {
    const double complex z = 0.85 * cexp(1.3 * I);
    for (int i = 0; i < SERIES; i++) {
        double complex c = (0.4 + 0.1 * i) * cexp(0.7 * i * I);
        double d = 0.2 - 0.1 * i;
        for (int q = 0; q < K; q++)
            y[i * K + q] = a[i] + creal(c * cpow(z, q)) + d * pow(0.3, q) +
                           (sigma > 0 ? sigma * rths_rng_normal(rng) : 0.0);
    }
}

/* Noise off: the steady state is recovered to rounding from 16 periods, while the series' last
 * period is still 0.85^15 = 9 % of the transient's size away from it. */
static void test_fit_recovers_steady_state_noise_free(void **state) {
    (void)state;
    const double a[SERIES] = {1.0, -0.5, 0.25, 2.0};
    int K = 16;
    double y[SERIES * 16], ainf[SERIES], se[SERIES];
    transient_fit fit;
    synthetic(K, 0, NULL, a, y);
    assert_int_equal(transient_fit_series(SERIES, K, y, 4, NULL, 0, &fit, ainf, se, NULL), 0);
    for (int i = 0; i < SERIES; i++)
        assert_close(ainf[i], a[i], 1e-8);
    assert_true(fit.order >= 3);
    assert_close(fit.max_abs_z, 0.85, 1e-6);
    /* the last period alone is far off: what waiting would have taken */
    assert_true(fabs(y[0 * K + K - 1] - a[0]) > 1e-3);
}

/* Noise on (sigma 2e-3 per period, the transient 0.4-0.7): over 400 seeds the errors of the
 * fitted steady state against the truth, in its own standard errors, fall within 1, 2 and 3 of
 * them in the Gaussian shares (68.3, 95.4, 99.7 %) within what 1600 draws scatter (+-2.3 % at
 * 68 %, 3 binomial standard deviations) plus the t distribution's heavier tails at the 20
 * residual degrees of freedom per series (66.9 / 94.1 / 99.2 %). */
static void test_fit_standard_error_coverage(void **state) {
    (void)state;
    enum { K = 24, SEEDS = 400 };
    const double a[SERIES] = {1.0, -0.5, 0.25, 2.0};
    rths_rng rng;
    rths_rng_seed(&rng, 2025);
    int within[4] = {0}, total = 0;
    double y[SERIES * K], ainf[SERIES], se[SERIES];
    for (int s = 0; s < SEEDS; s++) {
        synthetic(K, 2e-3, &rng, a, y);
        transient_fit fit;
        assert_int_equal(transient_fit_series(SERIES, K, y, 4, NULL, 0, &fit, ainf, se, NULL), 0);
        for (int i = 0; i < SERIES; i++) {
            double dev = fabs(ainf[i] - a[i]) / se[i];
            for (int k = 1; k <= 3; k++)
                within[k] += dev <= k;
            total++;
        }
    }
    double share1 = (double)within[1] / total, share2 = (double)within[2] / total,
           share3 = (double)within[3] / total;
    printf("fit coverage over %d: within 1 SE %.3f, 2 SE %.3f, 3 SE %.3f\n", total, share1, share2,
           share3);
    assert_true(share1 > 0.64 && share1 < 0.72);
    assert_true(share2 > 0.92 && share2 < 0.975);
    assert_true(share3 > 0.985);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fit_recovers_steady_state_noise_free),
        cmocka_unit_test(test_fit_standard_error_coverage),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
