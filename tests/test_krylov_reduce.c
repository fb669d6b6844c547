/* The Krylov / moment-matching reduction of a sparse numerical substructure (krylov_reduce.h)
 * against independent truths:
 *  - issue 26's 482-DoF frame (tools/gen_frame3d.py --nx 4 --ny 4 --nz 5, a two-storey specimen
 *    on the rig tied to ux of a roof node, the force on ux of the opposite roof node): the
 *    assembly's interface response from the dense complex solve of the 482 x 482 assembly
 *    (LAPACK, no MUMPS) against the reduced assembly (physical side + T^T {M, C, K} T, dense):
 *    Craig-Bampton with the 31 lowest fixed-interface modes (reduce.h, what the controller builds
 *    today) is tens of % off over the first ten modes of the band, the Krylov basis of the same
 *    size within 0.1 % at every check point and the report says where its worst is (equal to this
 *    independent error at the forcing to 1e-6 of its value or better: the report's error also
 *    covers a unit force at the interface, so it is an upper bound);
 *  - a 1000-DoF chain with non-proportional dampers (the 1000-DoF rod chain's shape), numerical
 *    side DoFs 1-999 with the interface first, the physical side the base spring, damper and the
 *    rest of the interface mass, the force on the top: the assembly's interface response from a
 *    complex tridiagonal (Thomas) solve, exact, within 0.1 % at the check points and, between
 *    them, at 10 times as many frequencies within 1 % (the greedy only sees the grid). */
#include "testlib.h"

#include "rths/config.h"
#include "rths/krylov_reduce.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- the reduced assembly, built here from its definition (not from krylov_reduce.c) ---- */

/* z = [x_P (np); r (nr)], x_B = r[0..nb-1]; rest (na = nb + np, interface first) on [x_B, x_P];
 * the reduced numerical side on r. Returns x_B[0] for the load [f_rest_P; T^T f_num]. */
static double complex reduced_assembly_response(const rths_reduced *r, const double *rest_m,
                                                const double *rest_c, const double *rest_k, int np,
                                                const double *f_rest_p, const double *tf,
                                                double w) {
    int nb = r->n_boundary, nr = r->nr, na = nb + np, nz = np + nr;
    double complex *d = calloc((size_t)nz * nz, sizeof *d), *x = calloc((size_t)nz, sizeof *x);
    /* rest index a (0..na-1) -> z index */
#define ZI(a) ((a) < nb ? np + (a) : (a)-nb)
    for (int j = 0; j < na; j++)
        for (int i = 0; i < na; i++)
            RTHS_AT(d, nz, ZI(i), ZI(j)) += RTHS_AT(rest_k, na, i, j) +
                                            I * w * RTHS_AT(rest_c, na, i, j) -
                                            w * w * RTHS_AT(rest_m, na, i, j);
#undef ZI
    for (int j = 0; j < nr; j++)
        for (int i = 0; i < nr; i++)
            RTHS_AT(d, nz, np + i, np + j) += RTHS_AT(r->stiffness, nr, i, j) +
                                              I * w * RTHS_AT(r->damping, nr, i, j) -
                                              w * w * RTHS_AT(r->mass, nr, i, j);
    for (int i = 0; i < np; i++)
        x[i] = f_rest_p[i];
    for (int i = 0; i < nr; i++)
        x[np + i] = tf[i];
    assert_int_equal(rths_cmat_solve(nz, 1, d, x), 0);
    double complex out = x[np];
    free(d), free(x);
    return out;
}

/* ---- issue 26's frame ---- */

typedef struct {
    rths_sparse_model m;
    rths_model_choice choice;
    rths_config *cfg;
    char dir[64];
} frame;

static void frame_load(frame *f) {
    snprintf(f->dir, sizeof f->dir, "/tmp/rths_test_krylov_XXXXXX");
    assert_non_null(mkdtemp(f->dir));
    char cmd[512], path[128];
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 %s --nx 4 --ny 4 --nz 5 --seed 1 --specimen 2000 3e5 %s "
             ">/dev/null",
             rths_test_source_path("tools/gen_frame3d.py"), f->dir);
    assert_int_equal(system(cmd), 0);
    snprintf(path, sizeof path, "%s/frame.yaml", f->dir);
    const char *sets[] = {"model.solver=sparse"};
    rths_error err;
    if (rths_config_load(path, sets, 1, &f->cfg, &err)) fail_msg("%s", err.msg);
    if (rths_model_choose_solver(f->cfg, &f->choice, &err)) fail_msg("%s", err.msg);
    if (rths_sparse_model_read(f->cfg, &f->choice, &f->m, &err)) fail_msg("%s", err.msg);
    assert_int_equal(f->m.n, 482);
}

