/* The converged point's report: the physical interface response extrapolated to zero mismatch
 * ("matched"), its standard error, and the amplitude a report shows (see rths_solution). */
#include "iterate/corrector_internal.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Standard errors of the response (sp) and reference (sn) entries: the pooled per-sample
 * variance when there is one, else the record's own. */
static void entry_noise(const rths_corrector *c, double *sp, double *sn) {
    const rths_residual *r = &c->cur.rec;
    const corrector_memory *mem = &c->mem;
    for (int i = 0; i < c->n; i++) {
        sp[i] = r->response_se[i];
        sn[i] = r->reference_se[i];
    }
    if (mem->noise_dof > 0 && r->samples > 0)
        for (int i = 0; i < c->n; i++) {
            sp[i] = sqrt(mem->noise_ss[0][i] / mem->noise_dof / r->samples);
            sn[i] = sqrt(mem->noise_ss[1][i] / mem->noise_dof / r->samples);
        }
}

/* LTI rig on a natural sweep: the gains refitted with this point's own evaluations; the fit's
 * scatter says how well R G^-1 is known, and that uncertainty times the residual joins the
 * standard error (per interface DoF; for the amplitude half the complex variance: the error's
 * phase is random). Returns 1 with *model (model_var, scatter_var) when the fit succeeded. */
static int refit_lti(rths_corrector *c, lti_model *model) {
    int N = c->harmonics;
    memset(model, 0, sizeof *model);
    if (!(c->mem.lti && (c->m == c->n || c->opt.rig_lti) && N > 0)) return 0;
    if (lti_model_fit(&c->mem, N, c->dofs, c->cur.sol.omega_rad_s, c->cur.rec.phi, model) != 0) {
        memset(model, 0, sizeof *model);
        return 0;
    }
    lti_model_apply(model, c->mem.jacobian, c->mem.response_jacobian);
    return 1;
}

/* The step to zero mismatch solves A d = -(Phi, 0), A being J over the first m unknowns: the
 * targets at fixed frequency (m = n), or on an arclength run also the frequency with the
 * arclength row (m = n + 1): the step then runs normal to the branch and stays well posed at
 * folds, where the target block of J alone is singular. Columns 0..n-1 of A^-1, mapped
 * by R, give K (x* = x - K Phi) and the frequency's share kw (w* = w - kw . Phi). Returns 0, or
 * -1 without a (usable) Jacobian. */
static int matched_gain(const rths_corrector *c, int m, int fitted, double *K, double *kw) {
    int n = c->n;
    const corrector_memory *mem = &c->mem;
    /* a fitted LTI model sets the target blocks from the history even when the carried
     * Jacobians were dropped (after a failed correction) */
    if (!mem->have_jacobian && !(fitted && m == n)) return -1;
    for (int i = 0; i < n; i++) {
        double a[LD * LD], z[LD] = {0};
        for (int q = 0; q < m; q++) {
            for (int p = 0; p < n; p++)
                a[p + q * LD] = mem->jacobian[p + q * LD];
            if (m > n) a[n + q * LD] = c->arc.tangent[q];
        }
        z[i] = 1;
        if (solve_small(m, a, LD, z) != 0) return -1;
        for (int p = 0; p < n; p++) {
            double r = 0;
            for (int q = 0; q < m; q++)
                r += mem->response_jacobian[p + q * LD] * z[q];
            if (!isfinite(r)) return -1;
            K[p + i * LD] = r;
        }
        if (m > n) kw[i] = z[n] * c->scale[n] / c->scale[0];
    }
    return 0;
}

/* x* = (I - K) x_phys + K x_num with independent noise on the two sides; the gradient of the
 * amplitude of pair p0 (cos entry p0, sin entry P + p0), (a, b) / |x*|, maps the covariance to a
 * variance. */
static double matched_variance(int n, int P, int p0, const double *xm, double am, const double *K,
                               const double *sp, const double *sn) {
    int c0 = p0, s0 = P + p0;
    double g0 = xm[c0] / fmax(am, 1e-300), gN = xm[s0] / fmax(am, 1e-300), var = 0;
    for (int p = 0; p < n; p++) {
        double w = g0 * K[c0 + p * LD] + gN * K[s0 + p * LD];
        double v = (p == c0 ? g0 : p == s0 ? gN : 0.0) - w;
        var += v * v * sp[p] * sp[p] + w * w * sn[p] * sn[p];
    }
    return var;
}

