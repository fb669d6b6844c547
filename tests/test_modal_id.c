/* Modal identification from a receptance (src/run/modal_id.c; docs/method.md, "Complex FRF and
 * modal identification") against synthetic FRFs whose modes are known exactly: a sum of
 * proportionally damped modes, H(w) = sum_r A_r / (w_r^2 - w^2 + 2 i zeta_r w_r w), with modes
 * outside the band that the fit only sees through its residual terms. Noise-free, the fit
 * recovers the modes in the band to rounding; with circular noise of known standard error the
 * bootstrap standard errors cover the truth as often as a normal law says (coverage over 100
 * noisy replicas). */
#include "testlib.h"

#include "run/modal_id.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

typedef struct {
    double f_hz, zeta, a;
} true_mode;

/* The seed building's modes (rths model examples/four_storey_linear.yaml, modes.csv): storey 3's
 * receptance to a force on storey 4, A_r = phi_3r phi_4r (1/kg). */
static const true_mode seed_modes[4] = {
    {4.3391625192798049, 0.0011322815545322365, 0.20227355378492992 * 0.24583539013965794},
    {13.473060238428708, 0.0035157282730446555, 0.11036392343582813 * -0.15579938630353707},
    {21.819442170621716, 0.0056936778944320877, 0.29370195272232513 * -0.08438230030686468},
    {27.366662536804618, 0.0071412072675272635, -0.21648121420235003 * 0.035791189187116212}};

static double complex receptance(const true_mode *modes, int count, double f_hz) {
    double w = 2 * M_PI * f_hz;
    double complex h = 0;
    for (int r = 0; r < count; r++) {
        double wr = 2 * M_PI * modes[r].f_hz;
        h += modes[r].a / (wr * wr - w * w + 2 * I * modes[r].zeta * wr * w);
    }
    return h;
}

/* Noise-free: the seed's second mode from 41 points over 12-14 Hz (the linear example's sweep),
 * the other three modes outside the band; and two modes at once over 3-16 Hz. The residual terms
 * model the out-of-band modes only approximately, so the tolerances are not rounding: measured
 * 3.1e-7 in frequency, 4.7e-4 in damping, 2.6e-4 in the modal constant for the one-mode band
 * (the acceptance on the hybrid test is 1e-3 and 0.1); for two modes at most 2e-6, 1e-4 and
 * 2e-3 (printed below). */
static void noise_free(void **state) {
    (void)state;
    enum { N = 41 };
    double f[N], se[N];
    double complex h[N];
    for (int k = 0; k < N; k++) {
        f[k] = 12 + 2.0 * k / (N - 1);
        h[k] = receptance(seed_modes, 4, f[k]);
        se[k] = 1e-12;
    }
    frf_modal_fit_options opt = {.modes = 1, .bootstrap = 0, .seed = 1};
    frf_mode_estimate est[2];
    rths_error err;
    assert_int_equal(frf_modal_fit(N, f, h, se, &opt, est, NULL, &err), 0);
    printf("one mode: f %.10f Hz (rel %.1e), zeta %.8f (rel %.1e), A %.6e%+.1ei (rel %.1e)\n",
           est[0].frequency_hz, est[0].frequency_hz / seed_modes[1].f_hz - 1, est[0].damping_ratio,
           est[0].damping_ratio / seed_modes[1].zeta - 1, creal(est[0].modal_constant),
           cimag(est[0].modal_constant), cabs(est[0].modal_constant / seed_modes[1].a - 1));
    assert_rel(est[0].frequency_hz, seed_modes[1].f_hz, 2e-6);
    assert_rel(est[0].damping_ratio, seed_modes[1].zeta, 2e-3);
    assert_true(cabs(est[0].modal_constant / seed_modes[1].a - 1) < 2e-3);
    assert_true(isnan(est[0].frequency_se_hz)); /* no bootstrap: no standard error */

    /* modes 1 and 2 over 3-16 Hz, every 0.1 Hz (about the second mode's half-power bandwidth) */
    enum { N2 = 131 };
    double f2[N2], se2[N2];
    double complex h2[N2];
    for (int k = 0; k < N2; k++) {
        f2[k] = 3 + 13.0 * k / (N2 - 1);
        h2[k] = receptance(seed_modes, 4, f2[k]);
        se2[k] = 1e-12;
    }
    opt.modes = 2;
    assert_int_equal(frf_modal_fit(N2, f2, h2, se2, &opt, est, NULL, &err), 0);
    for (int r = 0; r < 2; r++) {
        printf("two modes, mode %d: f rel %.1e, zeta rel %.1e, A rel %.1e\n", r + 1,
               est[r].frequency_hz / seed_modes[r].f_hz - 1,
               est[r].damping_ratio / seed_modes[r].zeta - 1,
               cabs(est[r].modal_constant / seed_modes[r].a - 1));
        assert_rel(est[r].frequency_hz, seed_modes[r].f_hz, 5e-6);
        assert_rel(est[r].damping_ratio, seed_modes[r].zeta, 2e-3);
        assert_true(cabs(est[r].modal_constant / seed_modes[r].a - 1) < 1e-2);
    }
}

