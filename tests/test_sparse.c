/* The sparse engine (sparse.h) against closed forms and dense LAPACK: the lowest modes of a
 * fixed-free spring-mass chain and of a 2-D grid Laplacian (both eigenvalue sets known exactly)
 * with the DoFs numbered at random and the entries split into duplicates over both triangles, on
 * every ordering; the complex symmetric solve of K + i w C - w^2 M against LAPACK's zgesv; the
 * streaming Matrix Market reader into CSC and its memory bound. */
#include "testlib.h"

#include "rths/mtx.h"
#include "rths/sparse.h"

#include <complex.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

/* Triplets of a symmetric matrix, assembled as an FE code would write them. */
typedef struct {
    int *i, *j;
    double *v;
    long n, cap;
} triplets;

static void push(triplets *t, int i, int j, double v) {
    if (t->n == t->cap) {
        t->cap = t->cap ? 2 * t->cap : 256;
        t->i = realloc(t->i, (size_t)t->cap * sizeof *t->i);
        t->j = realloc(t->j, (size_t)t->cap * sizeof *t->j);
        t->v = realloc(t->v, (size_t)t->cap * sizeof *t->v);
        assert_non_null(t->i);
        assert_non_null(t->j);
        assert_non_null(t->v);
    }
    t->i[t->n] = i;
    t->j[t->n] = j;
    t->v[t->n] = v;
    t->n++;
}

/* Entry (i, j) (and its mirror) of a symmetric matrix under the numbering perm: written as two
 * parts, one in each triangle for off-diagonal terms, so that duplicates and folding are
 * exercised. */
static void push_sym(triplets *t, const int *perm, int i, int j, double v) {
    int pi = perm[i], pj = perm[j];
    push(t, pi, pj, 0.25 * v);
    push(t, pj, pi, 0.75 * v);
}

static void free_triplets(triplets *t) {
    free(t->i);
    free(t->j);
    free(t->v);
    memset(t, 0, sizeof *t);
}

static int *random_permutation(int n, uint64_t seed) {
    int *p = malloc((size_t)n * sizeof *p);
    assert_non_null(p);
    for (int i = 0; i < n; i++)
        p[i] = i;
    uint64_t s = seed;
    for (int i = n - 1; i > 0; i--) {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        int k = (int)((s >> 33) % (uint64_t)(i + 1));
        int tmp = p[i];
        p[i] = p[k];
        p[k] = tmp;
    }
    return p;
}

static void build(triplets *t, int n, rths_sparse_sym *a) {
    rths_error err;
    if (rths_sparse_from_triplets(n, t->n, t->i, t->j, t->v, a, &err)) fail_msg("%s", err.msg);
}

/* ||A||_1 of the full symmetric matrix (largest absolute column sum, both triangles). */
static double norm1(const rths_sparse_sym *a) {
    double *sum = calloc((size_t)a->n, sizeof *sum), big = 0;
    for (int j = 0; j < a->n; j++)
        for (int e = a->colptr[j]; e < a->colptr[j + 1]; e++) {
            sum[j] += fabs(a->value[e]);
            if (a->rowidx[e] != j) sum[a->rowidx[e]] += fabs(a->value[e]);
        }
    for (int j = 0; j < a->n; j++)
        big = fmax(big, sum[j]);
    free(sum);
    return big;
}

/* Every mode's normwise backward error ||K phi - lambda M phi|| / ((||K|| + |lambda| ||M||)
 * ||phi||) at rounding level (a backward-stable solver's), and phi^T M phi = 1. */
