/* Euler-Bernoulli beam assembly against closed forms: cantilever and simply supported natural
 * frequencies (with the h^4 mesh convergence of cubic Hermite elements), the static tip
 * deflection (exact at the nodes for cubic elements, also across segments of different EI), a
 * tip mass (frequency equation and the Rayleigh quotient of the static shape), free-free rigid
 * modes, modal and Rayleigh damping read back from the damped system's complex eigenvalues, the
 * DoF map, the YAML reader and its located refusals, and the steel strip of the two-shaker
 * follow-up (Vizzaccaro, Beregi, Barton, Neild, arXiv 2406.08060). */
#include "testlib.h"

#include "rths/beam.h"

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* beta_r L of a clamped-free uniform beam, the roots of 1 + cos x cosh x = 0, to 10 digits;
 * cantilever_beta_l() refines them by bisection so the closed form carries no 1e-9 floor. */
static const double cantilever_beta_l_10[3] = {1.875104069, 4.694091133, 7.854757438};

static double bisect_root(double (*g)(double), double lo, double hi) {
    for (int i = 0; i < 200; i++) {
        double mid = 0.5 * (lo + hi);
        if ((g(mid) > 0) == (g(lo) > 0))
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* divided by cosh x so it stays O(1) near the roots of the higher modes */
static double clamped_free(double x) {
    return 1 / cosh(x) + cos(x);
}

static double cantilever_beta_l(int r) {
    double x =
        bisect_root(clamped_free, cantilever_beta_l_10[r] - 1e-3, cantilever_beta_l_10[r] + 1e-3);
    assert_close(x, cantilever_beta_l_10[r], 1e-9);
    return x;
}

/* An arbitrary, not nondimensional, beam so unit slips show */
#define EI 2.5  /* N m^2 */
#define MU 0.8  /* kg/m */
#define LEN 0.9 /* m */

static void uniform(int elements, const double *clamped, int n_clamped, const double *pinned,
                    int n_pinned, rths_beam *b) {
    rths_beam_segment seg = {LEN, elements, EI, MU};
    rths_beam_spec spec = {.n_segments = 1,
                           .segments = &seg,
                           .n_clamped = n_clamped,
                           .clamped_m = clamped,
                           .n_pinned = n_pinned,
                           .pinned_m = pinned};
    rths_error err;
    int rc = rths_beam_assemble(&spec, b, &err);
    if (rc) fail_msg("%s", err.msg);
}

/* undamped natural circular frequencies, ascending (n of them, malloc'ed) */
static double *omegas(const rths_beam *b) {
    rths_assembly a = {b->n, b->mass, b->damping, b->stiffness};
    rths_modes m;
    rths_error err;
    if (rths_modal_analysis(&a, &m, &err)) fail_msg("%s", err.msg);
    double *w = malloc((size_t)b->n * sizeof *w);
    memcpy(w, m.omega_rad_s, (size_t)b->n * sizeof *w);
    rths_modes_free(&m);
    return w;
}

static double cantilever_omega(int r) {
    double bl = cantilever_beta_l(r);
    return bl * bl * sqrt(EI / (MU * pow(LEN, 4)));
}

/* Cubic Hermite elements with consistent mass converge at h^4 in frequency, from above (a
 * Rayleigh-Ritz bound). The uniform mesh's dispersion relation, expanded in beta h, gives the
 * leading relative error (beta h)^4 / 1440 (h the element length, beta = omega^(1/2) (m/EI)^(1/4));
 * the measured errors approach it from below (0.75 of it at beta h ~ 2, 0.94 at beta h ~ 1, 1.00
 * for the simply supported beam whose nodal shapes are exact). So every comparison below asserts
 * -1e-8 <= error <= 1.05 (beta h)^4 / 1440 + 1e-8, and halving h must divide the error by 12..17
 * (16 in the limit, less while the h^6 term still shows). The 1e-8 is dsygv's rounding on the
 * lowest mode of a fine mesh (its absolute eigenvalue error scales with the highest mode):
 * measured -2.2e-9 on the 53-element strip below. Ratios are read where the finer mesh's error
 * exceeds 2e-7, so that rounding moves them by 5 % at most. */
#define ROUNDING 1e-8

static double h4_bound(double beta_l, double length_m, int elements) {
    return 1.05 * pow(beta_l * (length_m / elements) / length_m, 4) / 1440 + ROUNDING;
}

static void test_cantilever_convergence(void **state) {
    (void)state;
    const double x0 = 0;
    const int meshes[4] = {4, 8, 16, 32};
    double prev[3] = {0, 0, 0};
    for (int k = 0; k < 4; k++) {
        rths_beam b;
        uniform(meshes[k], &x0, 1, NULL, 0, &b);
        assert_int_equal(b.n, 2 * meshes[k]);
        double *w = omegas(&b);
        for (int r = 0; r < 3; r++) {
            double exact = cantilever_omega(r), e = (w[r] - exact) / exact;
            double bound = h4_bound(cantilever_beta_l(r), LEN, meshes[k]);
            printf("cantilever %2d elements, mode %d: %.9f rad/s (exact %.9f), error %.3e, "
                   "(beta h)^4/1440 %.3e\n",
                   meshes[k], r + 1, w[r], exact, e, (bound - ROUNDING) / 1.05);
            assert_true(e >= -ROUNDING && e <= bound);
            if (k > 0 && e > 2e-7) {
                double ratio = prev[r] / e;
                printf("  error ratio %d -> %d elements: %.2f\n", meshes[k - 1], meshes[k], ratio);
                assert_true(ratio > 12 && ratio < 17);
            }
            prev[r] = e;
        }
        free(w);
        rths_beam_free(&b);
    }
}

/* Pinned-pinned: omega_r = (r pi / L)^2 sqrt(EI / m), within the h^4 bound above. */
static void test_simply_supported(void **state) {
    (void)state;
    const double pins[2] = {0, LEN};
    rths_beam b;
    uniform(32, NULL, 0, pins, 2, &b);
    assert_int_equal(b.n, 2 * 33 - 2);
    double *w = omegas(&b);
    for (int r = 0; r < 3; r++) {
        double exact = pow((r + 1) * M_PI / LEN, 2) * sqrt(EI / MU);
        printf("simply supported mode %d: %.9f rad/s (exact %.9f)\n", r + 1, w[r], exact);
        double e = w[r] / exact - 1;
        assert_true(e >= -ROUNDING && e <= h4_bound((r + 1) * M_PI, LEN, 32));
    }
    free(w);
    rths_beam_free(&b);
}

/* K q = P e_tip. Cubic elements hold the exact solution of EI w'''' = 0 between nodes, so the
 * nodal values are exact (to rounding, 1e-12 relative): P L^3 / (3 EI) for a uniform cantilever,
 * and by the unit-load method, for EI1 on [0, a] and EI2 on [a, L],
 *   w(L) = P/EI1 (L^3 - (L-a)^3)/3 + P/EI2 (L-a)^3/3,  theta(L) = P/EI1 (L^2 - (L-a)^2)/2 +
 *   P/EI2 (L-a)^2/2. */
static void tip_load(const rths_beam *b, double p_n, double *w, double *theta) {
    int n = b->n, iw = rths_beam_find_dof(b, b->length_m, RTHS_BEAM_W),
        it = rths_beam_find_dof(b, b->length_m, RTHS_BEAM_THETA);
    assert_true(iw >= 0 && it >= 0);
    double *k = rths_mat_dup(b->stiffness, n, n), *f = rths_mat_new(n, 1);
    f[iw] = p_n;
    assert_int_equal(rths_mat_solve(n, 1, k, f), 0);
    *w = f[iw];
    *theta = f[it];
    rths_mat_free(k);
    rths_mat_free(f);
}

static void test_static_tip_deflection(void **state) {
    (void)state;
    const double x0 = 0, p = 3.0;
    rths_beam b;
    double w, th;
    uniform(5, &x0, 1, NULL, 0, &b);
    tip_load(&b, p, &w, &th);
    assert_rel(w, p * pow(LEN, 3) / (3 * EI), 1e-12);
    assert_rel(th, p * LEN * LEN / (2 * EI), 1e-12);
    rths_beam_free(&b);
    /* two segments: a = 0.3 m stiff (EI 7, one element), 0.6 m soft (EI 2, three elements) */
    const double a = 0.3, l2 = 0.6, ei1 = 7, ei2 = 2, l = a + l2;
    rths_beam_segment segs[2] = {{a, 1, ei1, MU}, {l2, 3, ei2, 2 * MU}};
    rths_beam_spec spec = {.n_segments = 2, .segments = segs, .n_clamped = 1, .clamped_m = &x0};
    rths_error err;
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_OK);
    tip_load(&b, p, &w, &th);
    double we = p / ei1 * (pow(l, 3) - pow(l2, 3)) / 3 + p / ei2 * pow(l2, 3) / 3;
    double te = p / ei1 * (l * l - l2 * l2) / 2 + p / ei2 * l2 * l2 / 2;
    assert_rel(w, we, 1e-12);
    assert_rel(th, te, 1e-12);
    rths_beam_free(&b);
}

/* A tip mass M_t on a cantilever: x = beta L solves 1 + cos x cosh x + (M_t / (m L)) x (cos x
 * sinh x - sin x cosh x) = 0 (the clamped-free beam's boundary value problem with the tip mass's
 * inertia in the shear condition; e.g. Blevins, "Formulas for natural frequency and mode shape").
 */
static double tip_mass_beta_l(double ratio) {
    double lo = 0.1, hi = cantilever_beta_l(0);
    for (int i = 0; i < 200; i++) {
        double x = 0.5 * (lo + hi);
        double g = 1 + cos(x) * cosh(x) + ratio * x * (cos(x) * sinh(x) - sin(x) * cosh(x));
        if (g > 0)
            lo = x;
        else
            hi = x;
    }
    return 0.5 * (lo + hi);
}

static void test_tip_mass_and_rayleigh_quotient(void **state) {
    (void)state;
    const double x0 = 0, tip = 0.5 * MU * LEN, inertia = 1e-4;
    rths_beam_segment seg = {LEN, 20, EI, MU};
    rths_beam_point_mass pm = {LEN, tip, 0};
    rths_beam_spec spec = {.n_segments = 1,
                           .segments = &seg,
                           .n_clamped = 1,
                           .clamped_m = &x0,
                           .n_point_masses = 1,
                           .point_masses = &pm};
    rths_beam b;
    rths_error err;
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_OK);
    double *w = omegas(&b), x = tip_mass_beta_l(tip / (MU * LEN));
    double exact = x * x * sqrt(EI / (MU * pow(LEN, 4)));
    printf("tip mass %.3g kg: %.9f rad/s, frequency equation %.9f\n", tip, w[0], exact);
    /* 20 elements: (beta h)^4 / 1440 = 2e-8 for mode 1 (beta L = 1.42); bisection to 1e-15 */
    assert_rel(w[0], exact, 1e-7);
    /* The static tip-load shape is a cubic, so the elements hold it exactly and its Rayleigh
     * quotient from M and K is the analytic one, 3 EI / L^3 / (M_t + 33/140 m L), to rounding:
     * the solve with K (condition ~ (L/h)^4 ~ 1e6) leaves ~1e-10, so 1e-9. */
    int n = b.n;
    double *k = rths_mat_dup(b.stiffness, n, n), *q = rths_mat_new(n, 1), *t = rths_mat_new(n, 1);
    q[rths_beam_find_dof(&b, LEN, RTHS_BEAM_W)] = 1.0;
    assert_int_equal(rths_mat_solve(n, 1, k, q), 0);
    double qkq, qmq;
    rths_mat_mul(n, 1, n, 1.0, b.stiffness, 0, q, 0, 0.0, t);
    rths_mat_mul(1, 1, n, 1.0, q, 1, t, 0, 0.0, &qkq);
    rths_mat_mul(n, 1, n, 1.0, b.mass, 0, q, 0, 0.0, t);
    rths_mat_mul(1, 1, n, 1.0, q, 1, t, 0, 0.0, &qmq);
    double rq = 3 * EI / pow(LEN, 3) / (tip + 33.0 / 140.0 * MU * LEN);
    assert_rel(qkq / qmq, rq, 1e-9);
    /* and, as a Rayleigh quotient, an upper bound on omega_1^2, close for a heavy tip (1 %) */
    printf("  Rayleigh estimate %.6f rad/s (%.3f %% above)\n", sqrt(rq),
           100 * (sqrt(rq) / exact - 1));
    assert_true(rq > exact * exact && sqrt(rq) < 1.01 * exact);
    free(w);
    rths_mat_free(k);
    rths_mat_free(q);
    rths_mat_free(t);
    rths_beam_free(&b);
    /* a rotary inertia lands on the tip's theta diagonal only */
    pm.rotary_inertia_kg_m2 = inertia;
    rths_beam c;
    assert_int_equal(rths_beam_assemble(&spec, &c, &err), RTHS_OK);
    pm.rotary_inertia_kg_m2 = 0;
    rths_beam d;
    assert_int_equal(rths_beam_assemble(&spec, &d, &err), RTHS_OK);
    int it = rths_beam_find_dof(&c, LEN, RTHS_BEAM_THETA), iw = rths_beam_find_dof(&c, LEN, 0);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double diff = RTHS_AT(c.mass, n, i, j) - RTHS_AT(d.mass, n, i, j);
            assert_close(diff, (i == it && j == it) ? inertia : 0.0, 1e-15);
        }
    /* and the tip's own w diagonal: consistent 156 m l / 420 plus the point mass */
    double h = LEN / 20;
    assert_rel(RTHS_AT(d.mass, n, iw, iw), 156 * MU * h / 420 + tip, 1e-14);
    rths_beam_free(&c);
    rths_beam_free(&d);
}