/* With noise: 100 replicas of the one-mode band, each point's parts perturbed by N(0, sigma^2)
 * with sigma = 3e-7 m/N (0.1 % of the peak, ten times the hybrid test's); each replica's
 * bootstrap SE (100 replicates) against its own error. For a normal estimator 68.3 % fall within
 * 1 SE and 95.4 % within 2; with 100 replicas the binomial spread is 4.7 and 2.1 points, so the
 * bounds below are 3 of those spreads wide. A standard error that were half or twice the right
 * size would fail them (38 % or 95 % within 1 SE). */
static void bootstrap_coverage(void **state) {
    (void)state;
    enum { N = 41, REPLICAS = 100 };
    double f[N], se[N];
    double complex clean[N], h[N];
    for (int k = 0; k < N; k++) {
        f[k] = 12 + 2.0 * k / (N - 1);
        clean[k] = receptance(seed_modes, 4, f[k]);
        se[k] = 3e-7;
    }
    rths_rng rng;
    rths_rng_seed(&rng, 20261201);
    int within1[3] = {0}, within2[3] = {0}, fitted = 0;
    double mean_se_f = 0, rms_err_f = 0;
    for (int rep = 0; rep < REPLICAS; rep++) {
        for (int k = 0; k < N; k++) {
            double e1 = rths_rng_normal(&rng), e2 = rths_rng_normal(&rng);
            h[k] = clean[k] + se[k] * (e1 + I * e2);
        }
        frf_modal_fit_options opt = {.modes = 1, .bootstrap = 100, .seed = 7 + (uint64_t)rep};
        frf_mode_estimate est;
        int used = 0;
        rths_error err;
        if (frf_modal_fit(N, f, h, se, &opt, &est, &used, &err)) continue;
        fitted++;
        assert_int_equal(used, 100);
        double z[3] = {(est.frequency_hz - seed_modes[1].f_hz) / est.frequency_se_hz,
                       (est.damping_ratio - seed_modes[1].zeta) / est.damping_ratio_se,
                       (creal(est.modal_constant) - seed_modes[1].a) / est.modal_constant_se_real};
        for (int q = 0; q < 3; q++) {
            within1[q] += fabs(z[q]) <= 1;
            within2[q] += fabs(z[q]) <= 2;
        }
        mean_se_f += est.frequency_se_hz / REPLICAS;
        rms_err_f += pow(est.frequency_hz - seed_modes[1].f_hz, 2) / REPLICAS;
    }
    printf("coverage over %d replicas: within 1 SE f %d, zeta %d, A %d; within 2 SE f %d, zeta "
           "%d, A %d; mean SE(f) %.3e Hz, rms error %.3e Hz\n",
           fitted, within1[0], within1[1], within1[2], within2[0], within2[1], within2[2],
           mean_se_f, sqrt(rms_err_f));
    assert_int_equal(fitted, REPLICAS);
    for (int q = 0; q < 3; q++) {
        assert_in_range(within1[q], 54, 82);
        assert_in_range(within2[q], 89, 100);
    }
}

/* Too few points for the unknowns: refused by name, nothing fitted. */
static void too_few_points(void **state) {
    (void)state;
    double f[3] = {13, 13.4, 13.8}, se[3] = {1e-9, 1e-9, 1e-9};
    double complex h[3];
    for (int k = 0; k < 3; k++)
        h[k] = receptance(seed_modes, 4, f[k]);
    frf_modal_fit_options opt = {.modes = 1, .bootstrap = 10, .seed = 1};
    frf_mode_estimate est;
    rths_error err;
    assert_int_equal(frf_modal_fit(3, f, h, se, &opt, &est, NULL, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "usable points"));
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(noise_free),
                                       cmocka_unit_test(bootstrap_coverage),
                                       cmocka_unit_test(too_few_points)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
