/* Model library against independent truths: the seed facts (docs/method.md, "The seed structure"),
 * closed-form 1- and 2-DoF results, matrix exponentials with known closed forms, z-domain transfer
 * functions of each scheme; the interface mass split by one p per DoF; spectral radii. */
#include "testlib.h"

#include "rths/model.h"

#include <complex.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double seed_m[4] = {5.37, 5.37, 5.37, 10.74};
static const double seed_c[4] = {4.4062, 3.7979, 3.7421, 3.7421};
static const double seed_k[4] = {53048, 45724, 45052, 45052};

static void seed_assembly(rths_assembly *a) {
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(4, seed_m, seed_c, seed_k, a, &err), RTHS_OK);
}

/* docs/method.md, "The seed structure": 4.339, 13.473, 21.819, 27.367 Hz (given to 3 decimals, so
 * 1e-3 Hz covers rounding). */
static void test_seed_natural_frequencies(void **state) {
    (void)state;
    rths_assembly a;
    rths_modes m;
    rths_error err;
    seed_assembly(&a);
    assert_int_equal(rths_modal_analysis(&a, &m, &err), RTHS_OK);
    const double expect_hz[4] = {4.339, 13.473, 21.819, 27.367};
    const double expect_zeta[4] = {0.0011, 0.0035, 0.0057, 0.0071};
    for (int r = 0; r < 4; r++) {
        assert_close(m.frequency_hz[r], expect_hz[r], 1e-3);
        /* the seed gives "about" two significant digits: half a unit in the last digit */
        assert_close(m.damping_ratio[r], expect_zeta[r], 0.00005 + 0.05 * expect_zeta[r]);
        /* mass normalisation phi^T M phi = 1 */
        double mm = 0;
        for (int i = 0; i < 4; i++)
            mm += seed_m[i] * pow(m.shapes[r * 4 + i], 2);
        assert_close(mm, 1.0, 1e-12);
    }
    rths_modes_free(&m);
    rths_assembly_free(&a);
}

/* docs/method.md, "The seed structure": with 1 N on storey 4 the storey-3 amplitude peaks
 * near 13.47 Hz at about 3.42e-4 m. */
static void test_seed_storey3_peak(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    seed_assembly(&a);
    double f[4] = {0, 0, 0, 1.0};
    double complex x[4];
    double best = 0, best_hz = 0;
    for (double hz = 13.3; hz <= 13.6; hz += 1e-5) {
        assert_int_equal(rths_frf(4, a.mass, a.damping, a.stiffness, f, 2 * M_PI * hz, x, &err),
                         RTHS_OK);
        if (cabs(x[2]) > best) best = cabs(x[2]), best_hz = hz;
    }
    assert_close(best_hz, 13.47, 0.005);
    assert_close(best, 3.42e-4, 0.005e-4);
    rths_assembly_free(&a);
}

/* 1 DoF: X = F / (k - m w^2 + i c w). */
static void test_one_dof_frf(void **state) {
    (void)state;
    double m = 2.0, c = 3.0, k = 5000.0, f = 7.0;
    rths_error err;
    for (double w = 1.0; w < 200.0; w *= 1.7) {
        double complex x;
        assert_int_equal(rths_frf(1, &m, &c, &k, &f, w, &x, &err), RTHS_OK);
        double complex expect = f / (k - m * w * w + I * c * w);
        assert_close(creal(x), creal(expect), 1e-14 * cabs(expect) + 1e-300);
        assert_close(cimag(x), cimag(expect), 1e-14 * cabs(expect) + 1e-300);
    }
}

/* One DoF, M = 5 kg, C = 1 N s/m, K = 40000 N/m (issue 24.8: the banded eigensolver's zero
 * shape gave mode 1 at 0 Hz and an all-zero FRF): w = sqrt(K / M), the shape 1 / sqrt(M), zeta =
 * C / (2 sqrt(K M)), and the sweep's response F / (K - M w^2 + i C w) at and off resonance. */