/* Unsupported: rigid translation and rotation are two zero eigenvalues (K's null space is exactly
 * {1, x} at the nodes), the first elastic mode at beta L = 4.730040745 (1 + ... cos x cosh x = 1).
 */
static double free_free(double x) {
    return 1 / cosh(x) - cos(x);
}

static void test_free_free(void **state) {
    (void)state;
    rths_beam b;
    uniform(32, NULL, 0, NULL, 0, &b);
    double *w = omegas(&b);
    double bl = bisect_root(free_free, 4.7, 4.76);
    assert_close(bl, 4.730040745, 1e-9);
    double elastic = bl * bl * sqrt(EI / (MU * pow(LEN, 4)));
    printf("free-free: %.3e %.3e rad/s (rigid), first elastic %.9f (exact %.9f)\n", w[0], w[1],
           w[2], elastic);
    /* rounding of dsygv on K ~ EI/h^3: eigenvalue errors ~ 1e-16 * omega_max^2 ~ 1e-6 rad^2/s^2,
     * i.e. omega below 1e-2 rad/s against 22 rad/s for the first elastic mode */
    assert_true(w[0] < 1e-2 && w[1] < 1e-2);
    assert_true(w[2] >= elastic * (1 - ROUNDING) && w[2] <= elastic * (1 + h4_bound(bl, LEN, 32)));
    /* K times the rigid motions is zero to rounding */
    int n = b.n;
    double *q = rths_mat_new(n, 2), *kq = rths_mat_new(n, 2);
    for (int i = 0; i < n; i++) {
        q[i] = b.dofs[i].kind == RTHS_BEAM_W ? 1.0 : 0.0;
        q[n + i] = b.dofs[i].kind == RTHS_BEAM_W ? b.dofs[i].position_m : 1.0;
    }
    rths_mat_mul(n, 2, n, 1.0, b.stiffness, 0, q, 0, 0.0, kq);
    assert_true(rths_mat_max_abs(kq, n, 2) < 1e-9 * rths_mat_max_abs(b.stiffness, n, n));
    free(w);
    rths_mat_free(q);
    rths_mat_free(kq);
    rths_beam_free(&b);
}

