/* Neutral delay equation of the delayed-feedback test: construction (see stability.h for the
 * derivation), characteristic function, Newton on roots, essential spectrum. */
#include "rths/stability.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void rths_dde_free(rths_dde *d) {
    if (!d) return;
    free(d->m0); /* one block holds all six */
    memset(d, 0, sizeof *d);
}

static int dde_alloc(int n, rths_dde *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    if (n < 1) return rths_error_set(err, RTHS_EINPUT, "delay equation needs n >= 1, got %d", n);
    size_t nn = (size_t)n * (size_t)n;
    double *blk = calloc(6 * nn, sizeof(double));
    if (!blk) return rths_error_set(err, RTHS_EFAIL, "out of memory building the delay equation");
    out->n = n;
    out->m0 = blk;
    out->mt = blk + nn;
    out->c0 = blk + 2 * nn;
    out->ct = blk + 3 * nn;
    out->k0 = blk + 4 * nn;
    out->kt = blk + 5 * nn;
    return RTHS_OK;
}

int rths_dde_from_matrices(int n, const double *m0, const double *mt, const double *c0,
                           const double *ct, const double *k0, const double *kt, rths_dde *out,
                           rths_error *err) {
    int rc = dde_alloc(n, out, err);
    if (rc) return rc;
    const double *src[6] = {m0, mt, c0, ct, k0, kt};
    double *dst[6] = {out->m0, out->mt, out->c0, out->ct, out->k0, out->kt};
    size_t nn = (size_t)n * (size_t)n;
    for (int m = 0; m < 6; m++) {
        if (!src[m]) continue;
        for (size_t k = 0; k < nn; k++) {
            if (!isfinite(src[m][k])) {
                rths_dde_free(out);
                return rths_error_set(err, RTHS_EINPUT,
                                      "delay equation matrix %d has a "
                                      "non-finite entry",
                                      m);
            }
            dst[m][k] = src[m][k];
        }
    }
    return RTHS_OK;
}

int rths_dde_from_split(const rths_assembly *a, const rths_split *s, rths_dde *out,
                        rths_error *err) {
    if (s->n != a->n) return rths_error_set(err, RTHS_EINPUT, "split and assembly sizes differ");
    int rc = dde_alloc(a->n, out, err);
    if (rc) return rc;
    int n = a->n, np = s->np, nn = s->nn;
    const double *pm[3] = {s->mass_phys, s->damping_phys, s->stiffness_phys};
    const double *nm[3] = {s->mass_num, s->damping_num, s->stiffness_num};
    double *x0[3] = {out->m0, out->c0, out->k0};
    double *xt[3] = {out->mt, out->ct, out->kt};
    for (int m = 0; m < 3; m++) {
        /* physical substructure: an interface column is the delayed numerical interface */
        for (int i = 0; i < np; i++) {
            int gi = i < s->n_phys ? s->phys_dofs[i] : s->int_dofs[i - s->n_phys];
            for (int j = 0; j < np; j++) {
                int delayed = j >= s->n_phys;
                int gj = delayed ? s->int_dofs[j - s->n_phys] : s->phys_dofs[j];
                RTHS_AT(delayed ? xt[m] : x0[m], n, gi, gj) += RTHS_AT(pm[m], np, i, j);
            }
        }
        for (int i = 0; i < nn; i++) {
            int gi = i < s->n_int ? s->int_dofs[i] : s->num_dofs[i - s->n_int];
            for (int j = 0; j < nn; j++) {
                int gj = j < s->n_int ? s->int_dofs[j] : s->num_dofs[j - s->n_int];
                RTHS_AT(x0[m], n, gi, gj) += RTHS_AT(nm[m], nn, i, j);
            }
        }
    }
    return RTHS_OK;
}

int rths_dde_from_setup(const rths_setup *s, rths_dde *out, rths_error *err) {
    int rc = rths_dde_from_split(&s->assembly, &s->split, out, err);
    if (rc) return rc;
    const rths_split *sp = &s->split;
    int n = s->assembly.n;
    for (int d = 0; d < sp->n_int; d++)
        for (int e = 0; e < sp->n_int; e++)
            RTHS_AT(out->mt, n, sp->int_dofs[d], sp->int_dofs[e]) =
                rths_setup_rig_interface_mass(s, d, e) - rths_setup_compensation_mass(s, d, e);
    return RTHS_OK;
}

