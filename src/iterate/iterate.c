/* Steady-state evaluation over a rig and the Newton-Broyden corrector with line search. */
#include "rths/iterate.h"

#include <complex.h>
#include <math.h>
#include <string.h>

void rths_settle_defaults(rths_settle_options *opt, int paper) {
    memset(opt, 0, sizeof *opt);
    opt->average_periods = paper ? 10 : 4;
    /* The seed waits a fixed time; 40 periods is ~3 s at 13.5 Hz, several decay times of the
     * PD-damped rig. The adaptive wait stops as soon as the transient is predicted to be gone. */
    opt->fixed_wait_periods = paper ? 40 : 0;
    /* The numerical storey above the interface, held by the grounding controller, rings near
     * 10 Hz; against a 12-14 Hz forcing that beats every 3-5 periods, and a steady-state judgement
     * from fewer periods can take a beat's flat stretch for steady state (at resonance the
     * leftover transient then shows as errors of 4-5 standard errors) */
    opt->min_wait_periods = 8;
    opt->max_wait_periods = 400;
    opt->abs_tolerance_m = 1e-10;
    opt->rel_tolerance = 3e-4;
    opt->noise_factor = 3.0;
}

void rths_newton_defaults(rths_newton_options *opt, int paper) {
    memset(opt, 0, sizeof *opt);
    opt->max_iterations = 12;
    opt->rel_tolerance = 1e-3;
    opt->abs_tolerance_m = 1e-9;
    opt->noise_factor = 3.0;
    opt->fd_step_rel = 0.05;
    opt->fd_step_min_m = 1e-7;
    opt->fd_step_omega_rel = 2e-3;
    opt->min_damping = 1.0 / 16.0;
    opt->fresh_jacobian = paper ? 1 : 0;
    opt->report_matched = paper ? 0 : 1;
}

/* ---- one evaluation ---- */

static int coefficient_vector(const rths_period *p, int harmonics, double *v) {
    int m = 0;
    for (int k = 1; k <= harmonics; k++) {
        v[m++] = p->phys.a[k];
        v[m++] = p->phys.b[k];
        v[m++] = p->num.a[k];
        v[m++] = p->num.b[k];
    }
    return m;
}

static double vec_norm(const double *v, int n) {
    double s = 0;
    for (int i = 0; i < n; i++)
        s += v[i] * v[i];
    return sqrt(s);
}

int rths_evaluate(rths_rig *rig, const rths_settle_options *opt, int harmonics, double frequency_hz,
                  double amplitude_n, const double *target_a, const double *target_b,
                  rths_evaluation *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    out->harmonics = harmonics;
    out->frequency_hz = frequency_hz;
    if (!(isfinite(frequency_hz) && frequency_hz > 0))
        return rths_error_set(err, RTHS_EFAIL, "corrector asked for a non-physical frequency %g Hz",
                              frequency_hz);
    for (int k = 0; k < harmonics; k++)
        if (!isfinite(target_a[k]) || !isfinite(target_b[k]))
            return rths_error_set(err, RTHS_EFAIL, "corrector produced a non-finite target");
    double t0 = rths_rig_time_s(rig);
    int rc = rths_rig_set_forcing(rig, frequency_hz, amplitude_n, err);
    if (!rc) rc = rths_rig_set_target(rig, harmonics, target_a, target_b, err);
    if (rc) return rc;

    enum { NC = 4 * RTHS_MAX_HARMONICS };
    double prev[NC], cur[NC], change_prev = -1;
    rths_period p;
    int waited = 0, steady = 0, m = 0;
    if (opt->fixed_wait_periods > 0) {
        for (; waited < opt->fixed_wait_periods; waited++)
            if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
        steady = 1;
    } else {
        double noise_m = rths_rig_noise_level_m(rig);
        while (waited < opt->max_wait_periods) {
            if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
            waited++;
            m = coefficient_vector(&p, harmonics, cur);
            if (waited > 1) {
                double d[NC];
                for (int i = 0; i < m; i++)
                    d[i] = cur[i] - prev[i];
                double change = vec_norm(d, m);
                /* White noise of std s on S samples gives each per-period coefficient a std of
                 * s sqrt(2/S); the change of m of them between periods, sqrt(2 m) times that. */
                double noise_change =
                    p.samples > 0 ? noise_m * sqrt(2.0 / p.samples) * sqrt(2.0 * m) : 0.0;
                double threshold =
                    fmax(opt->abs_tolerance_m, opt->rel_tolerance * vec_norm(cur, m));
                /* A geometric transient with ratio r per period still owes change * r / (1 - r);
                 * r is estimated from the last two changes (clamped so a noisy estimate near 1
                 * keeps us waiting rather than accepting). */
                double remaining;
                if (change == 0.0) {
                    remaining = 0.0; /* bit-identical periods: nothing left to settle */
                } else if (change_prev > 0) {
                    double r = fmin(change / change_prev, 0.98);
                    remaining = change * (1.0 + r / (1.0 - r));
                } else {
                    remaining = INFINITY;
                }
                if (waited >= opt->min_wait_periods &&
                    (remaining < threshold || change < opt->noise_factor * noise_change)) {
                    steady = 1;
                    break;
                }
                change_prev = change;
            }
            memcpy(prev, cur, sizeof cur);
        }
    }
    /* Average whole periods: mean and standard error of the mean of each coefficient. */
    int n_avg = opt->average_periods > 0 ? opt->average_periods : 1;
    double sum[2][2][RTHS_MAX_HARMONICS + 1] = {{{0}}},
                                          sum2[2][2][RTHS_MAX_HARMONICS + 1] = {{{0}}};
    for (int q = 0; q < n_avg; q++) {
        if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
        const rths_fourier *side[2] = {&p.phys, &p.num};
        /* every harmonic the rig measures, not only the matched ones: the report shows the
         * higher harmonics' interface error too */
        for (int s = 0; s < 2; s++)
            for (int k = 0; k <= RTHS_MAX_HARMONICS; k++) {
                sum[s][0][k] += side[s]->a[k];
                sum[s][1][k] += side[s]->b[k];
                sum2[s][0][k] += side[s]->a[k] * side[s]->a[k];
                sum2[s][1][k] += side[s]->b[k] * side[s]->b[k];
            }
    }
    rths_fourier *mean[2] = {&out->phys, &out->num}, *se[2] = {&out->phys_se, &out->num_se};
    for (int s = 0; s < 2; s++)
        for (int k = 0; k <= RTHS_MAX_HARMONICS; k++)
            for (int c = 0; c < 2; c++) {
                double mu = sum[s][c][k] / n_avg;
                double var = n_avg > 1 ? (sum2[s][c][k] - n_avg * mu * mu) / (n_avg - 1) : 0.0;
                double e = sqrt(fmax(var, 0.0) / n_avg);
                if (c == 0)
                    mean[s]->a[k] = mu, se[s]->a[k] = e;
                else
                    mean[s]->b[k] = mu, se[s]->b[k] = e;
            }
    out->wait_periods = waited;
    out->average_periods = n_avg;
    out->steady = steady;
    out->rig_time_s = rths_rig_time_s(rig) - t0;
    if (rths_rig_get_fault(rig) != RTHS_RIG_OK)
        return rths_error_set(err, RTHS_EFAIL, "rig fault during evaluation at %.6g Hz: %s",
                              frequency_hz, rths_rig_fault_name(rths_rig_get_fault(rig)));
    return RTHS_OK;
}