static void check_modes(const rths_sparse_sym *k, const rths_sparse_sym *m, int found,
                        const double *lambda, const double *phi) {
    int n = k->n;
    double *kp = malloc((size_t)n * sizeof *kp), *mp = malloc((size_t)n * sizeof *mp);
    double kn = norm1(k), mn = norm1(m);
    for (int c = 0; c < found; c++) {
        const double *x = phi + (size_t)c * n;
        rths_sparse_symv(k, x, kp);
        rths_sparse_symv(m, x, mp);
        double r = 0, xx = 0, mm = 0;
        for (int i = 0; i < n; i++) {
            r += (kp[i] - lambda[c] * mp[i]) * (kp[i] - lambda[c] * mp[i]);
            xx += x[i] * x[i];
            mm += x[i] * mp[i];
        }
        double eta = sqrt(r) / ((kn + fabs(lambda[c]) * mn) * sqrt(xx));
        if (eta > 1e-13) fail_msg("mode %d: backward error %.3g", c + 1, eta);
        assert_true(fabs(mm - 1) < 1e-12);
    }
    free(kp);
    free(mp);
}

/* n masses m on springs k, fixed at one end, free at the other:
 * lambda_j = 4 k/m sin^2((2j - 1) pi / (2 (2n + 1))), j = 1..n. */
static void test_chain_modes(void **state) {
    (void)state;
    const int n = 3000;
    const double k = 2.5e6, m = 3.0;
    int *perm = random_permutation(n, 7);
    triplets kt = {0}, mt = {0};
    for (int e = 0; e < n; e++) { /* spring e joins mass e - 1 (the base for e = 0) to mass e */
        push_sym(&kt, perm, e, e, k);
        if (e > 0) {
            push_sym(&kt, perm, e - 1, e - 1, k);
            push_sym(&kt, perm, e, e - 1, -k);
        }
        push_sym(&mt, perm, e, e, m);
    }
    rths_sparse_sym ks, ms;
    build(&kt, n, &ks);
    build(&mt, n, &ms);
    assert_int_equal(ks.colptr[n], 2 * n - 1); /* duplicates summed, both triangles folded */
    const rths_sparse_ordering orders[] = {RTHS_SPARSE_ORDER_AUTO, RTHS_SPARSE_ORDER_PORD,
                                           RTHS_SPARSE_ORDER_AMD};
    for (int o = 0; o < 3; o++) {
        rths_sparse_eigs_options opt = rths_sparse_eigs_defaults();
        opt.count = 12;
        opt.ordering = orders[o];
        double *lambda, *phi;
        int found;
        rths_error err;
        if (rths_sparse_eigs(&ks, &ms, &opt, &lambda, &phi, &found, NULL, &err))
            fail_msg("%s", err.msg);
        assert_int_equal(found, 12);
        for (int j = 1; j <= found; j++) {
            double s = sin((2 * j - 1) * M_PI / (2.0 * (2 * n + 1)));
            double exact = 4 * k / m * s * s;
            if (fabs(lambda[j - 1] / exact - 1) > 1e-9)
                fail_msg("%s: mode %d: %.17g, exact %.17g", rths_sparse_ordering_name(orders[o]), j,
                         lambda[j - 1], exact);
        }
        check_modes(&ks, &ms, found, lambda, phi);
        free(lambda);
        free(phi);
    }
    /* every mode below a cut-off halfway between modes 7 and 8: exactly 7, from the inertia */
    double s7 = sin(13 * M_PI / (2.0 * (2 * n + 1))), s8 = sin(15 * M_PI / (2.0 * (2 * n + 1)));
    rths_sparse_eigs_options opt = rths_sparse_eigs_defaults();
    opt.count = 50;
    opt.lambda_max = 2 * k / m * (s7 * s7 + s8 * s8);
    double *lambda;
    int found;
    rths_error err;
    if (rths_sparse_eigs(&ks, &ms, &opt, &lambda, NULL, &found, NULL, &err))
        fail_msg("%s", err.msg);
    assert_int_equal(found, 7);
    assert_true(fabs(lambda[6] / (4 * k / m * s7 * s7) - 1) < 1e-9);
    free(lambda);
    /* more modes below the cut-off than accepted: refused, naming both counts */
    opt.count = 5;
    assert_int_equal(rths_sparse_eigs(&ks, &ms, &opt, &lambda, NULL, &found, NULL, &err),
                     RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "7 modes lie below the cut-off"));
    rths_sparse_free(&ks);
    rths_sparse_free(&ms);
    free_triplets(&kt);
    free_triplets(&mt);
    free(perm);
}