/* ---- small dense complex LU (n is a handful of DoFs; LAPACK call overhead would dominate) ---- */

/* In place, partial pivoting. Returns the determinant; 0 when a pivot vanishes exactly. */
static double complex clu(int n, double complex *a, int *piv) {
    double complex det = 1.0;
    for (int k = 0; k < n; k++) {
        int p = k;
        double best = cabs(a[k + k * n]);
        for (int i = k + 1; i < n; i++) {
            double v = cabs(a[i + k * n]);
            if (v > best) best = v, p = i;
        }
        piv[k] = p;
        if (best == 0.0) return 0.0;
        if (p != k) {
            for (int j = 0; j < n; j++) {
                double complex t = a[k + j * n];
                a[k + j * n] = a[p + j * n];
                a[p + j * n] = t;
            }
            det = -det;
        }
        double complex pk = a[k + k * n];
        det *= pk;
        for (int i = k + 1; i < n; i++) {
            double complex l = a[i + k * n] / pk;
            a[i + k * n] = l;
            if (l != 0.0)
                for (int j = k + 1; j < n; j++)
                    a[i + j * n] -= l * a[k + j * n];
        }
    }
    return det;
}

static void clu_solve(int n, const double complex *lu, const int *piv, double complex *b) {
    /* clu swaps whole rows (L included), so P A = L U: permute b fully, then substitute */
    for (int k = 0; k < n; k++)
        if (piv[k] != k) {
            double complex t = b[k];
            b[k] = b[piv[k]];
            b[piv[k]] = t;
        }
    for (int k = 0; k < n; k++)
        for (int i = k + 1; i < n; i++)
            b[i] -= lu[i + k * n] * b[k];
    for (int k = n - 1; k >= 0; k--) {
        b[k] /= lu[k + k * n];
        for (int i = 0; i < k; i++)
            b[i] -= lu[i + k * n] * b[k];
    }
}

#define RTHS_DDE_STACK 16

/* A(lambda) into a (n x n complex); when da/dt are non-NULL also dA/dlambda and dA/dtau. */
static void char_matrix(const rths_dde *d, double tau, double complex l, double complex *a,
                        double complex *da, double complex *dt) {
    int n = d->n;
    double complex e = cexp(-l * tau);
    for (int k = 0; k < n * n; k++) {
        double complex del = l * l * d->mt[k] + l * d->ct[k] + d->kt[k];
        a[k] = l * l * d->m0[k] + l * d->c0[k] + d->k0[k] + e * del;
        if (da)
            da[k] = 2.0 * l * (d->m0[k] + e * d->mt[k]) + d->c0[k] + e * d->ct[k] - tau * e * del;
        if (dt) dt[k] = -l * e * del;
    }
}

int rths_dde_char(const rths_dde *d, double tau, double complex lambda, double complex *det_out,
                  double complex *dlog_dlambda, double complex *dlog_dtau) {
    int n = d->n;
    size_t nn = (size_t)n * (size_t)n;
    double complex sa[3 * RTHS_DDE_STACK * RTHS_DDE_STACK];
    int spiv[RTHS_DDE_STACK];
    double complex *a = sa, *heap = NULL;
    int *piv = spiv, *hpiv = NULL;
    if (n > RTHS_DDE_STACK) {
        heap = malloc(3 * nn * sizeof *heap);
        hpiv = malloc((size_t)n * sizeof *hpiv);
        if (!heap || !hpiv) {
            free(heap);
            free(hpiv);
            if (det_out) *det_out = NAN;
            return -1;
        }
        a = heap;
        piv = hpiv;
    }
    double complex *da = a + nn, *dt = a + 2 * nn;
    int want = dlog_dlambda || dlog_dtau;
    char_matrix(d, tau, lambda, a, want ? da : NULL, want ? dt : NULL);
    double complex det = clu(n, a, piv);
    if (det_out) *det_out = det;
    int rc = 0;
    if (det == 0.0 || !isfinite(creal(det)) || !isfinite(cimag(det))) {
        rc = -1;
    } else if (want) {
        /* trace(A^{-1} B) column by column: solve A x = B e_j, take x_j */
        double complex tl = 0, tt = 0;
        for (int j = 0; j < n; j++) {
            clu_solve(n, a, piv, da + (size_t)j * n);
            clu_solve(n, a, piv, dt + (size_t)j * n);
            tl += da[j + (size_t)j * n];
            tt += dt[j + (size_t)j * n];
        }
        if (dlog_dlambda) *dlog_dlambda = tl;
        if (dlog_dtau) *dlog_dtau = tt;
    }
    free(heap);
    free(hpiv);
    return rc;
}