/* Eigenvalues of the first-order system x' = [0 I; -M^-1 K  -M^-1 C] x, those with Im > 0,
 * sorted by modulus: lambda = -zeta omega + i omega sqrt(1 - zeta^2), so omega = |lambda| and
 * zeta = -Re lambda / |lambda|. */
static int damped_modes(const rths_beam *b, double *omega, double *zeta) {
    int n = b->n, n2 = 2 * n;
    double *a, *bu, *input = rths_mat_new(n, 1);
    rths_error err;
    assert_int_equal(
        rths_state_space(n, b->mass, b->damping, b->stiffness, 1, input, &a, &bu, &err), RTHS_OK);
    rths_mat_free(input);
    double *wr = malloc((size_t)n2 * sizeof *wr), *wi = malloc((size_t)n2 * sizeof *wi);
    assert_int_equal(LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', n2, a, n2, wr, wi, NULL, 1, NULL, 1),
                     0);
    int count = 0;
    for (int k = 0; k < n2; k++)
        if (wi[k] > 0) {
            omega[count] = hypot(wr[k], wi[k]);
            zeta[count] = -wr[k] / omega[count];
            count++;
        }
    for (int i = 1; i < count; i++) /* insertion sort by omega */
        for (int j = i; j > 0 && omega[j] < omega[j - 1]; j--) {
            double t = omega[j];
            omega[j] = omega[j - 1], omega[j - 1] = t;
            t = zeta[j];
            zeta[j] = zeta[j - 1], zeta[j - 1] = t;
        }
    free(a);
    free(bu);
    free(wr);
    free(wi);
    return count;
}

