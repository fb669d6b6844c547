/* One evaluation of the rig-backed zero problem: steady state, averaging, the residual record;
 * and the corrector's use of a record (noise pooling, LTI history, tolerance, arclength row). */
#include "iterate/corrector_internal.h"

#include <complex.h>
#include <math.h>
#include <string.h>

/* ---- one evaluation ---- */

static int coefficient_vector(const rths_period *p, int harmonics, double *v) {
    int m = 0;
    for (int k = 1; k <= harmonics; k++) {
        v[m++] = p->phys.a[k];
        v[m++] = p->phys.b[k];
        v[m++] = p->num.a[k];
        v[m++] = p->num.b[k];
    }
    /* the other interface DoFs of a rig that drives several */
    for (int d = 1; d < p->interface_dofs; d++)
        for (int k = 1; k <= harmonics; k++) {
            v[m++] = p->phys_dof[d].a[k];
            v[m++] = p->phys_dof[d].b[k];
            v[m++] = p->num_dof[d].a[k];
            v[m++] = p->num_dof[d].b[k];
        }
    return m;
}

static double vec_norm(const double *v, int n) {
    double s = 0;
    for (int i = 0; i < n; i++)
        s += v[i] * v[i];
    return sqrt(s);
}

/* Runs periods until the coefficient stream is steady (or the fixed wait elapses); *waited and
 * *steady say how it went. */
static int wait_steady(rths_rig *rig, const rths_settle_options *opt, int harmonics, int *waited,
                       int *steady, rths_error *err) {
    enum { NC = 4 * RTHS_MAX_HARMONICS * RTHS_MAX_INTERFACE_DOFS };
    double prev[NC], cur[NC], change_prev = -1;
    rths_period p;
    int rc, m = 0;
    *waited = 0;
    *steady = 0;
    if (opt->fixed_wait_periods > 0) {
        for (; *waited < opt->fixed_wait_periods; (*waited)++)
            if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
        *steady = 1;
        return RTHS_OK;
    }
    double noise_m = rths_rig_noise_level_m(rig);
    while (*waited < opt->max_wait_periods) {
        if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
        (*waited)++;
        m = coefficient_vector(&p, harmonics, cur);
        if (*waited > 1) {
            double d[NC];
            for (int i = 0; i < m; i++)
                d[i] = cur[i] - prev[i];
            double change = vec_norm(d, m);
            /* White noise of std s on S samples gives each per-period coefficient a std of
             * s sqrt(2/S); the change of m of them between periods, sqrt(2 m) times that. */
            double noise_change =
                p.samples > 0 ? noise_m * sqrt(2.0 / p.samples) * sqrt(2.0 * m) : 0.0;
            double threshold = fmax(opt->abs_tolerance_m, opt->rel_tolerance * vec_norm(cur, m));
            /* A geometric transient with ratio r per period still owes change * r / (1 - r);
             * r is estimated from the last two changes (clamped so a noisy estimate near 1
             * keeps us waiting rather than accepting). */
            double remaining;
            if (change == 0.0) {
                remaining = 0.0; /* bit-identical periods: nothing left to settle */
            } else if (change_prev > 0) {
                double r = fmin(change / change_prev, 0.995);
                remaining = change * (1.0 + r / (1.0 - r));
            } else {
                remaining = INFINITY;
            }
            if (*waited >= opt->min_wait_periods &&
                (remaining < threshold || change < opt->noise_factor * noise_change)) {
                *steady = 1;
                break;
            }
            change_prev = change;
        }
        memcpy(prev, cur, sizeof cur);
    }
    return RTHS_OK;
}

/* Mean and standard error of the mean of one interface DoF's coefficients over n_avg periods
 * (side 0 physical, 1 numerical). */
static void mean_and_error(int n_avg, double sum[2][2][RTHS_MAX_HARMONICS + 1],
                           double sum2[2][2][RTHS_MAX_HARMONICS + 1], rths_fourier *mean[2],
                           rths_fourier *se[2]) {
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
}

/* Averages n_avg whole periods: mean and standard error of the mean of every coefficient the rig
 * measures, not only the matched ones (the report shows the higher harmonics' error too), of
 * every interface DoF the periods carry. */
