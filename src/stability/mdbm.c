/* Multi-dimensional bisection (Bachrathy & Stepan) for D(i omega; tau, p) = 0: two real equations
 * (Re D, Im D) in three parameters, so the solution set is a curve whose projection on (tau, p) is
 * a stability boundary. A coarse grid is evaluated; a cell is kept when each of Re D and Im D takes
 * both signs on its corners; kept cells are bisected mdbm_refine times (keeping children with the
 * same property); each finest cell gives one point, projected onto D = 0 by Gauss-Newton (minimum
 * norm steps in cell units), and the points are chained into curves by nearest neighbours. D is the
 * row-scaled determinant (rths_dde_char_scaled): same zeros and signs, O(1) values. */
#include "stability_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct mdbm_ctx {
    rths_dde_family_fn family;
    void *fctx;
    double t0, p0, w0; /* coarse grid origin */
    double dt, dp, dw; /* coarse cell sizes */
    int pdeg;          /* p range is a single value: two-dimensional problem */
} mdbm_ctx;

typedef struct bpoint {
    double tau, p, omega, res;
} bpoint;

typedef struct bvec {
    bpoint *v;
    int n, cap;
} bvec;

static int bvec_push(bvec *b, bpoint pt) {
    if (b->n == b->cap) {
        int cap = b->cap ? 2 * b->cap : 16;
        bpoint *v = realloc(b->v, (size_t)cap * sizeof *v);
        if (!v) return -1;
        b->v = v;
        b->cap = cap;
    }
    b->v[b->n++] = pt;
    return 0;
}

static int sign_change(const double complex *v, int nv) {
    double rmin = INFINITY, rmax = -INFINITY, imin = INFINITY, imax = -INFINITY;
    for (int k = 0; k < nv; k++) {
        if (!isfinite(creal(v[k])) || !isfinite(cimag(v[k]))) return 0;
        rmin = fmin(rmin, creal(v[k]));
        rmax = fmax(rmax, creal(v[k]));
        imin = fmin(imin, cimag(v[k]));
        imax = fmax(imax, cimag(v[k]));
    }
    return rmin <= 0 && rmax >= 0 && imin <= 0 && imax >= 0;
}

/* D at normalised coordinates (a, b, c) = cell units from the origin */
static double complex eval_at(const mdbm_ctx *m, const rths_dde *d, double a, double c) {
    return rths_dde_char_scaled(d, m->t0 + a * m->dt, I * (m->w0 + c * m->dw));
}

/* Gauss-Newton onto D = 0 from (a, b, c); the p direction needs a DDE per p value. */
static int polish(const mdbm_ctx *m, double *x, double *res) {
    double h = 1e-4;
    rths_error err;
    for (int it = 0; it < 12; it++) {
        rths_dde d0, dp;
        double p = m->p0 + x[1] * m->dp;
        if (m->family(m->fctx, p, &d0, &err)) return -1;
        double complex f = eval_at(m, &d0, x[0], x[2]);
        double complex ja = (eval_at(m, &d0, x[0] + h, x[2]) - f) / h;
        double complex jc = (eval_at(m, &d0, x[0], x[2] + h) - f) / h;
        double complex jb = 0;
        if (!m->pdeg) {
            if (m->family(m->fctx, p + h * m->dp, &dp, &err)) {
                rths_dde_free(&d0);
                return -1;
            }
            jb = (eval_at(m, &dp, x[0], x[2]) - f) / h;
            rths_dde_free(&dp);
        }
        rths_dde_free(&d0);
        *res = cabs(f);
        /* J = [Re; Im] rows over columns (a, b, c); minimum-norm step -J^T (J J^T)^{-1} F */
        double J[2][3] = {{creal(ja), creal(jb), creal(jc)}, {cimag(ja), cimag(jb), cimag(jc)}};
        double g11 = 0, g12 = 0, g22 = 0;
        for (int k = 0; k < 3; k++) {
            g11 += J[0][k] * J[0][k];
            g12 += J[0][k] * J[1][k];
            g22 += J[1][k] * J[1][k];
        }
        double det = g11 * g22 - g12 * g12;
        if (!(fabs(det) > 0) || !isfinite(det)) return -1;
        double y0 = (g22 * creal(f) - g12 * cimag(f)) / det;
        double y1 = (-g12 * creal(f) + g11 * cimag(f)) / det;
        double step = 0;
        for (int k = 0; k < 3; k++) {
            double s = -(J[0][k] * y0 + J[1][k] * y1);
            x[k] += s;
            step += s * s;
        }
        if (sqrt(step) < 1e-10) {
            rths_dde d1;
            if (m->family(m->fctx, m->p0 + x[1] * m->dp, &d1, &err)) return -1;
            *res = cabs(eval_at(m, &d1, x[0], x[2]));
            rths_dde_free(&d1);
            return 0;
        }
    }
    return -1;
}

