/* The analytic FRF over many frequencies at a cost that does not grow as n^3 per frequency (see
 * model.h, rths_frf_sweep): banded complex solves when the matrices are banded, modal
 * superposition when the modes decouple C, complex (state-space) modes otherwise; the dense solve
 * only when the complex modes are too ill-conditioned to trust. Every path solves the same
 * equation exactly, up to rounding (tests/test_model.c checks each against the dense solve). */
#include "rths/model.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct rths_frf_sweep {
    rths_frf_method method;
    int n, n_out;
    int *out_dofs;
    const rths_assembly *a;
    double *force;
    /* modal: x_out = sum_r shape_out[:, r] g_r / (w_r^2 - w^2 + i w c_r) */
    double *shape_out; /* n_out x n */
    double *modal_force, *omega2, *modal_c;
    /* banded: half-bandwidth, band storage for zgbsv, pivots, right-hand side */
    int band;
    double complex *ab, *rhs;
    lapack_int *ipiv;
    /* state-space modes: x_out = sum_k w_out[:, k] z_k / (i w - lambda_k) */
    int ns;
    double complex *lambda, *w_out, *z;
};

const char *rths_frf_method_name(rths_frf_method m) {
    static const char *const names[] = {"modal superposition", "banded solves",
                                        "complex modes (state space)", "dense solves"};
    return (unsigned)m < sizeof names / sizeof names[0] ? names[m] : "?";
}

rths_frf_method rths_frf_sweep_method(const rths_frf_sweep *s) {
    return s->method;
}

void rths_frf_sweep_destroy(rths_frf_sweep *s) {
    if (!s) return;
    free(s->out_dofs);
    free(s->force);
    free(s->shape_out);
    free(s->modal_force);
    free(s->omega2);
    free(s->modal_c);
    free(s->ab);
    free(s->rhs);
    free(s->ipiv);
    free(s->lambda);
    free(s->w_out);
    free(s->z);
    free(s);
}

/* C~ = Phi^T C Phi (n x n, malloc'ed). */
static double *modal_damping(const rths_assembly *a, const rths_modes *m) {
    int n = a->n;
    double *cphi = rths_mat_new(n, n), *ct = rths_mat_new(n, n);
    if (cphi && ct) {
        rths_mat_mul(n, n, n, 1.0, a->damping, 0, m->shapes, 0, 0.0, cphi);
        rths_mat_mul(n, n, n, 1.0, m->shapes, 1, cphi, 0, 0.0, ct);
    } else {
        rths_mat_free(ct);
        ct = NULL;
    }
    rths_mat_free(cphi);
    return ct;
}

/* The modes decouple C when every off-diagonal modal damping term is below 1e-12 of the
 * geometric mean of its two diagonal ones (the coupling it would add to either mode). Anything
 * above, rounding included, takes one of the exact general paths instead: the seed's damping is
 * stiffness-proportional to 1e-5 only, which would shift a peak by far more than rounding. */
static int is_proportional(const double *ct, int n) {
    for (int j = 0; j < n; j++)
        for (int i = j + 1; i < n; i++)
            if (!(fabs(RTHS_AT(ct, n, i, j)) <=
                  1e-12 * sqrt(fabs(RTHS_AT(ct, n, i, i) * RTHS_AT(ct, n, j, j)))))
                return 0;
    return 1;
}

static int setup_modal(rths_frf_sweep *s, const rths_modes *m, const double *ct) {
    int n = s->n, no = s->n_out;
    s->shape_out = rths_mat_new(no, n);
    s->modal_force = calloc((size_t)n, sizeof(double));
    s->omega2 = calloc((size_t)n, sizeof(double));
    s->modal_c = calloc((size_t)n, sizeof(double));
    if (!s->shape_out || !s->modal_force || !s->omega2 || !s->modal_c) return -1;
    for (int r = 0; r < n; r++) {
        const double *phi = m->shapes + (size_t)r * (size_t)n;
        double g = 0;
        for (int i = 0; i < n; i++)
            g += phi[i] * s->force[i];
        s->modal_force[r] = g;
        s->omega2[r] = m->omega_rad_s[r] * m->omega_rad_s[r];
        s->modal_c[r] = RTHS_AT(ct, n, r, r);
        for (int i = 0; i < no; i++)
            RTHS_AT(s->shape_out, no, i, r) = phi[s->out_dofs[i]];
    }
    return 0;
}

static int setup_banded(rths_frf_sweep *s) {
    int n = s->n, ldab = 3 * s->band + 1;
    s->ab = malloc((size_t)ldab * (size_t)n * sizeof *s->ab);
    s->rhs = malloc((size_t)n * sizeof *s->rhs);
    s->ipiv = malloc((size_t)n * sizeof *s->ipiv);
    return s->ab && s->rhs && s->ipiv ? 0 : -1;
}