/* Modal damping: every mode has exactly its requested ratio and keeps its undamped frequency as
 * |lambda|. The tolerance is dgeev's: eigenvalue error ~ 1e-16 ||A|| with ||A|| ~ omega_max^2
 * ~ 1e7 here, against |lambda| >= 4 rad/s: 1e-9 relative, 1e-9 in zeta. */
static void test_modal_damping(void **state) {
    (void)state;
    const double x0 = 0, ratios[3] = {0.011, 0.02, 0.05}, rest = 0.03;
    rths_beam_segment seg = {LEN, 6, EI, MU};
    rths_beam_spec spec = {.n_segments = 1, .segments = &seg, .n_clamped = 1, .clamped_m = &x0};
    spec.damping = (rths_beam_damping){RTHS_BEAM_DAMPING_MODAL, 3, ratios, rest, 0, 0};
    rths_beam b;
    rths_error err;
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_OK);
    int n = b.n;
    assert_true(rths_mat_is_symmetric(b.damping, n, 0));
    double *w = omegas(&b), *om = malloc((size_t)n * sizeof *om), *ze = malloc((size_t)n * 8);
    assert_int_equal(damped_modes(&b, om, ze), n);
    for (int r = 0; r < n; r++) {
        double want = r < 3 ? ratios[r] : rest;
        if (r < 4) printf("modal damping mode %d: zeta %.12f (asked %.3f)\n", r + 1, ze[r], want);
        assert_close(ze[r], want, 1e-9);
        assert_rel(om[r], w[r], 1e-9);
    }
    free(w);
    free(om);
    free(ze);
    rths_beam_free(&b);
    /* one ratio for all, 1.1 % (the follow-up's) */
    spec.damping = (rths_beam_damping){RTHS_BEAM_DAMPING_MODAL, 0, NULL, 0.011, 0, 0};
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_OK);
    om = malloc((size_t)b.n * sizeof *om), ze = malloc((size_t)b.n * sizeof *ze);
    assert_int_equal(damped_modes(&b, om, ze), b.n);
    for (int r = 0; r < b.n; r++)
        assert_close(ze[r], 0.011, 1e-9);
    free(om);
    free(ze);
    rths_beam_free(&b);
}