static void test_one_dof_modes(void **state) {
    (void)state;
    double m = 5.0, c = 1.0, k = 40000.0, f = 1.0;
    rths_assembly a;
    rths_modes modes;
    rths_error err;
    assert_int_equal(rths_assembly_from_matrices(1, &m, &c, &k, &a, &err), RTHS_OK);
    assert_int_equal(rths_modal_analysis(&a, &modes, &err), RTHS_OK);
    double w = sqrt(k / m);
    assert_close(modes.omega_rad_s[0], w, 1e-12 * w);
    assert_close(modes.frequency_hz[0], 14.2353, 1e-4); /* the truth, 14.24 Hz */
    assert_close(modes.shapes[0], 1 / sqrt(m), 1e-15);
    assert_close(modes.damping_ratio[0], c / (2 * sqrt(k * m)), 1e-15);
    int out_dof = 0;
    rths_frf_sweep *sw;
    assert_int_equal(rths_frf_sweep_create(&a, &modes, &f, 1, &out_dof, &sw, &err), RTHS_OK);
    double ws[3] = {0.0, w, 1.7 * w};
    for (int i = 0; i < 3; i++) {
        double complex x, expect = f / (k - m * ws[i] * ws[i] + I * c * ws[i]);
        assert_int_equal(rths_frf_sweep_eval(sw, ws[i], &x, &err), RTHS_OK);
        assert_close(creal(x), creal(expect), 1e-12 * cabs(expect));
        assert_close(cimag(x), cimag(expect), 1e-12 * cabs(expect));
    }
    rths_frf_sweep_destroy(sw);
    rths_modes_free(&modes);
    /* a mode beyond any analysed range (1e-300 kg: 5e151 Hz) is refused by name, not reported */
    double tiny = 1e-300;
    rths_assembly b;
    assert_int_equal(rths_assembly_from_matrices(1, &tiny, &c, &k, &b, &err), RTHS_OK);
    assert_int_equal(rths_modal_analysis(&b, &modes, &err), RTHS_EINPUT);
    if (!strstr(err.msg, "mode 1's natural frequency is")) fail_msg("%s", err.msg);
    rths_assembly_free(&b);
    rths_assembly_free(&a);
}

/* 2-DoF chain with equal m and k: w^2 = (k/m)(3 -+ sqrt 5)/2, shapes (1, (1+-sqrt5)/2)... and
 * the FRF by the explicit 2x2 inverse. */
static void test_two_dof_modes_and_frf(void **state) {
    (void)state;
    double ms[2] = {3.0, 3.0}, cs[2] = {0.0, 0.0}, ks[2] = {900.0, 900.0};
    rths_assembly a;
    rths_modes modes;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(2, ms, cs, ks, &a, &err), RTHS_OK);
    assert_int_equal(rths_modal_analysis(&a, &modes, &err), RTHS_OK);
    double base = ks[0] / ms[0];
    assert_close(modes.omega_rad_s[0], sqrt(base * (3 - sqrt(5)) / 2), 1e-12);
    assert_close(modes.omega_rad_s[1], sqrt(base * (3 + sqrt(5)) / 2), 1e-12);
    /* first mode: x2/x1 = (1 + sqrt5)/2 (golden ratio) */
    assert_close(modes.shapes[1] / modes.shapes[0], (1 + sqrt(5)) / 2, 1e-12);
    rths_modes_free(&modes);
    rths_assembly_free(&a);

    double cs2[2] = {1.5, 0.7};
    assert_int_equal(rths_assembly_from_chain(2, ms, cs2, ks, &a, &err), RTHS_OK);
    double f[2] = {0.0, 2.0};
    double complex x[2];
    for (double w = 3.0; w < 60.0; w *= 1.3) {
        assert_int_equal(rths_frf(2, a.mass, a.damping, a.stiffness, f, w, x, &err), RTHS_OK);
        double complex d11 = ks[0] + ks[1] - ms[0] * w * w + I * w * (cs2[0] + cs2[1]);
        double complex d12 = -ks[1] - I * w * cs2[1];
        double complex d22 = ks[1] - ms[1] * w * w + I * w * cs2[1];
        double complex det = d11 * d22 - d12 * d12;
        double complex x1 = -d12 * f[1] / det, x2 = d11 * f[1] / det;
        assert_close(cabs(x[0] - x1), 0.0, 1e-12 * cabs(x1));
        assert_close(cabs(x[1] - x2), 0.0, 1e-12 * cabs(x2));
    }
    rths_assembly_free(&a);
}