/* Relative uncertainty of the step to zero mismatch when no fitted model gives one: a nonlinear
 * rig's Jacobian is known only to order one between updates (the secant updates see one direction
 * at a time, a carried one lags the branch), so the whole step counts as its own uncertainty. The
 * matched estimate is then never worse than the measurement it corrects without its standard
 * error saying so. */
enum { MATCHED_MAX_STEP_RATIO = 50 };
static const double UNFITTED_STEP_UNCERTAINTY = 1.0, FITTED_MIN_STEPS_SE = 3.0;

/* Size of the response's move K Phi. */
static double move_size(const rths_corrector *c, const double *K) {
    double sq = 0;
    for (int i = 0; i < c->n; i++) {
        double v = 0;
        for (int p = 0; p < c->n; p++)
            v += K[i + p * LD] * c->cur.rec.phi[p];
        sq += v * v;
    }
    return sqrt(sq);
}

/* The step's gains. On an arclength run with a fitted LTI model (a linear rig), at fixed
 * frequency, so the estimate stays at the frequency that was measured (a frequency moved by the
 * step moves the point along a steep flank: on a 3-25 Hz sweep 0.3 mHz shifts made 0.3 % errors
 * at the point's frequency), unless that step is more than three times the one normal to the
 * branch. Otherwise normal to the branch: Broyden updates along the branch know J with its
 * frequency column better than the target block alone (on the Duffing mock the fixed-frequency
 * step brought the share within one standard error from 0.80 to 0.50). */
static int choose_step(const rths_corrector *c, int fitted, double *K, double *kw) {
    int n = c->n;
    if (c->m == n) return matched_gain(c, n, fitted, K, kw);
    int fixed_ok = matched_gain(c, n, fitted, K, kw) == 0;
    double Ka[LD * LD], kwa[LD] = {0};
    if (matched_gain(c, c->m, fitted, Ka, kwa) != 0) return fitted && fixed_ok ? 0 : -1;
    for (int i = 0; i < n; i++)
        kw[i] = 0;
    if (fitted && fixed_ok && move_size(c, K) <= 3.0 * move_size(c, Ka)) return 0;
    memcpy(K, Ka, sizeof Ka);
    memcpy(kw, kwa, sizeof kwa);
    return 0;
}

/* A step normal to the branch also moves the frequency, by d_omega, which nothing vouches for
 * more than the step itself: at the point's frequency that is an amplitude uncertainty of the
 * branch's slope dA/d(omega) (from the arclength tangent, targets standing in for the response)
 * times d_omega. Grows without bound towards a fold, where the branch is vertical. */
static double frequency_move_variance(const rths_corrector *c, double d_omega, int p0) {
    int n = c->n, c0 = p0, s0 = c->harmonics + p0;
    if (c->m == n || d_omega == 0.0) return 0.0;
    const double *t = c->arc.tangent, *u = c->cur.u;
    double amp = hypot(u[c0], u[s0]);
    double dA = amp > 0 ? (u[c0] * t[c0] + u[s0] * t[s0]) / amp * c->scale[0] : 0.0;
    double dw = t[n] * c->scale[n];
    if (!(fabs(dw) > 0)) return INFINITY;
    double v = dA / dw * d_omega;
    return v * v;
}

/* The fundamental's gains measured at the point itself: a secant between two evaluations at its
 * frequency. On a natural sweep of an LTI rig the fitted model cannot supply them: the sweep's
 * targets sit on the zero-mismatch curve, where Phi = g z - f is unchanged when g and f are
 * scaled together, so the fit's g is set by noise and by the curvature its lines in w miss. On
 * the 3-25 Hz sweep it was off by a median 86 % (up to tenfold at 18-24 Hz) while its scatter
 * claimed 24 %, and the remaining mismatch times that wrong r/g put points 10 standard errors
 * off. x* = x - K Phi with K = dx/dPhi from the pair is the interpolation to Phi = 0,
 * x* = t_c x_c + t_p x_p with t_c = Phi_p / (Phi_p - Phi_c), t_p = 1 - t_c; its noise is each
 * evaluation's (1 - K) x + K x_num weighted by t, which carries the secant's own noise. */
