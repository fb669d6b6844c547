/* Stability module against closed forms: Hayes' equation, x' = -x(t - tau), the delayed
 * oscillator's D(i omega) = 0 curves, a scalar neutral equation's root chain, the seed's delay
 * equation (its structure, D(0) = det K, the p = 1/2 chain), chart self-consistency, and the
 * time-domain delayed-feedback simulation against the chart's labels. */
#include "testlib.h"

#include "rths/stability.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double seed_m[4] = {5.37, 5.37, 5.37, 10.74};
static const double seed_c[4] = {4.4062, 3.7979, 3.7421, 3.7421};
static const double seed_k[4] = {53048, 45724, 45052, 45052};
static const rths_dof_role seed_roles[4] = {RTHS_DOF_PHYSICAL, RTHS_DOF_PHYSICAL,
                                            RTHS_DOF_INTERFACE, RTHS_DOF_NUMERICAL};
static const double five_m[5] = {5.37, 5.37, 5.37, 10.74, 5.37};
static const double five_c[5] = {4.4062, 3.7979, 3.7421, 3.7421, 3.7421};
static const double five_k[5] = {53048, 45724, 45052, 45052, 45052};
static const rths_dof_role five_roles[5] = {RTHS_DOF_PHYSICAL, RTHS_DOF_PHYSICAL,
                                            RTHS_DOF_INTERFACE, RTHS_DOF_NUMERICAL,
                                            RTHS_DOF_NUMERICAL};

/* scalar first-order x' = a x + b x(t - tau) as (C_0 = 1, K_0 = -a, K_tau = -b) */
static void scalar_dde(double a, double b, double c_neutral, rths_dde *d) {
    double one = 1, k0 = -a, kt = -b;
    rths_error err;
    assert_int_equal(rths_dde_from_matrices(1, NULL, NULL, &one, &c_neutral, &k0, &kt, d, &err),
                     RTHS_OK);
}

static void seed_dde(double p, rths_assembly *a, rths_dde *d) {
    rths_error err;
    rths_split s;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, a, &err), RTHS_OK);
    assert_int_equal(rths_split_create(a, seed_roles, p, NULL, NULL, &s, &err), RTHS_OK);
    assert_int_equal(rths_dde_from_split(a, &s, d, &err), RTHS_OK);
    rths_split_free(&s);
}

/* x' = -x(t - tau): Hopf at tau = pi/2 with omega = 1 (D(i) = i + e^{-i pi/2} = 0 exactly). */
static void test_hopf_pi_over_2(void **state) {
    (void)state;
    rths_dde d;
    rths_error err;
    scalar_dde(0, -1, 0, &d);
    double tc, wc;
    assert_int_equal(rths_dde_critical_delay(&d, 0.05, 5.0, 150, 24, &tc, &wc, &err), RTHS_OK);
    assert_close(tc, M_PI / 2, 1e-6);
    assert_close(wc, 1.0, 1e-6);
    /* labels either side: 1 % away from the boundary the rightmost root is well off the axis */
    rths_dde_label l;
    assert_int_equal(rths_dde_label_at(&d, 0.99 * M_PI / 2, 24, &l, &err), RTHS_OK);
    assert_true(l.stable);
    assert_int_equal(rths_dde_label_at(&d, 1.01 * M_PI / 2, 24, &l, &err), RTHS_OK);
    assert_false(l.stable);
    assert_close(l.rightmost_imag, 1.0, 0.05);
    rths_dde_free(&d);
}

/* x' = -x - 2 x(t - tau): |1 + i w| = 2 gives w = sqrt 3, then w tau = 2 pi / 3. */
static void test_critical_delay_closed_form(void **state) {
    (void)state;
    rths_dde d;
    rths_error err;
    scalar_dde(-1, -2, 0, &d);
    double tc, wc;
    assert_int_equal(rths_dde_critical_delay(&d, 0.01, 10.0, 200, 24, &tc, &wc, &err), RTHS_OK);
    assert_close(wc, sqrt(3.0), 1e-8);
    assert_close(tc, 2 * M_PI / (3 * sqrt(3.0)), 1e-8);
    rths_dde_free(&d);
}

/* Hayes (1950): x' = a x + b x(t-1) is stable iff a < 1, a + b < 0 and b > -sqrt(a^2 + z^2),
 * z in (0, pi) the root of z = a tan z (z = pi/2 at a = 0). Points 2 % either side of each
 * boundary must be labelled accordingly. */