static double scale_of(double omega) {
    return omega > 0 ? omega : 1.0;
}

/* Complex modes of the modal-coordinate state space, eta'' + C~ eta' + W eta = Phi^T f with
 * W = diag(w_r^2): A = V Lambda V^-1. Returns 1 when V is too ill-conditioned to
 * trust (near-defective: critically damped pairs; rounding in the expansion grows as eps / rcond,
 * so rcond >= 1e-6 keeps it below 1e-10), 0 on success, -1 on failure. */
static int setup_state_space(rths_frf_sweep *s, const rths_modes *m, const double *ct) {
    int n = s->n, ns = 2 * n, no = s->n_out, rc = -1;
    s->ns = ns;
    double *a = rths_mat_new(ns, ns), *wr = calloc((size_t)ns, sizeof(double)),
           *wi = calloc((size_t)ns, sizeof(double)), *vr = rths_mat_new(ns, ns);
    double complex *v = malloc((size_t)ns * (size_t)ns * sizeof *v);
    lapack_int *ipiv = malloc((size_t)ns * sizeof *ipiv);
    s->lambda = malloc((size_t)ns * sizeof *s->lambda);
    s->w_out = malloc((size_t)no * (size_t)ns * sizeof *s->w_out);
    s->z = calloc((size_t)ns, sizeof *s->z);
    if (!a || !wr || !wi || !vr || !v || !ipiv || !s->lambda || !s->w_out || !s->z) goto done;
    /* state (S eta, eta') with S = diag(w_r): A = [[0, S], [-W S^-1, -C~]] is skew-symmetric
     * plus the damping, so its eigenvectors are nearly orthogonal for a lightly damped structure
     * whatever the spread of its frequencies (with (eta, eta') their rows would scale as w_r) */
    for (int i = 0; i < n; i++) {
        double w = m->omega_rad_s[i];
        RTHS_AT(a, ns, i, n + i) = scale_of(w);
        RTHS_AT(a, ns, n + i, i) = -w * w / scale_of(w);
        for (int j = 0; j < n; j++)
            RTHS_AT(a, ns, n + i, n + j) = -RTHS_AT(ct, n, i, j);
    }
    double dummy;
    if (LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'V', ns, a, ns, wr, wi, &dummy, 1, vr, ns)) goto done;
    for (int k = 0; k < ns; k++) {
        s->lambda[k] = wr[k] + I * wi[k];
        const double *re = vr + (size_t)k * ns;
        for (int i = 0; i < ns; i++) {
            /* dgeev stores a conjugate pair as (re, im) in columns k, k + 1 */
            if (wi[k] > 0)
                v[i + (size_t)k * ns] = re[i] + I * re[i + ns];
            else if (wi[k] < 0)
                v[i + (size_t)k * ns] = re[i - ns] - I * re[i];
            else
                v[i + (size_t)k * ns] = re[i];
        }
    }
    /* W_out = Phi_out S^-1 V_top */
    for (int k = 0; k < ns; k++)
        for (int o = 0; o < no; o++) {
            double complex acc = 0;
            for (int r = 0; r < n; r++)
                acc += RTHS_AT(m->shapes, n, s->out_dofs[o], r) * v[r + (size_t)k * ns] /
                       scale_of(m->omega_rad_s[r]);
            s->w_out[o + (size_t)k * no] = acc;
        }
    /* z = V^-1 (0, Phi^T f) */
    for (int r = 0; r < n; r++) {
        double g = 0;
        for (int i = 0; i < n; i++)
            g += RTHS_AT(m->shapes, n, i, r) * s->force[i];
        s->z[n + r] = g;
    }
    double norm1 = LAPACKE_zlange(LAPACK_COL_MAJOR, '1', ns, ns, (lapack_complex_double *)v, ns);
    double rcond = 0;
    if (LAPACKE_zgetrf(LAPACK_COL_MAJOR, ns, ns, (lapack_complex_double *)v, ns, ipiv) ||
        LAPACKE_zgecon(LAPACK_COL_MAJOR, '1', ns, (lapack_complex_double *)v, ns, norm1, &rcond) ||
        rcond < 1e-6) {
        rc = 1;
        goto done;
    }
    rc = LAPACKE_zgetrs(LAPACK_COL_MAJOR, 'N', ns, 1, (lapack_complex_double *)v, ns, ipiv,
                        (lapack_complex_double *)s->z, ns)
             ? -1
             : 0;
done:
    free(a), free(wr), free(wi), free(vr), free(v), free(ipiv);
    return rc;
}