/* A free-free chain (no base spring: K singular, one rigid mode) of n masses m, springs k:
 * lambda_j = 4 k/m sin^2((j - 1) pi / (2 n)), j = 1..n. Numbered in order, its LDL^T at shift 0
 * meets an exactly zero pivot: refused, naming the singular matrix (not NaN modes). Numbered at
 * random, with a negative shift, the rigid mode comes out at 0 (to rounding of the stiffness
 * scale) and the elastic ones at the closed form. */
static void free_chain(int n, double k, double m, const int *perm, rths_sparse_sym *ks,
                       rths_sparse_sym *ms) {
    triplets kt = {0}, mt = {0};
    for (int e = 1; e < n; e++) {
        push_sym(&kt, perm, e - 1, e - 1, k);
        push_sym(&kt, perm, e, e, k);
        push_sym(&kt, perm, e, e - 1, -k);
    }
    for (int e = 0; e < n; e++)
        push_sym(&mt, perm, e, e, m);
    build(&kt, n, ks);
    build(&mt, n, ms);
    free_triplets(&kt), free_triplets(&mt);
}

static void test_free_chain_shift(void **state) {
    (void)state;
    const int n = 500;
    const double k = 1e4, m = 2.0;
    int *identity = malloc((size_t)n * sizeof *identity);
    for (int i = 0; i < n; i++)
        identity[i] = i;
    rths_sparse_sym ks, ms;
    free_chain(n, k, m, identity, &ks, &ms);
    rths_sparse_eigs_options opt = rths_sparse_eigs_defaults();
    opt.count = 6;
    double *lambda, *phi;
    int found;
    rths_error err;
    assert_int_equal(rths_sparse_eigs(&ks, &ms, &opt, &lambda, &phi, &found, NULL, &err),
                     RTHS_EFAIL);
    assert_non_null(strstr(err.msg, "numerically singular (1 null pivots of 500)"));
    rths_sparse_free(&ks), rths_sparse_free(&ms);

    int *perm = random_permutation(n, 13);
    free_chain(n, k, m, perm, &ks, &ms);
    opt.shift = -0.1 * k / m * pow(M_PI / (2.0 * n), 2); /* a tenth of the first elastic one */
    if (rths_sparse_eigs(&ks, &ms, &opt, &lambda, &phi, &found, NULL, &err))
        fail_msg("%s", err.msg);
    assert_int_equal(found, 6);
    assert_true(fabs(lambda[0]) < 1e-12 * 4 * k / m);
    for (int j = 2; j <= found; j++) {
        double s = sin((j - 1) * M_PI / (2.0 * n)), exact = 4 * k / m * s * s;
        if (fabs(lambda[j - 1] / exact - 1) > 1e-9)
            fail_msg("mode %d: %.17g, exact %.17g", j, lambda[j - 1], exact);
    }
    check_modes(&ks, &ms, found, lambda, phi);
    free(lambda), free(phi);
    rths_sparse_free(&ks), rths_sparse_free(&ms);
    free(perm), free(identity);
}

/* The 5-point Laplacian on an nx x ny grid with Dirichlet edges, M = I:
 * lambda(p, q) = 4 sin^2(p pi / (2 (nx + 1))) + 4 sin^2(q pi / (2 (ny + 1))). */