/* Recursive bisection of one coarse cell on a (2^R + 1)^3 lattice of lazily evaluated values. */
typedef struct cell_work {
    const mdbm_ctx *m;
    int R, L;       /* levels, lattice points per side = 2^R + 1 */
    int ci, cj, ck; /* coarse cell */
    rths_dde *dd;   /* DDE per lattice p index (L of them, built lazily) */
    int *dd_ok;
    double complex *val; /* L^3 */
    unsigned char *have;
    bvec *out;
    int fail;
} cell_work;

static double complex lattice(cell_work *w, int a, int b, int c) {
    size_t k = (size_t)a + (size_t)w->L * ((size_t)b + (size_t)w->L * (size_t)c);
    if (!w->have[k]) {
        if (!w->dd_ok[b]) {
            rths_error err;
            double p = w->m->p0 + (w->cj + (double)b / (w->L - 1)) * w->m->dp;
            if (w->m->family(w->m->fctx, p, &w->dd[b], &err)) {
                w->fail = 1;
                return NAN;
            }
            w->dd_ok[b] = 1;
        }
        double s = (double)(w->L - 1);
        w->val[k] = eval_at(w->m, &w->dd[b], w->ci + a / s, w->ck + c / s);
        w->have[k] = 1;
    }
    return w->val[k];
}

static void refine(cell_work *w, int a0, int b0, int c0, int size) {
    if (w->fail) return;
    double complex v[8] = {0};
    int nv = 0;
    int bs = w->m->pdeg ? 0 : size;
    for (int da = 0; da <= size; da += size)
        for (int db = 0; db <= bs; db += (bs ? bs : 1))
            for (int dc = 0; dc <= size; dc += size)
                v[nv++] = lattice(w, a0 + da, b0 + db, c0 + dc);
    if (!sign_change(v, nv)) return;
    if (size == 1) {
        double s = (double)(w->L - 1);
        double x[3] = {w->ci + (a0 + 0.5) / s, w->cj + (w->m->pdeg ? 0 : (b0 + 0.5) / s),
                       w->ck + (c0 + 0.5) / s};
        double c0x[3] = {x[0], x[1], x[2]};
        double res;
        if (polish(w->m, x, &res) != 0) return;
        double dist = 0;
        for (int k = 0; k < 3; k++)
            dist = fmax(dist, fabs(x[k] - c0x[k]) * s);
        if (dist > 2.0 || !isfinite(res)) return; /* wandered off: another cell's point */
        bpoint pt = {w->m->t0 + x[0] * w->m->dt, w->m->p0 + x[1] * w->m->dp,
                     w->m->w0 + x[2] * w->m->dw, res};
        if (bvec_push(w->out, pt)) w->fail = 1;
        return;
    }
    int h = size / 2;
    for (int da = 0; da <= h; da += h)
        for (int db = 0; db <= (w->m->pdeg ? 0 : h); db += (w->m->pdeg ? 1 : h))
            for (int dc = 0; dc <= h; dc += h)
                refine(w, a0 + da, b0 + db, c0 + dc, h);
}