static void frame_free(frame *f) {
    rths_sparse_model_free(&f->m);
    rths_model_choice_free(&f->choice);
    rths_config_free(f->cfg);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", f->dir);
    assert_int_equal(system(cmd), 0);
}

enum { FRAME_POINTS = 41 };
static const double frame_lo_hz = 0.5, frame_hi_hz = 2.2; /* the assembly's modes 1-10 */

static void test_frame_krylov_vs_craig_bampton(void **state) {
    (void)state;
    if (system("/usr/bin/python3 -c 'import numpy' 2>/dev/null")) {
        skip();
        return;
    }
    frame f;
    frame_load(&f);
    rths_sparse_model *m = &f.m;
    int n = m->n, nb = m->n_int;
    assert_int_equal(nb, 1);
    rths_error err;

    rths_krylov_options opt;
    rths_krylov_defaults(&opt);
    opt.start_hz = frame_lo_hz, opt.end_hz = frame_hi_hz, opt.check_points = FRAME_POINTS;
    rths_reduced kr;
    rths_krylov_report rep;
    int *dofs;
    if (rths_sparse_model_krylov_reduce(m, &opt, &kr, &dofs, &rep, &err))
        fail_msg("%s (error %g at %g Hz)", err.msg, rep.max_error, rep.at_hz);
    int nn = kr.n;
    assert_true(kr.nr <= RTHS_REALTIME_MAX_DOFS);
    assert_int_equal(kr.n_boundary, 1);
    assert_int_equal(dofs[0], m->int_dofs[0]);
    print_message("Krylov: %d DoFs, %d shifts, max error %.3g at %g Hz (truth %.2f s, basis %.2f "
                  "s)\n",
                  kr.nr, rep.shifts, rep.max_error, rep.at_hz, rep.truth_s, rep.basis_s);

    /* the dense truth and the physical side, from the model's dense matrices */
    double *full[3] = {rths_sparse_to_dense(&m->mass), rths_sparse_to_dense(&m->damping),
                       rths_sparse_to_dense(&m->stiffness)};
    rths_sparse_sym nm, nc, nk;
    int *dofs2, nn2;
    if (rths_sparse_model_numerical_side(m, &nm, &nc, &nk, &dofs2, &nn2, &err))
        fail_msg("%s", err.msg);
    assert_int_equal(nn2, nn);
    double *num[3] = {rths_sparse_to_dense(&nm), rths_sparse_to_dense(&nc),
                      rths_sparse_to_dense(&nk)};
    /* rest = full - numerical side (embedded): nonzero on interface and physical DoFs only */
    int np = 0, pdofs[8];
    for (int i = 0; i < n; i++)
        if (m->roles[i] == RTHS_DOF_PHYSICAL) pdofs[np++] = i;
    assert_int_equal(np, 2);
    int na = nb + np, adofs[3] = {m->int_dofs[0], pdofs[0], pdofs[1]};
    double *rest[3];
    for (int t = 0; t < 3; t++) {
        double *diff = rths_mat_dup(full[t], n, n);
        for (int j = 0; j < nn; j++)
            for (int i = 0; i < nn; i++)
                RTHS_AT(diff, n, dofs[i], dofs[j]) -= RTHS_AT(num[t], nn, i, j);
        double scale = rths_mat_max_abs(full[t], n, n);
        rest[t] = rths_mat_new(na, na);
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                int ai = -1, aj = -1;
                for (int a = 0; a < na; a++) {
                    if (adofs[a] == i) ai = a;
                    if (adofs[a] == j) aj = a;
                }
                if (ai >= 0 && aj >= 0)
                    RTHS_AT(rest[t], na, ai, aj) = RTHS_AT(diff, n, i, j);
                else if (fabs(RTHS_AT(diff, n, i, j)) > 1e-12 * scale)
                    fail_msg("the split's rest couples DoFs %d and %d", i + 1, j + 1);
            }
        free(diff);
    }
    double f_rest_p[2] = {m->force[pdofs[0]], m->force[pdofs[1]]};
    double *f_num = malloc(sizeof(double) * (size_t)nn);
    for (int i = 0; i < nn; i++)
        f_num[i] = m->force[dofs[i]];

    /* Craig-Bampton with as many DoFs: the 31 lowest fixed-interface modes */
    rths_reduced cb;
    if (rths_reduce_craig_bampton(nn, nb, num[0], num[1], num[2], 1e9, RTHS_REALTIME_MAX_DOFS - nb,
                                  1, &cb, &err))
        fail_msg("%s", err.msg);
    assert_int_equal(cb.nr, RTHS_REALTIME_MAX_DOFS);
    double *tf_k = malloc(sizeof(double) * RTHS_REALTIME_MAX_DOFS);
    double *tf_c = malloc(sizeof(double) * RTHS_REALTIME_MAX_DOFS);
    rths_mat_mul(kr.nr, 1, nn, 1.0, kr.transform, 1, f_num, 0, 0.0, tf_k);
    rths_mat_mul(cb.nr, 1, nn, 1.0, cb.transform, 1, f_num, 0, 0.0, tf_c);

    double complex *d = malloc(sizeof *d * (size_t)n * n), *x = malloc(sizeof *x * (size_t)n);
    double worst_k = 0, worst_c = 0, worst_k_hz = 0, worst_c_hz = 0;
    for (int p = 0; p < FRAME_POINTS; p++) {
        double hz = frame_lo_hz + (frame_hi_hz - frame_lo_hz) * p / (FRAME_POINTS - 1);
        double w = 2 * M_PI * hz;
        for (size_t e = 0; e < (size_t)n * n; e++)
            d[e] = full[2][e] + I * w * full[1][e] - w * w * full[0][e];
        for (int i = 0; i < n; i++)
            x[i] = m->force[i];
        assert_int_equal(rths_cmat_solve(n, 1, d, x), 0);
        double complex truth = x[m->int_dofs[0]];
        double complex yk =
            reduced_assembly_response(&kr, rest[0], rest[1], rest[2], np, f_rest_p, tf_k, w);
        double complex yc =
            reduced_assembly_response(&cb, rest[0], rest[1], rest[2], np, f_rest_p, tf_c, w);
        double ek = cabs(yk - truth) / cabs(truth), ec = cabs(yc - truth) / cabs(truth);
        if (ek > worst_k) worst_k = ek, worst_k_hz = hz;
        if (ec > worst_c) worst_c = ec, worst_c_hz = hz;
    }
    print_message("independent: Krylov %.3g at %g Hz, Craig-Bampton (31 modes) %.3g at %g Hz\n",
                  worst_k, worst_k_hz, worst_c, worst_c_hz);
    /* today's reduction: tens of % off (issue 26: 58-65 % on its band) */
    assert_true(worst_c > 0.2);
    /* the Krylov basis: within controller.reduction.max_error, and the report bounds it */
    assert_true(worst_k < RTHS_KRYLOV_MAX_ERROR_DEFAULT);
    assert_true(rep.max_error < RTHS_KRYLOV_MAX_ERROR_DEFAULT);
    assert_true(worst_k <= rep.max_error * (1 + 1e-6) + 1e-8);
    /* the reduced interior is the Craig-Bampton form: M_r's interior block I, K_r's diagonal */
    for (int j = nb; j < kr.nr; j++)
        for (int i = nb; i < kr.nr; i++) {
            double mij = RTHS_AT(kr.mass, kr.nr, i, j), kij = RTHS_AT(kr.stiffness, kr.nr, i, j);
            assert_true(fabs(mij - (i == j)) < 1e-9);
            if (i != j)
                assert_true(fabs(kij) < 1e-9 * sqrt(RTHS_AT(kr.stiffness, kr.nr, i, i) *
                                                    RTHS_AT(kr.stiffness, kr.nr, j, j)));
        }
    for (int c = 1; c < kr.n_modes; c++)
        assert_true(kr.mode_hz[c] >= kr.mode_hz[c - 1]);

    /* a bound it cannot meet is refused, naming the key, and the report still says why */
    opt.max_error = 1e-14;
    rths_reduced bad;
    assert_int_equal(rths_sparse_model_krylov_reduce(m, &opt, &bad, NULL, &rep, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "controller.reduction.max_error"));
    assert_true(rep.max_error > 1e-14);
    assert_null(bad.transform);

    free(d), free(x), free(tf_k), free(tf_c), free(f_num), free(dofs), free(dofs2);
    for (int t = 0; t < 3; t++)
        free(full[t]), free(num[t]), free(rest[t]);
    rths_sparse_free(&nm), rths_sparse_free(&nc), rths_sparse_free(&nk);
    rths_reduced_free(&kr), rths_reduced_free(&cb);
    frame_free(&f);
}