int rths_frf_sweep_create(const rths_assembly *a, const rths_modes *modes, const double *force,
                          int n_out, const int *out_dofs, rths_frf_sweep **out, rths_error *err) {
    *out = NULL;
    int n = a->n;
    rths_frf_sweep *s = calloc(1, sizeof *s);
    if (!s) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    s->n = n;
    s->n_out = n_out;
    s->a = a;
    s->out_dofs = malloc((size_t)n_out * sizeof(int));
    s->force = malloc((size_t)n * sizeof(double));
    s->band = rths_assembly_half_bandwidth(a);
    /* a banded model goes straight to banded solves (O(n b^2) per frequency, as cheap as modal
     * superposition), sparing the n^3 projection of C onto the modes */
    int banded = n > 8 && s->band <= n / 8;
    double *ct = banded ? NULL : modal_damping(a, modes);
    int rc = s->out_dofs && s->force && (banded || ct) ? 0 : -1;
    if (!rc) {
        memcpy(s->out_dofs, out_dofs, (size_t)n_out * sizeof(int));
        memcpy(s->force, force, (size_t)n * sizeof(double));
        if (banded) {
            s->method = RTHS_FRF_BANDED;
            rc = setup_banded(s);
        } else if (is_proportional(ct, n)) {
            s->method = RTHS_FRF_MODAL;
            rc = setup_modal(s, modes, ct);
        } else {
            s->method = RTHS_FRF_STATE_SPACE;
            rc = setup_state_space(s, modes, ct);
            if (rc == 1) s->method = RTHS_FRF_DENSE, rc = 0;
        }
    }
    rths_mat_free(ct);
    if (rc) {
        rths_frf_sweep_destroy(s);
        return rths_error_set(err, RTHS_EFAIL, "could not prepare the FRF (%d DoFs)", n);
    }
    *out = s;
    return RTHS_OK;
}

static int eval_banded(rths_frf_sweep *s, double w, double complex *x_out, rths_error *err) {
    int n = s->n, b = s->band, ldab = 3 * b + 1;
    const rths_assembly *a = s->a;
    memset(s->ab, 0, (size_t)ldab * (size_t)n * sizeof *s->ab);
    for (int j = 0; j < n; j++)
        for (int i = j - b < 0 ? 0 : j - b; i <= j + b && i < n; i++)
            s->ab[(size_t)(2 * b + i - j) + (size_t)j * ldab] =
                RTHS_AT(a->stiffness, n, i, j) - w * w * RTHS_AT(a->mass, n, i, j) +
                I * w * RTHS_AT(a->damping, n, i, j);
    for (int i = 0; i < n; i++)
        s->rhs[i] = s->force[i];
    lapack_int info = LAPACKE_zgbsv(LAPACK_COL_MAJOR, n, b, b, 1, (lapack_complex_double *)s->ab,
                                    ldab, s->ipiv, (lapack_complex_double *)s->rhs, n);
    if (info)
        return rths_error_set(err, RTHS_EFAIL,
                              "dynamic stiffness is singular at %g rad/s (zgbsv info %d)", w,
                              (int)info);
    for (int o = 0; o < s->n_out; o++)
        x_out[o] = s->rhs[s->out_dofs[o]];
    return RTHS_OK;
}

static int eval_dense(rths_frf_sweep *s, double w, double complex *x_out, rths_error *err) {
    double complex *x = malloc((size_t)s->n * sizeof *x);
    if (!x) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = rths_frf(s->n, s->a->mass, s->a->damping, s->a->stiffness, s->force, w, x, err);
    for (int o = 0; o < s->n_out && !rc; o++)
        x_out[o] = x[s->out_dofs[o]];
    free(x);
    return rc;
}

int rths_frf_sweep_eval(rths_frf_sweep *s, double w, double complex *x_out, rths_error *err) {
    int no = s->n_out;
    switch (s->method) {
    case RTHS_FRF_MODAL:
        for (int o = 0; o < no; o++)
            x_out[o] = 0;
        for (int r = 0; r < s->n; r++) {
            double complex d = s->omega2[r] - w * w + I * w * s->modal_c[r];
            if (d == 0)
                return rths_error_set(err, RTHS_EFAIL,
                                      "undamped resonance at %g rad/s: the response is unbounded",
                                      w);
            double complex g = s->modal_force[r] / d;
            const double *col = s->shape_out + (size_t)r * no;
            for (int o = 0; o < no; o++)
                x_out[o] += col[o] * g;
        }
        return RTHS_OK;
    case RTHS_FRF_BANDED:
        return eval_banded(s, w, x_out, err);
    case RTHS_FRF_STATE_SPACE:
        for (int o = 0; o < no; o++)
            x_out[o] = 0;
        for (int k = 0; k < s->ns; k++) {
            double complex g = s->z[k] / (I * w - s->lambda[k]);
            const double complex *col = s->w_out + (size_t)k * no;
            for (int o = 0; o < no; o++)
                x_out[o] += col[o] * g;
        }
        return RTHS_OK;
    default:
        return eval_dense(s, w, x_out, err);
    }
}