static double hayes_zeta(double a) {
    if (a == 0) return M_PI / 2;
    /* bisection of g(z) = z cos z - a sin z on (0, pi): sign change bracketing the root */
    double lo = 1e-9, hi = M_PI - 1e-9;
    if (a < 0)
        lo = M_PI / 2;
    else
        hi = M_PI / 2;
    for (int i = 0; i < 200; i++) {
        double mid = 0.5 * (lo + hi);
        double gl = lo * cos(lo) - a * sin(lo), gm = mid * cos(mid) - a * sin(mid);
        if ((gl < 0) == (gm < 0))
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

static int hayes_label(double a, double b) {
    rths_dde d;
    rths_error err;
    rths_dde_label l;
    scalar_dde(a, b, 0, &d);
    assert_int_equal(rths_dde_label_at(&d, 1.0, 24, &l, &err), RTHS_OK);
    rths_dde_free(&d);
    return l.stable;
}

static void test_hayes(void **state) {
    (void)state;
    const double as[4] = {-2.0, -1.0, 0.0, 0.5};
    for (int k = 0; k < 4; k++) {
        double a = as[k], z = hayes_zeta(a);
        assert_close(z * cos(z) - a * sin(z), 0, 1e-9);
        double bh = -sqrt(a * a + z * z); /* oscillatory (Hopf) boundary */
        double br = -a;                   /* real root through 0 */
        assert_true(hayes_label(a, bh * 0.98));
        assert_false(hayes_label(a, bh * 1.02));
        if (br > bh) {
            assert_true(hayes_label(a, br - 0.02 * fabs(br) - 0.01));
            assert_false(hayes_label(a, br + 0.02 * fabs(br) + 0.01));
        }
    }
    /* a >= 1: unstable for every b */
    assert_false(hayes_label(1.05, -1.0));
}

/* x' + c x'(t - tau) = a x + b x(t - tau): chain at Re lambda = ln|c| / tau. The roots near
 * Im = (2k+1) pi / tau deviate from the line by about |a - b/c| / |lambda| (first-order expansion
 * of 1 + c e^{-lambda tau} = (a + b e^{-lambda tau}) / lambda), so that bound (x 1.5) is the
 * tolerance and it must shrink as k grows. */
static void test_neutral_scalar_chain(void **state) {
    (void)state;
    const double a = -1, b = 0.2, c = 0.5, tau = 1.0;
    rths_dde d;
    rths_error err;
    double one = 1, k0 = -a, kt = -b;
    assert_int_equal(rths_dde_from_matrices(1, NULL, NULL, &one, &c, &k0, &kt, &d, &err), RTHS_OK);
    double rt;
    assert_int_equal(rths_dde_essential(&d, &rt, NULL, NULL, &err), RTHS_OK);
    assert_close(rt / tau, log(c) / tau, 1e-12);
    const int ks[3] = {5, 20, 200};
    double prev = INFINITY;
    for (int i = 0; i < 3; i++) {
        double complex l = log(c) / tau + I * (2 * ks[i] + 1) * M_PI / tau;
        assert_int_equal(rths_dde_newton(&d, tau, &l), 0);
        double dev = fabs(creal(l) - log(c) / tau);
        assert_true(dev <= 1.5 * fabs(a - b / c) / cabs(l));
        assert_true(dev < prev);
        prev = dev;
    }
    /* spectral roots: every accepted root solves D = 0 and none lies right of the stable real
     * root of the delay-free limit... the rightmost is the real root of lambda (1 + c e) = a + b e
     */
    double complex *r;
    int nr;
    assert_int_equal(rths_dde_spectral_roots(&d, tau, 32, 0, &r, &nr, &err), RTHS_OK);
    assert_true(nr >= 3);
    for (int i = 0; i < nr; i++)
        assert_true(rths_dde_residual(&d, tau, r[i]) < 1e-10);
    double complex lr = r[0];
    assert_close(cimag(lr), 0, 1e-9);
    double complex e = cexp(-lr * tau);
    assert_close(cabs(lr * (1 + c * e) - (a + b * e)), 0, 1e-10);
    free(r);
    rths_dde_free(&d);
}

/* Delayed oscillator x'' + 0.1 x' + x + k x(t - tau) = 0 charted over (tau, k): every MDBM point
 * must satisfy the closed form k = |1 - w^2 + 0.1 i w| and e^{-i w tau} = -(1 - w^2 + 0.1 i w) / k.
 */
static int oscillator_family(void *ctx, double k, rths_dde *out, rths_error *err) {
    (void)ctx;
    double m = 1, c = 0.1, k0 = 1;
    return rths_dde_from_matrices(1, &m, NULL, &c, NULL, &k0, &k, out, err);
}

static void test_delayed_oscillator_mdbm(void **state) {
    (void)state;
    rths_chart_options o;
    rths_chart_options_default(&o);
    o.tau_min_s = 0.2, o.tau_max_s = 6.0, o.tau_points = 40;
    o.p_min = 0.05, o.p_max = 1.5, o.p_points = 30;
    o.omega_min_rad_s = 0.05, o.omega_max_rad_s = 2.5, o.omega_points = 60;
    o.mdbm_tau_points = 30, o.mdbm_p_points = 30, o.mdbm_refine = 3;
    o.chebyshev_nodes = 20;
    rths_chart c;
    rths_error err;
    assert_int_equal(rths_chart_compute(oscillator_family, NULL, &o, &c, &err), RTHS_OK);
    assert_true(c.n_boundary > 50);
    for (int b = 0; b < c.n_boundary; b++) {
        double w = c.b_omega[b], k = c.b_p[b], t = c.b_tau[b];
        double complex h = 1 - w * w + 0.1 * I * w;
        assert_close(k, cabs(h), 1e-7);
        assert_close(cabs(cexp(-I * w * t) + h / k), 0, 1e-6);
    }
    assert_true(c.b_max_residual < 1e-9);
    /* labels agree with the boundaries */
    assert_true(c.label_changes > 10);
    assert_int_equal(c.label_changes_unexplained, 0);
    assert_int_equal(c.boundary_unexplained, 0);
    /* k < 0.1 (below the minimum of |1 - w^2 + 0.1 i w| = 0.0999) no root can cross: stable for
     * every delay; the critical delay for k = 0.05 is then not found (NaN) */
    for (int i = 0; i < c.nt; i++)
        assert_true(c.stable[i]);
    assert_true(isnan(c.critical_tau[0]));
    rths_chart_free(&c);
}

/* The seed's delay equation: paper eq. (2.10)'s block structure, X_0 + X_tau = X, and
 * D(0) = det K = k1 k2 k3 sigma4 (a grounded spring chain; the paper's printed D(0) is not
 * dimensionally consistent). */
static void test_seed_structure(void **state) {
    (void)state;
    const double p = 0.67;
    rths_assembly a;
    rths_dde d;
    seed_dde(p, &a, &d);
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double mt = (i == 2 && j == 2) ? (1 - p) * 5.37 : 0;
            assert_close(RTHS_AT(d.mt, 4, i, j), mt, 1e-12);
            double kt = j == 2 && i == 1 ? -seed_k[2] : (j == 2 && i == 2 ? seed_k[2] : 0);
            assert_close(RTHS_AT(d.kt, 4, i, j), kt, 1e-9);
            double ct = j == 2 && i == 1 ? -seed_c[2] : (j == 2 && i == 2 ? seed_c[2] : 0);
            assert_close(RTHS_AT(d.ct, 4, i, j), ct, 1e-12);
            assert_close(RTHS_AT(d.m0, 4, i, j) + RTHS_AT(d.mt, 4, i, j), RTHS_AT(a.mass, 4, i, j),
                         1e-12);
            assert_close(RTHS_AT(d.k0, 4, i, j) + RTHS_AT(d.kt, 4, i, j),
                         RTHS_AT(a.stiffness, 4, i, j), 1e-9);
        }
    double complex det;
    rths_dde_char(&d, 1e-4, 0.0, &det, NULL, NULL);
    double expect = seed_k[0] * seed_k[1] * seed_k[2] * seed_k[3];
    assert_rel(creal(det), expect, 1e-12);
    assert_close(cimag(det), 0, 1e-12 * expect);
    rths_dde_free(&d);
    rths_assembly_free(&a);
}

/* Essential spectrum of the seed split: z = -p/(1-p), so Re lambda -> ln((1-p)/p)/tau. */
static void test_seed_essential(void **state) {
    (void)state;
    const double ps[5] = {0.2, 0.33, 0.5, 0.67, 0.9};
    for (int k = 0; k < 5; k++) {
        rths_assembly a;
        rths_dde d;
        rths_error err;
        seed_dde(ps[k], &a, &d);
        double rt;
        double complex z[4];
        int nz;
        assert_int_equal(rths_dde_essential(&d, &rt, z, &nz, &err), RTHS_OK);
        assert_int_equal(nz, 1);
        assert_close(creal(z[0]), -ps[k] / (1 - ps[k]), 1e-12);
        assert_close(rt, log((1 - ps[k]) / ps[k]), 1e-12);
        /* a chain root from the asymptotic guess converges near the line */
        double tau = 1e-4;
        double complex l = rt / tau + I * 41 * M_PI / tau;
        assert_int_equal(rths_dde_newton(&d, tau, &l), 0);
        /* off the line by the first-order correction |dz/z| / tau with dz ~ C/(M lambda):
         * (c3 + c4) / (m3_phys lambda tau) <= 7.5 / (0.537 * 1.29e6 * 1e-4) ~ 0.11 /s */
        assert_close(creal(l), rt / tau, 0.2);
        rths_dde_free(&d);
        rths_assembly_free(&a);
    }
}

/* The seed at p = 0.67: critical delay of the order of 1e-4 s, lost by the first mode
 * (27.26 rad/s undamped); p <= 1/2 unstable for every delay. */
static void test_seed_critical(void **state) {
    (void)state;
    rths_assembly a;
    rths_dde d;
    rths_error err;
    seed_dde(0.67, &a, &d);
    double tc, wc;
    assert_int_equal(rths_dde_critical_delay(&d, 1e-6, 1e-2, 300, 12, &tc, &wc, &err), RTHS_OK);
    printf("seed p=0.67: critical delay %.6e s at %.4f rad/s\n", tc, wc);
    assert_true(tc > 2e-5 && tc < 5e-4);
    assert_close(wc, 27.26, 0.1 * 27.26);
    /* the point found is on D(i w) = 0 */
    assert_true(cabs(rths_dde_char_scaled(&d, tc, I * wc)) < 1e-10);
    rths_dde_label l;
    assert_int_equal(rths_dde_label_at(&d, 0.98 * tc, 12, &l, &err), RTHS_OK);
    assert_true(l.stable);
    assert_int_equal(rths_dde_label_at(&d, 1.02 * tc, 12, &l, &err), RTHS_OK);
    assert_false(l.stable);
    rths_dde_free(&d);
    rths_assembly_free(&a);
    const double low[3] = {0.1, 0.33, 0.5};
    for (int k = 0; k < 3; k++) {
        seed_dde(low[k], &a, &d);
        assert_int_equal(rths_dde_critical_delay(&d, 1e-6, 1e-2, 50, 12, &tc, &wc, &err), RTHS_OK);
        assert_close(tc, 0.0, 0.0);
        const double taus[3] = {1e-6, 5e-5, 3e-4};
        for (int t = 0; t < 3; t++) {
            assert_int_equal(rths_dde_label_at(&d, taus[t], 12, &l, &err), RTHS_OK);
            assert_false(l.stable);
        }
        rths_dde_free(&d);
        rths_assembly_free(&a);
    }
}

static int chart_at(const rths_chart *c, double tau, double p) {
    int bi = 0, bj = 0;
    for (int i = 0; i < c->nt; i++)
        if (fabs(c->tau[i] - tau) < fabs(c->tau[bi] - tau)) bi = i;
    for (int j = 0; j < c->np; j++)
        if (fabs(c->p[j] - p) < fabs(c->p[bj] - p)) bj = j;
    return c->stable[bi + bj * c->nt];
}

/* A coarse seed chart: boundaries on D = 0, labels consistent with them, p <= 1/2 unstable,
 * and the chart's critical delays agree with the stand-alone search. */
static rths_chart seed_chart;
static int seed_chart_done;

static const rths_chart *get_seed_chart(void) {
    if (seed_chart_done) return &seed_chart;
    rths_assembly *a = malloc(sizeof *a);
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, a, &err), RTHS_OK);
    static rths_split_family fam;
    fam.assembly = a;
    fam.roles = seed_roles;
    rths_chart_options o;
    rths_chart_options_default(&o);
    o.tau_points = 40, o.p_points = 34;
    o.p_min = 0.01, o.p_max = 0.97;
    o.mdbm_tau_points = 25, o.mdbm_p_points = 25, o.omega_points = 56;
    assert_int_equal(rths_chart_compute(rths_split_family_build, &fam, &o, &seed_chart, &err),
                     RTHS_OK);
    seed_chart_done = 1;
    return &seed_chart;
}