typedef struct {
    int have;
    double complex gain;    /* K = dx/dPhi of the fundamental */
    double weight_variance; /* |t_c|^2 + |t_p|^2 */
    /* the fitted model's own account (set by matched_estimate): whether it fitted, its gain
     * uncertainty's share of the variance and the whole variance it reports, m^2 */
    int fitted;
    double fit_gain_var, fit_se_var;
} local_gain;

/* The fit's scatter understated the gains' error by a median 2.3 times (up to tenfold): its
 * account is trusted to skip the extra evaluation only where five times its gain term is still
 * within a third of the standard error it reports (a noise-free rig, a tiny mismatch). On the
 * 3-25 Hz sweep 5 cost 0.3 more evaluations per point (1.38) and 10 0.55 more, with the same
 * coverage. */
static const double FIT_GAIN_PESSIMISM = 5.0;

/* A secant well above its noise: the gain to within a tenth, first order holds */
static const double LOCAL_GAIN_MIN_SNR = 10.0;
/* the probe shrinks the fundamental's target by a fifth: never past a limit the point itself
 * respected, and the mismatch changes by a fifth of g z, well above the noise. A larger change
 * leaves more transient to the next point (its steady-state test accepts a slow tail below the
 * noise): halving the target biased the sweep's last points by 4e-8 m (2.5 standard errors),
 * a fifth by 1.7e-8 m. */
static const double PROBE_TARGET_FACTOR = 0.8;

static double complex fundamental(const double *v, int N) {
    return v[0] + I * v[N];
}

/* The secant between the current point and a record at the same frequency, if it is well above
 * the noise of the two mismatches. */
static int secant_gain(const rths_corrector *c, const double *phi_p, const double *x_p,
                       const double *phi_se_p, local_gain *lg) {
    int N = c->harmonics;
    const rths_residual *r = &c->cur.rec;
    double complex phi_c = fundamental(r->phi, N), d_phi = fundamental(phi_p, N) - phi_c;
    double noise = sqrt(r->phi_se[0] * r->phi_se[0] + r->phi_se[N] * r->phi_se[N] +
                        phi_se_p[0] * phi_se_p[0] + phi_se_p[N] * phi_se_p[N]);
    if (!(cabs(d_phi) > LOCAL_GAIN_MIN_SNR * noise)) return 0;
    double complex t_p = -phi_c / d_phi, t_c = 1.0 - t_p;
    lg->gain = (fundamental(x_p, N) - fundamental(r->response, N)) / d_phi;
    lg->weight_variance = creal(t_c * conj(t_c) + t_p * conj(t_p));
    lg->have = finite_complex(lg->gain);
    return lg->have;
}

/* Measures the fundamental's local gain by one more evaluation at this frequency with the
 * fundamental's target shrunk (it also joins the model's history, whose identification it
 * helps). Leaves lg->have 0 if the secant stays in the noise; returns a rig error. */
static int measure_local_gain(rths_corrector *c, local_gain *lg, rths_error *err) {
    int N = c->harmonics;
    lg->have = 0;
    corrector_point *probe = malloc(sizeof *probe);
    if (!probe) return rths_error_set(err, RTHS_EFAIL, "out of memory in the corrector");
    double u[LD];
    memcpy(u, c->cur.u, sizeof u);
    u[0] *= PROBE_TARGET_FACTOR;
    u[N] *= PROBE_TARGET_FACTOR;
    int rc = corrector_evaluate(c, u, probe, RTHS_EVALUATION_GAIN_PROBE, 0.0, err);
    if (!rc) secant_gain(c, probe->rec.phi, probe->rec.response, probe->rec.phi_se, lg);
    free(probe);
    return rc;
}

/* Whether the point needs its own gain: a natural sweep of an LTI rig whose fitted model does
 * not vouch for the step to zero mismatch (see FIT_GAIN_PESSIMISM). */
static int needs_local_gain(const rths_corrector *c, int have_matched, const local_gain *lg) {
    /* one interface DoF: with several the n x n fit's own uncertainty (the jackknife) holds */
    if (!(c->opt.report_matched && c->harmonics > 0 && c->dofs == 1 && c->m == c->n && c->mem.lti))
        return 0;
    double pessimistic = FIT_GAIN_PESSIMISM * FIT_GAIN_PESSIMISM * lg->fit_gain_var;
    return have_matched && lg->fitted && 9.0 * pessimistic > lg->fit_se_var;
}