static int average_periods(rths_rig *rig, int n_avg, rths_evaluation *out, rths_error *err) {
    enum { H = RTHS_MAX_HARMONICS + 1, D = RTHS_MAX_INTERFACE_DOFS };
    static const double zero[2][2][H];
    double sum[D][2][2][H], sum2[D][2][2][H];
    for (int d = 0; d < D; d++) {
        memcpy(sum[d], zero, sizeof zero);
        memcpy(sum2[d], zero, sizeof zero);
    }
    rths_period p;
    int rc, dofs = 1;
    for (int q = 0; q < n_avg; q++) {
        if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
        dofs = p.interface_dofs > 1 ? p.interface_dofs : 1;
        for (int d = 1; d < dofs; d++) {
            const rths_fourier *side[2] = {&p.phys_dof[d], &p.num_dof[d]};
            for (int s = 0; s < 2; s++)
                for (int k = 0; k < H; k++) {
                    sum[d][s][0][k] += side[s]->a[k];
                    sum[d][s][1][k] += side[s]->b[k];
                    sum2[d][s][0][k] += side[s]->a[k] * side[s]->a[k];
                    sum2[d][s][1][k] += side[s]->b[k] * side[s]->b[k];
                }
        }
        const rths_fourier *side[2] = {&p.phys, &p.num};
        for (int s = 0; s < 2; s++)
            for (int k = 0; k < H; k++) {
                sum[0][s][0][k] += side[s]->a[k];
                sum[0][s][1][k] += side[s]->b[k];
                sum2[0][s][0][k] += side[s]->a[k] * side[s]->a[k];
                sum2[0][s][1][k] += side[s]->b[k] * side[s]->b[k];
            }
    }
    rths_fourier *mean[2] = {&out->phys, &out->num}, *se[2] = {&out->phys_se, &out->num_se};
    mean_and_error(n_avg, sum[0], sum2[0], mean, se);
    if (dofs > 1) {
        out->interface_dofs = dofs;
        out->phys_dof[0] = out->phys, out->num_dof[0] = out->num;
        out->phys_dof_se[0] = out->phys_se, out->num_dof_se[0] = out->num_se;
    }
    for (int d = 1; d < dofs; d++) {
        rths_fourier *mean_d[2] = {&out->phys_dof[d], &out->num_dof[d]},
                     *se_d[2] = {&out->phys_dof_se[d], &out->num_dof_se[d]};
        mean_and_error(n_avg, sum[d], sum2[d], mean_d, se_d);
    }
    return RTHS_OK;
}

int rths_evaluate(rths_rig *rig, const rths_settle_options *opt, int harmonics, double frequency_hz,
                  double amplitude_n, const double *target_a, const double *target_b,
                  rths_evaluation *out, rths_error *err) {
    return rths_evaluate_dofs(rig, opt, harmonics, 1, frequency_hz, amplitude_n, target_a, target_b,
                              out, err);
}

int rths_evaluate_dofs(rths_rig *rig, const rths_settle_options *opt, int harmonics, int dofs,
                       double frequency_hz, double amplitude_n, const double *target_a,
                       const double *target_b, rths_evaluation *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    out->harmonics = harmonics;
    out->frequency_hz = frequency_hz;
    if (!(isfinite(frequency_hz) && frequency_hz > 0))
        return rths_error_set(err, RTHS_EFAIL, "corrector asked for a non-physical frequency %g Hz",
                              frequency_hz);
    for (int k = 0; k < harmonics * dofs; k++)
        if (!isfinite(target_a[k]) || !isfinite(target_b[k]))
            return rths_error_set(err, RTHS_EFAIL, "corrector produced a non-finite target");
    double t0 = rths_rig_time_s(rig);
    int rc = rths_rig_set_forcing(rig, frequency_hz, amplitude_n, err);
    if (!rc) rc = rths_rig_set_target_dofs(rig, dofs, harmonics, target_a, target_b, err);
    if (rc) return rc;
    int waited = 0, steady = 0;
    if ((rc = wait_steady(rig, opt, harmonics, &waited, &steady, err))) return rc;
    int n_avg = opt->average_periods > 0 ? opt->average_periods : 1;
    if ((rc = average_periods(rig, n_avg, out, err))) return rc;
    out->wait_periods = waited;
    out->average_periods = n_avg;
    out->steady = steady;
    out->rig_time_s = rths_rig_time_s(rig) - t0;
    if (rths_rig_get_fault(rig) != RTHS_RIG_OK)
        return rths_error_set(err, RTHS_EFAIL, "rig fault during evaluation at %.6g Hz: %s",
                              frequency_hz, rths_rig_fault_name(rths_rig_get_fault(rig)));
    return RTHS_OK;
}

/* Interface DoF d's physical and numerical means and standard errors. */
static void dof_sides(const rths_evaluation *ev, int d, const rths_fourier **phys,
                      const rths_fourier **num, const rths_fourier **phys_se,
                      const rths_fourier **num_se) {
    int several = ev->interface_dofs > 1;
    *phys = several ? &ev->phys_dof[d] : &ev->phys;
    *num = several ? &ev->num_dof[d] : &ev->num;
    *phys_se = several ? &ev->phys_dof_se[d] : &ev->phys_se;
    *num_se = several ? &ev->num_dof_se[d] : &ev->num_se;
}