void rths_evaluation_residual(const rths_evaluation *ev, double *phi, double *phi_se) {
    int n = ev->harmonics;
    for (int k = 1; k <= n; k++) {
        phi[k - 1] = ev->phys.a[k] - ev->num.a[k];
        phi[n + k - 1] = ev->phys.b[k] - ev->num.b[k];
        if (phi_se) {
            phi_se[k - 1] = hypot(ev->phys_se.a[k], ev->num_se.a[k]);
            phi_se[n + k - 1] = hypot(ev->phys_se.b[k], ev->num_se.b[k]);
        }
    }
}

/* ---- corrector ---- */

typedef struct {
    rths_rig *rig;
    const rths_settle_options *settle;
    const rths_newton_options *opt;
    const rths_arclength *arc;
    rths_corrector_state *st;
    double amplitude_n;
    int n; /* 2N */
    int m; /* unknowns: n, or n + 1 with the arclength row */
    double scale[RTHS_MAX_UNKNOWNS];
    int jacobian_here; /* the Jacobians were measured or secant-updated at this point */
} corrector;

/* Unknown vector (scaled): targets / amplitude scale, then omega / omega scale. */
static void pack(const corrector *c, const rths_solution *s, double *u) {
    int N = s->harmonics;
    for (int k = 0; k < N; k++) {
        u[k] = s->target_a[k] / c->scale[k];
        u[N + k] = s->target_b[k] / c->scale[N + k];
    }
    u[c->n] = s->omega_rad_s / c->scale[c->n];
}

static void unpack(const corrector *c, const double *u, rths_solution *s) {
    int N = s->harmonics;
    for (int k = 0; k < N; k++) {
        s->target_a[k] = u[k] * c->scale[k];
        s->target_b[k] = u[N + k] * c->scale[N + k];
    }
    s->omega_rad_s = u[c->n] * c->scale[c->n];
}

/* Physical interface coefficients in the residual's order (cos terms, then sin terms). */
static void response_vector(const rths_evaluation *ev, double *x) {
    int N = ev->harmonics;
    for (int k = 1; k <= N; k++) {
        x[k - 1] = ev->phys.a[k];
        x[N + k - 1] = ev->phys.b[k];
    }
}

/* Evaluates at scaled u: fills the physical residual and response (both scaled by the amplitude
 * scale), the extended residual norm and the measurement. */