/* A point of a natural sweep accepted with no Jacobian at all (its first evaluation, after a
 * failed correction dropped the carried one): nothing says how far the remaining mismatch moves
 * the response. One evaluation with the fundamental's target shrunk measures it (the demo's
 * p = 0.67 sweep had such a point 29 standard errors, 0.16 %, from the truth, its standard error
 * the noise's alone). */
static int needs_gain_without_jacobian(const rths_corrector *c, double move) {
    return c->opt.report_matched && c->harmonics > 0 && c->dofs == 1 && c->m == c->n && isnan(move);
}

/* K's fundamental block set to the local gain (no coupling to other harmonics: an LTI rig). */
static void use_local_gain(int n, int N, const local_gain *lg, double *K) {
    for (int p = 0; p < n; p++) {
        K[0 + p * LD] = K[N + p * LD] = 0;
        K[p + 0 * LD] = K[p + N * LD] = 0;
    }
    K[0 + 0 * LD] = K[N + N * LD] = creal(lg->gain);
    K[0 + N * LD] = -cimag(lg->gain);
    K[N + 0 * LD] = cimag(lg->gain);
}

/* The matched estimate of every interface DoF's fundamental amplitude (pair d N of P) and its
 * standard error from the step's gains; move[d]: the step's change of that amplitude. */
typedef struct {
    double amplitude[DOF_MAX], se[DOF_MAX], move[DOF_MAX];
} matched_dofs;

/* The standard error of DoF d's matched amplitude am (see rths_solution): the noise, the
 * sensitivity's uncertainty times the mismatch, the frequency move. */
static double matched_se(rths_corrector *c, const double *K, const double *xm, double am,
                         double move, double wm, int p0, const lti_model *model, int d, int fitted,
                         const double *sp, const double *sn, local_gain *lg) {
    /* a fitted model's own scatter can understate a wrong model (on a 4-DoF structure with a
     * non-diagonal mass the matched amplitude was once 6.9 % off where the measurement was
     * 0.02 % off): whatever the fit says, the standard error is at least a third of the step, so
     * the estimate is never further from the measurement than three standard errors */
    double jac_var = fitted ? fmax(model->model_var[d],
                                   move * move / (FITTED_MIN_STEPS_SE * FITTED_MIN_STEPS_SE))
                            : UNFITTED_STEP_UNCERTAINTY * UNFITTED_STEP_UNCERTAINTY * move * move;
    /* the noise as the periods of this point show it, or as the evaluations' scatter about the
     * fitted model shows it, whichever is larger: on the virtual rig the numerical side's
     * resonant response to sensor noise is correlated from period to period, and on a 3-25 Hz
     * sweep the periods' scatter alone left 6 % of the points beyond three standard errors */
    double noise_var =
        fmax(matched_variance(c->n, c->harmonics, p0, xm, am, K, sp, sn), model->scatter_var[d]);
    if (d == 0 && lg->have) { /* the local secant's interpolation to zero mismatch (local_gain) */
        c->se_noise_m[d] = sqrt(noise_var * lg->weight_variance);
        c->se_step_m[d] = fabs(move) / FITTED_MIN_STEPS_SE;
        return sqrt(noise_var * lg->weight_variance +
                    move * move / (FITTED_MIN_STEPS_SE * FITTED_MIN_STEPS_SE));
    }
    if (d == 0) {
        lg->fitted = fitted;
        lg->fit_gain_var = model->model_var[0];
        lg->fit_se_var = noise_var + jac_var;
    }
    double freq_var = frequency_move_variance(c, wm - c->cur.sol.omega_rad_s, p0);
    c->se_noise_m[d] = sqrt(noise_var);
    c->se_step_m[d] = sqrt(jac_var + freq_var);
    return sqrt(noise_var + jac_var + freq_var);
}

/* Fills the matched estimate when a Jacobian allows it; returns 1 if it did. out->move receives
 * each DoF's step (the mismatch times the response's sensitivity to it; NAN without a usable
 * Jacobian). */