static void test_assembly_validation(void **state) {
    (void)state;
    rths_assembly a;
    rths_error err;
    double bad_m[2] = {1.0, -1.0}, c[2] = {0, 0}, k[2] = {1, 1};
    assert_int_equal(rths_assembly_from_chain(2, bad_m, c, k, &a, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "storey 2"));
    double m[4] = {1, 0, 0, 1}, ns[4] = {2, 1, 0, 2}, z[4] = {0};
    assert_int_equal(rths_assembly_from_matrices(2, m, z, ns, &a, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "stiffness matrix is not symmetric"));
    double indef[4] = {1, 2, 2, 1};
    assert_int_equal(rths_assembly_from_matrices(2, indef, z, z, &a, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "positive definite"));
    double nan_m[4] = {1, 0, 0, NAN};
    assert_int_equal(rths_assembly_from_matrices(2, nan_m, z, z, &a, &err), RTHS_EINPUT);
}

/* Random chains, random interface position and p: recombination must return the assembly, the
 * interface mass must divide as (1-p, p), and for a chain the leg below the interface is physical.
 */
static void test_split_recombine_random(void **state) {
    (void)state;
    rths_rng rng;
    rths_rng_seed(&rng, 12345);
    for (int trial = 0; trial < 200; trial++) {
        int n = 2 + (int)(rths_rng_uniform(&rng) * 7);
        double m[9], c[9], k[9];
        for (int i = 0; i < n; i++) {
            m[i] = 0.5 + 10 * rths_rng_uniform(&rng);
            c[i] = 10 * rths_rng_uniform(&rng);
            k[i] = 1e3 + 1e5 * rths_rng_uniform(&rng);
        }
        int s = (int)(rths_rng_uniform(&rng) * n); /* interface storey index */
        double p = 0.01 + 0.98 * rths_rng_uniform(&rng);
        rths_dof_role role[9];
        for (int i = 0; i < n; i++)
            role[i] =
                i < s ? RTHS_DOF_PHYSICAL : (i == s ? RTHS_DOF_INTERFACE : RTHS_DOF_NUMERICAL);
        rths_assembly a;
        rths_split sp;
        rths_error err;
        assert_int_equal(rths_assembly_from_chain(n, m, c, k, &a, &err), RTHS_OK);
        assert_int_equal(rths_split_create(&a, role, p, NULL, NULL, &sp, &err), RTHS_OK);
        assert_int_equal(sp.np, s + 1);
        assert_int_equal(sp.nn, n - s);
        double *rm = rths_mat_new(n, n), *rc = rths_mat_new(n, n), *rk = rths_mat_new(n, n);
        rths_split_recombine(&sp, rm, rc, rk);
        for (int i = 0; i < n * n; i++) {
            assert_close(rm[i], a.mass[i], 1e-12 * m[0] + 1e-12 * fabs(a.mass[i]));
            assert_close(rc[i], a.damping[i], 1e-12 * fabs(a.damping[i]) + 1e-15);
            assert_close(rk[i], a.stiffness[i], 1e-12 * fabs(a.stiffness[i]));
        }
        int ip = sp.np - 1; /* interface is last in the physical ordering, first in numerical */
        assert_close(RTHS_AT(sp.mass_num, sp.nn, 0, 0), p * m[s], 1e-12 * m[s]);
        assert_close(RTHS_AT(sp.mass_phys, sp.np, ip, ip), (1 - p) * m[s], 1e-12 * m[s]);
        assert_close(RTHS_AT(sp.stiffness_phys, sp.np, ip, ip), k[s], 1e-9 * k[s]);
        assert_close(RTHS_AT(sp.damping_phys, sp.np, ip, ip), c[s], 1e-9 * (c[s] + 1));
        if (s + 1 < n)
            assert_close(RTHS_AT(sp.stiffness_num, sp.nn, 0, 0), k[s + 1], 1e-9 * k[s + 1]);
        free(rm), free(rc), free(rk);
        rths_split_free(&sp);
        rths_assembly_free(&a);
    }
}