static int eval_at(corrector *c, const double *u, rths_solution *s, double *phi_scaled,
                   double *resp_scaled, double *ext_norm, rths_error *err) {
    unpack(c, u, s);
    int rc = rths_evaluate(c->rig, c->settle, s->harmonics, s->omega_rad_s / (2 * M_PI),
                           c->amplitude_n, s->target_a, s->target_b, &s->eval, err);
    c->st->evaluations++;
    c->st->rig_time_s += s->eval.rig_time_s;
    if (rc) return rc;
    double phi[RTHS_MAX_UNKNOWNS], se[RTHS_MAX_UNKNOWNS], x[RTHS_MAX_UNKNOWNS];
    rths_evaluation_residual(&s->eval, phi, se);
    response_vector(&s->eval, x);
    int n_avg = s->eval.average_periods, N = s->harmonics;
    if (n_avg > 1) {
        for (int k = 1; k <= N; k++) {
            const rths_fourier *sd[2] = {&s->eval.phys_se, &s->eval.num_se};
            for (int side = 0; side < 2; side++) {
                /* se^2 n (n - 1) is the sum of squared deviations from the mean */
                c->st->noise_ss[side][k - 1] +=
                    sd[side]->a[k] * sd[side]->a[k] * n_avg * (n_avg - 1);
                c->st->noise_ss[side][N + k - 1] +=
                    sd[side]->b[k] * sd[side]->b[k] * n_avg * (n_avg - 1);
            }
        }
        c->st->noise_dof += n_avg - 1;
    }
    if (c->m == c->n) { /* natural sweep: remember the evaluation for the LTI model */
        rths_corrector_state *st = c->st;
        int h = st->history_next;
        st->history[h].omega_rad_s = s->omega_rad_s;
        for (int k = 0; k < N; k++) {
            st->history[h].target[k] = s->target_a[k];
            st->history[h].target[N + k] = s->target_b[k];
        }
        memcpy(st->history[h].phi, phi, sizeof(double) * (size_t)(2 * N));
        memcpy(st->history[h].response, x, sizeof(double) * (size_t)(2 * N));
        st->history_next = (h + 1) % RTHS_LTI_HISTORY;
        if (st->history_count < RTHS_LTI_HISTORY) st->history_count++;
    }
    double sq = 0, num_sq = 0, se_sq = 0;
    for (int i = 0; i < c->n; i++) {
        phi_scaled[i] = phi[i] / c->scale[0];
        resp_scaled[i] = x[i] / c->scale[0];
        sq += phi[i] * phi[i];
        se_sq += se[i] * se[i];
    }
    for (int k = 1; k <= s->harmonics; k++)
        num_sq += s->eval.num.a[k] * s->eval.num.a[k] + s->eval.num.b[k] * s->eval.num.b[k];
    s->residual_norm_m = sqrt(sq);
    s->tolerance_m = fmax(fmax(c->opt->rel_tolerance * sqrt(num_sq), c->opt->abs_tolerance_m),
                          c->opt->noise_factor * sqrt(se_sq));
    double ext = sq / (c->scale[0] * c->scale[0]);
    if (c->m > c->n) {
        double g = 0;
        for (int j = 0; j < c->m; j++)
            g += c->arc->tangent[j] * (u[j] - c->arc->predicted[j]);
        phi_scaled[c->n] = g;
        ext += g * g;
    }
    *ext_norm = sqrt(ext);
    return RTHS_OK;
}

static int arc_satisfied(const corrector *c, const double *phi_scaled) {
    /* the arclength row is linear: after a full step it holds to rounding; 1e-6 of a scaled unit
     * is far below any physical resolution */
    return c->m == c->n || fabs(phi_scaled[c->n]) < 1e-6;
}

/* A linear time-invariant rig maps each harmonic of the target to the same harmonic alone, by a
 * complex gain g_k: (Phi_a + i Phi_b)_k = g_k (A* + i B*)_k, i.e. the 2N x 2N Jacobian (cos rows
 * and columns k, sin rows and columns N + k) has blocks [[Re g, -Im g], [Im g, Re g]] on the
 * diagonal and zeros elsewhere. */
static void lti_block(double *J, int N, int k, double complex g) {
    enum { L = RTHS_MAX_UNKNOWNS };
    int a = k, b = N + k;
    J[a + a * L] = creal(g);
    J[a + b * L] = -cimag(g);
    J[b + a * L] = cimag(g);
    J[b + b * L] = creal(g);
}

static double complex lti_gain(const double *J, int N, int k) {
    enum { L = RTHS_MAX_UNKNOWNS };
    int a = k, b = N + k;
    return 0.5 * (J[a + a * L] + J[b + b * L]) + I * 0.5 * (J[b + a * L] - J[a + b * L]);
}

/* Whether the target block of a measured J is of the LTI form: its Frobenius distance from the
 * nearest LTI form is within 5 % of its size plus what entry noise of std noise_entry explains
 * (the distance has 4N^2 - 2N degrees of freedom; twice its expected size under noise alone). */
static int lti_like(const double *J, int N, double noise_entry) {
    enum { L = RTHS_MAX_UNKNOWNS };
    int n = 2 * N;
    double total = 0, off = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double v = J[i + j * L];
            total += v * v;
            if (i % N != j % N) off += v * v;
        }
    for (int k = 0; k < N; k++) {
        double P[L * L];
        lti_block(P, N, k, lti_gain(J, N, k));
        int idx[2] = {k, N + k};
        for (int p = 0; p < 2; p++)
            for (int q = 0; q < 2; q++) {
                double d = J[idx[p] + idx[q] * L] - P[idx[p] + idx[q] * L];
                off += d * d;
            }
    }
    double dof = 4.0 * N * N - 2.0 * N;
    return total > 0 && sqrt(off) <= 0.05 * sqrt(total) + 2.0 * noise_entry * sqrt(dof);
}

static void lti_project(double *J, int N) {
    enum { L = RTHS_MAX_UNKNOWNS };
    double complex g[RTHS_MAX_HARMONICS];
    for (int k = 0; k < N; k++)
        g[k] = lti_gain(J, N, k);
    for (int j = 0; j < 2 * N; j++)
        for (int i = 0; i < 2 * N; i++)
            J[i + j * L] = 0;
    for (int k = 0; k < N; k++)
        lti_block(J, N, k, g[k]);
}