static void test_seed_chart(void **state) {
    (void)state;
    const rths_chart *c = get_seed_chart();
    assert_true(c->n_boundary > 20);
    assert_true(c->b_max_residual < 1e-9);
    assert_true(c->label_changes > 0);
    assert_int_equal(c->label_changes_unexplained, 0);
    assert_int_equal(c->boundary_unexplained, 0);
    for (int j = 0; j < c->np; j++) {
        if (c->p[j] <= 0.5) {
            for (int i = 0; i < c->nt; i++)
                assert_false(c->stable[i + j * c->nt]);
            assert_close(c->critical_tau[j], 0, 0);
        }
        /* the chart's critical delay separates its own labels along the row */
        double tc = c->critical_tau[j];
        if (isfinite(tc) && tc > 0)
            for (int i = 0; i < c->nt; i++) {
                if (fabs(c->tau[i] - tc) < 1e-9) continue;
                if (c->tau[i] > tc)
                    assert_false(c->stable[i + j * c->nt]);
                else
                    assert_true(c->stable[i + j * c->nt]);
            }
    }
    /* boundary points: on D(i w) = 0 of the split at their own p */
    rths_assembly a;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, &a, &err), RTHS_OK);
    rths_split_family fam = {.assembly = &a, .roles = seed_roles};
    for (int b = 0; b < c->n_boundary; b += 7) {
        rths_dde d;
        assert_int_equal(rths_split_family_build(&fam, c->b_p[b], &d, &err), RTHS_OK);
        assert_true(cabs(rths_dde_char_scaled(&d, c->b_tau[b], I * c->b_omega[b])) < 1e-9);
        rths_dde_free(&d);
    }
    /* the chart's critical delays (found while tracking its rows) equal the stand-alone search
     * at the same p: both end in Newton on D(i w; tau) = 0, so to 1e-9 relative */
    for (int j = 0; j < c->np; j += 5) {
        if (c->p[j] <= 0.5) continue;
        rths_dde d;
        double tc, wc;
        assert_int_equal(rths_split_family_build(&fam, c->p[j], &d, &err), RTHS_OK);
        assert_int_equal(rths_dde_critical_delay(&d, 1e-6, 1e-2, 300, 12, &tc, &wc, &err), RTHS_OK);
        assert_rel(c->critical_tau[j], tc, 1e-9);
        assert_rel(c->critical_omega[j], wc, 1e-9);
        rths_dde_free(&d);
    }
    rths_assembly_free(&a);
}