static void test_split_refuses_direct_coupling(void **state) {
    (void)state;
    rths_assembly a;
    rths_split sp;
    rths_error err;
    seed_assembly(&a);
    rths_dof_role role[4] = {RTHS_DOF_PHYSICAL, RTHS_DOF_NUMERICAL, RTHS_DOF_INTERFACE,
                             RTHS_DOF_NUMERICAL};
    assert_int_equal(rths_split_create(&a, role, 0.5, NULL, NULL, &sp, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "physical DoF 1 directly to numerical DoF 2"));
    rths_dof_role ok[4] = {RTHS_DOF_PHYSICAL, RTHS_DOF_PHYSICAL, RTHS_DOF_INTERFACE,
                           RTHS_DOF_NUMERICAL};
    assert_int_equal(rths_split_create(&a, ok, 1.0, NULL, NULL, &sp, &err), RTHS_EINPUT);
    assert_int_equal(rths_split_create(&a, ok, NAN, NULL, NULL, &sp, &err), RTHS_EINPUT);
    rths_assembly_free(&a);
}

/* e^{A} for a rotation generator [[0,-t],[t,0]] is [[cos t, -sin t],[sin t, cos t]]; large t
 * exercises scaling and squaring. */
static void test_expm_rotation(void **state) {
    (void)state;
    const double thetas[] = {1e-6, 0.3, 2.0, 17.0, 100.0};
    for (size_t q = 0; q < sizeof thetas / sizeof thetas[0]; q++) {
        double t = thetas[q];
        double a[4] = {0, t, -t, 0}, e[4];
        assert_int_equal(rths_expm(2, a, e), 0);
        /* error bound grows with the number of squarings ~ t * eps */
        double tol = 1e-14 * (1 + t);
        assert_close(e[0], cos(t), tol);
        assert_close(e[1], sin(t), tol);
        assert_close(e[2], -sin(t), tol);
        assert_close(e[3], cos(t), tol);
    }
    double nil[4] = {0, 0, 1, 0}, e[4];
    assert_int_equal(rths_expm(2, nil, e), 0);
    assert_close(e[0], 1, 1e-15);
    assert_close(e[1], 0, 1e-15);
    assert_close(e[2], 1, 1e-15);
    assert_close(e[3], 1, 1e-15);
}

/* Underdamped oscillator x'' + 2 z w x' + w^2 x = 0, state (x, v): closed-form e^{At}. */
static void oscillator_expm_closed_form(double w, double z, double t, double out[4]) {
    double wd = w * sqrt(1 - z * z), s = z * w, ex = exp(-s * t);
    double cw = cos(wd * t), sw = sin(wd * t);
    out[0] = ex * (cw + s / wd * sw); /* x from x0 */
    out[1] = ex * (-w * w / wd * sw); /* v from x0 */
    out[2] = ex * (sw / wd);          /* x from v0 */
    out[3] = ex * (cw - s / wd * sw); /* v from v0 */
}

static void test_expm_damped_oscillator(void **state) {
    (void)state;
    double w = 2 * M_PI * 13.47, z = 0.02;
    const double ts[] = {1e-4, 1e-2, 0.5, 3.0};
    for (size_t q = 0; q < 4; q++) {
        double t = ts[q];
        double a[4] = {0, -w * w * t, t, -2 * z * w * t}, e[4], ref[4];
        assert_int_equal(rths_expm(2, a, e), 0);
        oscillator_expm_closed_form(w, z, t, ref);
        /* relative to the largest entry, with a factor for the squarings (||A t|| up to ~1e4) */
        double scale = fabs(ref[1]) + 1;
        for (int i = 0; i < 4; i++)
            assert_close(e[i], ref[i], 1e-11 * scale * (1 + w * t));
    }
}

/* H(z) = (zI - Ad)^{-1}(b_prev + z b_curr) for the scalar x' = -a x + u. */
static double complex discrete_tf_scalar(const rths_discrete *d, double complex zz) {
    return (d->b_prev[0] + zz * d->b_curr[0]) / (zz - d->ad[0]);
}