/* Rayleigh from two pairs placed on modes 1 and 3: those two modes get exactly their ratios (the
 * damping is proportional, so the modes stay real), mode 2 gets alpha/(2 w2) + beta w2/2. */
static void test_rayleigh_damping(void **state) {
    (void)state;
    const double x0 = 0;
    rths_beam b;
    uniform(6, &x0, 1, NULL, 0, &b);
    double *w = omegas(&b);
    rths_beam_free(&b);
    double alpha, beta;
    rths_error err;
    assert_int_equal(rths_beam_rayleigh_from_pairs(w[0] / (2 * M_PI), 0.01, w[2] / (2 * M_PI), 0.02,
                                                   &alpha, &beta, &err),
                     RTHS_OK);
    rths_beam_segment seg = {LEN, 6, EI, MU};
    rths_beam_spec spec = {.n_segments = 1, .segments = &seg, .n_clamped = 1, .clamped_m = &x0};
    spec.damping = (rths_beam_damping){RTHS_BEAM_DAMPING_RAYLEIGH, 0, NULL, 0, alpha, beta};
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_OK);
    assert_close(b.rayleigh_alpha_per_s, alpha, 0);
    double om[12], ze[12];
    assert_int_equal(damped_modes(&b, om, ze), 12);
    printf("Rayleigh alpha %.6g /s beta %.6g s: zeta %.9f %.9f %.9f\n", alpha, beta, ze[0], ze[1],
           ze[2]);
    assert_close(ze[0], 0.01, 1e-9);
    assert_close(ze[2], 0.02, 1e-9);
    assert_close(ze[1], alpha / (2 * w[1]) + beta * w[1] / 2, 1e-9);
    free(w);
    rths_beam_free(&b);
    /* pairs needing a negative coefficient, equal frequencies: refused */
    assert_int_equal(rths_beam_rayleigh_from_pairs(1, 0.1, 10, 0.001, &alpha, &beta, &err),
                     RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "beta < 0"));
    assert_int_equal(rths_beam_rayleigh_from_pairs(1, 0.001, 10, 0.1, &alpha, &beta, &err),
                     RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "alpha < 0"));
    assert_int_equal(rths_beam_rayleigh_from_pairs(5, 0.01, 5, 0.02, &alpha, &beta, &err),
                     RTHS_EINPUT);
}

/* DoF map: nodes in order, w before theta, fixed DoFs absent; positions by name. */
static void test_dof_map(void **state) {
    (void)state;
    const double x0 = 0;
    rths_beam_segment segs[2] = {{0.17, 4, EI, MU}, {0.36, 8, EI, MU}};
    rths_beam_spec spec = {.n_segments = 2, .segments = segs, .n_clamped = 1, .clamped_m = &x0};
    rths_beam b;
    rths_error err;
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_OK);
    assert_int_equal(b.n_nodes, 13);
    assert_int_equal(b.n, 24);
    assert_close(b.length_m, 0.53, 1e-15);
    int i = rths_beam_find_dof(&b, 0.17, RTHS_BEAM_W);
    assert_int_equal(i, 6); /* node 4; node 0 is clamped */
    assert_int_equal(b.dofs[i].node, 4);
    assert_close(b.dofs[i].position_m, 0.17, 1e-15);
    assert_int_equal(rths_beam_find_dof(&b, 0.17, RTHS_BEAM_THETA), 7);
    assert_int_equal(b.dofs[7].kind, RTHS_BEAM_THETA);
    assert_string_equal(rths_beam_dof_kind_name(b.dofs[7].kind), "theta");
    assert_int_equal(rths_beam_find_dof(&b, 0.53, RTHS_BEAM_THETA), 23);
    assert_int_equal(rths_beam_find_dof(&b, 0.0, RTHS_BEAM_W), -1);  /* clamped */
    assert_int_equal(rths_beam_find_dof(&b, 0.10, RTHS_BEAM_W), -1); /* no node */
    assert_close(b.dofs[9].position_m, 0.17 + 0.045, 1e-15);
    rths_assembly a;
    assert_int_equal(rths_beam_to_assembly(&b, &a, &err), RTHS_OK);
    assert_int_equal(a.n, 24);
    rths_assembly_free(&a);
    rths_beam_free(&b);
}