/* Time-domain cross-check against the chart (issue 5): 1 N at 2 Hz on storey 4. */
static double last_peak_ratio; /* max |x_num| over the trace / true steady amplitude */

static void sim_point(double p, double tau, double duration, int *diverged, double *rate) {
    rths_assembly a;
    rths_split s;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, &a, &err), RTHS_OK);
    assert_int_equal(rths_split_create(&a, seed_roles, p, NULL, NULL, &s, &err), RTHS_OK);
    double f[4] = {0, 0, 0, 1.0};
    rths_delay_sim_result r;
    assert_int_equal(rths_delay_feedback_simulate(&a, &s, f, 2.0, tau, duration, 0, &r, &err),
                     RTHS_OK);
    printf("sim p=%.2f tau=%.1e: diverged %d at %.4g s, growth %.4g /s, trace %d\n", p, tau,
           r.diverged, r.divergence_time_s, r.growth_rate_per_s, r.n);
    assert_true(r.n > 10);
    double peak = 0;
    for (int i = 0; i < r.n; i++)
        peak = fmax(peak, fabs(r.x_num_m[i]));
    last_peak_ratio = peak / r.steady_amplitude_m;
    printf("  peak / steady amplitude %.3g\n", last_peak_ratio);
    *diverged = r.diverged;
    *rate = r.growth_rate_per_s;
    rths_delay_sim_result_free(&r);
    rths_split_free(&s);
    rths_assembly_free(&a);
}

