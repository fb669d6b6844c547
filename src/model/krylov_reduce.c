/* A real-time reduction right in the tested band, from sparse factorisations (krylov_reduce.h;
 * docs/architecture.md, "Sparse algebra"; docs/method.md, "Reduced numerical substructures"). */
#include "rths/krylov_reduce.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A vector is dropped as dependent when M-orthogonalisation leaves less than this of its norm. */
#define DEPENDENT_FRACTION 1e-8

void rths_krylov_defaults(rths_krylov_options *opt) {
    *opt = (rths_krylov_options){.start_hz = 0,
                                 .end_hz = 0,
                                 .check_points = RTHS_KRYLOV_CHECK_POINTS_DEFAULT,
                                 .max_error = RTHS_KRYLOV_MAX_ERROR_DEFAULT,
                                 .max_size = RTHS_REALTIME_MAX_DOFS,
                                 .fill = 1,
                                 .ordering = RTHS_SPARSE_ORDER_AUTO};
}

int rths_krylov_config_read(rths_config *cfg, rths_krylov_options *opt, rths_error *err) {
    long points = opt->check_points;
    int rc = rths_config_get_double_ex(cfg, "controller.reduction.max_error", 0, opt->max_error, 0,
                                       1, RTHS_CONFIG_LO_OPEN, &opt->max_error, err);
    if (!rc)
        rc = rths_config_get_int(cfg, "controller.reduction.check_points", 0, points, 2, 10000,
                                 &points, err);
    if (!rc)
        rc = rths_config_get_bool(cfg, "controller.reduction.fill", 0, opt->fill, &opt->fill, err);
    opt->check_points = (int)points;
    return rc;
}

/* ---- the assembly's interface response from the numerical side's interface receptances ---- */

/* x (nb x (nb + nl)): the numerical side's interface displacements under unit interface forces
 * (its receptance Hb) then under the loads (Hf), overwritten with the assembly's when rest is
 * attached: the numerical side condensed on the interface is S = Hb^-1 with blocked force S Hf,
 * so (D_rest + [S 0; 0 0]) y = rest loads + [S Hf; 0] (unit interface forces: e_b). */
static int couple(int nb, int nl, double complex *x, const rths_krylov_attachment *rest, double w,
                  rths_error *err) {
    if (!rest) return RTHS_OK;
    int na = nb + rest->n_extra, nc = nb + nl, rc = RTHS_OK;
    double complex *hb = malloc(sizeof *hb * (size_t)(nb * nb));
    double complex *s = calloc((size_t)(nb * nb), sizeof *s);
    double complex *d = malloc(sizeof *d * (size_t)na * (size_t)na);
    double complex *y = calloc((size_t)na * (size_t)nc, sizeof *y);
    if (!hb || !s || !d || !y) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    memcpy(hb, x, sizeof *hb * (size_t)(nb * nb));
    for (int i = 0; i < nb; i++)
        RTHS_AT(s, nb, i, i) = 1;
    if (rths_cmat_solve(nb, nb, hb, s)) {
        rc = rths_error_set(err, RTHS_EFAIL,
                            "the numerical side's interface receptance is singular at %g rad/s", w);
        goto done;
    }
    for (int j = 0; j < na; j++)
        for (int i = 0; i < na; i++)
            RTHS_AT(d, na, i, j) = RTHS_AT(rest->stiffness, na, i, j) +
                                   I * w * RTHS_AT(rest->damping, na, i, j) -
                                   w * w * RTHS_AT(rest->mass, na, i, j) +
                                   (i < nb && j < nb ? RTHS_AT(s, nb, i, j) : 0);
    for (int c = 0; c < nb; c++)
        RTHS_AT(y, na, c, c) = 1;
    for (int l = 0; l < nl; l++) {
        double complex *col = y + (size_t)(nb + l) * na;
        if (rest->loads)
            for (int i = 0; i < na; i++)
                col[i] = RTHS_AT(rest->loads, na, i, l);
        for (int i = 0; i < nb; i++)
            for (int k = 0; k < nb; k++)
                col[i] += RTHS_AT(s, nb, i, k) * RTHS_AT(x, nb, k, nb + l);
    }
    if (rths_cmat_solve(na, nc, d, y)) {
        rc = rths_error_set(err, RTHS_EFAIL, "the assembly is singular at %g rad/s", w);
        goto done;
    }
    for (int c = 0; c < nc; c++)
        for (int i = 0; i < nb; i++)
            RTHS_AT(x, nb, i, c) = RTHS_AT(y, na, i, c);
done:
    free(hb), free(s), free(d), free(y);
    return rc;
}