static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void test_grid_laplacian_modes(void **state) {
    (void)state;
    const int nx = 70, ny = 45, n = nx * ny, want = 10;
    int *perm = random_permutation(n, 11);
    triplets kt = {0}, mt = {0};
    for (int y = 0; y < ny; y++)
        for (int x = 0; x < nx; x++) {
            int me = x + nx * y;
            push_sym(&kt, perm, me, me, 4);
            if (x > 0) push_sym(&kt, perm, me, me - 1, -1);
            if (y > 0) push_sym(&kt, perm, me, me - nx, -1);
            push_sym(&mt, perm, me, me, 1);
        }
    rths_sparse_sym ks, ms;
    build(&kt, n, &ks);
    build(&mt, n, &ms);
    double *exact = malloc((size_t)n * sizeof *exact);
    for (int q = 1; q <= ny; q++)
        for (int p = 1; p <= nx; p++) {
            double a = sin(p * M_PI / (2.0 * (nx + 1))), b = sin(q * M_PI / (2.0 * (ny + 1)));
            exact[(p - 1) + nx * (q - 1)] = 4 * a * a + 4 * b * b;
        }
    qsort(exact, (size_t)n, sizeof *exact, cmp_double);
    const rths_sparse_ordering orders[] = {RTHS_SPARSE_ORDER_SCOTCH, RTHS_SPARSE_ORDER_PORD,
                                           RTHS_SPARSE_ORDER_AMD};
    for (int o = 0; o < 3; o++) {
        rths_sparse_eigs_options opt = rths_sparse_eigs_defaults();
        opt.count = want;
        opt.ordering = orders[o];
        double *lambda, *phi;
        int found;
        rths_error err;
        rths_sparse_eigs_stats stats;
        if (rths_sparse_eigs(&ks, &ms, &opt, &lambda, &phi, &found, &stats, &err))
            fail_msg("%s", err.msg);
        assert_int_equal(found, want);
        /* the ordering asked is the one MUMPS used (INFOG(7)): none silently replaced */
        assert_int_equal(stats.ordering, orders[o]);
        for (int c = 0; c < want; c++)
            if (fabs(lambda[c] / exact[c] - 1) > 1e-9)
                fail_msg("%s: mode %d: %.17g, exact %.17g", rths_sparse_ordering_name(orders[o]),
                         c + 1, lambda[c], exact[c]);
        check_modes(&ks, &ms, found, lambda, phi);
        free(lambda);
        free(phi);
    }
    free(exact);
    rths_sparse_free(&ks);
    rths_sparse_free(&ms);
    free_triplets(&kt);
    free_triplets(&mt);
    free(perm);
}

/* K + i w C - w^2 M of a random sparse symmetric model, DoFs permuted, solved for two
 * right-hand sides at three frequencies (one analysis, three numerical factorisations) against
 * LAPACK's dense zgesv of the same matrix: agreement to 1e-10 of the solution's size (both are
 * backward stable; the matrix's condition number here is below 1e4). */