void rths_evaluation_residual(const rths_evaluation *ev, double *phi, double *phi_se) {
    int N = ev->harmonics, dofs = ev->interface_dofs > 1 ? ev->interface_dofs : 1, M = N * dofs;
    for (int d = 0; d < dofs; d++) {
        const rths_fourier *ph, *nu, *ph_se, *nu_se;
        dof_sides(ev, d, &ph, &nu, &ph_se, &nu_se);
        for (int k = 1; k <= N; k++) {
            int j = d * N + k - 1;
            phi[j] = ph->a[k] - nu->a[k];
            phi[M + j] = ph->b[k] - nu->b[k];
            if (phi_se) {
                phi_se[j] = hypot(ph_se->a[k], nu_se->a[k]);
                phi_se[M + j] = hypot(ph_se->b[k], nu_se->b[k]);
            }
        }
    }
}

void rths_residual_from_evaluation(const rths_evaluation *ev, rths_residual *out) {
    int N = ev->harmonics, dofs = ev->interface_dofs > 1 ? ev->interface_dofs : 1, M = N * dofs;
    out->n = 2 * M;
    rths_evaluation_residual(ev, out->phi, out->phi_se);
    for (int d = 0; d < dofs; d++) {
        const rths_fourier *ph, *nu, *ph_se, *nu_se;
        dof_sides(ev, d, &ph, &nu, &ph_se, &nu_se);
        for (int k = 1; k <= N; k++) {
            int j = d * N + k - 1;
            out->response[j] = ph->a[k];
            out->response[M + j] = ph->b[k];
            out->response_se[j] = ph_se->a[k];
            out->response_se[M + j] = ph_se->b[k];
            out->reference[j] = nu->a[k];
            out->reference[M + j] = nu->b[k];
            out->reference_se[j] = nu_se->a[k];
            out->reference_se[M + j] = nu_se->b[k];
        }
    }
    out->rig_time_s = ev->rig_time_s;
    out->samples = ev->average_periods;
    out->eval = *ev;
}

static int rig_problem_eval(void *ctx, const double *u, double omega_rad_s, rths_residual *out,
                            rths_error *err) {
    const rths_rig_problem *rp = ctx;
    int N = rp->harmonics, dofs = rp->interface_dofs > 1 ? rp->interface_dofs : 1, M = N * dofs;
    double a[RTHS_MAX_UNKNOWNS], b[RTHS_MAX_UNKNOWNS];
    for (int j = 0; j < M; j++) { /* pair j = (DoF j / N, harmonic j % N + 1) */
        a[j] = u[j];
        b[j] = u[M + j];
    }
    rths_evaluation ev;
    int rc = rths_evaluate_dofs(rp->rig, rp->settle, N, dofs, omega_rad_s / (2 * M_PI),
                                rp->amplitude_n, a, b, &ev, err);
    memset(out, 0, sizeof *out);
    if (rc) {
        out->rig_time_s = ev.rig_time_s;
        out->eval = ev;
        return rc;
    }
    rths_residual_from_evaluation(&ev, out);
    return RTHS_OK;
}

void rths_rig_problem_init(rths_zero_problem *problem, rths_rig_problem *ctx, rths_rig *rig,
                           const rths_settle_options *settle, int harmonics, double amplitude_n) {
    *ctx = (rths_rig_problem){.rig = rig,
                              .settle = settle,
                              .harmonics = harmonics,
                              .amplitude_n = amplitude_n,
                              .interface_dofs = 1};
    *problem = (rths_zero_problem){
        .n = 2 * harmonics, .harmonics = harmonics, .eval = rig_problem_eval, .ctx = ctx};
}

int rths_rig_problem_init_dofs(rths_zero_problem *problem, rths_rig_problem *ctx, rths_rig *rig,
                               const rths_settle_options *settle, int harmonics, double amplitude_n,
                               rths_error *err) {
    rths_rig_problem_init(problem, ctx, rig, settle, harmonics, amplitude_n);
    int dofs = rths_rig_interface_dofs(rig);
    if (dofs == 1) return RTHS_OK;
    if (2 * harmonics * dofs > 2 * RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT,
                              "%d harmonics on %d interface DoFs are %d unknowns; the corrector "
                              "takes at most %d (2 RTHS_MAX_HARMONICS)",
                              harmonics, dofs, 2 * harmonics * dofs, 2 * RTHS_MAX_HARMONICS);
    ctx->interface_dofs = dofs;
    problem->n = 2 * harmonics * dofs;
    problem->harmonics = harmonics * dofs;
    problem->interface_dofs = dofs;
    return RTHS_OK;
}