static void test_discretisation_scalar_transfer_functions(void **state) {
    (void)state;
    double a = 37.0, h = 1e-3;
    double am = -a, bm = 1.0;
    rths_error err;
    for (int s = 0; s < RTHS_SCHEME_COUNT; s++) {
        rths_discrete d;
        assert_int_equal(rths_discretise(1, 1, &am, &bm, h, (rths_scheme)s, &d, &err), RTHS_OK);
        for (double w = 1.0; w < 3000.0; w *= 2.1) {
            double complex zz = cexp(I * w * h), expect;
            switch (s) {
            case RTHS_SCHEME_IMPLICIT_EULER:
                expect = 1.0 / ((zz - 1) / (h * zz) + a);
                break;
            case RTHS_SCHEME_TRAPEZOIDAL:
                expect = 1.0 / (2.0 / h * (zz - 1) / (zz + 1) + a);
                break;
            case RTHS_SCHEME_EXACT_ZOH:
                expect = (1 - exp(-a * h)) / a / (zz - exp(-a * h));
                break;
            default: /* triangle hold: (z-1)^2/(z h) Z[G(s)/s^2] */
                expect = 1.0 / a - (zz - 1) / (a * a * h) +
                         (zz - 1) * (zz - 1) / (a * a * h * (zz - exp(-a * h)));
            }
            double complex got = discrete_tf_scalar(&d, zz);
            assert_close(cabs(got - expect), 0.0, 1e-10 * cabs(expect));
        }
        rths_discrete_free(&d);
    }
}

/* Oscillator: implicit Euler and trapezoid against their s-substitutions of the continuous
 * transfer function; exact ZOH against the closed-form Phi. */
static void test_discretisation_oscillator(void **state) {
    (void)state;
    double m = 5.37, c = 3.7, k = 45052, h = 1e-4;
    double *A, *B;
    rths_error err;
    double in = 1.0;
    assert_int_equal(rths_state_space(1, &m, &c, &k, 1, &in, &A, &B, &err), RTHS_OK);
    assert_close(A[1], -k / m, 1e-9);
    assert_close(B[1], 1 / m, 1e-15);
    double w0 = sqrt(k / m), z = c / (2 * sqrt(k * m));
    for (int s = 0; s < RTHS_SCHEME_COUNT; s++) {
        rths_discrete d;
        assert_int_equal(rths_discretise(2, 1, A, B, h, (rths_scheme)s, &d, &err), RTHS_OK);
        if (s == RTHS_SCHEME_EXACT_ZOH || s == RTHS_SCHEME_EXACT_FOH) {
            double ref[4];
            oscillator_expm_closed_form(w0, z, h, ref);
            for (int i = 0; i < 4; i++)
                assert_close(d.ad[i], ref[i], 1e-12 * (1 + fabs(ref[i])));
        }
        for (double w = 10; w < 3000; w *= 1.9) {
            double complex zz = cexp(I * w * h), sv;
            /* position output: H(z) = e1^T (zI - Ad)^{-1} (b_prev + z b_curr) via 2x2 inverse */
            double complex r0 = d.b_prev[0] + zz * d.b_curr[0], r1 = d.b_prev[1] + zz * d.b_curr[1];
            double complex m00 = zz - d.ad[0], m10 = -d.ad[1], m01 = -d.ad[2], m11 = zz - d.ad[3];
            double complex det = m00 * m11 - m01 * m10;
            double complex got = (m11 * r0 - m01 * r1) / det;
            if (s == RTHS_SCHEME_IMPLICIT_EULER)
                sv = (zz - 1) / (h * zz);
            else if (s == RTHS_SCHEME_TRAPEZOIDAL)
                sv = 2 / h * (zz - 1) / (zz + 1);
            else {
                /* Well below resonance the exact schemes' only error is the hold's: the ZOH lags
                 * by half a sample (|e^{-iwh/2} - 1| ~ wh/2); the triangle hold's gain is
                 * sinc^2(wh/2) ~ 1 - (wh)^2/12. Both leading terms checked to 10 %. */
                double complex cont = 1.0 / (k - m * w * w + I * c * w);
                double expect_err = s == RTHS_SCHEME_EXACT_ZOH ? w * h / 2 : pow(w * h, 2) / 12;
                if (w < 2 * M_PI * 10)
                    assert_close(cabs(got / cont - 1), expect_err, 0.1 * expect_err);
                continue;
            }
            double complex expect = 1.0 / (m * sv * sv + c * sv + k);
            assert_close(cabs(got - expect), 0.0, 1e-9 * cabs(expect));
        }
        rths_discrete_free(&d);
    }
    free(A), free(B);
}