/* Greedy chaining: points in coarse-cell units, a link only between points closer than `gap`. */
static void chain(const bpoint *pts, int n, const mdbm_ctx *m, double gap, int *order, int *curve) {
    unsigned char *used = calloc((size_t)n, 1);
    int *tmp = malloc((size_t)(2 * n + 1) * sizeof(int));
    if (!used || !tmp) {
        for (int k = 0; k < n; k++)
            order[k] = k, curve[k] = 0;
        free(used);
        free(tmp);
        return;
    }
    int pos = 0, cid = 0;
#define DIST(a, b)                                                                                 \
    sqrt(pow((pts[a].tau - pts[b].tau) / m->dt, 2) +                                               \
         (m->pdeg ? 0.0 : pow((pts[a].p - pts[b].p) / m->dp, 2)) +                                 \
         pow((pts[a].omega - pts[b].omega) / m->dw, 2))
    for (int s = 0; s < n; s++) {
        if (used[s]) continue;
        /* grow both ways from s: tmp holds the chain centred at index n */
        int lo = n, hi = n;
        tmp[n] = s;
        used[s] = 1;
        for (int dir = 0; dir < 2; dir++) {
            int end = s;
            for (;;) {
                int best = -1;
                double bd = gap;
                for (int k = 0; k < n; k++) {
                    if (used[k]) continue;
                    double dk = DIST(end, k);
                    if (dk < bd) bd = dk, best = k;
                }
                if (best < 0) break;
                used[best] = 1;
                if (dir == 0)
                    tmp[++hi] = best;
                else
                    tmp[--lo] = best;
                end = best;
            }
        }
        for (int k = lo; k <= hi; k++) {
            order[pos] = tmp[k];
            curve[pos] = cid;
            pos++;
        }
        cid++;
    }
#undef DIST
    free(used);
    free(tmp);
}