static double row_scale(const rths_dde *d, int i, double r) {
    int n = d->n;
    double sm = 0, sc = 0, sk = 0;
    for (int j = 0; j < n; j++) {
        sm += fabs(RTHS_AT(d->m0, n, i, j)) + fabs(RTHS_AT(d->mt, n, i, j));
        sc += fabs(RTHS_AT(d->c0, n, i, j)) + fabs(RTHS_AT(d->ct, n, i, j));
        sk += fabs(RTHS_AT(d->k0, n, i, j)) + fabs(RTHS_AT(d->kt, n, i, j));
    }
    double s = r * r * sm + r * sc + sk;
    return s > 0 ? s : 1.0;
}

/* D(lambda) with each row divided by its row_scale at |lambda|: the form both the scaled
 * determinant and the residual work on. */
static void scaled_char_matrix(const rths_dde *d, double tau, double complex lambda,
                               double complex *a) {
    int n = d->n;
    char_matrix(d, tau, lambda, a, NULL, NULL);
    double r = cabs(lambda);
    for (int i = 0; i < n; i++) {
        double s = 1.0 / row_scale(d, i, r);
        for (int j = 0; j < n; j++)
            a[i + (size_t)j * n] *= s;
    }
}

double complex rths_dde_char_scaled(const rths_dde *d, double tau, double complex lambda) {
    int n = d->n;
    size_t nn = (size_t)n * (size_t)n;
    double complex sa[RTHS_DDE_STACK * RTHS_DDE_STACK];
    int spiv[RTHS_DDE_STACK];
    double complex *a = sa;
    int *piv = spiv;
    if (n > RTHS_DDE_STACK) {
        a = malloc(nn * sizeof *a);
        piv = malloc((size_t)n * sizeof *piv);
        if (!a || !piv) {
            if (a != sa) free(a);
            if (piv != spiv) free(piv);
            return NAN;
        }
    }
    scaled_char_matrix(d, tau, lambda, a);
    double complex det = clu(n, a, piv);
    if (a != sa) free(a);
    if (piv != spiv) free(piv);
    return det;
}

double rths_dde_residual(const rths_dde *d, double tau, double complex lambda) {
    /* 1 / ||A^{-1}||_F lies within a factor sqrt(n) of the smallest singular value; for an
     * acceptance threshold that is plenty, and it needs only the small LU (no LAPACK call). */
    int n = d->n;
    size_t nn = (size_t)n * (size_t)n;
    double complex *a = malloc(2 * nn * sizeof *a);
    int *piv = malloc((size_t)n * sizeof *piv);
    if (!a || !piv) {
        free(a);
        free(piv);
        return INFINITY;
    }
    double complex *col = a + nn;
    scaled_char_matrix(d, tau, lambda, a);
    double complex det = clu(n, a, piv);
    double res = 0.0;
    if (det != 0.0 && isfinite(creal(det)) && isfinite(cimag(det))) {
        double fro = 0;
        for (int j = 0; j < n; j++) {
            memset(col, 0, (size_t)n * sizeof *col);
            col[j] = 1.0;
            clu_solve(n, a, piv, col);
            for (int i = 0; i < n; i++)
                fro += creal(col[i] * conj(col[i]));
        }
        res = isfinite(fro) && fro > 0 ? 1.0 / sqrt(fro) : 0.0;
    } else if (!isfinite(creal(det)) || !isfinite(cimag(det))) {
        res = INFINITY;
    }
    free(a);
    free(piv);
    return res;
}

