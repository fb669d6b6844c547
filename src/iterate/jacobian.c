/* The corrector's Jacobians: finite differences, Broyden's secant update (erratum 6), the LTI
 * form's update, and the small dense solve of the Newton step. */
#include "iterate/corrector_internal.h"

#include <math.h>
#include <string.h>

/* Entry noise of one finite-difference column (scaled units): two evaluations' standard errors
 * over the step h, of Phi and of the response. */
static void column_noise(const rths_corrector *c, const rths_residual *r, double h, double *noise_j,
                         double *noise_r) {
    int n = c->n, N = c->harmonics;
    double se_phi = 0, se_x = 0;
    for (int i = 0; i < n; i++)
        se_phi += r->phi_se[i] * r->phi_se[i] / n;
    for (int k = 0; k < N; k++)
        se_x += (r->response_se[k] * r->response_se[k] +
                 r->response_se[N + k] * r->response_se[N + k]) /
                n;
    if (!N)
        for (int i = 0; i < n; i++)
            se_x += r->response_se[i] * r->response_se[i] / n;
    *noise_j = fmax(*noise_j, sqrt(2 * se_phi) / c->scale[0] / h);
    *noise_r = fmax(*noise_r, sqrt(2 * se_x) / c->scale[0] / h);
}

/* Finite-difference Jacobian columns 0..m-1 around the current iterate, of Phi and of the
 * response (scaled variables). On a natural sweep with Fourier unknowns, it also decides whether
 * the rig looks LTI (see corrector_memory.lti). */
int corrector_fd_jacobian(rths_corrector *c, rths_error *err) {
    int n = c->n;
    const corrector_point *base = &c->cur;
    double noise_j = 0, noise_r = 0;
    corrector_point tmp = c->cur;
    for (int j = 0; j < c->m; j++) {
        double up[LD];
        memcpy(up, base->u, sizeof up);
        double h;
        if (j < n) /* relative to the coefficient scale, but above the noise floor */
            h = fmax(c->opt.fd_step_rel * fmax(fabs(up[j]), 1.0),
                     c->opt.fd_step_min_m / c->scale[j]);
        else
            h = c->opt.fd_step_omega_rel * fabs(up[j]);
        up[j] += h;
        int rc = corrector_evaluate(c, up, &tmp, RTHS_EVALUATION_JACOBIAN, 0.0, err);
        if (rc) return rc;
        column_noise(c, &tmp.rec, h, &noise_j, &noise_r);
        for (int i = 0; i < n; i++) {
            c->mem.jacobian[i + j * LD] = (tmp.phi[i] - base->phi[i]) / h;
            c->mem.response_jacobian[i + j * LD] = (tmp.resp[i] - base->resp[i]) / h;
        }
    }
    c->mem.have_jacobian = 1;
    c->jacobian_here = 1;
    c->fresh = 1;
    int N = c->harmonics;
    c->mem.lti = (c->m == n || c->opt.rig_lti) && N > 0 && !c->problem.coupled &&
                 lti_like(c->mem.jacobian, N, c->dofs, noise_j) &&
                 lti_like(c->mem.response_jacobian, N, c->dofs, noise_r);
    if (c->mem.lti) {
        lti_project(c->mem.jacobian, N, c->dofs);
        lti_project(c->mem.response_jacobian, N, c->dofs);
    }
    return RTHS_OK;
}

/* Solves the m x m extended system J du = -phi by Gaussian elimination with partial pivoting:
 * m <= 7, so LAPACK's call overhead buys nothing here. Returns 0, or -1 if singular. */