static int matched_estimate(rths_corrector *c, const double *sp, const double *sn, local_gain *lg,
                            matched_dofs *out) {
    int n = c->n, P = c->harmonics, N = P / c->dofs;
    rths_solution *sol = &c->cur.sol;
    const double *phi = c->cur.rec.phi, *x = c->cur.rec.response;
    lti_model model;
    int fitted = refit_lti(c, &model);
    double K[LD * LD], kw[LD] = {0};
    for (int d = 0; d < DOF_MAX; d++)
        out->move[d] = NAN;
    if (P == 0) return 0;
    if (choose_step(c, fitted, K, kw) != 0) {
        if (!lg->have) return 0;
        /* no Jacobian: the gain measured at the point moves the fundamental alone */
        memset(K, 0, sizeof K);
    }
    if (lg->have) use_local_gain(n, P, lg, K); /* one interface DoF: P = N */
    double xm[LD] = {0}, wm = sol->omega_rad_s, step = 0, phi_norm = 0;
    for (int i = 0; i < n; i++) {
        xm[i] = x[i];
        for (int p = 0; p < n; p++)
            xm[i] -= K[i + p * LD] * phi[p];
        wm -= kw[i] * phi[i];
        step += (xm[i] - x[i]) * (xm[i] - x[i]);
        phi_norm += phi[i] * phi[i];
    }
    for (int d = 0; d < c->dofs; d++) {
        int p0 = d * N;
        out->amplitude[d] = hypot(xm[p0], xm[P + p0]);
        out->move[d] = out->amplitude[d] - hypot(x[p0], x[P + p0]);
    }
    /* Without a fitted model (a nonlinear rig, secant-updated Jacobians) a step of more than 50
     * times the mismatch (a resonance amplifies by up to ~40) says the Jacobians are not known
     * well enough to extrapolate: near a fold a stale one moved the estimate by 18 % where the
     * measurement was 0.8 % off. Keep the measurement then (its error is not known: the caller
     * flags the standard error). */
    if (!fitted && step > (double)MATCHED_MAX_STEP_RATIO * MATCHED_MAX_STEP_RATIO * phi_norm)
        return 0;
    sol->matched_omega_rad_s = wm;
    for (int k = 0; k < P; k++) {
        sol->matched_a[k] = xm[k];
        sol->matched_b[k] = xm[P + k];
    }
    for (int d = 0; d < c->dofs; d++)
        out->se[d] = matched_se(c, K, xm, out->amplitude[d], out->move[d], wm, d * N, &model, d,
                                fitted, sp, sn, lg);
    sol->matched_amplitude_m = out->amplitude[0];
    sol->matched_amplitude_se_m = out->se[0];
    return 1;
}

/* The measured fundamental amplitude of pair p0 and its standard error: the noise and, when a
 * Jacobian gave it, the step to zero mismatch (move; NAN: none). *honest: whether it did. */
static double measured_amplitude(rths_corrector *c, int p0, const double *sp, double move,
                                 double *se, int *honest) {
    const double *x = c->cur.rec.response;
    int s0 = c->harmonics + p0;
    double amp = hypot(x[p0], x[s0]);
    double noise_se = hypot(x[p0] * sp[p0], x[s0] * sp[s0]) / fmax(amp, 1e-300);
    /* the measurement still carries the mismatch's effect, of the size of the step to zero
     * mismatch: reported as its standard error also where the step was not trusted to be
     * taken (a Jacobian that overstates the sensitivity, near a fold, only makes the error
     * bar longer); without any Jacobian nothing says how large it is */
    *honest = isfinite(move);
    *se = isfinite(move) ? sqrt(noise_se * noise_se + move * move) : noise_se;
    int d = p0 / (c->harmonics / c->dofs);
    c->se_noise_m[d] = noise_se;
    c->se_step_m[d] = isfinite(move) ? fabs(move) : 0.0;
    return amp;
}

/* docs/method.md, "One evaluation": each interface DoF's fundamental response amplitude |x_d|
 * against the measured standard error of its mismatch per coefficient,
 * s_d = sqrt((s_cos^2 + s_sin^2) / 2) with s^2 = s_phys^2 + s_num^2 (the pooled noise). The
 * mismatch's error, not only the response's, because it is what the tolerance and the step to
 * zero mismatch are judged against: a response resolved while its numerical partner is buried in
 * noise gives a mismatch that cannot be told from zero (a tolerance wider than the response).
 * The point is below the floor when even its best-resolved DoF is below min_snr s_d: the
 * interface as a whole does not stand out of the noise. One DoF near its own antiresonance while
 * another moves clearly is a measured point, its small amplitude reported with its standard
 * error. The solution names the best-resolved DoF. */
