/* The LTI rig's local model for several interface DoFs: per harmonic, complex n x n gain matrices
 * fitted to the evaluation history (the residual-model predictor's basis, docs/method.md,
 * "Iteration and continuation"). One interface DoF goes through lti.c's scalar fit unchanged. */
#include "iterate/corrector_internal.h"

#include <math.h>
#include <string.h>

enum { UMAX = 2 * DOF_MAX + 2, RHS_MAX = 2 * DOF_MAX };
/* Smallest eigenvalue ratio of the normal matrix for a fit. Neighbouring points' targets are
 * nearly parallel (both DoFs move in the mode's shape), so the n x n fit is less well conditioned
 * than one DoF's: with one DoF's 1e-10, 246 of 251 points of a pseudo-arclength run over the
 * two-interface example (noise off) had no fitted model and 3 % lay beyond 3 standard errors; at
 * 1e-13 (a condition number of the regressor near 3e6, still far from rounding) 36 of 252 had
 * none and every point lay within 3 SE.
 * The jackknife standard error shows what an ill-determined fit costs. */
static const double LTI_DOFS_MIN_EIGEN_RATIO = 1e-13;

/* Normal equations of harmonic k's fit for n DoFs. Unknowns of every residual row d (and response
 * row): G's entries (d, e) as lines, coefficients of 1 and d_w = (w - omega) / spread, at
 * 2 e + j, then f_d's at 2 n + j; targets scaled by zs. The rows share the regressor, so one
 * normal matrix serves them all. Right-hand sides (leading dimension U): Phi_d at column d, x_d at
 * n + d. */
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

/* K Phi = R G^-1 Phi of the fundamental from solved normal equations (solution columns d: G's
 * row d, n + d: R's row d), per DoF into kphi. Returns 0, or -1 if G is singular. */
static int move_of(int P, int n, int U, const double complex *sol, double zs, const double *phi,
                   double complex *kphi) {
    int N = P / n;
    double complex G[DOF_MAX * DOF_MAX], v[DOF_MAX];
    for (int d = 0; d < n; d++) {
        v[d] = pair_value(phi, P, d * N);
        for (int e = 0; e < n; e++)
            G[d + n * e] = sol[d * U + 2 * e] / zs;
    }
    if (rths_cmat_solve(n, 1, G, v) != 0) return -1;
    for (int d = 0; d < n; d++) {
        kphi[d] = 0;
        for (int e = 0; e < n; e++)
            kphi[d] += sol[(n + d) * U + 2 * e] / zs * v[e];
    }
    return 0;
}

/* Per DoF, the variances of the fundamental's matched estimate x - K Phi (K = R G^-1), half of
 * each complex variance for the amplitude (the error's phase is random):
 * - model_var, the uncertainty of K Phi, by the jackknife over the history (the fit without each
 *   evaluation in turn). The first-order propagation of the fit's covariance is useless here: the
 *   targets of neighbouring points are nearly parallel (both interface DoFs move in the mode's
 *   shape), so the entries of G and R are separately ill-determined (covariance factors of 1e7)
 *   while K Phi along the branch is not; on the two-interface example the propagation claimed
 *   standard errors up to 19 % where the estimates were 0.6 % off at most;
 * - scatter_var, the scatter of x - K Phi about the fit per evaluation: the noise as the
 *   evaluations show it, with the noise the two sides share (the physical side's, in both x and
 *   Phi) cancelled as it is in the estimate. */
static int dofs_variances(const corrector_memory *mem, int P, int n, const dofs_normal *ne,
                          const double complex *raw_atb, double zs, const double *phi,
                          lti_model *out) {
    int N = P / n, U = ne->U, count = ne->count, dof = count - U;
    double complex kphi[RTHS_LTI_HISTORY][DOF_MAX], mean[DOF_MAX] = {0};
    for (int h = 0; h < count; h++) {
        const double complex *row = ne->rows[h];
        double complex ata[UMAX * UMAX], atb[UMAX * 2 * DOF_MAX];
        for (int p = 0; p < U; p++) {
            for (int q = 0; q < U; q++)
                ata[p + U * q] = ne->ata[p + U * q] - conj(row[p]) * row[q];
            for (int r = 0; r < n; r++) {
                atb[r * U + p] =
                    raw_atb[r * U + p] - conj(row[p]) * pair_value(mem->history[h].phi, P, r * N);
                atb[(n + r) * U + p] =
                    raw_atb[(n + r) * U + p] -
                    conj(row[p]) * pair_value(mem->history[h].response, P, r * N);
            }
        }
        if (rths_cmat_solve(U, 2 * n, ata, atb) != 0 || move_of(P, n, U, atb, zs, phi, kphi[h]))
            return -1;
        for (int d = 0; d < n; d++)
            mean[d] += kphi[h][d] / count;
    }
    double complex K[DOF_MAX * DOF_MAX] = {0};
    double jack[DOF_MAX] = {0}, scatter[DOF_MAX] = {0};
    for (int h = 0; h < count; h++)
        for (int d = 0; d < n; d++) {
            double complex dev = kphi[h][d] - mean[d];
            jack[d] += (count - 1.0) / count * creal(conj(dev) * dev);
        }
    /* K itself, for the scatter of x - K Phi: K e_e, column by column */
    for (int e = 0; e < n; e++) {
        double unit[2 * RTHS_MAX_HARMONICS] = {0};
        double complex col[DOF_MAX];
        unit[e * N] = 1.0;
        if (move_of(P, n, U, ne->atb, zs, unit, col) != 0) return -1;
        for (int d = 0; d < n; d++)
            K[d + n * e] = col[d];
    }
    for (int h = 0; h < count; h++)
        for (int d = 0; d < n; d++) {
            double complex m =
                pair_value(mem->history[h].response, P, d * N) - fitted(ne, h, n + d);
            for (int e = 0; e < n; e++)
                m -= K[d + n * e] * (pair_value(mem->history[h].phi, P, e * N) - fitted(ne, h, e));
            scatter[d] += creal(conj(m) * m) / dof;
        }
    for (int d = 0; d < n; d++) {
        out->scatter_var[d] = 0.5 * scatter[d];
        out->model_var[d] = 0.5 * jack[d];
    }
    return 0;
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
    if (!(rths_cmat_hermitian_eigen_ratio(U, ne.ata) > LTI_DOFS_MIN_EIGEN_RATIO)) return -1;
    double complex ata[UMAX * UMAX], raw_atb[UMAX * RHS_MAX];
    memcpy(ata, ne.ata, sizeof ata);
    memcpy(raw_atb, ne.atb, sizeof raw_atb);
    if (rths_cmat_solve(U, 2 * n, ata, ne.atb) != 0) return -1;
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
    if (k == 0 && phi) return dofs_variances(mem, P, n, &ne, raw_atb, zs, phi, out);
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