/* ---- YAML ---- */

static char yaml_path[64];

static int load(const char *yaml, rths_config **cfg, rths_error *err) {
    snprintf(yaml_path, sizeof yaml_path, "/tmp/rths_test_beam_XXXXXX");
    int fd = mkstemp(yaml_path);
    assert_true(fd >= 0);
    FILE *f = fdopen(fd, "w");
    fputs(yaml, f);
    fclose(f);
    return rths_config_load(yaml_path, NULL, 0, cfg, err);
}

/* Reads yaml as a command would (section reader, then the unknown-key check); *b is filled only
 * when both pass. */
static int read_yaml(const char *yaml, rths_beam *b, rths_error *err) {
    rths_config *cfg;
    if (load(yaml, &cfg, err)) fail_msg("%s", err->msg);
    int rc = rths_beam_config_read(cfg, "structure.beam", b, err);
    if (!rc && (rc = rths_config_check_unknown(cfg, err))) rths_beam_free(b);
    rths_config_free(cfg);
    unlink(yaml_path);
    return rc;
}

/* Line numbers in the comments; columns 1-based (a flow list's column is its '['). */
static const char *const strip_yaml = "structure:\n"                          /* 1 */
                                      "  beam:\n"                             /* 2 */
                                      "    segments:\n"                       /* 3 */
                                      "      length_m: [0.17, 0.36]\n"        /* 4 */
                                      "      elements: [17, 36]\n"            /* 5 */
                                      "      EI_n_m2: [0.459317, 0.459317]\n" /* 6: col 16 */
                                      "      mass_per_length_kg_per_m: [0.19939, 0.19939]\n" /* 7 */
                                      "    clamped_m: [0]\n"       /* 8: col 16 */
                                      "    point_masses:\n"        /* 9 */
                                      "      position_m: [0.53]\n" /* 10 */
                                      "      mass_kg: [0.0]\n"     /* 11 */
                                      "    damping:\n"             /* 12 */
                                      "      model: modal\n"       /* 13 */
                                      "      ratio: 0.011\n";      /* 14 */

/* base with the first `from` replaced by `to` (malloc'ed) */
static char *replaced_in(const char *base, const char *from, const char *to) {
    const char *at = strstr(base, from);
    if (!at) fail_msg("'%s' not in the YAML", from);
    size_t head = (size_t)(at - base);
    char *s = malloc(strlen(base) + strlen(to) + 1);
    memcpy(s, base, head);
    strcpy(s + head, to);
    strcat(s, at + strlen(from));
    return s;
}

static char *replaced(const char *from, const char *to) {
    return replaced_in(strip_yaml, from, to);
}

static void refused(const char *from, const char *to, const char *where, const char *what) {
    char *yaml = replaced(from, to);
    rths_beam b;
    rths_error err;
    assert_int_equal(read_yaml(yaml, &b, &err), RTHS_EINPUT);
    free(yaml);
    char want[512];
    snprintf(want, sizeof want, "%s%s", yaml_path, where);
    if (!strstr(err.msg, want) || !strstr(err.msg, what))
        fail_msg("message\n  '%s'\nlacks\n  '%s' / '%s'", err.msg, want, what);
    printf("refused: %s\n", err.msg);
}

/* The config reader gives the same matrices as the API. */
static void test_config_reads(void **state) {
    (void)state;
    rths_beam b;
    rths_error err;
    if (read_yaml(strip_yaml, &b, &err)) fail_msg("%s", err.msg);
    assert_int_equal(b.n, 2 * 53);
    rths_beam_segment segs[2] = {{0.17, 17, 0.459317, 0.19939}, {0.36, 36, 0.459317, 0.19939}};
    const double x0 = 0;
    rths_beam_spec spec = {.n_segments = 2, .segments = segs, .n_clamped = 1, .clamped_m = &x0};
    spec.damping = (rths_beam_damping){RTHS_BEAM_DAMPING_MODAL, 0, NULL, 0.011, 0, 0};
    rths_beam c;
    assert_int_equal(rths_beam_assemble(&spec, &c, &err), RTHS_OK);
    size_t nn = (size_t)b.n * (size_t)b.n;
    assert_memory_equal(b.mass, c.mass, nn * sizeof(double));
    assert_memory_equal(b.stiffness, c.stiffness, nn * sizeof(double));
    assert_memory_equal(b.damping, c.damping, nn * sizeof(double));
    rths_beam_free(&b);
    rths_beam_free(&c);
    /* Rayleigh pairs through the reader */
    char *yaml = replaced("      model: modal\n      ratio: 0.011\n",
                          "      model: rayleigh\n      frequencies_hz: [3, 50]\n"
                          "      ratios: [0.011, 0.011]\n");
    if (read_yaml(yaml, &b, &err)) fail_msg("%s", err.msg);
    double alpha, beta;
    assert_int_equal(rths_beam_rayleigh_from_pairs(3, 0.011, 50, 0.011, &alpha, &beta, &err), 0);
    assert_close(b.rayleigh_alpha_per_s, alpha, 0);
    assert_close(b.rayleigh_beta_s, beta, 0);
    free(yaml);
    rths_beam_free(&b);
}