static double seed_rightmost(double p, double tau, double *essential) {
    rths_assembly a;
    rths_dde d;
    rths_error err;
    rths_dde_label l;
    seed_dde(p, &a, &d);
    assert_int_equal(rths_dde_label_at(&d, tau, 12, &l, &err), RTHS_OK);
    rths_dde_free(&d);
    rths_assembly_free(&a);
    *essential = l.essential_per_s;
    return l.rightmost_real;
}

static void test_time_domain_cross_check(void **state) {
    (void)state;
    int div;
    double rate, ess, re;
    /* p = 0.33: the neutral chain grows by (1-p)/p = 2.03 per delay whatever the delay; the
     * fitted growth must match the chain's rate ln((1-p)/p)/tau (to 25 %: the envelope fit over a
     * few delays before the bound is hit) */
    sim_point(0.33, 5e-5, 0.05, &div, &rate);
    assert_true(div);
    re = seed_rightmost(0.33, 5e-5, &ess);
    printf("  chart: rightmost root %.4g /s, essential %.4g /s\n", re, ess);
    assert_rel(rate, ess, 0.25);
    sim_point(0.33, 1e-3, 0.5, &div, &rate);
    assert_true(div);
    re = seed_rightmost(0.33, 1e-3, &ess);
    assert_rel(rate, ess, 0.25);
    /* p = 0.67: 50 us holds (bounded, no growth), 1 ms diverges through the first mode at the rate
     * of the chart's rightmost root */
    sim_point(0.67, 5e-5, 2.0, &div, &rate);
    assert_false(div);
    re = seed_rightmost(0.67, 5e-5, &ess);
    assert_true(re < 0 && ess < 0);
    /* the start-up transient of the lightly damped modes (zeta ~ 0.1 %) decays over tens of
     * seconds, so "holds" means: bounded by a small multiple of the true steady amplitude */
    assert_true(last_peak_ratio < 10);
    sim_point(0.67, 1e-3, 12.0, &div, &rate);
    re = seed_rightmost(0.67, 1e-3, &ess);
    printf("  chart: rightmost root %.4g /s, essential %.4g /s\n", re, ess);
    assert_true(re > 0);
    assert_rel(rate, re, 0.2);
    /* the chart says the same at these points */
    const rths_chart *c = get_seed_chart();
    assert_false(chart_at(c, 5e-5, 0.33));
    assert_true(chart_at(c, 5e-5, 0.67));
    /* either side of the critical delay at p = 0.67 */
    rths_assembly a;
    rths_dde d;
    rths_error err;
    seed_dde(0.67, &a, &d);
    double tc, wc;
    assert_int_equal(rths_dde_critical_delay(&d, 1e-6, 1e-2, 300, 12, &tc, &wc, &err), RTHS_OK);
    rths_dde_free(&d);
    rths_assembly_free(&a);
    sim_point(0.67, 0.7 * tc, 8.0, &div, &rate);
    re = seed_rightmost(0.67, 0.7 * tc, &ess);
    printf("  chart: rightmost root %.4g /s\n", re);
    assert_false(div);
    assert_true(re < 0 && last_peak_ratio < 10);
    sim_point(0.67, 1.4 * tc, 8.0, &div, &rate);
    re = seed_rightmost(0.67, 1.4 * tc, &ess);
    printf("  chart: rightmost root %.4g /s\n", re);
    assert_true(re > 0 && rate > 0.3 * re);
}

/* ---- analysis of a feedback test's trace (src/stability/feedback_analysis.c) ---- */

/* n samples of x(t) on t = i dt */
static double *sampled(int n, double dt, double (*x)(double t, const double *q), const double *q,
                       double **t_out) {
    double *t = malloc((size_t)n * sizeof *t), *v = malloc((size_t)n * sizeof *v);
    assert_true(t && v);
    for (int i = 0; i < n; i++)
        t[i] = i * dt, v[i] = x(t[i], q);
    *t_out = t;
    return v;
}

/* q = {a0, a1, b1, a2, b2, a3, b3, w}: a Fourier series of three harmonics */
static double series(double t, const double *q) {
    double x = q[0];
    for (int k = 1; k <= 3; k++)
        x += q[2 * k - 1] * cos(k * q[7] * t) + q[2 * k] * sin(k * q[7] * t);
    return x;
}

/* A three-harmonic series sampled 200 times per period over 3.5 periods: three whole periods, each
 * with the series' own coefficients. Uniform samples over a whole period make the discrete sums
 * orthogonal, so the only error is rounding (1e-12 of amplitudes of order 1). */
static void test_whole_period_fourier(void **state) {
    (void)state;
    const double f_hz = 13.0, w = 2 * M_PI * f_hz;
    const double q[8] = {0.3, 2.0, -1.5, 0.0, 0.25, 0.7, 0.0, w};
    double *t, *x = sampled(700, 1.0 / (200 * f_hz), series, q, &t);
    double coef[5 * 7];
    int samples[5];
    int periods = rths_whole_period_fourier(t, x, 700, f_hz, 3, 5, coef, samples);
    assert_int_equal(periods, 3);
    for (int j = 0; j < periods; j++) {
        assert_int_equal(samples[j], 200);
        for (int c = 0; c < 7; c++)
            assert_close(coef[j * 7 + c], q[c], 1e-12);
    }
    /* fewer harmonics asked: the same leading coefficients; max_periods caps the count */
    assert_int_equal(rths_whole_period_fourier(t, x, 700, f_hz, 1, 2, coef, NULL), 2);
    assert_close(coef[3 + 1], 2.0, 1e-12);
    assert_close(coef[3 + 2], -1.5, 1e-12);
    free(t);
    free(x);
}