int rths_krylov_interface_response(const rths_reduced *r, int n_loads, const double *reduced_loads,
                                   const rths_krylov_attachment *rest, double omega_rad_s,
                                   double complex *x_out, rths_error *err) {
    int nr = r->nr, nb = r->n_boundary, nc = nb + n_loads;
    double w = omega_rad_s;
    double complex *d = malloc(sizeof *d * (size_t)nr * (size_t)nr);
    double complex *y = calloc((size_t)nr * (size_t)nc, sizeof *y);
    if (!d || !y) {
        free(d), free(y);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (size_t e = 0; e < (size_t)nr * (size_t)nr; e++)
        d[e] = r->stiffness[e] + I * w * r->damping[e] - w * w * r->mass[e];
    for (int c = 0; c < nb; c++)
        RTHS_AT(y, nr, c, c) = 1; /* T^T e_b = e_b: the interface rows of T are [I 0] */
    for (int l = 0; l < n_loads; l++)
        for (int i = 0; i < nr; i++)
            RTHS_AT(y, nr, i, nb + l) = RTHS_AT(reduced_loads, nr, i, l);
    int rc = rths_cmat_solve(nr, nc, d, y)
                 ? rths_error_set(err, RTHS_EFAIL, "the reduced model is singular at %g rad/s", w)
                 : RTHS_OK;
    for (int c = 0; c < nc && !rc; c++)
        for (int i = 0; i < nb; i++)
            RTHS_AT(x_out, nb, i, c) = RTHS_AT(y, nr, i, c);
    free(d), free(y);
    return rc ? rc : couple(nb, n_loads, x_out, rest, w, err);
}

/* ---- the reduction ---- */

/* The interior block A_ii (compressed) and the coupling A_ib (dense ni x nb) of the lower
 * triangle a whose first nb DoFs are the interface. */
static int split_blocks(const rths_sparse_sym *a, int nb, rths_sparse_sym *aii, double *aib,
                        rths_error *err) {
    int n = a->n, ni = n - nb;
    long count = 0, cap = a->colptr[n];
    int *ti = malloc(sizeof(int) * (size_t)(cap > 0 ? cap : 1));
    int *tj = malloc(sizeof(int) * (size_t)(cap > 0 ? cap : 1));
    double *tv = malloc(sizeof(double) * (size_t)(cap > 0 ? cap : 1));
    if (!ti || !tj || !tv) {
        free(ti), free(tj), free(tv);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int j = 0; j < n; j++)
        for (int e = a->colptr[j]; e < a->colptr[j + 1]; e++) {
            int i = a->rowidx[e]; /* i >= j */
            if (j >= nb)
                ti[count] = i - nb, tj[count] = j - nb, tv[count++] = a->value[e];
            else if (i >= nb)
                RTHS_AT(aib, ni, i - nb, j) += a->value[e];
        }
    int rc = rths_sparse_from_triplets(ni, count, ti, tj, tv, aii, err);
    free(ti), free(tj), free(tv);
    return rc;
}

typedef struct {
    int nn, nb, ni, nl, max_basis;
    const rths_sparse_sym *full[3];  /* M, C, K */
    rths_sparse_sym inner[3];        /* M_ii, C_ii, K_ii */
    const rths_sparse_sym *terms[3]; /* K_ii, C_ii, M_ii for the factor */
    rths_sparse_factor *factor;
    double *psi;  /* ni x nb */
    double *rhs;  /* ni x (nl + 2 nb): f_i, G, H */
    double *v;    /* ni x max_basis, M_ii-orthonormal */
    double *mv;   /* M_ii v */
    int k;        /* columns of v */
    double *work; /* ni */
    double complex *cx;
} builder;

static void builder_free(builder *b) {
    for (int t = 0; t < 3; t++)
        rths_sparse_free(&b->inner[t]);
    if (b->factor) rths_sparse_factor_destroy(b->factor);
    free(b->psi), free(b->rhs), free(b->v), free(b->mv), free(b->work), free(b->cx);
}

static double dot(int n, const double *a, const double *b) {
    double s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

/* Adds x (ni, overwritten) to the basis when it is not in its span: two passes of classical
 * Gram-Schmidt in the M_ii inner product, then M_ii-normalised. 1 when added. */
static int add_vector(builder *b, double *x) {
    int ni = b->ni;
    double *mx = b->work;
    rths_sparse_symv(&b->inner[0], x, mx);
    double before = sqrt(fmax(dot(ni, x, mx), 0));
    if (!(before > 0)) return 0;
    for (int pass = 0; pass < 2; pass++) {
        for (int c = 0; c < b->k; c++) {
            double h = dot(ni, b->mv + (size_t)c * ni, x);
            const double *vc = b->v + (size_t)c * ni;
            for (int i = 0; i < ni; i++)
                x[i] -= h * vc[i];
        }
    }
    rths_sparse_symv(&b->inner[0], x, mx);
    double after = sqrt(fmax(dot(ni, x, mx), 0));
    if (!(after > DEPENDENT_FRACTION * before)) return 0;
    double *vk = b->v + (size_t)b->k * ni, *mvk = b->mv + (size_t)b->k * ni;
    for (int i = 0; i < ni; i++)
        vk[i] = x[i] / after, mvk[i] = mx[i] / after;
    b->k++;
    return 1;
}

/* The candidates of one frequency: Re and Im of the columns of sol (ni x (nl + 2 nb), the
 * interior's solves D_ii(w)^-1 [f_i, G, H]) in that order (the loads first: the forcing's shapes
 * matter most), each added while the basis has room. Returns how many were added, or -1. */
static int add_candidates(builder *b, const double complex *sol, rths_error *err) {
    int ni = b->ni, nc = b->nl + 2 * b->nb, added = 0;
    double *x = malloc(sizeof(double) * (size_t)ni);
    if (!x) {
        rths_error_set(err, RTHS_EFAIL, "out of memory");
        return -1;
    }
    for (int c = 0; c < nc && b->k < b->max_basis; c++)
        for (int part = 0; part < 2 && b->k < b->max_basis; part++) {
            const double complex *col = sol + (size_t)c * ni;
            for (int i = 0; i < ni; i++)
                x[i] = part ? cimag(col[i]) : creal(col[i]);
            added += add_vector(b, x);
        }
    free(x);
    return added;
}

static double *project(const rths_sparse_sym *a, const double *t, int n, int nr) {
    double *at = rths_mat_new(n, nr), *out = rths_mat_new(nr, nr);
    if (!at || !out) {
        rths_mat_free(at), rths_mat_free(out);
        return NULL;
    }
    for (int c = 0; c < nr; c++)
        rths_sparse_symv(a, t + (size_t)c * n, at + (size_t)c * n);
    rths_mat_mul(nr, nr, n, 1.0, t, 1, at, 0, 0.0, out);
    for (int j = 0; j < nr; j++) /* exactly symmetric, as the real-time form assumes */
        for (int i = j + 1; i < nr; i++) {
            double s = 0.5 * (RTHS_AT(out, nr, i, j) + RTHS_AT(out, nr, j, i));
            RTHS_AT(out, nr, i, j) = RTHS_AT(out, nr, j, i) = s;
        }
    rths_mat_free(at);
    return out;
}

/* out from the current basis: T = [[I, 0], [Psi, V]] and T^T {M, C, K} T. */
static int build_reduced(const builder *b, rths_reduced *out, rths_error *err) {
    rths_reduced_free(out);
    int nn = b->nn, nb = b->nb, ni = b->ni, nr = nb + b->k;
    *out = (rths_reduced){.n = nn,
                          .n_boundary = nb,
                          .n_modes = b->k,
                          .nr = nr,
                          .cutoff_hz = NAN,
                          .first_dropped_hz = INFINITY,
                          .dropped_mass_kg = NAN};
    out->transform = rths_mat_new(nn, nr);
    out->mode_hz = calloc((size_t)(b->k > 0 ? b->k : 1), sizeof(double));
    if (!out->transform || !out->mode_hz) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int c = 0; c < nb; c++) {
        RTHS_AT(out->transform, nn, c, c) = 1;
        for (int i = 0; i < ni; i++)
            RTHS_AT(out->transform, nn, nb + i, c) = RTHS_AT(b->psi, ni, i, c);
    }
    for (int c = 0; c < b->k; c++)
        memcpy(out->transform + (size_t)(nb + c) * nn + nb, b->v + (size_t)c * ni,
               sizeof(double) * (size_t)ni);
    if (!(out->mass = project(b->full[0], out->transform, nn, nr)) ||
        !(out->damping = project(b->full[1], out->transform, nn, nr)) ||
        !(out->stiffness = project(b->full[2], out->transform, nn, nr)))
        return rths_error_set(err, RTHS_EFAIL, "out of memory in the reduction");
    return RTHS_OK;
}

/* Rotates V to the Ritz vectors of (K_ii, M_ii) in its span (V^T M_ii V = I, so the small
 * problem is the standard V^T K_ii V y = lambda y), ascending; their frequencies in hz. */
static int ritz_rotate(builder *b, double *hz, rths_error *err) {
    int ni = b->ni, k = b->k;
    if (k == 0) return RTHS_OK;
    double *kv = rths_mat_new(ni, k), *small = rths_mat_new(k, k),
           *lambda = malloc(sizeof(double) * (size_t)k);
    double *rotated = rths_mat_new(ni, k);
    int rc = kv && small && lambda && rotated ? RTHS_OK
                                              : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int c = 0; c < k && !rc; c++)
        rths_sparse_symv(&b->inner[2], b->v + (size_t)c * ni, kv + (size_t)c * ni);
    if (!rc) {
        rths_mat_mul(k, k, ni, 1.0, b->v, 1, kv, 0, 0.0, small);
        int info = LAPACKE_dsyev(LAPACK_COL_MAJOR, 'V', 'L', k, small, k, lambda);
        if (info)
            rc = rths_error_set(err, RTHS_EFAIL, "Ritz rotation failed (dsyev info %d)", info);
    }
    if (!rc) {
        rths_mat_mul(ni, k, k, 1.0, b->v, 0, small, 0, 0.0, rotated);
        memcpy(b->v, rotated, sizeof(double) * (size_t)ni * (size_t)k);
        for (int c = 0; c < k; c++)
            hz[c] = sqrt(fmax(lambda[c], 0)) / (2 * M_PI);
    }
    free(kv), free(small), free(lambda), free(rotated);
    return rc;
}