static void test_config_refusals(void **state) {
    (void)state;
    refused("[0.459317, 0.459317]", "[0.459317, -1]",
            ":6:16: key 'structure.beam.segments.EI_n_m2'",
            "segment 2: must be > 0 N m^2 (got -1)");
    refused("[17, 36]", "[17, 0]", ":5:17: key 'structure.beam.segments.elements'",
            "segment 2: needs at least 1 element");
    refused("[0.17, 0.36]", "[0.17, 0.36, 0.1]", ":5:17: key 'structure.beam.segments.elements'",
            "has 2 entries but structure.beam.segments.length_m has 3");
    refused("[0.17, 0.36]", "[0.17, .nan]", ":4:", "structure.beam.segments.length_m'");
    refused("clamped_m: [0]", "clamped_m: [0.205]", ":8:16: key 'structure.beam.clamped_m'",
            "entry 1: no node at 0.205 m (nearest node at 0.2 m");
    refused("clamped_m: [0]", "clamped_m: [0, 0.53]\n    pinned_m: [0.53]",
            ":9:15: key 'structure.beam.pinned_m'", "the node at 0.53 m is already clamped");
    refused("mass_kg: [0.0]", "mass_kg: [-0.01]",
            ":11:16: key 'structure.beam.point_masses.mass_kg'", "entry 1: must be >= 0 kg");
    refused("mass_kg: [0.0]", "mass_kg: [0.0, 1]",
            ":11:16: key 'structure.beam.point_masses.mass_kg'", "has 2 entries but");
    refused("ratio: 0.011", "ratio: 1.5", ":14:14: key 'structure.beam.damping.ratio'",
            "must be in [0, 1) (got 1.5)");
    refused("ratio: 0.011", "ratios: [0.01, -0.02]", ":14:15: key 'structure.beam.damping.ratios'",
            "mode 2: must be in [0, 1)");
    refused("model: modal\n      ratio: 0.011", "model: modal",
            ":13:14: key 'structure.beam.damping.model'", "modal damping needs damping.ratio");
    refused("model: modal", "model: viscous", ":13:14: key 'structure.beam.damping.model'",
            "modal");
    refused("model: modal\n      ratio: 0.011",
            "model: rayleigh\n      frequencies_hz: [3, 3]\n      ratios: [0.01, 0.01]",
            ":14:23: key 'structure.beam.damping.frequencies_hz'", "two different frequencies");
    refused("model: modal\n      ratio: 0.011",
            "model: rayleigh\n      frequencies_hz: [3, 30]\n      ratios: [0.001, 0.1]",
            ":14:23: key 'structure.beam.damping.frequencies_hz'", "need alpha < 0");
    refused("model: modal\n      ratio: 0.011",
            "model: rayleigh\n      alpha_per_s: 0.1\n      frequencies_hz: [3, 30]",
            ":15:23: key 'structure.beam.damping.frequencies_hz'", "not both");
    refused("model: modal\n      ratio: 0.011", "model: none\n      ratio: 0.011",
            ":14:", "structure.beam.damping.ratio");
    /* more ratios than the 4 modes of a 2-element cantilever */
    char *two = replaced("[17, 36]", "[1, 1]");
    char *yaml = replaced_in(two, "ratio: 0.011", "ratios: [0.01, 0.01, 0.01, 0.01, 0.01]");
    rths_beam b;
    rths_error err;
    assert_int_equal(read_yaml(yaml, &b, &err), RTHS_EINPUT);
    printf("refused: %s\n", err.msg);
    assert_non_null(strstr(err.msg, ":14:15: key 'structure.beam.damping.ratios': lists 5 ratios "
                                    "but the beam has only 4 modes"));
    free(yaml);
    /* everything fixed: both elements' nodes clamped */
    yaml = replaced_in(two, "clamped_m: [0]", "clamped_m: [0, 0.17, 0.53]");
    assert_int_equal(read_yaml(yaml, &b, &err), RTHS_EINPUT);
    printf("refused: %s\n", err.msg);
    assert_non_null(strstr(err.msg, ":3:5: key 'structure.beam': every DoF is fixed"));
    free(yaml);
    free(two);
}