/* ---- the 1000-DoF chain ---- */

enum { CHAIN = 1000, CHAIN_POINTS = 31 };

/* masses m_i, springs k_i joining i - 1 and i (k_0 to the ground), dampers c_i likewise */
static void chain_props(double *m, double *c, double *k) {
    for (int i = 0; i < CHAIN; i++) {
        m[i] = 1.0 + 0.2 * sin(0.37 * i);
        k[i] = 1e6 * (1.0 + 0.1 * cos(0.11 * i));
        c[i] = 5.0 + 40.0 * (i % 7 == 0); /* not proportional to M or K */
    }
}

/* (T x = rhs) for the tridiagonal complex T (diag d, off-diagonal e: T[i][i+1] = e[i]) */
static void thomas(int n, const double complex *d, const double complex *e, double complex *x) {
    double complex *cp = malloc(sizeof *cp * (size_t)n), *dp = malloc(sizeof *dp * (size_t)n);
    cp[0] = e[0] / d[0], dp[0] = x[0] / d[0];
    for (int i = 1; i < n; i++) {
        double complex den = d[i] - e[i - 1] * cp[i - 1];
        cp[i] = i < n - 1 ? e[i] / den : 0;
        dp[i] = (x[i] - e[i - 1] * dp[i - 1]) / den;
    }
    x[n - 1] = dp[n - 1];
    for (int i = n - 2; i >= 0; i--)
        x[i] = dp[i] - cp[i] * x[i + 1];
    free(cp), free(dp);
}