int rths_krylov_reduce(const rths_sparse_sym *mass, const rths_sparse_sym *damping,
                       const rths_sparse_sym *stiffness, int n_boundary, int n_loads,
                       const double *loads, const rths_krylov_attachment *rest,
                       const rths_krylov_options *opt, rths_reduced *out, rths_krylov_report *rep,
                       rths_error *err) {
    memset(out, 0, sizeof *out);
    *rep = (rths_krylov_report){.max_error = NAN, .at_hz = NAN};
    int nn = stiffness->n, nb = n_boundary, nl = n_loads, ni = nn - nb, nc = nb + nl;
    int np = opt->check_points;
    if (mass->n != nn || damping->n != nn)
        return rths_error_set(err, RTHS_EINPUT, "Krylov reduction: M, C, K of orders %d, %d, %d",
                              mass->n, damping->n, nn);
    if (nb < 1 || nb >= nn || nl < 0 || (nl > 0 && !loads))
        return rths_error_set(err, RTHS_EINPUT,
                              "Krylov reduction: %d interface DoFs of %d (an interior needed), "
                              "%d loads",
                              nb, nn, nl);
    if (opt->max_size < nb || opt->max_size > RTHS_REALTIME_MAX_DOFS)
        return rths_error_set(err, RTHS_EINPUT,
                              "Krylov reduction: size bound %d outside %d..%d (the interface's "
                              "DoFs .. RTHS_REALTIME_MAX_DOFS)",
                              opt->max_size, nb, RTHS_REALTIME_MAX_DOFS);
    if (!(opt->start_hz >= 0) || !(opt->end_hz > opt->start_hz) || np < 2 || np > 10000 ||
        !(opt->max_error > 0))
        return rths_error_set(err, RTHS_EINPUT,
                              "Krylov reduction: band %g..%g Hz (0 <= start < end), %d check "
                              "points (2..10000), max_error %g (> 0)",
                              opt->start_hz, opt->end_hz, np, opt->max_error);
    builder b = {.nn = nn, .nb = nb, .ni = ni, .nl = nl, .full = {mass, damping, stiffness}};
    b.max_basis = opt->max_size - nb < ni ? opt->max_size - nb : ni;
    const int ncand = nl + 2 * nb; /* candidate columns per frequency: f_i, G, H */
    const int nsolve = nb + ncand; /* interior solves per check point: D_ib, then those */
    double *hz = malloc(sizeof(double) * (size_t)np);
    double complex *truth = malloc(sizeof(double complex) * (size_t)np * (size_t)(nb * nc));
    double complex *xr = malloc(sizeof(double complex) * (size_t)(nb * nc));
    /* every check point's candidates, so a shift costs no further factorisation:
     * ni x ncand complex per point */
    double complex *cand =
        malloc(sizeof(double complex) * (size_t)ni * (size_t)ncand * (size_t)(np + 1));
    double complex *dib = malloc(sizeof(double complex) * (size_t)ni * (size_t)nb);
    double complex *schur = malloc(sizeof(double complex) * (size_t)(nb * nb));
    double *dense_bb[3] = {rths_mat_new(nb, nb), rths_mat_new(nb, nb), rths_mat_new(nb, nb)};
    double *coupling[3] = {rths_mat_new(ni, nb), rths_mat_new(ni, nb), rths_mat_new(ni, nb)};
    double *reduced_loads = NULL;
    int *used = calloc((size_t)np, sizeof(int));
    b.psi = rths_mat_new(ni, nb);
    b.rhs = rths_mat_new(ni, ncand);
    b.v = rths_mat_new(ni, b.max_basis > 0 ? b.max_basis : 1);
    b.mv = rths_mat_new(ni, b.max_basis > 0 ? b.max_basis : 1);
    b.work = malloc(sizeof(double) * (size_t)ni);
    b.cx = malloc(sizeof(double complex) * (size_t)ni * (size_t)nsolve);
    int rc = hz && truth && xr && cand && dib && schur && used && b.psi && b.rhs && b.v && b.mv &&
                     b.work && b.cx
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int t = 0; t < 3 && !rc; t++)
        if (!dense_bb[t] || !coupling[t]) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");

    /* the interior: its blocks, the constraint modes, the right-hand sides f_i, G, H and the
     * static candidates (D_ii(0) = K_ii) */
    double t0 = rths_monotonic_s();
    for (int t = 0; t < 3 && !rc; t++) {
        rc = split_blocks(b.full[t], nb, &b.inner[t], coupling[t], err);
        for (int j = 0; j < nb && !rc; j++)
            for (int i = 0; i < nb; i++)
                RTHS_AT(dense_bb[t], nb, i, j) = rths_sparse_get(b.full[t], i, j);
    }
    b.terms[0] = &b.inner[2], b.terms[1] = &b.inner[1], b.terms[2] = &b.inner[0];
    if (!rc) rc = rths_sparse_factor_create(3, b.terms, opt->ordering, &b.factor, err);
    if (!rc) {
        double coef[3] = {1, 0, 0};
        for (size_t e = 0; e < (size_t)ni * (size_t)nb; e++)
            b.psi[e] = -coupling[2][e];
        rc = rths_sparse_factor_real(b.factor, coef, err);
        if (!rc) rc = rths_sparse_solve_real(b.factor, b.psi, nb, err);
    }
    if (!rc) {
        for (int l = 0; l < nl; l++)
            for (int i = 0; i < ni; i++)
                RTHS_AT(b.rhs, ni, i, l) = RTHS_AT(loads, nn, nb + i, l);
        for (int t = 0; t < 2; t++) /* G (mass), H (damping) */
            for (int c = 0; c < nb; c++) {
                double *col = b.rhs + (size_t)(nl + t * nb + c) * ni;
                rths_sparse_symv(&b.inner[t], b.psi + (size_t)c * ni, col);
                for (int i = 0; i < ni; i++)
                    col[i] += RTHS_AT(coupling[t], ni, i, c);
            }
        double *stat = rths_mat_dup(b.rhs, ni, ncand);
        rc = stat ? rths_sparse_solve_real(b.factor, stat, ncand, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
        double complex *c0 = cand + (size_t)np * ni * ncand; /* the static point: slot np */
        for (size_t e = 0; !rc && e < (size_t)ni * (size_t)ncand; e++)
            c0[e] = stat[e];
        rths_mat_free(stat);
    }
    rep->basis_s = rths_monotonic_s() - t0;

    /* each check point: one complex LDL^T of D_ii(w) and one solve with [D_ib, f_i, G, H]; the
     * numerical side's interface response by the Schur complement S = D_bb - D_bi D_ii^-1 D_ib
     * (exact: the same as one full solve), x_b = S^-1 (e_b | f_b - D_bi D_ii^-1 f_i) */
    t0 = rths_monotonic_s();
    for (int p = 0; p < np && !rc; p++) {
        hz[p] = opt->start_hz + (opt->end_hz - opt->start_hz) * p / (np - 1);
        double w = 2 * M_PI * hz[p];
        double complex coef[3] = {1, I * w, -w * w};
        rc = rths_sparse_factor_complex(b.factor, coef, err);
        if (rc) break;
        for (size_t e = 0; e < (size_t)ni * (size_t)nb; e++)
            dib[e] = coupling[2][e] + I * w * coupling[1][e] - w * w * coupling[0][e];
        memcpy(b.cx, dib, sizeof(double complex) * (size_t)ni * (size_t)nb);
        for (size_t e = 0; e < (size_t)ni * (size_t)ncand; e++)
            b.cx[(size_t)ni * nb + e] = b.rhs[e];
        rc = rths_sparse_solve_complex(b.factor, b.cx, nsolve, err);
        if (rc) break;
        const double complex *y = b.cx, *z = b.cx + (size_t)ni * nb;
        memcpy(cand + (size_t)p * ni * ncand, z, sizeof(double complex) * (size_t)ni * ncand);
        double complex *tp = truth + (size_t)p * (size_t)(nb * nc);
        for (int j = 0; j < nb; j++)
            for (int i = 0; i < nb; i++) {
                double complex sij = RTHS_AT(dense_bb[2], nb, i, j) +
                                     I * w * RTHS_AT(dense_bb[1], nb, i, j) -
                                     w * w * RTHS_AT(dense_bb[0], nb, i, j);
                for (int k = 0; k < ni; k++)
                    sij -= RTHS_AT(dib, ni, k, i) * RTHS_AT(y, ni, k, j);
                RTHS_AT(schur, nb, i, j) = sij;
                RTHS_AT(tp, nb, i, j) = i == j;
            }
        for (int l = 0; l < nl; l++)
            for (int i = 0; i < nb; i++) {
                double complex r = RTHS_AT(loads, nn, i, l);
                for (int k = 0; k < ni; k++)
                    r -= RTHS_AT(dib, ni, k, i) * RTHS_AT(z, ni, k, l);
                RTHS_AT(tp, nb, i, nb + l) = r;
            }
        if (rths_cmat_solve(nb, nc, schur, tp))
            rc = rths_error_set(err, RTHS_EFAIL,
                                "Krylov reduction: the numerical side is singular at %g Hz", hz[p]);
        if (!rc) rc = couple(nb, nl, tp, rest, w, err);
    }
    rep->truth_s = rths_monotonic_s() - t0;
    rep->check_points = np;
    for (int t = 0; t < 3; t++)
        rths_mat_free(coupling[t]), rths_mat_free(dense_bb[t]);

    /* greedy: the static candidates, then each time the worst check point's */
    t0 = rths_monotonic_s();
    int next_p = np; /* the static slot */
    for (;;) {
        if (rc) break;
        int added = 0;
        if (b.k < b.max_basis) {
            added = add_candidates(&b, cand + (size_t)next_p * ni * ncand, err);
            if (added < 0) {
                rc = RTHS_EFAIL;
                break;
            }
            if (rep->shifts < RTHS_REALTIME_MAX_DOFS)
                rep->shift_hz[rep->shifts++] = next_p < np ? hz[next_p] : 0.0;
            if (next_p < np) used[next_p] = 1;
        }
        rc = build_reduced(&b, out, err);
        free(reduced_loads);
        reduced_loads = rc ? NULL : rths_mat_new(out->nr, nl > 0 ? nl : 1);
        if (!rc && !reduced_loads) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        if (!rc && nl > 0)
            rths_mat_mul(out->nr, nl, nn, 1.0, out->transform, 1, loads, 0, 0.0, reduced_loads);
        double worst = 0, worst_free_e = -1;
        int worst_p = 0, worst_free = -1;
        for (int p = 0; p < np && !rc; p++) {
            rc = rths_krylov_interface_response(out, nl, reduced_loads, rest, 2 * M_PI * hz[p], xr,
                                                err);
            const double complex *tp = truth + (size_t)p * (size_t)(nb * nc);
            double e = 0;
            for (int c = 0; c < nc && !rc; c++) {
                double num = 0, den = 0;
                for (int i = 0; i < nb; i++) {
                    double complex d = RTHS_AT(xr, nb, i, c) - RTHS_AT(tp, nb, i, c);
                    num += creal(d * conj(d));
                    den += creal(RTHS_AT(tp, nb, i, c) * conj(RTHS_AT(tp, nb, i, c)));
                }
                double ec = den > 0 ? sqrt(num / den) : (num > 0 ? INFINITY : 0);
                if (!(ec <= e)) e = ec; /* NAN counts as worst */
            }
            if (!(e <= worst)) worst = e, worst_p = p;
            if (!used[p] && !(e <= worst_free_e)) worst_free_e = e, worst_free = p;
        }
        if (rc) break;
        rep->max_error = worst;
        rep->at_hz = hz[worst_p];
        if ((worst <= opt->max_error && !opt->fill) || b.k >= b.max_basis || worst_free < 0 ||
            (added == 0 && rep->shifts > 1))
            break;
        next_p = worst_free;
    }
    /* the final basis as Ritz vectors (the same span: the same reduced response) */
    if (!rc && b.k > 0) {
        double *ritz_hz = malloc(sizeof(double) * (size_t)b.k);
        rc = ritz_hz ? ritz_rotate(&b, ritz_hz, err)
                     : rths_error_set(err, RTHS_EFAIL, "out of memory");
        if (!rc) rc = build_reduced(&b, out, err);
        if (!rc) memcpy(out->mode_hz, ritz_hz, sizeof(double) * (size_t)b.k);
        free(ritz_hz);
    }
    rep->basis = b.k;
    rep->basis_s += rths_monotonic_s() - t0;
    if (!rc && !(rep->max_error <= opt->max_error))
        rc = rths_error_set(err, RTHS_EINPUT,
                            "Krylov reduction: the reduced numerical substructure (%d DoFs, at "
                            "most %d) is %.3g %% off the full sparse solve at %g Hz, above "
                            "controller.reduction.max_error %.3g %% (over %d check points of "
                            "%g-%g Hz); narrow the band, or set split.numerical_solver to "
                            "frequency",
                            nb + b.k, opt->max_size, 100 * rep->max_error, rep->at_hz,
                            100 * opt->max_error, np, opt->start_hz, opt->end_hz);
    builder_free(&b);
    free(hz), free(truth), free(xr), free(cand), free(dib), free(schur), free(used);
    free(reduced_loads);
    if (rc) rths_reduced_free(out);
    return rc;
}