/* Hermitian eigenvalue ratio: [[2, i], [-i, 2]] has eigenvalues 1 and 3; a rank-one matrix has
 * ratio 0 (to rounding). */
static void test_hermitian_eigen_ratio(void **state) {
    (void)state;
    double complex a[4] = {2, -I, I, 2}; /* column-major: a(1,0) = -i, a(0,1) = i */
    assert_close(rths_cmat_hermitian_eigen_ratio(2, a), 1.0 / 3.0, 1e-14);
    double complex v[2] = {1, 2 * I}, r1[4];
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++)
            r1[i + 2 * j] = v[i] * conj(v[j]);
    assert_true(fabs(rths_cmat_hermitian_eigen_ratio(2, r1)) < 1e-15);
}

static void test_scheme_names(void **state) {
    (void)state;
    rths_scheme s;
    for (int i = 0; i < RTHS_SCHEME_COUNT; i++) {
        assert_int_equal(rths_scheme_parse(rths_scheme_name((rths_scheme)i), &s), 0);
        assert_int_equal(s, i);
    }
    assert_int_equal(rths_scheme_parse("euler", &s), -1);
    assert_int_equal(RTHS_SCHEME_DEFAULT, RTHS_SCHEME_EXACT_FOH);
}

/* Uniform fixed-free chain of n storeys (mass m, legs k, c): its natural frequencies in closed
 * form, w_r = 2 sqrt(k / m) sin((2r - 1) pi / (2 (2n + 1))), r = 1..n. */
static void uniform_chain(int n, double m, double c, double k, rths_assembly *a) {
    double *mv = malloc((size_t)n * sizeof *mv), *cv = malloc((size_t)n * sizeof *cv),
           *kv = malloc((size_t)n * sizeof *kv);
    for (int i = 0; i < n; i++)
        mv[i] = m, cv[i] = c, kv[i] = k;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(n, mv, cv, kv, a, &err), RTHS_OK);
    free(mv), free(cv), free(kv);
}

/* The modal analysis (dsbgvd for the banded chain, dsygvd once a spring joins its ends) against
 * the closed form (chain only) (1e-10 relative: eigenvalues of a symmetric-definite pencil
 * are accurate to ~n eps times the condition of M, here 1) and against LAPACK's dense dsygv,
 * the reference of `rths model` at any size (1e-8 relative, the acceptance bound). */
static void test_modes_large_chain(void **state) {
    (void)state;
    const int n = 300;
    const double m = 2.0, k = 1e4;
    rths_assembly a;
    uniform_chain(n, m, 0.1, k, &a);
    for (int pass = 0; pass < 2; pass++) {
        /* pass 1: a spring from the first storey to the last takes the band away (dsygvd) */
        if (pass == 1) {
            RTHS_AT(a.stiffness, n, 0, 0) += k, RTHS_AT(a.stiffness, n, n - 1, n - 1) += k;
            RTHS_AT(a.stiffness, n, 0, n - 1) -= k, RTHS_AT(a.stiffness, n, n - 1, 0) -= k;
        }
        rths_modes modes;
        rths_error err;
        assert_int_equal(rths_modal_analysis(&a, &modes, &err), RTHS_OK);
        double *kk = rths_mat_dup(a.stiffness, n, n), *mm = rths_mat_dup(a.mass, n, n);
        double *w2 = malloc((size_t)n * sizeof *w2);
        assert_int_equal(LAPACKE_dsygv(LAPACK_COL_MAJOR, 1, 'N', 'L', n, kk, n, mm, n, w2), 0);
        for (int r = 0; r < n; r++) {
            if (pass == 0) {
                double exact = 2 * sqrt(k / m) * sin((2 * r + 1) * M_PI / (2.0 * (2 * n + 1)));
                assert_rel(modes.omega_rad_s[r], exact, 1e-10);
            }
            assert_rel(modes.omega_rad_s[r] * modes.omega_rad_s[r], w2[r], 1e-8);
        }
        free(kk), free(mm), free(w2);
        rths_modes_free(&modes);
    }
    rths_assembly_free(&a);
}

