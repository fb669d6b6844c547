/* The LTI rig's local model for several interface DoFs: per harmonic, complex n x n gain matrices
 * fitted to the evaluation history (the residual-model predictor's basis, docs/method.md,
 * "Iteration and continuation"). One interface DoF goes through lti.c's scalar fit unchanged. */
#include "iterate/corrector_internal.h"

#include <math.h>
#include <string.h>

enum { UMAX = 2 * DOF_MAX + 2, RHS_MAX = 3 * DOF_MAX };

/* Normal equations of harmonic k's fit for n DoFs. Unknowns of every residual row d (and response
 * row): G's entries (d, e) as lines, coefficients of 1 and d_w = (w - omega) / spread, at
 * 2 e + j, then f_d's at 2 n + j; targets scaled by zs. The rows share the regressor, so one
 * normal matrix serves them all. Right-hand sides (leading dimension U): Phi_d at column d, x_d at
 * n + d, and the unit vectors at G's constant terms 2 e (column 2 n + e) for the covariance of
 * those terms. */
typedef struct {
    int U, count;
    double complex rows[RTHS_LTI_HISTORY][UMAX];
    double complex ata[UMAX * UMAX], atb[UMAX * RHS_MAX];
} dofs_normal;

static double complex pair_value(const double *v, int P, int p) {
    return v[p] + I * v[P + p];
}

static void dofs_normal_equations(const corrector_memory *mem, int P, int n, int k, double omega,
                                  double spread, double zs, dofs_normal *ne) {
    int N = P / n, U = 2 * n + 2;
    memset(ne, 0, sizeof *ne);
    ne->U = U;
    ne->count = mem->history_count;
    for (int e = 0; e < n; e++)
        ne->atb[(2 * n + e) * U + 2 * e] = 1.0;
    for (int h = 0; h < mem->history_count; h++) {
        double d = (mem->history[h].omega_rad_s - omega) / spread;
        double complex *row = ne->rows[h];
        for (int e = 0; e < n; e++) {
            double complex z = pair_value(mem->history[h].target, P, e * N + k) / zs;
            row[2 * e] = z;
            row[2 * e + 1] = z * d;
        }
        row[2 * n] = -1.0;
        row[2 * n + 1] = -d;
        for (int p = 0; p < U; p++) {
            for (int q = 0; q < U; q++)
                ne->ata[p + U * q] += conj(row[p]) * row[q];
            for (int r = 0; r < n; r++) {
                ne->atb[r * U + p] += conj(row[p]) * pair_value(mem->history[h].phi, P, r * N + k);
                ne->atb[(n + r) * U + p] +=
                    conj(row[p]) * pair_value(mem->history[h].response, P, r * N + k);
            }
        }
    }
}

/* The fitted value of right-hand side `col` at history entry h. */
static double complex fitted(const dofs_normal *ne, int h, int col) {
    double complex v = 0;
    for (int p = 0; p < ne->U; p++)
        v += ne->rows[h][p] * ne->atb[col * ne->U + p];
    return v;
}

/* Per DoF d', the variances of the fundamental's matched estimate x - K Phi (K = R G^-1):
 * delta K Phi = delta R v - K delta G v with v = G^-1 Phi, the rows of G and R independent with
 * the residual variances of their fits, so Var((delta K Phi)_d') = v^H C v (s_x,d'^2 +
 * sum_d |K_d'd|^2 s_phi,d^2), C the covariance factor of G's constant terms; half of it for the
 * amplitude (the error's phase is random). The scatter of x - K Phi about the fit, per
 * evaluation, is the noise as the evaluations show it. */