/* Least-squares fit of the local LTI model (see rths_corrector_state.history) at omega: per
 * harmonic, Phi = g z - f and x = r z + e with each of g, f, r, e a line in w (on the virtual
 * rig a quadratic fitted the noise and made the matched estimate worse: 12 of 492 points beyond
 * three standard errors against none); returns the gains g and r at omega, the prediction
 * z = f / g and, if var_ratio is given, the variance E|d(r/g)|^2 of the ratio that maps a residual
 * onto the response, from the fits' scatter (noise and model error alike). */
enum { LTI_TERMS = 2, LTI_UNKNOWNS = 2 * LTI_TERMS };
static int lti_fit(const rths_corrector_state *st, int N, double omega, double complex *g,
                   double complex *r, double complex *z_pred, double *var_ratio) {
    enum { U = LTI_UNKNOWNS };
    int count = st->history_count, distinct = 0;
    if (count < U + 2) return -1;
    double spread = 0, seen[LTI_TERMS];
    for (int e = 0; e < count; e++) {
        double w = st->history[e].omega_rad_s;
        spread = fmax(spread, fabs(w - omega));
        int known = 0;
        for (int q = 0; q < distinct; q++)
            known |= seen[q] == w;
        if (!known && distinct < LTI_TERMS) seen[distinct++] = w;
    }
    if (distinct < LTI_TERMS || !(spread > 0)) return -1;
    for (int k = 0; k < N; k++) {
        double zs = 0;
        for (int e = 0; e < count; e++)
            zs = fmax(zs, hypot(st->history[e].target[k], st->history[e].target[N + k]));
        if (!(zs > 0)) return -1;
        /* unknowns: g's and f's (or r's and e's) coefficients of 1, d with d = (w - omega) /
         * spread, z scaled by zs, so the normal equations are well scaled; value at omega = the
         * constant term. Three right-hand sides: Phi, x, and e_0 for (A^H A)^-1's (0, 0) entry,
         * the variance factor of g0 and r0. */
        double complex rows[RTHS_LTI_HISTORY][U], ata[U * U] = {0}, atb[3 * U] = {0};
        atb[2 * U] = 1.0;
        for (int e = 0; e < count; e++) {
            double d = (st->history[e].omega_rad_s - omega) / spread, dj = 1;
            double complex z = (st->history[e].target[k] + I * st->history[e].target[N + k]) / zs;
            for (int j = 0; j < LTI_TERMS; j++, dj *= d) {
                rows[e][j] = z * dj;
                rows[e][LTI_TERMS + j] = -dj;
            }
            double complex phi = st->history[e].phi[k] + I * st->history[e].phi[N + k];
            double complex x = st->history[e].response[k] + I * st->history[e].response[N + k];
            for (int p = 0; p < U; p++) {
                for (int q = 0; q < U; q++)
                    ata[p + U * q] += conj(rows[e][p]) * rows[e][q];
                atb[p] += conj(rows[e][p]) * phi;
                atb[U + p] += conj(rows[e][p]) * x; /* e's terms come out negated, unused */
            }
        }
        /* Two frequencies are not enough when one has a single evaluation: g and f there cannot
         * be told apart, the normal matrix is rank deficient, and zgesv would still answer with
         * made-up gains (and a tiny scatter). Demand a well-conditioned fit. */
        if (!(rths_cmat_hermitian_eigen_ratio(U, ata) > 1e-10)) return -1;
        if (rths_cmat_solve(U, 3, ata, atb) != 0) return -1;
        double complex g0 = atb[0] / zs, f0 = atb[LTI_TERMS], r0 = atb[U] / zs;
        if (!isfinite(creal(g0)) || !isfinite(cimag(g0)) || !(cabs(g0) > 0) ||
            !isfinite(creal(r0)) || !isfinite(cimag(r0)) || !isfinite(creal(f0)) ||
            !isfinite(cimag(f0)))
            return -1;
        g[k] = g0;
        r[k] = r0;
        z_pred[k] = f0 / g0;
        if (var_ratio) {
            double ss_phi = 0, ss_x = 0;
            for (int e = 0; e < count; e++) {
                double complex fit_phi = 0, fit_x = 0;
                for (int p = 0; p < U; p++) {
                    fit_phi += rows[e][p] * atb[p];
                    fit_x += rows[e][p] * atb[U + p];
                }
                double complex phi = st->history[e].phi[k] + I * st->history[e].phi[N + k];
                double complex x = st->history[e].response[k] + I * st->history[e].response[N + k];
                ss_phi += creal(conj(phi - fit_phi) * (phi - fit_phi));
                ss_x += creal(conj(x - fit_x) * (x - fit_x));
            }
            double factor = fabs(creal(atb[2 * U])) / (zs * zs) / (count - U);
            double var_g = ss_phi * factor, var_r = ss_x * factor, ag = cabs(g0);
            var_ratio[k] = var_r / (ag * ag) + cabs(r0) * cabs(r0) * var_g / (ag * ag * ag * ag);
        }
    }
    return 0;
}