/* q = {forced amplitude, forcing w, sigma, transient w}: a forced steady state plus a transient
 * e^{sigma t} cos(w_t t) of known rate sigma */
static double forced_plus_transient(double t, const double *q) {
    return q[0] * cos(q[1] * t) + exp(q[2] * t) * cos(q[3] * t);
}

static double pure_exponential(double t, const double *q) {
    return exp(q[0] * t);
}

/* The growth rate against the closed form sigma. x(t) - x(t - T) removes the forced part and
 * leaves e^{sigma t} R cos(w_t t + phi); the windows (one period of the 3 Hz transient) each see
 * its maximum at the same phase, so ln(max) rises exactly by sigma per second. What is left is
 * the sampling of the maximum ((w_t dt)^2 / 2 = 2e-4 relative) and the linear interpolation of
 * x(t - T) ((w_f dt)^2 / 8 of the forced amplitude, 1e-3 here): 2e-3 1/s covers both. */
static void test_growth_rate_closed_form(void **state) {
    (void)state;
    const double f_hz = 13.0, dt = 1e-3;
    const double sigmas[3] = {-0.5, 0.3, 0.0};
    for (int k = 0; k < 3; k++) {
        const double q[4] = {1e-3, 2 * M_PI * f_hz, sigmas[k], 2 * M_PI * 3.0};
        double *t, *x = sampled(12001, dt, forced_plus_transient, q, &t), env, span;
        double g = rths_feedback_growth_rate(t, x, 12001, 1.0 / f_hz, 1.0 / 3.0, &env, &span);
        printf("  sigma %+.2f: growth rate %+.6f 1/s over %.3f s\n", sigmas[k], g, span);
        assert_close(g, sigmas[k], 2e-3);
        /* the second half of 11.92 s in windows of 1/3 s */
        assert_true(span > 5 && span < 6);
        free(t);
        free(x);
    }
    /* a pure exponential: d(t) = e^{sigma t}(1 - e^{-sigma T}) is one too */
    const double q[1] = {0.2};
    double *t, *x = sampled(5001, dt, pure_exponential, q, &t), env, span;
    double g = rths_feedback_growth_rate(t, x, 5001, 1.0 / f_hz, 0.25, &env, &span);
    assert_close(g, 0.2, 1e-6);
    /* the last window of 0.25 s ends at T + 19 x 0.25 s; its last sample is within dt of that */
    double t_end = 1.0 / f_hz + 19 * 0.25;
    assert_close(env, exp(0.2 * t_end) * (1 - exp(-0.2 / f_hz)), 1e-3 * env);
    /* too short to say */
    assert_true(isnan(rths_feedback_growth_rate(t, x, 7, 1.0 / f_hz, 0.25, &env, &span)));
    free(t);
    free(x);
}

/* The divergence verdict's cases, on the seed assembly (slowest mode 4.9 Hz). */
static void test_feedback_assess(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, &a, &err), RTHS_OK);
    const double f_hz = 13.0, dt = 1e-3;
    rths_feedback_verdict v;
    /* growing at 0.5 1/s over 10 s: diverged, at that rate */
    double q[4] = {1e-3, 2 * M_PI * f_hz, 0.5, 2 * M_PI * 4.9};
    double *t, *x = sampled(10001, dt, forced_plus_transient, q, &t);
    rths_feedback_assess(&a, t, x, x, 10001, f_hz, 10.0, 0, 0, 1e-9, &v);
    assert_true(v.diverged);
    assert_string_equal(v.reason,
                        "the response grows (its unforced part more than doubled over the second "
                        "half)");
    assert_close(v.growth_rate_per_s, 0.5, 0.01);
    assert_close(v.reached_s, 10.0, 1e-9);
    /* the same trace within the sensor noise (its unforced part reaches e^5 = 148 at the end,
     * less than 10 x 100): a note, not divergence */
    rths_feedback_assess(&a, t, x, x, 10001, f_hz, 10.0, 0, 0, 100.0, &v);
    assert_false(v.diverged);
    assert_non_null(v.note);
    /* a limit trip and an early stop are divergence whatever the rate */
    rths_feedback_assess(&a, t, x, x, 10001, f_hz, 10.0, 1, 0, 1e-9, &v);
    assert_string_equal(v.reason, "a safety limit tripped");
    rths_feedback_assess(&a, t, x, x, 10001, f_hz, 11.0, 0, 0, 1e-9, &v);
    assert_string_equal(v.reason,
                        "the response grew beyond bounds (1000 x the true steady amplitude)");
    x[5000] = NAN;
    rths_feedback_assess(&a, t, x, x, 10001, f_hz, 10.0, 0, 0, 1e-9, &v);
    assert_string_equal(v.reason, "the response became non-finite");
    free(t);
    free(x);
    /* decaying: bounded, no note, max |x| is the first sample's 1 + 1e-3 */
    q[2] = -0.5;
    x = sampled(10001, dt, forced_plus_transient, q, &t);
    rths_feedback_assess(&a, t, x, x, 10001, f_hz, 10.0, 0, 0, 1e-9, &v);
    assert_false(v.diverged);
    assert_null(v.note);
    assert_close(v.growth_rate_per_s, -0.5, 0.01);
    assert_close(v.max_abs_x_num_m, 1.001, 1e-12);
    free(t);
    free(x);
    rths_assembly_free(&a);
}