static int dofs_variances(const corrector_memory *mem, int P, int n, const dofs_normal *ne,
                          double zs, const double complex *G, const double complex *R,
                          const double *phi, lti_model *out) {
    int N = P / n, U = ne->U, dof = ne->count - U;
    double complex ginv[DOF_MAX * DOF_MAX], a[DOF_MAX * DOF_MAX], K[DOF_MAX * DOF_MAX] = {0};
    double complex v[DOF_MAX];
    memcpy(a, G, sizeof(double complex) * (size_t)(n * n));
    for (int j = 0; j < n * n; j++)
        ginv[j] = j % (n + 1) == 0 ? 1.0 : 0.0;
    if (rths_cmat_solve(n, n, a, ginv) != 0) return -1;
    for (int d = 0; d < n; d++)
        for (int e = 0; e < n; e++)
            for (int q = 0; q < n; q++)
                K[d + n * e] += R[d + n * q] * ginv[q + n * e];
    for (int d = 0; d < n; d++) {
        v[d] = 0;
        for (int e = 0; e < n; e++)
            v[d] += ginv[d + n * e] * pair_value(phi, P, e * N);
    }
    double complex qv = 0;
    for (int e = 0; e < n; e++)
        for (int f = 0; f < n; f++)
            qv += conj(v[f]) * ne->atb[(2 * n + e) * U + 2 * f] * v[e];
    double quad = fabs(creal(qv)) / (zs * zs), var_phi[DOF_MAX] = {0}, var_x[DOF_MAX] = {0};
    double scatter[DOF_MAX] = {0};
    for (int h = 0; h < ne->count; h++) {
        double complex dphi[DOF_MAX], dx[DOF_MAX];
        for (int d = 0; d < n; d++) {
            dphi[d] = pair_value(mem->history[h].phi, P, d * N) - fitted(ne, h, d);
            dx[d] = pair_value(mem->history[h].response, P, d * N) - fitted(ne, h, n + d);
            var_phi[d] += creal(conj(dphi[d]) * dphi[d]) / dof;
            var_x[d] += creal(conj(dx[d]) * dx[d]) / dof;
        }
        for (int d = 0; d < n; d++) {
            double complex m = dx[d];
            for (int e = 0; e < n; e++)
                m -= K[d + n * e] * dphi[e];
            scatter[d] += creal(conj(m) * m) / dof;
        }
    }
    for (int d = 0; d < n; d++) {
        double spread = var_x[d];
        for (int e = 0; e < n; e++)
            spread += creal(conj(K[d + n * e]) * K[d + n * e]) * var_phi[e];
        out->model_var[d] = 0.5 * quad * spread;
        out->scatter_var[d] = 0.5 * scatter[d];
    }
    return 0;
}

static int finite_complex(double complex z) {
    return isfinite(creal(z)) && isfinite(cimag(z));
}

/* Harmonic k's gains, prediction and (k = 0, phi given) variances. */
static int dofs_fit_harmonic(const corrector_memory *mem, int P, int n, int k, double omega,
                             double spread, const double *phi, lti_model *out) {
    int N = P / n;
    double zs = 0;
    for (int h = 0; h < mem->history_count; h++)
        for (int e = 0; e < n; e++)
            zs = fmax(zs, cabs(pair_value(mem->history[h].target, P, e * N + k)));
    if (!(zs > 0)) return -1;
    dofs_normal ne;
    dofs_normal_equations(mem, P, n, k, omega, spread, zs, &ne);
    int U = ne.U;
    /* as for one DoF: a rank-deficient history (targets that never left one direction at one
     * frequency) would still give made-up gains; demand a well-conditioned fit */
    if (!(rths_cmat_hermitian_eigen_ratio(U, ne.ata) > 1e-10)) return -1;
    double complex ata[UMAX * UMAX];
    memcpy(ata, ne.ata, sizeof ata);
    if (rths_cmat_solve(U, 3 * n, ata, ne.atb) != 0) return -1;
    double complex *G = out->g[k], *R = out->r[k], f[DOF_MAX], a[DOF_MAX * DOF_MAX];
    for (int d = 0; d < n; d++) {
        f[d] = ne.atb[d * U + 2 * n];
        for (int e = 0; e < n; e++) {
            G[d + n * e] = ne.atb[d * U + 2 * e] / zs;
            R[d + n * e] = ne.atb[(n + d) * U + 2 * e] / zs;
            if (!finite_complex(G[d + n * e]) || !finite_complex(R[d + n * e])) return -1;
        }
        if (!finite_complex(f[d])) return -1;
    }
    memcpy(a, G, sizeof(double complex) * (size_t)(n * n));
    if (rths_cmat_solve(n, 1, a, f) != 0) return -1;
    for (int d = 0; d < n; d++) {
        if (!finite_complex(f[d])) return -1;
        out->z[k][d] = f[d];
    }
    if (k == 0 && phi) return dofs_variances(mem, P, n, &ne, zs, G, R, phi, out);
    return 0;
}