/* ---- on a sparse model ---- */

int rths_sparse_model_krylov_reduce(const rths_sparse_model *m, const rths_krylov_options *opt,
                                    rths_reduced *out, int **dofs_out, rths_krylov_report *rep,
                                    rths_error *err) {
    memset(out, 0, sizeof *out);
    *rep = (rths_krylov_report){.max_error = NAN, .at_hz = NAN};
    if (dofs_out) *dofs_out = NULL;
    /* the physical side is what a rig carries: a few DoFs; dense here */
    enum { MAX_PHYSICAL = 2000 };
    double *phys[3];
    int np = 0, nb = m->n_int;
    int rc =
        rths_sparse_model_physical_side(m, MAX_PHYSICAL, &phys[0], &phys[1], &phys[2], &np, err);
    if (rc) return rc;
    rths_sparse_sym nm, nc, nk;
    int *dofs = NULL, nn = 0;
    rc = rths_sparse_model_numerical_side(m, &nm, &nc, &nk, &dofs, &nn, err);
    if (rc) {
        for (int t = 0; t < 3; t++)
            rths_mat_free(phys[t]);
        return rc;
    }
    /* the attachment's order: interface first, then the internal physical DoFs (phys is in
     * rths_split's order: internal physical, then interface) */
    int n_phys = np - nb;
    double *rest_m[3] = {rths_mat_new(np, np), rths_mat_new(np, np), rths_mat_new(np, np)};
    double *loads = malloc(sizeof(double) * (size_t)nn), *rl = rths_mat_new(np, 1);
    int *phys_dofs = malloc(sizeof(int) * (size_t)(n_phys > 0 ? n_phys : 1));
    if (!rest_m[0] || !rest_m[1] || !rest_m[2] || !loads || !rl || !phys_dofs)
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0, q = 0; i < m->n && !rc; i++)
        if (m->roles[i] == RTHS_DOF_PHYSICAL) phys_dofs[q++] = i;