/* The stability section's reader: defaults, values, and located refusals. */
static void test_chart_config(void **state) {
    (void)state;
    rths_config *cfg;
    rths_error err;
    rths_chart_options o, def;
    rths_chart_options_default(&def);
    assert_int_equal(rths_config_load(NULL, NULL, 0, &cfg, &err), RTHS_OK);
    assert_int_equal(rths_chart_config_read(cfg, &o, &err), RTHS_OK);
    assert_memory_equal(&o, &def, sizeof o);
    rths_config_free(cfg);
    const char *ov[] = {"stability.tau_points=30", "stability.p_min=0.4",
                        "stability.mdbm_refine=2"};
    assert_int_equal(rths_config_load(NULL, ov, 3, &cfg, &err), RTHS_OK);
    assert_int_equal(rths_chart_config_read(cfg, &o, &err), RTHS_OK);
    assert_int_equal(o.tau_points, 30);
    assert_true(o.p_min == 0.4);
    assert_int_equal(o.mdbm_refine, 2);
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_OK);
    rths_config_free(cfg);
    const char *bad[][2] = {
        {"stability.tau_min_s=4e-4", "--set stability.tau_min_s=4e-4: key 'stability.tau_max_s': "
                                     "must be above stability.tau_min_s"},
        {"stability.p_max=0.005", "key 'stability.p_max': must not be below stability.p_min"},
        {"stability.omega_points=100000", "the MDBM grid (50 x 50 x 100000) is too large"},
        {"stability.chebyshev_nodes=2", "key 'stability.chebyshev_nodes': must be in [4, 200]"},
    };
    for (int k = 0; k < 4; k++) {
        assert_int_equal(rths_config_load(NULL, &bad[k][0], 1, &cfg, &err), RTHS_OK);
        assert_int_equal(rths_chart_config_read(cfg, &o, &err), RTHS_EINPUT);
        if (!strstr(err.msg, bad[k][1])) fail_msg("'%s' lacks '%s'", err.msg, bad[k][1]);
        rths_config_free(cfg);
    }
}

/* The family of a configured split gives back that split's delay equation at its own p (its
 * interface shares kept), and the essential limit interpolates the sign change of the bound. */
static void test_split_family_and_essential_limit(void **state) {
    (void)state;
    rths_assembly a;
    rths_dde want, got;
    rths_error err;
    seed_dde(0.67, &a, &want);
    rths_split s;
    assert_int_equal(rths_split_create(&a, seed_roles, 0.67, NULL, NULL, &s, &err), RTHS_OK);
    rths_split_family fam;
    double *ci, *ki;
    assert_int_equal(rths_split_family_of(&a, seed_roles, &s, &fam, &ci, &ki, &err), RTHS_OK);
    assert_int_equal(rths_split_family_build(&fam, 0.67, &got, &err), RTHS_OK);
    size_t bytes = sizeof(double) * 16;
    assert_memory_equal(got.m0, want.m0, bytes);
    assert_memory_equal(got.mt, want.mt, bytes);
    assert_memory_equal(got.c0, want.c0, bytes);
    assert_memory_equal(got.ct, want.ct, bytes);
    assert_memory_equal(got.k0, want.k0, bytes);
    assert_memory_equal(got.kt, want.kt, bytes);
    rths_dde_free(&got);
    rths_dde_free(&want);
    free(ci);
    free(ki);
    rths_split_free(&s);
    rths_assembly_free(&a);
    /* rate x tau 0.2, 0.1, -0.1 at p 0.4, 0.5, 0.6: zero at 0.55 */
    double p[3] = {0.4, 0.5, 0.6}, rate[3] = {0.2, 0.1, -0.1};
    rths_chart c = {.np = 3, .p = p, .essential_rate_times_tau = rate};
    assert_close(rths_chart_essential_limit(&c), 0.55, 1e-15);
    rate[2] = 0.05;
    assert_true(isnan(rths_chart_essential_limit(&c)));
}

static void test_bad_input(void **state) {
    (void)state;
    rths_dde d;
    rths_error err;
    scalar_dde(0, -1, 0, &d);
    double complex *r;
    int nr;
    assert_int_equal(rths_dde_spectral_roots(&d, 0.0, 10, 0, &r, &nr, &err), RTHS_EINPUT);
    assert_int_equal(rths_dde_spectral_roots(&d, 1.0, 1, 0, &r, &nr, &err), RTHS_EINPUT);
    rths_chart_options o;
    rths_chart_options_default(&o);
    o.tau_min_s = -1;
    rths_chart c;
    assert_int_equal(rths_chart_compute(oscillator_family, NULL, &o, &c, &err), RTHS_EINPUT);
    rths_dde_free(&d);
    rths_assembly a;
    rths_split s;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, &a, &err), RTHS_OK);
    assert_int_equal(rths_split_create(&a, seed_roles, 0.5, NULL, NULL, &s, &err), RTHS_OK);
    double f[4] = {0, 0, 0, 1};
    rths_delay_sim_result res;
    assert_int_equal(rths_delay_feedback_simulate(&a, &s, f, 2, 0.0, 1, 0, &res, &err),
                     RTHS_EINPUT);
    assert_int_equal(rths_delay_feedback_simulate(&a, &s, f, 2, 1e-4, 1, 1e-5, &res, &err),
                     RTHS_EINPUT); /* step > tau/20 */
    rths_split_free(&s);
    rths_assembly_free(&a);
}

