/* Harmonic balance with alternating frequency-time evaluation (harmonic_balance.h). The
 * Jacobian of the truncated system is exact: the linear part per harmonic, the elements' part
 * as the AFT transform of their slopes times the series' basis, both at the same samples as the
 * residual, so Newton converges quadratically on smooth elements. */
#include "rths/harmonic_balance.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void rths_hb_defaults(rths_hb_options *opt) {
    opt->harmonics = 15;
    opt->samples = 256;
    opt->max_newton = 50;
    opt->tol = 1e-11;
}

/* basis function j at phase theta and its derivative in time (omega given) */
static double basis(int j, double theta) {
    if (j == 0) return 1.0;
    int k = (j + 1) / 2;
    return j % 2 ? cos(k * theta) : sin(k * theta);
}

static double basis_rate(int j, double theta, double omega) {
    if (j == 0) return 0.0;
    int k = (j + 1) / 2;
    return j % 2 ? -k * omega * sin(k * theta) : k * omega * cos(k * theta);
}

/* residual r (nu) and Jacobian jac (nu x nu) at coef */
static void hb_residual(const rths_assembly *a, int count, const rths_nl_element *el,
                        const double *static_force, const double *force, double omega, int H, int N,
                        const double *coef, const double *tab, const double *tab_rate, double *r,
                        double *jac) {
    const int n = a->n, nb = 2 * H + 1, nu = n * nb;
    memset(r, 0, sizeof(double) * (size_t)nu);
    memset(jac, 0, sizeof(double) * (size_t)nu * (size_t)nu);
    /* linear part: harmonic k couples (cos, sin) through K - k^2 w^2 M and k w C */
    for (int j = 0; j < nb; j++) {
        int k = (j + 1) / 2;
        double w2 = (double)k * k * omega * omega, kw = k * omega;
        for (int i = 0; i < n; i++)
            for (int l = 0; l < n; l++) {
                double kd = RTHS_AT(a->stiffness, n, i, l) - w2 * RTHS_AT(a->mass, n, i, l);
                double c = RTHS_AT(a->damping, n, i, l);
                int row = i + n * j;
                jac[row + (size_t)(l + n * j) * nu] += kd;
                if (j > 0 && j % 2) /* cos row: + k w C s_k */
                    jac[row + (size_t)(l + n * (j + 1)) * nu] += kw * c;
                else if (j > 0) /* sin row: - k w C c_k */
                    jac[row + (size_t)(l + n * (j - 1)) * nu] -= kw * c;
            }
    }
    for (int row = 0; row < nu; row++) {
        double sum = 0;
        for (int col = 0; col < nu; col++)
            sum += jac[row + (size_t)col * nu] * coef[col];
        r[row] = sum;
    }
    for (int i = 0; i < n; i++) {
        r[i] -= static_force[i];
        r[i + n] -= force[i];
    }
    /* elements by AFT */
    for (int e = 0; e < count; e++) {
        const rths_nl_element *ne = &el[e];
        const double *t = rths_nl_on_rate(ne) ? tab_rate : tab;
        int di = ne->dof_i, dj = ne->dof_j;
        for (int m = 0; m < N; m++) {
            const double *bm = t + (size_t)m * nb, *bf = tab + (size_t)m * nb;
            double y = 0;
            for (int j = 0; j < nb; j++)
                y += bm[j] * (coef[di + n * j] - (dj >= 0 ? coef[dj + n * j] : 0.0));
            double slope, g = rths_nl_force(ne, y, &slope);
            for (int j = 0; j < nb; j++) {
                double wj = (j == 0 ? 1.0 : 2.0) / N * bf[j];
                r[di + n * j] += wj * g;
                if (dj >= 0) r[dj + n * j] -= wj * g;
                for (int l = 0; l < nb; l++) {
                    double d = wj * slope * bm[l];
                    jac[(di + n * j) + (size_t)(di + n * l) * nu] += d;
                    if (dj >= 0) {
                        jac[(di + n * j) + (size_t)(dj + n * l) * nu] -= d;
                        jac[(dj + n * j) + (size_t)(di + n * l) * nu] -= d;
                        jac[(dj + n * j) + (size_t)(dj + n * l) * nu] += d;
                    }
                }
            }
        }
    }
}

int rths_hb_solve(const rths_assembly *a, int count, const rths_nl_element *el,
                  const double *static_force, const double *force, double omega_rad_s,
                  const rths_hb_options *opt, double *coef, int *iterations, rths_error *err) {
    const int n = a->n, H = opt->harmonics, N = opt->samples, nb = 2 * H + 1, nu = n * nb;
    if (H < 1 || N < 2 * H + 1 || !(omega_rad_s > 0))
        return rths_error_set(err, RTHS_EINPUT,
                              "harmonic balance: %d harmonics need at least %d time samples "
                              "(got %d) and a positive frequency",
                              H, 2 * H + 1, N);
    double *tab = malloc(sizeof(double) * (size_t)N * nb * 2);
    double *r = malloc(sizeof(double) * (size_t)nu);
    double *jac = malloc(sizeof(double) * (size_t)nu * (size_t)nu);
    lapack_int *ipiv = malloc(sizeof(lapack_int) * (size_t)nu);
    int rc = tab && r && jac && ipiv ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    double *tab_rate = tab ? tab + (size_t)N * nb : NULL;
    for (int m = 0; !rc && m < N; m++)
        for (int j = 0; j < nb; j++) {
            double theta = 2 * M_PI * m / N;
            tab[(size_t)m * nb + j] = basis(j, theta);
            tab_rate[(size_t)m * nb + j] = basis_rate(j, theta, omega_rad_s);
        }
    double scale = 0;
    for (int i = 0; i < n && !rc; i++)
        scale = fmax(scale, fmax(fabs(force[i]), fabs(static_force[i])));
    int it = 0, converged = 0;
    for (; it <= opt->max_newton && !rc; it++) {
        hb_residual(a, count, el, static_force, force, omega_rad_s, H, N, coef, tab, tab_rate, r,
                    jac);
        double worst = 0;
        for (int i = 0; i < nu; i++)
            worst = fmax(worst, fabs(r[i]));
        if (!(worst <= opt->tol * scale) && !isfinite(worst)) break;
        if (worst <= opt->tol * scale) {
            converged = 1;
            break;
        }
        if (it == opt->max_newton) break;
        if (LAPACKE_dgesv(LAPACK_COL_MAJOR, nu, 1, jac, nu, ipiv, r, nu) != 0) break;
        for (int i = 0; i < nu; i++)
            coef[i] -= r[i];
    }
    if (!rc && !converged)
        rc = rths_error_set(err, RTHS_EFAIL,
                            "harmonic balance did not converge at %g Hz within %d Newton steps "
                            "(%d harmonics, %d samples)",
                            omega_rad_s / (2 * M_PI), opt->max_newton, H, N);
    if (iterations) *iterations = it;
    free(tab), free(r), free(jac), free(ipiv);
    return rc;
}