int corrector_below_noise_floor(rths_corrector *c) {
    rths_solution *sol = &c->cur.sol;
    int P = c->harmonics, N = P > 0 ? P / c->dofs : 0;
    sol->snr = INFINITY;
    sol->snr_dof = 0;
    sol->snr_amplitude_m = 0;
    sol->noise_floor_m = 0;
    sol->below_noise_floor = 0;
    if (P == 0) return 0;
    double sp[LD], sn[LD];
    entry_noise(c, sp, sn);
    const double *x = c->cur.rec.response;
    for (int d = 0; d < c->dofs; d++) {
        int c0 = d * N, s0 = P + d * N;
        double amplitude = hypot(x[c0], x[s0]);
        double se =
            sqrt(0.5 * (sp[c0] * sp[c0] + sn[c0] * sn[c0] + sp[s0] * sp[s0] + sn[s0] * sn[s0]));
        double snr = se > 0 ? amplitude / se : INFINITY;
        if (d == 0 || snr > sol->snr) {
            sol->snr = snr;
            sol->snr_dof = d;
            sol->snr_amplitude_m = amplitude;
            sol->noise_floor_m = c->opt.min_snr * se;
        }
    }
    return c->opt.min_snr > 0 && !(sol->snr >= c->opt.min_snr);
}

/* The reported amplitude and its standard error, with every known source: the noise, the
 * remaining mismatch times the response's sensitivity to it (the step to zero mismatch), and the
 * uncertainty of that sensitivity (a fitted model's scatter, else the whole step). When no
 * Jacobian gives the sensitivity the standard error covers the noise alone and
 * amplitude_se_honest says so. With several interface DoFs, every DoF's likewise. */
int corrector_finish(rths_corrector *c, rths_error *err) {
    local_gain lg = {0};
    int N = c->harmonics;
    rths_solution *sol = &c->cur.sol;
    double sp[LD], sn[LD];
    matched_dofs m;
    memset(c->se_noise_m, 0, sizeof c->se_noise_m);
    memset(c->se_step_m, 0, sizeof c->se_step_m);
    entry_noise(c, sp, sn);
    sol->have_matched = matched_estimate(c, sp, sn, &lg, &m);
    if (needs_local_gain(c, sol->have_matched, &lg) ||
        (!sol->have_matched && needs_gain_without_jacobian(c, m.move[0]))) {
        int rc = measure_local_gain(c, &lg, err);
        if (rc) return rc;
        /* the probe joined the pooled noise and the model's history */
        entry_noise(c, sp, sn);
        sol->have_matched = matched_estimate(c, sp, sn, &lg, &m);
    }
    sol->amplitude_se_honest = 0;
    int use_matched = c->opt.report_matched && sol->have_matched, honest = 0;
    if (use_matched) {
        sol->frequency_hz = sol->matched_omega_rad_s / (2 * M_PI);
        sol->amplitude_m = sol->matched_amplitude_m;
        sol->amplitude_se_m = sol->matched_amplitude_se_m;
        sol->amplitude_se_honest = 1;
    } else if (N > 0) {
        sol->frequency_hz = sol->omega_rad_s / (2 * M_PI);
        sol->amplitude_m = measured_amplitude(c, 0, sp, m.move[0], &sol->amplitude_se_m, &honest);
        sol->amplitude_se_honest = honest;
    } else {
        sol->frequency_hz = sol->omega_rad_s / (2 * M_PI);
    }
    sol->interface_dofs = c->dofs > 1 ? c->dofs : 0;
    for (int d = 0; d < c->dofs && c->dofs > 1; d++) {
        if (use_matched) {
            sol->dof_amplitude_m[d] = m.amplitude[d];
            sol->dof_amplitude_se_m[d] = m.se[d];
        } else {
            sol->dof_amplitude_m[d] = measured_amplitude(c, d * (N / c->dofs), sp, m.move[d],
                                                         &sol->dof_amplitude_se_m[d], &honest);
        }
    }
    return RTHS_OK;
}