int rths_corrector_lti_predict(rths_corrector_state *state, int harmonics, double omega_rad_s,
                               double *target_a, double *target_b) {
    double complex g[RTHS_MAX_HARMONICS], r[RTHS_MAX_HARMONICS], z[RTHS_MAX_HARMONICS];
    if (!state->lti || state->harmonics != harmonics ||
        lti_fit(state, harmonics, omega_rad_s, g, r, z, NULL) != 0)
        return -1;
    for (int k = 0; k < harmonics; k++) {
        target_a[k] = creal(z[k]);
        target_b[k] = cimag(z[k]);
        lti_block(state->jacobian, harmonics, k, g[k]);
        lti_block(state->response_jacobian, harmonics, k, r[k]);
    }
    return 0;
}

void rths_corrector_seed_jacobians(rths_corrector_state *state, const double *jacobian,
                                   const double *response_jacobian) {
    enum { L = RTHS_MAX_UNKNOWNS };
    for (int j = 0; j < state->n; j++)
        for (int i = 0; i < state->n; i++) {
            state->jacobian[i + j * L] = jacobian[i + j * L];
            state->response_jacobian[i + j * L] = response_jacobian[i + j * L];
        }
    if (state->lti) {
        lti_project(state->jacobian, state->harmonics);
        lti_project(state->response_jacobian, state->harmonics);
    }
}

/* Secant update in the LTI form: one pair (s, y) fixes each harmonic's gain, g_k = y_k / s_k,
 * where Broyden would correct one direction of the block. A harmonic whose change is not well
 * above the noise (noise_k, same units) keeps its gain: a gain from noise is worse than a stale
 * one. */
static void lti_update(double *J, int N, const double *s, const double *y, const double *noise) {
    for (int k = 0; k < N; k++) {
        double complex sk = s[k] + I * s[N + k], yk = y[k] + I * y[N + k];
        if (cabs(yk) > 3 * noise[k] && cabs(sk) > 0) lti_block(J, N, k, yk / sk);
    }
}

/* Noise of each harmonic's change between two evaluations, in the corrector's scaled units:
 * of the mismatch (both sides of both evaluations) and of the physical response. */
static void secant_noise(const rths_evaluation *e0, const rths_evaluation *e1, double scale,
                         double *noise_phi, double *noise_resp) {
    double se0[RTHS_MAX_UNKNOWNS], se1[RTHS_MAX_UNKNOWNS], unused[RTHS_MAX_UNKNOWNS];
    int N = e0->harmonics;
    rths_evaluation_residual(e0, unused, se0);
    rths_evaluation_residual(e1, unused, se1);
    for (int k = 0; k < N; k++) {
        double v = 0;
        for (int h = 0; h < 2; h++)
            v += se0[h * N + k] * se0[h * N + k] + se1[h * N + k] * se1[h * N + k];
        noise_phi[k] = sqrt(v) / scale;
        const rths_fourier *p0 = &e0->phys_se, *p1 = &e1->phys_se;
        noise_resp[k] = sqrt(p0->a[k + 1] * p0->a[k + 1] + p0->b[k + 1] * p0->b[k + 1] +
                             p1->a[k + 1] * p1->a[k + 1] + p1->b[k + 1] * p1->b[k + 1]) /
                        scale;
    }
}

/* Finite-difference Jacobian columns 0..m-1 around u, of Phi and of the physical response
 * (scaled variables). */
static int fd_jacobian(corrector *c, const double *u, const double *phi0, const double *resp0,
                       rths_solution *s, rths_error *err) {
    int n = c->n;
    double up[RTHS_MAX_UNKNOWNS], phi[RTHS_MAX_UNKNOWNS], resp[RTHS_MAX_UNKNOWNS], ext;
    double noise_j = 0, noise_r = 0;
    rths_solution tmp = *s;
    for (int j = 0; j < c->m; j++) {
        memcpy(up, u, sizeof up);
        double h;
        if (j < n) {
            /* relative to the coefficient scale, but above the noise floor */
            h = fmax(c->opt->fd_step_rel * fmax(fabs(u[j]), 1.0),
                     c->opt->fd_step_min_m / c->scale[j]);
        } else {
            h = c->opt->fd_step_omega_rel * fabs(u[j]);
        }
        up[j] += h;
        int rc = eval_at(c, up, &tmp, phi, resp, &ext, err);
        if (rc) return rc;
        /* entry noise of this column: two evaluations' standard errors over the step */
        double se[RTHS_MAX_UNKNOWNS], unused[RTHS_MAX_UNKNOWNS], se_phi = 0, se_x = 0;
        rths_evaluation_residual(&tmp.eval, unused, se);
        for (int i = 0; i < n; i++)
            se_phi += se[i] * se[i] / n;
        for (int k = 1; k <= s->harmonics; k++)
            se_x += (tmp.eval.phys_se.a[k] * tmp.eval.phys_se.a[k] +
                     tmp.eval.phys_se.b[k] * tmp.eval.phys_se.b[k]) /
                    n;
        noise_j = fmax(noise_j, sqrt(2 * se_phi) / c->scale[0] / h);
        noise_r = fmax(noise_r, sqrt(2 * se_x) / c->scale[0] / h);
        for (int i = 0; i < n; i++) {
            c->st->jacobian[i + j * RTHS_MAX_UNKNOWNS] = (phi[i] - phi0[i]) / h;
            c->st->response_jacobian[i + j * RTHS_MAX_UNKNOWNS] = (resp[i] - resp0[i]) / h;
        }
    }
    c->st->have_jacobian = 1;
    c->jacobian_here = 1;
    c->st->lti = c->m == c->n && lti_like(c->st->jacobian, s->harmonics, noise_j) &&
                 lti_like(c->st->response_jacobian, s->harmonics, noise_r);
    if (c->st->lti) {
        lti_project(c->st->jacobian, s->harmonics);
        lti_project(c->st->response_jacobian, s->harmonics);
    }
    return RTHS_OK;
}