static void test_complex_solve(void **state) {
    (void)state;
    const int n = 80, nrhs = 2;
    int *perm = random_permutation(n, 5);
    triplets kt = {0}, mt = {0}, ct = {0};
    rths_rng rng;
    rths_rng_seed(&rng, 99);
    for (int i = 0; i < n; i++) {
        push_sym(&kt, perm, i, i, 10 + 5 * rths_rng_uniform(&rng));
        push_sym(&mt, perm, i, i, 1 + rths_rng_uniform(&rng));
        push_sym(&ct, perm, i, i, 0.05 * rths_rng_uniform(&rng));
        for (int off = 1; off <= 3; off++)
            if (i + off < n && rths_rng_uniform(&rng) < 0.6) {
                push_sym(&kt, perm, i + off, i, -2 * rths_rng_uniform(&rng));
                if (off == 1) push_sym(&mt, perm, i + off, i, 0.1 * rths_rng_uniform(&rng));
                if (off == 2) push_sym(&ct, perm, i + off, i, -0.01 * rths_rng_uniform(&rng));
            }
    }
    rths_sparse_sym ks, ms, cs;
    build(&kt, n, &ks);
    build(&mt, n, &ms);
    build(&ct, n, &cs);
    const rths_sparse_sym *terms[3] = {&ks, &cs, &ms};
    rths_sparse_factor *f;
    rths_error err;
    if (rths_sparse_factor_create(3, terms, RTHS_SPARSE_ORDER_AUTO, &f, &err))
        fail_msg("%s", err.msg);
    double *kd = rths_sparse_to_dense(&ks), *md = rths_sparse_to_dense(&ms),
           *cd = rths_sparse_to_dense(&cs);
    double complex *a = malloc((size_t)n * n * sizeof *a),
                   *b = malloc((size_t)n * nrhs * sizeof *b),
                   *x = malloc((size_t)n * nrhs * sizeof *x);
    lapack_int *ipiv = malloc((size_t)n * sizeof *ipiv);
    const double omegas[] = {0.5, 2.9, 7.0};
    for (int q = 0; q < 3; q++) {
        double w = omegas[q];
        for (size_t e = 0; e < (size_t)n * n; e++)
            a[e] = kd[e] + I * w * cd[e] - w * w * md[e];
        for (int e = 0; e < n * nrhs; e++)
            b[e] = x[e] = rths_rng_uniform(&rng) - 0.5 + I * (rths_rng_uniform(&rng) - 0.5);
        double complex coef[3] = {1, I * w, -w * w};
        if (rths_sparse_factor_complex(f, coef, &err)) fail_msg("%s", err.msg);
        if (rths_sparse_solve_complex(f, x, nrhs, &err)) fail_msg("%s", err.msg);
        assert_int_equal(LAPACKE_zgesv(LAPACK_COL_MAJOR, n, nrhs, (lapack_complex_double *)a, n,
                                       ipiv, (lapack_complex_double *)b, n),
                         0);
        double diff = 0, size = 0;
        for (int e = 0; e < n * nrhs; e++) {
            diff = fmax(diff, cabs(x[e] - b[e]));
            size = fmax(size, cabs(b[e]));
        }
        if (diff > 1e-10 * size) fail_msg("w = %g: max difference %.3g of %.3g", w, diff, size);
    }
    /* one symbolic analysis, three numerical factorisations */
    rths_sparse_factor_stats fs = rths_sparse_factor_get_stats(f);
    assert_int_equal(fs.analyses, 1);
    assert_int_equal(fs.factorisations, 3);
    /* the real path through the same factor: K x = b against dgesv */
    double coef[3] = {1, 0, 0};
    double *xr = malloc((size_t)n * sizeof *xr), *br = malloc((size_t)n * sizeof *br);
    lapack_int *ip2 = malloc((size_t)n * sizeof *ip2);
    for (int i = 0; i < n; i++)
        xr[i] = br[i] = rths_rng_uniform(&rng);
    if (rths_sparse_factor_real(f, coef, &err)) fail_msg("%s", err.msg);
    assert_int_equal(rths_sparse_factor_negative_pivots(f), 0); /* K positive definite */
    fs = rths_sparse_factor_get_stats(f);
    assert_int_equal(fs.analyses, 2); /* the real arithmetic's own analysis */
    assert_int_equal(fs.factorisations, 4);
    if (rths_sparse_solve_real(f, xr, 1, &err)) fail_msg("%s", err.msg);
    assert_int_equal(LAPACKE_dgesv(LAPACK_COL_MAJOR, n, 1, kd, n, ip2, br, n), 0);
    for (int i = 0; i < n; i++)
        assert_true(fabs(xr[i] - br[i]) < 1e-12 * (1 + fabs(br[i])) * 100);
    free(xr), free(br), free(ip2);
    free(a), free(b), free(x), free(ipiv), free(kd), free(md), free(cd);
    rths_sparse_factor_destroy(f);
    rths_sparse_free(&ks), rths_sparse_free(&ms), rths_sparse_free(&cs);
    free_triplets(&kt), free_triplets(&mt), free_triplets(&ct);
    free(perm);
}