/* Five storeys: same shape (p <= 1/2 never stable, a finite critical delay of order 1e-4 s). */
static void test_five_storey(void **state) {
    (void)state;
    rths_assembly a;
    rths_split s;
    rths_dde d;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(5, five_m, five_c, five_k, &a, &err), RTHS_OK);
    assert_int_equal(rths_split_create(&a, five_roles, 0.67, NULL, NULL, &s, &err), RTHS_OK);
    assert_int_equal(rths_dde_from_split(&a, &s, &d, &err), RTHS_OK);
    double tc, wc;
    assert_int_equal(rths_dde_critical_delay(&d, 1e-6, 1e-2, 300, 12, &tc, &wc, &err), RTHS_OK);
    printf("five storeys p=0.67: critical delay %.6e s at %.4f rad/s\n", tc, wc);
    assert_true(tc > 2e-5 && tc < 5e-4);
    double rt;
    assert_int_equal(rths_dde_essential(&d, &rt, NULL, NULL, &err), RTHS_OK);
    assert_close(rt, log(0.33 / 0.67), 1e-12);
    rths_dde_free(&d);
    rths_split_free(&s);
    rths_assembly_free(&a);
}

static int teardown_chart(void **state) {
    (void)state;
    if (seed_chart_done) rths_chart_free(&seed_chart);
    return 0;
}

/* rig.interface_mass (issue 23.1): the chart of a light specimen (physical_share: the rig carries
 * (1 - p) M_II, nothing compensated) and of the seed's lab (full: the rig carries M_II, the
 * controller compensates p M_II from the delayed measured acceleration) is one and the same
 * neutral equation: M_tau's interface block (1 - p) m3 in both, every other block the split's;
 * the neutral chain at Re lambda tau = ln((1 - p) / p) (the seed's p = 1/2 limit) for both. */
static void test_interface_mass_modes_share_the_dde(void **state) {
    (void)state;
    const char *modes[2] = {"rig.interface_mass=full", "rig.interface_mass=physical_share"};
    const double p = 0.6;
    for (int m = 0; m < 2; m++) {
        const char *ov[] = {modes[m], "split.mass_ratio=0.6"};
        rths_config *cfg;
        rths_setup s;
        rths_error err;
        if (rths_config_load(rths_test_source_path("examples/four_storey.yaml"), ov, 2, &cfg,
                             &err) ||
            rths_setup_read(cfg, &s, &err))
            fail_msg("%s", err.msg);
        assert_int_equal(s.interface_mass,
                         m == 0 ? RTHS_INTERFACE_MASS_FULL : RTHS_INTERFACE_MASS_PHYSICAL_SHARE);
        rths_dde d, split;
        assert_int_equal(rths_dde_from_setup(&s, &d, &err), RTHS_OK);
        assert_int_equal(rths_dde_from_split(&s.assembly, &s.split, &split, &err), RTHS_OK);
        const double *a[6] = {d.m0, d.mt, d.c0, d.ct, d.k0, d.kt},
                     *b[6] = {split.m0, split.mt, split.c0, split.ct, split.k0, split.kt};
        for (int k = 0; k < 6; k++)
            for (int e = 0; e < 16; e++)
                assert_close(a[k][e], b[k][e], 1e-12 * (1 + fabs(b[k][e])));
        assert_close(RTHS_AT(d.mt, 4, 2, 2), (1 - p) * 5.37, 1e-12);
        assert_close(RTHS_AT(d.m0, 4, 2, 2), p * 5.37, 1e-12);
        double rate;
        int nz = 0;
        assert_int_equal(rths_dde_essential(&d, &rate, NULL, &nz, &err), RTHS_OK);
        assert_close(rate, log((1 - p) / p), 1e-9);
        rths_dde_free(&d);
        rths_dde_free(&split);
        rths_setup_free(&s);
        rths_config_free(cfg);
    }
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hopf_pi_over_2),
        cmocka_unit_test(test_critical_delay_closed_form),
        cmocka_unit_test(test_hayes),
        cmocka_unit_test(test_interface_mass_modes_share_the_dde),
        cmocka_unit_test(test_neutral_scalar_chain),
        cmocka_unit_test(test_delayed_oscillator_mdbm),
        cmocka_unit_test(test_seed_structure),
        cmocka_unit_test(test_seed_essential),
        cmocka_unit_test(test_seed_critical),
        cmocka_unit_test(test_seed_chart),
        cmocka_unit_test(test_time_domain_cross_check),
        cmocka_unit_test(test_five_storey),
        cmocka_unit_test(test_bad_input),
        cmocka_unit_test(test_whole_period_fourier),
        cmocka_unit_test(test_growth_rate_closed_form),
        cmocka_unit_test(test_feedback_assess),
        cmocka_unit_test(test_chart_config),
        cmocka_unit_test(test_split_family_and_essential_limit),
    };
    return cmocka_run_group_tests(tests, NULL, teardown_chart);
}