/* Every FRF path of the sweep against the dense complex solve (rths_frf) over a grid through
 * every resonance: banded LU (a long chain with non-proportional damping), modal superposition
 * (Rayleigh damping, no band), complex modes (no band; the seed), dense (a critically damped
 * oscillator, whose state matrix is defective). Tolerance 1e-9 of the largest response: each path
 * is exact, rounding grows with the condition of the complex eigenvectors, measured <= 1e-12. */
static double sweep_error(const rths_assembly *a, const double *force, rths_frf_method expect) {
    int n = a->n;
    rths_modes modes;
    rths_error err;
    assert_int_equal(rths_modal_analysis(a, &modes, &err), RTHS_OK);
    int *dofs = malloc((size_t)n * sizeof *dofs);
    for (int i = 0; i < n; i++)
        dofs[i] = i;
    rths_frf_sweep *sw;
    if (rths_frf_sweep_create(a, &modes, force, n, dofs, &sw, &err)) fail_msg("%s", err.msg);
    assert_int_equal(rths_frf_sweep_method(sw), expect);
    double complex *x = malloc((size_t)n * sizeof *x), *y = malloc((size_t)n * sizeof *y);
    double worst = 0, size = 0;
    for (int r = 0; r < n && r < 12; r++)
        for (int j = -3; j <= 3; j++) {
            double w = modes.omega_rad_s[r] * (1 + 0.002 * j) + 0.1;
            assert_int_equal(rths_frf_sweep_eval(sw, w, x, &err), RTHS_OK);
            assert_int_equal(rths_frf(n, a->mass, a->damping, a->stiffness, force, w, y, &err),
                             RTHS_OK);
            for (int i = 0; i < n; i++) {
                worst = fmax(worst, cabs(x[i] - y[i]));
                size = fmax(size, cabs(y[i]));
            }
        }
    print_message("%s, %d DoFs: max |sweep - dense| = %.2e of %.2e\n", rths_frf_method_name(expect),
                  n, worst, size);
    free(x), free(y), free(dofs);
    rths_frf_sweep_destroy(sw);
    rths_modes_free(&modes);
    return worst / size;
}

static void test_frf_sweep_paths(void **state) {
    (void)state;
    /* non-proportional: one leg ten times as damped as the others (banded, 40 DoFs) */
    rths_assembly a;
    uniform_chain(40, 3.0, 0.0, 2e4, &a);
    for (int i = 0; i < 40 * 40; i++)
        a.damping[i] = 1e-4 * a.stiffness[i];
    RTHS_AT(a.damping, 40, 0, 0) += 2.0;
    double f[80] = {0};
    f[39] = 1.0;
    assert_true(sweep_error(&a, f, RTHS_FRF_BANDED) < 1e-9);
    /* a spring and dashpot from the first storey to the last: no band, complex modes over a
     * frequency spread of 50 */
    RTHS_AT(a.stiffness, 40, 0, 0) += 5e3, RTHS_AT(a.stiffness, 40, 39, 39) += 5e3;
    RTHS_AT(a.stiffness, 40, 0, 39) -= 5e3, RTHS_AT(a.stiffness, 40, 39, 0) -= 5e3;
    RTHS_AT(a.damping, 40, 0, 0) += 1.0, RTHS_AT(a.damping, 40, 39, 39) += 1.0;
    RTHS_AT(a.damping, 40, 0, 39) -= 1.0, RTHS_AT(a.damping, 40, 39, 0) -= 1.0;
    assert_true(sweep_error(&a, f, RTHS_FRF_STATE_SPACE) < 1e-9);
    /* the same unbanded model with Rayleigh damping C = 0.5 M + 1e-4 K: modal superposition */
    for (int i = 0; i < 40 * 40; i++)
        a.damping[i] = 0.5 * a.mass[i] + 1e-4 * a.stiffness[i];
    assert_true(sweep_error(&a, f, RTHS_FRF_MODAL) < 1e-9);
    rths_assembly_free(&a);
    /* the seed: 4 DoFs, nearly but not exactly proportional */
    seed_assembly(&a);
    double f4[4] = {0, 0, 0, 1};
    assert_true(sweep_error(&a, f4, RTHS_FRF_STATE_SPACE) < 1e-9);
    rths_assembly_free(&a);
    /* 2 DoFs with C whose modal form couples the modes and makes mode 1 critically damped
     * (defective eigenvalue): the complex modes are not trusted, the sweep solves densely */
    double m2[4] = {1, 0, 0, 1}, k2[4] = {2, -1, -1, 2};
    /* modes (1, 1)/sqrt2 at w = 1 and (1, -1)/sqrt2 at sqrt3; C = 2 phi1 phi1^T gives c~11 = 2 */
    double c2[4] = {1, 1, 1, 1};
    rths_error err;
    assert_int_equal(rths_assembly_from_matrices(2, m2, c2, k2, &a, &err), RTHS_OK);
    double f2[2] = {1, 0};
    assert_true(sweep_error(&a, f2, RTHS_FRF_DENSE) < 1e-9);
    rths_assembly_free(&a);
}