static void test_chain_krylov(void **state) {
    (void)state;
    double m[CHAIN], c[CHAIN], k[CHAIN];
    chain_props(m, c, k);
    const double p = 0.5; /* the numerical side's share of the interface mass */
    /* numerical side: DoFs 0..CHAIN-1 of the chain, DoF 0 the interface (first) */
    static int ti[3 * CHAIN], tj[3 * CHAIN];
    static double tv[3][3 * CHAIN];
    long t = 0;
    for (int i = 0; i < CHAIN; i++) {
        ti[t] = tj[t] = i;
        tv[0][t] = i == 0 ? p * m[0] : m[i];
        double kk = (i > 0 ? k[i] : 0) + (i + 1 < CHAIN ? k[i + 1] : 0);
        double cc = (i > 0 ? c[i] : 0) + (i + 1 < CHAIN ? c[i + 1] : 0);
        tv[1][t] = cc, tv[2][t] = kk;
        t++;
        if (i + 1 < CHAIN) {
            ti[t] = i + 1, tj[t] = i;
            tv[0][t] = 0, tv[1][t] = -c[i + 1], tv[2][t] = -k[i + 1];
            t++;
        }
    }
    rths_sparse_sym sm, sc, sk;
    rths_error err;
    assert_int_equal(rths_sparse_from_triplets(CHAIN, t, ti, tj, tv[0], &sm, &err), 0);
    assert_int_equal(rths_sparse_from_triplets(CHAIN, t, ti, tj, tv[1], &sc, &err), 0);
    assert_int_equal(rths_sparse_from_triplets(CHAIN, t, ti, tj, tv[2], &sk, &err), 0);
    double load[CHAIN] = {0};
    load[CHAIN - 1] = 1.0;
    /* the physical side: the rest of the interface mass, the base spring and damper */
    double rm = (1 - p) * m[0], rc = c[0], rk = k[0];
    rths_krylov_attachment rest = {
        .n_extra = 0, .mass = &rm, .damping = &rc, .stiffness = &rk, .loads = NULL};
    rths_krylov_options opt;
    rths_krylov_defaults(&opt);
    /* the fixed-free chain's first modes: about (2 j - 1) pi / (2 N) sqrt(k / m) / (2 pi) */
    opt.start_hz = 0.05, opt.end_hz = 1.2, opt.check_points = CHAIN_POINTS;
    rths_reduced r;
    rths_krylov_report rep;
    if (rths_krylov_reduce(&sm, &sc, &sk, 1, 1, load, &rest, &opt, &r, &rep, &err))
        fail_msg("%s", err.msg);
    print_message("chain: %d DoFs, %d shifts, report %.3g at %g Hz\n", r.nr, rep.shifts,
                  rep.max_error, rep.at_hz);
    double tf[RTHS_REALTIME_MAX_DOFS];
    rths_mat_mul(r.nr, 1, CHAIN, 1.0, r.transform, 1, load, 0, 0.0, tf);
    double worst_grid = 0, worst_fine = 0, worst_fine_hz = 0;
    const int fine = 10 * (CHAIN_POINTS - 1);
    for (int q = 0; q <= fine; q++) {
        double hz = opt.start_hz + (opt.end_hz - opt.start_hz) * q / fine, w = 2 * M_PI * hz;
        /* the assembly: the whole chain from the ground, tridiagonal */
        double complex d[CHAIN], e[CHAIN], x[CHAIN];
        for (int i = 0; i < CHAIN; i++) {
            double kk = k[i] + (i + 1 < CHAIN ? k[i + 1] : 0);
            double cc = c[i] + (i + 1 < CHAIN ? c[i + 1] : 0);
            d[i] = kk + I * w * cc - w * w * m[i];
            e[i] = i + 1 < CHAIN ? -k[i + 1] - I * w * c[i + 1] : 0;
            x[i] = i == CHAIN - 1;
        }
        thomas(CHAIN, d, e, x);
        double complex y =
            reduced_assembly_response(&r, &rm, &rc, &rk, 0, NULL, tf, w); /* rest: 1 x 1 */
        double err_q = cabs(y - x[0]) / cabs(x[0]);
        if (q % 10 == 0 && err_q > worst_grid) worst_grid = err_q;
        if (err_q > worst_fine) worst_fine = err_q, worst_fine_hz = hz;
    }
    print_message("chain: independent error %.3g on the check grid, %.3g at %g Hz between\n",
                  worst_grid, worst_fine, worst_fine_hz);
    assert_true(worst_grid < RTHS_KRYLOV_MAX_ERROR_DEFAULT);
    assert_true(worst_grid <= rep.max_error * (1 + 1e-6) + 1e-8);
    assert_true(worst_fine < 1e-2);
    rths_reduced_free(&r);
    rths_sparse_free(&sm), rths_sparse_free(&sc), rths_sparse_free(&sk);
}