/* ---- the corrector's use of one record ---- */

/* Pools the record's per-sample variances (se^2 n (n - 1) is the sum of squared deviations). */
static void pool_noise(corrector_memory *mem, const rths_residual *r, int n) {
    int s = r->samples;
    if (s <= 1) return;
    int N = n / 2;
    for (int k = 1; k <= N; k++) {
        const double *sd[2] = {r->response_se, r->reference_se};
        for (int side = 0; side < 2; side++) {
            mem->noise_ss[side][k - 1] += sd[side][k - 1] * sd[side][k - 1] * s * (s - 1);
            mem->noise_ss[side][N + k - 1] +=
                sd[side][N + k - 1] * sd[side][N + k - 1] * s * (s - 1);
        }
    }
    if (n % 2)
        for (int side = 0; side < 2; side++) {
            const double *sd = side ? r->reference_se : r->response_se;
            mem->noise_ss[side][n - 1] += sd[n - 1] * sd[n - 1] * s * (s - 1);
        }
    mem->noise_dof += s - 1;
}

/* Natural sweep on Fourier unknowns: the record joins the LTI model's history (ring). */
static void remember_evaluation(corrector_memory *mem, const double *target, double omega,
                                const rths_residual *r, int n) {
    int h = mem->history_next;
    mem->history[h].omega_rad_s = omega;
    memcpy(mem->history[h].target, target, sizeof(double) * (size_t)n);
    memcpy(mem->history[h].phi, r->phi, sizeof(double) * (size_t)n);
    memcpy(mem->history[h].response, r->response, sizeof(double) * (size_t)n);
    mem->history_next = (h + 1) % RTHS_LTI_HISTORY;
    if (mem->history_count < RTHS_LTI_HISTORY) mem->history_count++;
}

/* The solution view of an iterate (its targets were set by corrector_evaluate): the norm of Phi and
 * the tolerance max(rel * ||reference||, abs, noise_factor * ||standard error of Phi||). Returns
 * ||Phi||^2. */
static double describe(const rths_corrector *c, corrector_point *p) {
    const rths_residual *r = &p->rec;
    int N = c->harmonics, n = c->n;
    p->sol.eval = r->eval;
    double sq = 0, ref_sq = 0, se_sq = 0;
    for (int i = 0; i < n; i++) {
        sq += r->phi[i] * r->phi[i];
        se_sq += r->phi_se[i] * r->phi_se[i];
    }
    for (int k = 0; k < N; k++)
        ref_sq += r->reference[k] * r->reference[k] + r->reference[N + k] * r->reference[N + k];
    if (!N)
        for (int i = 0; i < n; i++)
            ref_sq += r->reference[i] * r->reference[i];
    p->sol.residual_norm_m = sqrt(sq);
    p->sol.tolerance_m = fmax(fmax(c->opt.rel_tolerance * sqrt(ref_sq), c->opt.abs_tolerance_m),
                              c->opt.noise_factor * sqrt(se_sq));
    return sq;
}

/* Evaluates at scaled u into *p: the record, then the scaled residual and response, the
 * arclength row and the extended residual norm. */
int corrector_evaluate(rths_corrector *c, const double *u, corrector_point *p, rths_error *err) {
    int n = c->n;
    double target[LD];
    for (int i = 0; i < n; i++)
        target[i] = u[i] * c->scale[i];
    p->sol.omega_rad_s = u[n] * c->scale[n];
    memcpy(p->u, u, sizeof p->u);
    int rc = c->problem.eval(c->problem.ctx, target, p->sol.omega_rad_s, &p->rec, err);
    c->evaluations++;
    c->rig_time_s += p->rec.rig_time_s;
    for (int k = 0; k < c->harmonics; k++) {
        p->sol.target_a[k] = target[k];
        p->sol.target_b[k] = target[c->harmonics + k];
    }
    if (rc) return rc;
    pool_noise(&c->mem, &p->rec, n);
    if ((c->m == n || c->opt.rig_lti) && c->harmonics > 0)
        remember_evaluation(&c->mem, target, p->sol.omega_rad_s, &p->rec, n);
    double ext = describe(c, p) / (c->scale[0] * c->scale[0]);
    for (int i = 0; i < n; i++) {
        p->phi[i] = p->rec.phi[i] / c->scale[0];
        p->resp[i] = p->rec.response[i] / c->scale[0];
    }
    if (c->m > n) {
        double g = 0;
        for (int j = 0; j < c->m; j++)
            g += c->arc.tangent[j] * (u[j] - c->arc.predicted[j]);
        p->phi[n] = g;
        ext += g * g;
    }
    p->ext = sqrt(ext);
    return RTHS_OK;
}