int solve_small(int m, double *a, int lda, double *b) {
    for (int k = 0; k < m; k++) {
        int p = k;
        for (int i = k + 1; i < m; i++)
            if (fabs(a[i + k * lda]) > fabs(a[p + k * lda])) p = i;
        if (!(fabs(a[p + k * lda]) > 0)) return -1;
        if (p != k) {
            for (int j = 0; j < m; j++) {
                double t = a[k + j * lda];
                a[k + j * lda] = a[p + j * lda];
                a[p + j * lda] = t;
            }
            double t = b[k];
            b[k] = b[p];
            b[p] = t;
        }
        for (int i = k + 1; i < m; i++) {
            double f = a[i + k * lda] / a[k + k * lda];
            for (int j = k; j < m; j++)
                a[i + j * lda] -= f * a[k + j * lda];
            b[i] -= f * b[k];
        }
    }
    for (int k = m - 1; k >= 0; k--) {
        for (int j = k + 1; j < m; j++)
            b[k] -= a[k + j * lda] * b[j];
        b[k] /= a[k + k * lda];
    }
    return 0;
}

/* Broyden's rank-one update of the n x m matrix J (leading dimension LD) so that J s = y, with
 * the erratum-6 denominator ||s||^2. */
static void broyden_update(double *J, int n, int m, const double *s, const double *y, double ss) {
    for (int i = 0; i < n; i++) {
        double js = 0;
        for (int j = 0; j < m; j++)
            js += J[i + j * LD] * s[j];
        double f = (y[i] - js) / ss;
        for (int j = 0; j < m; j++)
            J[i + j * LD] += f * s[j];
    }
}

/* After an accepted step from the current iterate to trial: Broyden updates of the Phi and
 * response rows (scaled variables), or on an LTI-like rig the gains refitted to every recorded
 * evaluation (or, while the history cannot determine them, fixed by this secant pair). */
void corrector_secant_update(rths_corrector *c, const corrector_point *trial) {
    int n = c->n, N = c->harmonics;
    const corrector_point *cur = &c->cur;
    double s[LD], y[LD] = {0}, ss = 0;
    for (int j = 0; j < c->m; j++) {
        s[j] = trial->u[j] - cur->u[j];
        ss += s[j] * s[j];
    }
    if (!(ss > 0)) return;
    for (int i = 0; i < n; i++)
        y[i] = trial->phi[i] - cur->phi[i];
    int lti = c->mem.lti && c->m == n && N > 0;
    lti_model model;
    if (c->mem.lti && c->m > n && N > 0) {
        /* pseudo-arclength on a rig known to be LTI: Broyden keeps the frequency column, the
         * target block keeps the LTI form, refitted to the history when it can be */
        broyden_update(c->mem.jacobian, n, c->m, s, y, ss);
        for (int i = 0; i < n; i++)
            y[i] = trial->resp[i] - cur->resp[i];
        broyden_update(c->mem.response_jacobian, n, c->m, s, y, ss);
        lti_project(c->mem.jacobian, N, c->dofs);
        lti_project(c->mem.response_jacobian, N, c->dofs);
        if (lti_model_fit(&c->mem, N, c->dofs, trial->sol.omega_rad_s, NULL, &model) == 0)
            lti_model_apply(&model, c->mem.jacobian, c->mem.response_jacobian);
    } else if (lti &&
               lti_model_fit(&c->mem, N, c->dofs, trial->sol.omega_rad_s, NULL, &model) == 0) {
        lti_model_apply(&model, c->mem.jacobian, c->mem.response_jacobian);
    } else if (lti) {
        double noise_phi[RTHS_MAX_HARMONICS], noise_resp[RTHS_MAX_HARMONICS];
        lti_secant_noise(&cur->rec, &trial->rec, N, c->scale[0], noise_phi, noise_resp);
        lti_model_secant(c->mem.jacobian, N, c->dofs, s, y, noise_phi);
        for (int i = 0; i < n; i++)
            y[i] = trial->resp[i] - cur->resp[i];
        lti_model_secant(c->mem.response_jacobian, N, c->dofs, s, y, noise_resp);
    } else {
        broyden_update(c->mem.jacobian, n, c->m, s, y, ss);
        for (int i = 0; i < n; i++)
            y[i] = trial->resp[i] - cur->resp[i];
        broyden_update(c->mem.response_jacobian, n, c->m, s, y, ss);
    }
}