/* A 3-D frame from tools/gen_frame3d.py (DoFs numbered at random, lumped and consistent mass):
 * the lowest modes read with rths_mtx_read_sparse and found by Lanczos equal LAPACK's dense
 * dsygvd of the same matrices to 1e-9 relative (a real FE pattern: 6 DoFs per node, rotations and
 * translations of very different stiffness). Skipped without python3 and numpy. */
static void test_frame_modes_vs_dense(void **state) {
    (void)state;
    if (system("/usr/bin/python3 -c 'import numpy' 2>/dev/null")) {
        skip();
        return;
    }
    const char *masses[] = {"consistent", "lumped"};
    for (int q = 0; q < 2; q++) {
        char dir[] = "/tmp/rths_test_sparse_XXXXXX", cmd[512], path[300];
        assert_non_null(mkdtemp(dir));
        snprintf(
            cmd, sizeof cmd,
            "/usr/bin/python3 tools/gen_frame3d.py --nx 3 --ny 2 --nz 3 --elements-per-member 2 "
            "--mass %s --seed 9 %s >/dev/null",
            masses[q], dir);
        assert_int_equal(system(cmd), 0);
        rths_sparse_sym ks, ms;
        rths_error err;
        snprintf(path, sizeof path, "%s/stiffness_n_per_m.mtx", dir);
        if (rths_mtx_read_sparse(path, RTHS_MTX_POSITIVE_DIAGONAL, &ks, &err))
            fail_msg("%s", err.msg);
        snprintf(path, sizeof path, "%s/mass_kg.mtx", dir);
        if (rths_mtx_read_sparse(path, RTHS_MTX_POSITIVE_DIAGONAL, &ms, &err))
            fail_msg("%s", err.msg);
        int n = ks.n;
        assert_true(n > 300);
        rths_sparse_eigs_options opt = rths_sparse_eigs_defaults();
        opt.count = 15;
        double *lambda, *phi;
        int found;
        if (rths_sparse_eigs(&ks, &ms, &opt, &lambda, &phi, &found, NULL, &err))
            fail_msg("%s", err.msg);
        assert_int_equal(found, 15);
        check_modes(&ks, &ms, found, lambda, phi);
        double *kd = rths_sparse_to_dense(&ks), *md = rths_sparse_to_dense(&ms);
        double *w = malloc((size_t)n * sizeof *w);
        assert_int_equal(LAPACKE_dsygvd(LAPACK_COL_MAJOR, 1, 'N', 'L', n, kd, n, md, n, w), 0);
        for (int c = 0; c < found; c++)
            if (fabs(lambda[c] / w[c] - 1) > 1e-9)
                fail_msg("%s mass: mode %d: Lanczos %.17g, dsygvd %.17g", masses[q], c + 1,
                         lambda[c], w[c]);
        free(kd), free(md), free(w), free(lambda), free(phi);
        rths_sparse_free(&ks), rths_sparse_free(&ms);
        snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
        assert_int_equal(system(cmd), 0);
    }
}

static const char *mtx_path(const char *name) {
    static char path[1024];
    char rel[256];
    snprintf(rel, sizeof rel, "tests/data/mtx/%s", name);
    snprintf(path, sizeof path, "%s", rths_test_source_path(rel));
    return path;
}

/* The sparse reader gives exactly the dense reader's matrix on symmetric files (either
 * triangle) and on a symmetric general array file; a general file that is not symmetric is
 * refused naming the entry. */