int rths_mdbm_boundaries(rths_dde_family_fn family, void *ctx, const rths_chart_options *o,
                         rths_chart *c, rths_error *err) {
    int T = o->mdbm_tau_points > 1 ? o->mdbm_tau_points : o->tau_points;
    int P = o->mdbm_p_points > 1 ? o->mdbm_p_points : o->p_points;
    int W = o->omega_points;
    mdbm_ctx m = {family,
                  ctx,
                  o->tau_min_s,
                  o->p_min,
                  o->omega_min_rad_s,
                  (o->tau_max_s - o->tau_min_s) / (T - 1),
                  0,
                  (o->omega_max_rad_s - o->omega_min_rad_s) / (W - 1),
                  0};
    if (o->p_max > o->p_min && P > 1) {
        m.dp = (o->p_max - o->p_min) / (P - 1);
    } else {
        P = 1;
        m.dp = 1.0;
        m.pdeg = 1;
    }
    size_t ng = (size_t)T * (size_t)P * (size_t)W;
    double complex *g = malloc(ng * sizeof *g);
    int *rcs = calloc((size_t)P, sizeof(int));
    if (!g || !rcs) {
        free(g);
        free(rcs);
        return rths_error_set(err, RTHS_EFAIL, "out of memory (MDBM grid)");
    }
#define G(i, j, k) g[(size_t)(i) + (size_t)T * ((size_t)(j) + (size_t)P * (size_t)(k))]
#pragma omp parallel for schedule(dynamic)
    for (int j = 0; j < P; j++) {
        rths_dde d;
        rths_error e;
        if ((rcs[j] = family(ctx, m.p0 + j * m.dp, &d, &e))) continue;
        for (int k = 0; k < W; k++)
            for (int i = 0; i < T; i++)
                G(i, j, k) = eval_at(&m, &d, i, k);
        rths_dde_free(&d);
    }
    for (int j = 0; j < P; j++)
        if (rcs[j]) {
            free(g);
            free(rcs);
            return rths_error_set(err, RTHS_EFAIL, "MDBM: building the delay equation failed");
        }
    free(rcs);
    /* candidate cells, in a fixed order */
    int ncell = 0, capc = 256;
    int *cells = malloc((size_t)capc * 3 * sizeof(int));
    int Pc = m.pdeg ? 1 : P - 1;
    for (int k = 0; k + 1 < W && cells; k++)
        for (int j = 0; j < Pc; j++)
            for (int i = 0; i + 1 < T; i++) {
                double complex v[8];
                int nv = 0;
                for (int a = 0; a <= 1; a++)
                    for (int b = 0; b <= (m.pdeg ? 0 : 1); b++)
                        for (int e = 0; e <= 1; e++)
                            v[nv++] = G(i + a, j + b, k + e);
                if (!sign_change(v, nv)) continue;
                if (ncell == capc) {
                    capc *= 2;
                    int *nc = realloc(cells, (size_t)capc * 3 * sizeof(int));
                    if (!nc) {
                        free(cells);
                        cells = NULL;
                        break;
                    }
                    cells = nc;
                }
                if (!cells) break;
                cells[3 * ncell] = i, cells[3 * ncell + 1] = j, cells[3 * ncell + 2] = k;
                ncell++;
            }
#undef G
    free(g);
    if (!cells) return rths_error_set(err, RTHS_EFAIL, "out of memory (MDBM cells)");
    int R = o->mdbm_refine, L = (1 << R) + 1;
    bvec *outs = calloc((size_t)(ncell ? ncell : 1), sizeof *outs);
    int *fails = calloc((size_t)(ncell ? ncell : 1), sizeof(int));
    if (!outs || !fails) {
        free(cells), free(outs), free(fails);
        return rths_error_set(err, RTHS_EFAIL, "out of memory (MDBM)");
    }
#pragma omp parallel for schedule(dynamic)
    for (int q = 0; q < ncell; q++) {
        size_t l3 = (size_t)L * L * L;
        cell_work w = {&m,
                       R,
                       L,
                       cells[3 * q],
                       cells[3 * q + 1],
                       cells[3 * q + 2],
                       calloc((size_t)L, sizeof(rths_dde)),
                       calloc((size_t)L, sizeof(int)),
                       malloc(l3 * sizeof(double complex)),
                       calloc(l3, 1),
                       &outs[q],
                       0};
        if (!w.dd || !w.dd_ok || !w.val || !w.have)
            w.fail = 1;
        else
            refine(&w, 0, 0, 0, L - 1);
        if (w.dd)
            for (int b = 0; b < L; b++)
                if (w.dd_ok[b]) rths_dde_free(&w.dd[b]);
        free(w.dd), free(w.dd_ok), free(w.val), free(w.have);
        fails[q] = w.fail;
    }
    int total = 0, fail = 0;
    for (int q = 0; q < ncell; q++)
        total += outs[q].n, fail |= fails[q];
    bpoint *all = malloc((size_t)(total ? total : 1) * sizeof *all);
    int *order = malloc((size_t)(total ? total : 1) * sizeof(int));
    int *curve = malloc((size_t)(total ? total : 1) * sizeof(int));
    c->b_tau = malloc((size_t)(total ? total : 1) * sizeof(double));
    c->b_p = malloc((size_t)(total ? total : 1) * sizeof(double));
    c->b_omega = malloc((size_t)(total ? total : 1) * sizeof(double));
    c->b_curve = malloc((size_t)(total ? total : 1) * sizeof(int));
    int rc = RTHS_OK;
    if (!all || !order || !curve || !c->b_tau || !c->b_p || !c->b_omega || !c->b_curve || fail) {
        rc = rths_error_set(err, RTHS_EFAIL, "MDBM refinement failed (memory or model build)");
    } else {
        int pos = 0;
        for (int q = 0; q < ncell; q++)
            for (int k = 0; k < outs[q].n; k++)
                all[pos++] = outs[q].v[k];
        chain(all, total, &m, 2.5 * sqrt(3.0) / (L - 1), order, curve);
        c->n_boundary = total;
        c->b_max_residual = 0;
        for (int k = 0; k < total; k++) {
            const bpoint *b = &all[order[k]];
            c->b_tau[k] = b->tau;
            c->b_p[k] = b->p;
            c->b_omega[k] = b->omega;
            c->b_curve[k] = curve[k];
            c->b_max_residual = fmax(c->b_max_residual, b->res);
        }
    }
    for (int q = 0; q < ncell; q++)
        free(outs[q].v);
    free(outs), free(fails), free(cells), free(all), free(order), free(curve);
    return rc;
}