#define FROM(a) ((a) < nb ? n_phys + (a) : (a)-nb)
    for (int t = 0; t < 3 && !rc; t++)
        for (int j = 0; j < np; j++)
            for (int i = 0; i < np; i++)
                RTHS_AT(rest_m[t], np, i, j) = RTHS_AT(phys[t], np, FROM(i), FROM(j));
#undef FROM
    if (!rc) {
        /* the load: the model's force where it acts, the interface's share on the numerical side
         * (either side would do: the check sums them) */
        for (int i = 0; i < nn; i++)
            loads[i] = m->force[dofs[i]];
        for (int i = 0; i < n_phys; i++)
            rl[nb + i] = m->force[phys_dofs[i]];
        rths_krylov_attachment rest = {.n_extra = n_phys,
                                       .mass = rest_m[0],
                                       .damping = rest_m[1],
                                       .stiffness = rest_m[2],
                                       .loads = rl};
        rc = rths_krylov_reduce(&nm, &nc, &nk, nb, 1, loads, &rest, opt, out, rep, err);
    }
    for (int t = 0; t < 3; t++)
        rths_mat_free(phys[t]), rths_mat_free(rest_m[t]);
    free(loads), free(rl), free(phys_dofs);
    rths_sparse_free(&nm), rths_sparse_free(&nc), rths_sparse_free(&nk);
    if (!rc && dofs_out)
        *dofs_out = dofs;
    else
        free(dofs);
    return rc;
}