static void test_mtx_sparse_matches_dense(void **state) {
    (void)state;
    const char *files[] = {"coord_symmetric.mtx", "coord_symmetric_upper.mtx",
                           "array_symmetric.mtx", "seed_stiffness_n_per_m.mtx"};
    for (size_t f = 0; f < sizeof files / sizeof *files; f++) {
        double *d;
        int r, c;
        rths_error err;
        if (rths_mtx_read(mtx_path(files[f]), &d, &r, &c, &err)) fail_msg("%s", err.msg);
        rths_sparse_sym s;
        if (rths_mtx_read_sparse(mtx_path(files[f]), RTHS_MTX_POSITIVE_DIAGONAL, &s, &err))
            fail_msg("%s: %s", files[f], err.msg);
        assert_int_equal(s.n, r);
        for (int i = 0; i < r; i++)
            for (int j = 0; j < r; j++)
                assert_true(rths_sparse_get(&s, i, j) == RTHS_AT(d, r, i, j));
        free(d);
        rths_sparse_free(&s);
    }
    char dir[] = "/tmp/rths_test_sparse_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[256];
    snprintf(path, sizeof path, "%s/general.mtx", dir);
    FILE *fp = fopen(path, "w");
    fprintf(fp, "%%%%MatrixMarket matrix coordinate real general\n3 3 6\n1 1 2\n2 2 2\n3 3 2\n"
                "2 1 -1\n1 2 -1\n3 2 -0.5\n");
    fclose(fp);
    rths_sparse_sym s;
    rths_error err;
    assert_int_equal(rths_mtx_read_sparse(path, 0, &s, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "not symmetric: entry (3,2) is -0.5 but (2,3) is 0"));
    fp = fopen(path, "w");
    fprintf(fp, "%%%%MatrixMarket matrix coordinate real general\n3 3 7\n1 1 2\n2 2 2\n3 3 2\n"
                "2 1 -1\n1 2 -1\n3 2 -0.5\n2 3 -0.5\n");
    fclose(fp);
    if (rths_mtx_read_sparse(path, 0, &s, &err)) fail_msg("%s", err.msg);
    assert_int_equal(s.colptr[3], 5);
    assert_true(rths_sparse_get(&s, 1, 2) == -0.5);
    rths_sparse_free(&s);
    unlink(path);
    rmdir(dir);
}

/* A 100-byte file declaring 100000 x 100000 (a dense form would be 80 GB) with three entries is
 * read in memory that follows the entries: under a 256 MB address-space limit it is read, and
 * with RTHS_MTX_POSITIVE_DIAGONAL refused for what it is (too few entries), not for memory. */
static void test_mtx_sparse_memory_bound(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_test_sparse_XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[256];
    snprintf(path, sizeof path, "%s/huge.mtx", dir);
    FILE *fp = fopen(path, "w");
    fprintf(fp, "%%%%MatrixMarket matrix coordinate real symmetric\n100000 100000 3\n1 1 5\n"
                "99999 2 -1\n100000 100000 7\n");
    fclose(fp);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
#if !defined(__SANITIZE_ADDRESS__)
        struct rlimit lim = {256ul << 20, 256ul << 20};
        if (setrlimit(RLIMIT_AS, &lim)) _exit(3);
#endif
        rths_sparse_sym s;
        rths_error err;
        if (rths_mtx_read_sparse(path, 0, &s, &err)) _exit(4);
        if (s.n != 100000 || s.colptr[s.n] != 3 || rths_sparse_get(&s, 1, 99998) != -1 ||
            rths_sparse_get(&s, 99999, 99999) != 7)
            _exit(5);
        rths_sparse_free(&s);
        if (rths_mtx_read_sparse(path, RTHS_MTX_POSITIVE_DIAGONAL, &s, &err) != RTHS_EINPUT)
            _exit(6);
        if (!strstr(err.msg, "declares 100000 x 100000 but holds 3 entries")) _exit(7);
        _exit(0);
    }
    int status;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 0);
    unlink(path);
    rmdir(dir);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_chain_modes),
        cmocka_unit_test(test_free_chain_shift),
        cmocka_unit_test(test_grid_laplacian_modes),
        cmocka_unit_test(test_complex_solve),
        cmocka_unit_test(test_frame_modes_vs_dense),
        cmocka_unit_test(test_mtx_sparse_matches_dense),
        cmocka_unit_test(test_mtx_sparse_memory_bound),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