/* Solves the m x m extended system J du = -phi by Gaussian elimination with partial pivoting:
 * m <= 11, so LAPACK's call overhead buys nothing here. Returns 0, or -1 if singular. */
static int solve_small(int m, double *a, int lda, double *b) {
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

/* Broyden's rank-one update of the n x m matrix J (leading dimension RTHS_MAX_UNKNOWNS) so that
 * J s = y, with the erratum-6 denominator ||s||^2. */
static void broyden_update(double *J, int n, int m, const double *s, const double *y, double ss) {
    for (int i = 0; i < n; i++) {
        double js = 0;
        for (int j = 0; j < m; j++)
            js += J[i + j * RTHS_MAX_UNKNOWNS] * s[j];
        double f = (y[i] - js) / ss;
        for (int j = 0; j < m; j++)
            J[i + j * RTHS_MAX_UNKNOWNS] += f * s[j];
    }
}

/* Fills sol's matched estimate and the amplitude a report shows (see rths_solution). */
static void finish_solution(const corrector *c, rths_solution *sol) {
    int n = c->n, N = sol->harmonics;
    const rths_evaluation *ev = &sol->eval;
    double phi[RTHS_MAX_UNKNOWNS], x[RTHS_MAX_UNKNOWNS], sp[RTHS_MAX_UNKNOWNS],
        sn[RTHS_MAX_UNKNOWNS];
    rths_evaluation_residual(ev, phi, NULL);
    response_vector(ev, x);
    for (int k = 1; k <= N; k++) {
        sp[k - 1] = ev->phys_se.a[k];
        sp[N + k - 1] = ev->phys_se.b[k];
        sn[k - 1] = ev->num_se.a[k];
        sn[N + k - 1] = ev->num_se.b[k];
    }
    const rths_corrector_state *st = c->st;
    if (st->noise_dof > 0 && ev->average_periods > 0)
        for (int i = 0; i < n; i++) {
            sp[i] = sqrt(st->noise_ss[0][i] / st->noise_dof / ev->average_periods);
            sn[i] = sqrt(st->noise_ss[1][i] / st->noise_dof / ev->average_periods);
        }
    double amp = hypot(x[0], x[N]);
    double amp_se = hypot(x[0] * sp[0], x[N] * sp[N]) / fmax(amp, 1e-300);
    /* LTI rig on a natural sweep: the gains refitted with this point's own evaluations; the
     * fit's scatter says how well r/g is known, and that uncertainty times the residual joins the
     * standard error (for the amplitude, half the complex variance: the error's phase is random) */
    double model_var = 0;
    int fitted = 0;
    if (c->st->lti && c->m == c->n) {
        double complex g[RTHS_MAX_HARMONICS], r[RTHS_MAX_HARMONICS], z[RTHS_MAX_HARMONICS];
        double var_ratio[RTHS_MAX_HARMONICS];
        if (lti_fit(c->st, N, sol->omega_rad_s, g, r, z, var_ratio) == 0) {
            for (int k = 0; k < N; k++) {
                lti_block(c->st->jacobian, N, k, g[k]);
                lti_block(c->st->response_jacobian, N, k, r[k]);
            }
            model_var = 0.5 * var_ratio[0] * (phi[0] * phi[0] + phi[N] * phi[N]);
            fitted = 1;
        }
    }
    sol->have_matched = 0;
    /* The step to zero mismatch solves A d = -(Phi, 0), A being J over the unknowns in use plus,
     * on an arclength run, the arclength row: the step then runs normal to the branch and stays
     * well posed at folds, where the target block of J alone is singular. Columns 0..n-1 of
     * A^-1, mapped by R, give K (x* = x - K Phi) and the frequency's share (w* = w - k_w . Phi). */
    enum { L = RTHS_MAX_UNKNOWNS };
    int m = c->m;
    double K[L * L], kw[L] = {0};
    int ok = st->have_jacobian;
    for (int i = 0; i < n && ok; i++) {
        double a[L * L], z[L] = {0};
        for (int q = 0; q < m; q++) {
            for (int p = 0; p < n; p++)
                a[p + q * L] = st->jacobian[p + q * L];
            if (m > n) a[n + q * L] = c->arc->tangent[q];
        }
        z[i] = 1;
        if (solve_small(m, a, L, z) != 0) {
            ok = 0;
            break;
        }
        for (int p = 0; p < n; p++) {
            double r = 0;
            for (int q = 0; q < m; q++)
                r += st->response_jacobian[p + q * L] * z[q];
            if (!isfinite(r)) ok = 0;
            K[p + i * L] = r;
        }
        if (m > n) kw[i] = z[n] * c->scale[n] / c->scale[0];
    }
    double xm[L], wm = sol->omega_rad_s, step = 0, phi_norm = 0;
    for (int i = 0; i < n && ok; i++) {
        xm[i] = x[i];
        for (int p = 0; p < n; p++)
            xm[i] -= K[i + p * L] * phi[p];
        wm -= kw[i] * phi[i];
        step += (xm[i] - x[i]) * (xm[i] - x[i]);
        phi_norm += phi[i] * phi[i];
    }
    /* Without a fitted model (a nonlinear rig, secant-updated Jacobians) the step's size is the
     * only check: more than 50 times the mismatch (a resonance amplifies by up to ~40) says the
     * Jacobians are not known well enough to extrapolate; near a fold a stale one moved the
     * estimate by 18 % where the measurement was 0.8 % off. Keep the measurement then. A fitted
     * LTI model carries its own uncertainty in model_var. */
    if (ok && !fitted && step > 50.0 * 50.0 * phi_norm) ok = 0;
    /* ...and Jacobians carried from earlier points, unchecked here, are no basis either */
    if (ok && !fitted && !c->jacobian_here) ok = 0;
    if (ok) {
        sol->matched_omega_rad_s = wm;
        for (int k = 0; k < N; k++) {
            sol->matched_a[k] = xm[k];
            sol->matched_b[k] = xm[N + k];
        }
        double am = hypot(xm[0], xm[N]);
        /* x* = (I - K) x_phys + K x_num with independent noise on the two sides; the amplitude's
         * gradient g = (a1, b1) / |x*_1| maps the covariance to a variance */
        double g0 = xm[0] / fmax(am, 1e-300), gN = xm[N] / fmax(am, 1e-300), var = 0;
        for (int p = 0; p < n; p++) {
            double w = g0 * K[0 + p * L] + gN * K[N + p * L];
            double v = (p == 0 ? g0 : p == N ? gN : 0.0) - w;
            var += v * v * sp[p] * sp[p] + w * w * sn[p] * sn[p];
        }
        sol->matched_amplitude_m = am;
        sol->matched_amplitude_se_m = sqrt(var + model_var);
        sol->have_matched = 1;
    }
    if (c->opt->report_matched && sol->have_matched) {
        sol->frequency_hz = sol->matched_omega_rad_s / (2 * M_PI);
        sol->amplitude_m = sol->matched_amplitude_m;
        sol->amplitude_se_m = sol->matched_amplitude_se_m;
    } else {
        sol->frequency_hz = sol->omega_rad_s / (2 * M_PI);
        sol->amplitude_m = amp;
        sol->amplitude_se_m = amp_se;
    }
}

int rths_correct(rths_rig *rig, const rths_settle_options *settle, const rths_newton_options *opt,
                 double amplitude_n, const rths_arclength *arc, rths_corrector_state *state,
                 rths_solution *sol, rths_error *err) {
    corrector c = {.rig = rig,
                   .settle = settle,
                   .opt = opt,
                   .arc = arc,
                   .st = state,
                   .amplitude_n = amplitude_n};
    int N = sol->harmonics;
    c.n = 2 * N;
    c.m = (arc && arc->active) ? c.n + 1 : c.n;
    double amp_scale = (arc && arc->amplitude_scale_m > 0) ? arc->amplitude_scale_m : 1e-4;
    double om_scale = (arc && arc->omega_scale_rad_s > 0) ? arc->omega_scale_rad_s : 1.0;
    for (int j = 0; j < c.n; j++)
        c.scale[j] = amp_scale;
    c.scale[c.n] = om_scale;
    if (state->harmonics != N) {
        memset(state, 0, sizeof *state);
        state->harmonics = N;
        state->n = c.n;
    }
    state->evaluations = 0;
    state->iterations = 0;
    state->rig_time_s = 0;
    /* earlier attempts' noise counts half per attempt: close in frequency, similar noise */
    for (int i = 0; i < c.n; i++) {
        state->noise_ss[0][i] *= 0.5;
        state->noise_ss[1][i] *= 0.5;
    }
    state->noise_dof *= 0.5;
    sol->converged = 0;

    double u[RTHS_MAX_UNKNOWNS] = {0}, phi[RTHS_MAX_UNKNOWNS] = {0}, resp[RTHS_MAX_UNKNOWNS] = {0},
           ext;
    pack(&c, sol, u);
    int rc = eval_at(&c, u, sol, phi, resp, &ext, err);
    if (rc) return rc;
    if (sol->residual_norm_m < sol->tolerance_m && arc_satisfied(&c, phi)) {
        sol->converged = 1;
        finish_solution(&c, sol);
        return RTHS_OK;
    }
    int fresh = 0;
    if (!state->have_jacobian || opt->fresh_jacobian) {
        if ((rc = fd_jacobian(&c, u, phi, resp, sol, err))) return rc;
        fresh = 1;
    } else if (c.m > c.n && fabs(state->jacobian[c.n * RTHS_MAX_UNKNOWNS]) == 0.0) {
        /* carried Jacobian lacks the frequency column (natural sweep before): measure it once */
        if ((rc = fd_jacobian(&c, u, phi, resp, sol, err))) return rc;
        fresh = 1;
    }
    while (state->iterations < opt->max_iterations) {
        state->iterations++;
        double a[RTHS_MAX_UNKNOWNS * RTHS_MAX_UNKNOWNS], du[RTHS_MAX_UNKNOWNS];
        for (int j = 0; j < c.m; j++) {
            for (int i = 0; i < c.n; i++)
                a[i + j * RTHS_MAX_UNKNOWNS] = state->jacobian[i + j * RTHS_MAX_UNKNOWNS];
            if (c.m > c.n) a[c.n + j * RTHS_MAX_UNKNOWNS] = arc->tangent[j];
        }
        for (int i = 0; i < c.m; i++)
            du[i] = -phi[i];
        if (solve_small(c.m, a, RTHS_MAX_UNKNOWNS, du) != 0) {
            if (fresh) return rths_error_set(err, RTHS_EFAIL, "singular Jacobian");
            if ((rc = fd_jacobian(&c, u, phi, resp, sol, err))) return rc;
            fresh = 1;
            continue;
        }
        /* Rig safety: never step by more than twice the larger of the current target and the
         * measured numerical response. A step
         * from a stale (Broyden) or noisy Jacobian can be huge, and on a real rig the trial
         * evaluation itself would trip a limit before the line search could reject it. */
        double tnorm = 0, dnorm = 0;
        for (int i = 0; i < c.n; i++) {
            tnorm += u[i] * u[i];
            dnorm += du[i] * du[i];
        }
        tnorm = sqrt(tnorm);
        dnorm = sqrt(dnorm);
        /* scale: the current target or the numerical response it should follow */
        double rnorm = 0;
        for (int k = 1; k <= N; k++)
            rnorm +=
                sol->eval.num.a[k] * sol->eval.num.a[k] + sol->eval.num.b[k] * sol->eval.num.b[k];
        rnorm = sqrt(rnorm) / amp_scale;
        double limit = 2.0 * fmax(tnorm, rnorm);
        if (dnorm > limit)
            for (int i = 0; i < c.m; i++)
                du[i] *= limit / dnorm;
        /* Backtracking line search on the residual norm (erratum 5). */
        double lambda = 1.0, ut[RTHS_MAX_UNKNOWNS] = {0}, phit[RTHS_MAX_UNKNOWNS] = {0},
               respt[RTHS_MAX_UNKNOWNS] = {0}, extt = 0;
        int accepted = 0;
        rths_solution trial = *sol;
        while (lambda >= opt->min_damping) {
            for (int i = 0; i < c.m; i++)
                ut[i] = u[i] + lambda * du[i];
            for (int i = c.m; i < RTHS_MAX_UNKNOWNS; i++)
                ut[i] = u[i];
            if ((rc = eval_at(&c, ut, &trial, phit, respt, &extt, err))) return rc;
            if (extt < ext) {
                accepted = 1;
                break;
            }
            lambda *= 0.5;
        }
        if (!accepted) {
            if (fresh) break; /* a fresh Jacobian could not reduce the residual: give up */
            if ((rc = fd_jacobian(&c, u, phi, resp, sol, err))) return rc;
            fresh = 1;
            continue;
        }
        /* Broyden updates of the Phi and response rows, scaled variables. */
        double s[RTHS_MAX_UNKNOWNS], y[RTHS_MAX_UNKNOWNS], ss = 0;
        for (int j = 0; j < c.m; j++) {
            s[j] = ut[j] - u[j];
            ss += s[j] * s[j];
        }
        for (int i = 0; i < c.n; i++)
            y[i] = phit[i] - phi[i];
        double complex g[RTHS_MAX_HARMONICS], r[RTHS_MAX_HARMONICS], z[RTHS_MAX_HARMONICS];
        if (ss > 0 && state->lti && c.m == c.n &&
            lti_fit(state, N, trial.omega_rad_s, g, r, z, NULL) == 0) {
            /* every recorded evaluation informs the gains, not only this secant pair */
            for (int k = 0; k < N; k++) {
                lti_block(state->jacobian, N, k, g[k]);
                lti_block(state->response_jacobian, N, k, r[k]);
            }
        } else if (ss > 0 && state->lti && c.m == c.n) {
            double noise_phi[RTHS_MAX_HARMONICS], noise_resp[RTHS_MAX_HARMONICS];
            secant_noise(&sol->eval, &trial.eval, c.scale[0], noise_phi, noise_resp);
            lti_update(state->jacobian, N, s, y, noise_phi);
            for (int i = 0; i < c.n; i++)
                y[i] = respt[i] - resp[i];
            lti_update(state->response_jacobian, N, s, y, noise_resp);
        } else if (ss > 0) {
            broyden_update(state->jacobian, c.n, c.m, s, y, ss);
            for (int i = 0; i < c.n; i++)
                y[i] = respt[i] - resp[i];
            broyden_update(state->response_jacobian, c.n, c.m, s, y, ss);
        }
        fresh = 0;
        c.jacobian_here = 1;
        memcpy(u, ut, sizeof u);
        memcpy(phi, phit, sizeof phi);
        memcpy(resp, respt, sizeof resp);
        ext = extt;
        *sol = trial;
        if (sol->residual_norm_m < sol->tolerance_m && arc_satisfied(&c, phi)) {
            sol->converged = 1;
            finish_solution(&c, sol);
            return RTHS_OK;
        }
    }
    return rths_error_set(err, RTHS_EFAIL,
                          "corrector did not converge at %.6g Hz: residual %.3g m > tolerance "
                          "%.3g m after %d iterations",
                          sol->omega_rad_s / (2 * M_PI), sol->residual_norm_m, sol->tolerance_m,
                          state->iterations);
}