/* One p per interface DoF: storeys 2 and 3 of the seed at p = 0.25 and 0.75 put 0.25 and 0.75 of
 * their 5.37 kg on the numerical side; a list of the wrong length is refused. */
static void test_split_mass_ratio_per_dof(void **state) {
    (void)state;
    rths_assembly a;
    seed_assembly(&a);
    rths_dof_role role[4] = {RTHS_DOF_PHYSICAL, RTHS_DOF_INTERFACE, RTHS_DOF_INTERFACE,
                             RTHS_DOF_NUMERICAL};
    const double p[2] = {0.25, 0.75};
    rths_split s;
    rths_error err;
    assert_int_equal(rths_split_create_ratios(&a, role, 2, p, NULL, NULL, &s, &err), RTHS_OK);
    assert_close(RTHS_AT(s.mass_num, s.nn, 0, 0), 0.25 * 5.37, 1e-15);
    assert_close(RTHS_AT(s.mass_num, s.nn, 1, 1), 0.75 * 5.37, 1e-15);
    assert_close(RTHS_AT(s.mass_phys, s.np, 1, 1), 0.75 * 5.37, 1e-15);
    assert_close(RTHS_AT(s.mass_phys, s.np, 2, 2), 0.25 * 5.37, 1e-15);
    assert_close(s.mass_ratio, 0.25, 0);
    rths_split_free(&s);
    const double three[3] = {0.5, 0.5, 0.5};
    assert_int_equal(rths_split_create_ratios(&a, role, 3, three, NULL, NULL, &s, &err),
                     RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "3 mass ratios for 2 interface DoFs"));
    rths_assembly_free(&a);
}

/* The spectral radius of [[a, -b], [b, a]] is hypot(a, b); of a Jordan block its eigenvalue. */
static void test_spectral_radius(void **state) {
    (void)state;
    const double rot[4] = {0.6, 0.8, -0.8, 0.6}, jordan[4] = {0.9, 0, 1e3, 0.9};
    assert_close(rths_spectral_radius(2, rot), 1.0, 1e-15);
    assert_close(rths_spectral_radius(2, jordan), 0.9, 1e-12);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_modes_large_chain),
        cmocka_unit_test(test_frf_sweep_paths),
        cmocka_unit_test(test_seed_natural_frequencies),
        cmocka_unit_test(test_seed_storey3_peak),
        cmocka_unit_test(test_one_dof_frf),
        cmocka_unit_test(test_one_dof_modes),
        cmocka_unit_test(test_two_dof_modes_and_frf),
        cmocka_unit_test(test_assembly_validation),
        cmocka_unit_test(test_split_recombine_random),
        cmocka_unit_test(test_split_refuses_direct_coupling),
        cmocka_unit_test(test_expm_rotation),
        cmocka_unit_test(test_expm_damped_oscillator),
        cmocka_unit_test(test_discretisation_scalar_transfer_functions),
        cmocka_unit_test(test_discretisation_oscillator),
        cmocka_unit_test(test_scheme_names),
        cmocka_unit_test(test_hermitian_eigen_ratio),
        cmocka_unit_test(test_split_mass_ratio_per_dof),
        cmocka_unit_test(test_spectral_radius),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