static void test_config_missing(void **state) {
    (void)state;
    rths_config *cfg;
    rths_error err;
    assert_int_equal(load("structure:\n  storeys: {}\n", &cfg, &err), RTHS_OK);
    rths_beam b;
    assert_int_equal(rths_beam_config_read(cfg, "structure.beam", &b, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "key 'structure.beam': is required but missing"));
    rths_config_free(cfg);
    unlink(yaml_path);
}

/* The follow-up's steel strip: 25.4 x 1 mm, E = 217 GPa, 7850 kg/m^3 (steel's usual density: the
 * paper's value is assumed, not read), clamped, 170 + 360 mm, no added masses. I = b h^3 / 12.
 * 10 mm elements; the closed form for the uniform 530 mm cantilever within the h^4 bound. */
static void test_follow_up_strip(void **state) {
    (void)state;
    const double b_m = 25.4e-3, h_m = 1e-3, e_pa = 217e9, rho = 7850, l = 0.53, x0 = 0;
    const double ei = e_pa * b_m * pow(h_m, 3) / 12, mu = rho * b_m * h_m;
    rths_beam_segment segs[2] = {{0.17, 17, ei, mu}, {0.36, 36, ei, mu}};
    rths_beam_spec spec = {.n_segments = 2, .segments = segs, .n_clamped = 1, .clamped_m = &x0};
    rths_beam b;
    rths_error err;
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_OK);
    double *w = omegas(&b);
    printf("steel strip EI = %.6f N m^2, m = %.6f kg/m, L = %.3f m\n", ei, mu, l);
    for (int r = 0; r < 3; r++) {
        double bl = cantilever_beta_l(r), exact = bl * bl * sqrt(ei / (mu * pow(l, 4)));
        printf("steel strip mode %d: %.4f Hz (closed form %.4f Hz, relative error %.2e)\n", r + 1,
               w[r] / (2 * M_PI), exact / (2 * M_PI), w[r] / exact - 1);
        double e = w[r] / exact - 1;
        assert_true(e >= -ROUNDING && e <= h4_bound(bl, l, 53));
    }
    free(w);
    rths_beam_free(&b);
}

/* The example in docs/config/beam.md reads as documented: 106 free DoFs, the cut's w and theta
 * at DoFs 33 and 34, Rayleigh damping of exactly 1.1 % at the strip's first two frequencies. */
static void test_doc_example(void **state) {
    (void)state;
    FILE *f = fopen(rths_test_source_path("docs/config/beam.md"), "r");
    assert_non_null(f);
    static char doc[65536];
    size_t len = fread(doc, 1, sizeof doc - 1, f);
    fclose(f);
    doc[len] = 0;
    char *start = strstr(doc, "```yaml\n"), *end = start ? strstr(start + 8, "```") : NULL;
    assert_true(start && end);
    *end = 0;
    rths_beam b;
    rths_error err;
    if (read_yaml(start + 8, &b, &err)) fail_msg("%s", err.msg);
    assert_int_equal(b.n, 106);
    assert_int_equal(rths_beam_find_dof(&b, 0.17, RTHS_BEAM_W) + 1, 33);
    assert_int_equal(rths_beam_find_dof(&b, 0.17, RTHS_BEAM_THETA) + 1, 34);
    double *w = omegas(&b);
    for (int r = 0; r < 2; r++) {
        double zeta = b.rayleigh_alpha_per_s / (2 * w[r]) + b.rayleigh_beta_s * w[r] / 2;
        /* the pairs are the documented 4-decimal frequencies, within 1e-4 Hz of the modes' */
        assert_close(zeta, 0.011, 1e-6);
    }
    free(w);
    rths_beam_free(&b);
}

static void test_api_refusals(void **state) {
    (void)state;
    rths_beam_segment seg = {0.5, 4, 1, 1};
    const double x = 0.3;
    rths_beam_spec spec = {.n_segments = 1, .segments = &seg, .n_clamped = 1, .clamped_m = &x};
    rths_beam b;
    rths_error err;
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "beam clamped_m: entry 1: no node at 0.3 m"));
    spec.n_clamped = 0;
    spec.n_segments = 0;
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "needs at least one segment"));
    seg.elements = 2000;
    spec.n_segments = 1;
    assert_int_equal(rths_beam_assemble(&spec, &b, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "more than 1000 elements"));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cantilever_convergence),
        cmocka_unit_test(test_simply_supported),
        cmocka_unit_test(test_static_tip_deflection),
        cmocka_unit_test(test_tip_mass_and_rayleigh_quotient),
        cmocka_unit_test(test_free_free),
        cmocka_unit_test(test_modal_damping),
        cmocka_unit_test(test_rayleigh_damping),
        cmocka_unit_test(test_dof_map),
        cmocka_unit_test(test_config_reads),
        cmocka_unit_test(test_config_refusals),
        cmocka_unit_test(test_config_missing),
        cmocka_unit_test(test_follow_up_strip),
        cmocka_unit_test(test_doc_example),
        cmocka_unit_test(test_api_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