/* One DoF: lti_fit's scalar gains, bit for bit as before. */
static int scalar_fit(const corrector_memory *mem, int N, double omega, const double *phi,
                      lti_model *out) {
    double complex g[RTHS_MAX_HARMONICS], r[RTHS_MAX_HARMONICS], z[RTHS_MAX_HARMONICS];
    double var_ratio[RTHS_MAX_HARMONICS], var_matched[RTHS_MAX_HARMONICS];
    if (lti_fit(mem, N, omega, g, r, z, phi ? var_ratio : NULL, phi ? var_matched : NULL) != 0)
        return -1;
    for (int k = 0; k < N; k++) {
        out->g[k][0] = g[k];
        out->r[k][0] = r[k];
        out->z[k][0] = z[k];
    }
    if (phi) {
        out->model_var[0] = 0.5 * var_ratio[0] * (phi[0] * phi[0] + phi[N] * phi[N]);
        out->scatter_var[0] = 0.5 * var_matched[0];
    }
    return 0;
}

int lti_model_fit(const corrector_memory *mem, int P, int dofs, double omega, const double *phi,
                  lti_model *out) {
    memset(out, 0, sizeof *out);
    int n = dofs > 1 ? dofs : 1;
    if (P <= 0 || P % n || n > DOF_MAX) return -1;
    out->harmonics = P / n;
    out->dofs = n;
    if (n == 1) return scalar_fit(mem, P, omega, phi, out);
    double spread;
    if (!lti_history_usable(mem, omega, 2 * n + 2, &spread)) return -1;
    for (int k = 0; k < out->harmonics; k++)
        if (dofs_fit_harmonic(mem, P, n, k, omega, spread, phi, out) != 0) return -1;
    return 0;
}

void lti_model_apply(const lti_model *m, double *J, double *R) {
    int N = m->harmonics, n = m->dofs, P = N * n;
    for (int k = 0; k < N; k++)
        for (int d = 0; d < n; d++)
            for (int e = 0; e < n; e++) {
                if (J) lti_pair_block(J, P, d * N + k, e * N + k, m->g[k][d + n * e]);
                if (R) lti_pair_block(R, P, d * N + k, e * N + k, m->r[k][d + n * e]);
            }
}

void lti_model_secant(double *J, int P, int dofs, const double *s, const double *y,
                      const double *noise) {
    int n = dofs > 1 ? dofs : 1, N = P / n;
    if (n == 1) {
        lti_update(J, P, s, y, noise);
        return;
    }
    for (int k = 0; k < N; k++) {
        double complex sv[DOF_MAX], yv[DOF_MAX], G[DOF_MAX * DOF_MAX];
        double ss = 0, yy = 0, nn = 0;
        for (int d = 0; d < n; d++) {
            int p = d * N + k;
            sv[d] = pair_value(s, P, p);
            yv[d] = pair_value(y, P, p);
            ss += creal(conj(sv[d]) * sv[d]);
            yy += creal(conj(yv[d]) * yv[d]);
            nn += noise[p] * noise[p];
            for (int e = 0; e < n; e++) {
                G[d + n * e] = lti_gain(J, P, p, e * N + k);
            }
        }
        /* a change within the noise says nothing about the gains: keep them */
        if (!(sqrt(yy) > 3 * sqrt(nn)) || !(ss > 0)) continue;
        for (int d = 0; d < n; d++) {
            double complex miss = yv[d];
            for (int e = 0; e < n; e++)
                miss -= G[d + n * e] * sv[e];
            for (int e = 0; e < n; e++)
                lti_pair_block(J, P, d * N + k, e * N + k, G[d + n * e] + miss * conj(sv[e]) / ss);
        }
    }
}