int rths_dde_newton(const rths_dde *d, double tau, double complex *lambda) {
    double complex l = *lambda;
    for (int it = 0; it < 50; it++) {
        double complex g;
        if (rths_dde_char(d, tau, l, NULL, &g, NULL)) {
            *lambda = l; /* exactly singular: l is a root */
            return 0;
        }
        if (g == 0.0 || !isfinite(creal(g)) || !isfinite(cimag(g))) return -1;
        double complex step = 1.0 / g;
        /* a step longer than the root's own size means Newton left the basin: damp it */
        double lim = 0.5 * (1.0 + cabs(l));
        if (cabs(step) > lim) step *= lim / cabs(step);
        l -= step;
        if (cabs(step) <= 1e-12 * (1.0 + cabs(l))) {
            *lambda = l;
            return 0;
        }
    }
    *lambda = l;
    return -1;
}

int rths_dde_essential(const rths_dde *d, double *rate_times_tau, double complex *z, int *n_z,
                       rths_error *err) {
    int n = d->n;
    size_t nn = (size_t)n * (size_t)n;
    if (n_z) *n_z = 0;
    /* the leading (highest-derivative) coefficients decide the chain: M, or C for a first-order
     * equation without masses */
    const double *lead0 = d->m0, *leadt = d->mt;
    if (rths_mat_max_abs(d->m0, n, n) == 0 && rths_mat_max_abs(d->mt, n, n) == 0)
        lead0 = d->c0, leadt = d->ct;
    int any_mt = 0;
    for (size_t k = 0; k < nn; k++)
        any_mt |= leadt[k] != 0.0;
    double *a = rths_mat_dup(lead0, n, n), *b = NULL;
    double *ar = malloc((size_t)n * 3 * sizeof(double));
    if (!a || !ar) {
        free(a);
        free(ar);
        return rths_error_set(err, RTHS_EFAIL, "out of memory (essential spectrum)");
    }
    /* det(M_0 + z M_tau) = 0  <=>  M_0 v = z (-M_tau) v */
    b = rths_mat_new(n, n);
    if (!b) {
        free(a);
        free(ar);
        return rths_error_set(err, RTHS_EFAIL, "out of memory (essential spectrum)");
    }
    for (size_t k = 0; k < nn; k++)
        b[k] = -leadt[k];
    double *ai = ar + n, *be = ar + 2 * n;
    lapack_int info =
        LAPACKE_dggev(LAPACK_COL_MAJOR, 'N', 'N', n, a, n, b, n, ar, ai, be, NULL, 1, NULL, 1);
    if (info != 0) {
        free(a);
        free(b);
        free(ar);
        return rths_error_set(err, RTHS_EFAIL, "essential spectrum: LAPACK dggev info %d",
                              (int)info);
    }
    double m0n = rths_mat_max_abs(lead0, n, n), mtn = rths_mat_max_abs(leadt, n, n);
    double best = -INFINITY;
    int cnt = 0;
    for (int k = 0; k < n; k++) {
        double complex al = ar[k] + I * ai[k];
        /* beta ~ 0 relative to |M_tau|: an infinite z (no delayed mass in that direction, no
         * chain); alpha ~ 0 relative to |M_0|: z = 0, M_0 singular, an advanced equation */
        if (fabs(be[k]) <= 1e-12 * mtn) continue;
        if (cabs(al) <= 1e-12 * m0n) {
            best = INFINITY;
            continue;
        }
        double complex zk = al / be[k];
        if (z) z[cnt] = zk;
        cnt++;
        double r = -log(cabs(zk));
        if (r > best) best = r;
    }
    if (!any_mt) best = -INFINITY;
    *rate_times_tau = best;
    if (n_z) *n_z = cnt;
    free(a);
    free(b);
    free(ar);
    return RTHS_OK;
}