/* the keys: defaults, values, and a bad value refused naming the key and its range */
static void test_config_keys(void **state) {
    (void)state;
    rths_config *cfg;
    rths_error err;
    rths_krylov_options opt;
    assert_int_equal(rths_config_load(NULL, NULL, 0, &cfg, &err), 0);
    rths_krylov_defaults(&opt);
    assert_int_equal(rths_krylov_config_read(cfg, &opt, &err), 0);
    assert_true(opt.max_error == 1e-3 && opt.check_points == 31 && opt.fill == 1);
    rths_config_free(cfg);
    const char *sets[] = {"controller.reduction.max_error=2e-4",
                          "controller.reduction.check_points=61",
                          "controller.reduction.fill=false"};
    assert_int_equal(rths_config_load(NULL, sets, 3, &cfg, &err), 0);
    assert_int_equal(rths_krylov_config_read(cfg, &opt, &err), 0);
    assert_true(opt.max_error == 2e-4 && opt.check_points == 61 && opt.fill == 0);
    rths_config_free(cfg);
    const char *bad[] = {"controller.reduction.max_error=0"};
    assert_int_equal(rths_config_load(NULL, bad, 1, &cfg, &err), 0);
    assert_int_equal(rths_krylov_config_read(cfg, &opt, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "controller.reduction.max_error"));
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_keys),
        cmocka_unit_test(test_chain_krylov),
        cmocka_unit_test(test_frame_krylov_vs_craig_bampton),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
