/* The zero problem with the numerical substructure solved on the host, per harmonic (see
 * iterate.h, rths_frequency_problem; docs/method.md, "Numerical substructure integration").
 *
 * The hybrid rig is seen through a view that converts every published period's interface force
 * into the numerical interface displacement before anyone reads it. The evaluation is then the
 * real-time form's own (rths_rig_problem: steady-state test, averaging, standard errors), all in
 * metres, so the settling and noise rules need nothing new. */
#include "rths/iterate.h"

#include "rths/harmonic_balance.h"

#include <math.h>
#include <string.h>

/* x = a cos + b sin = Re((a - i b) e^{i k w t}): the complex amplitude of a coefficient pair */
static double complex phasor(double a, double b) {
    return a - I * b;
}

/* A numerical substructure with nonlinear elements (receptance rths_hb_substructure_eval): every
 * harmonic depends on every other. A period's record is converted force-driven (harmonic balance
 * of the substructure under the measured interface force, the interface mean the physical one).
 * The force-driven substructure can fold on its own where a harmonic meets one of its resonances
 * (the bilinear example near its folds: no solution near the last one); there, and for an
 * averaged evaluation, the conversion runs the other way (docs/method.md, "Nonlinear elements in
 * the frequency form"): harmonic balance gives the interface force F_req the numerical side needs
 * to follow the measured physical interface motion x, and the numerical interface displacement is
 *     x_num = x + H(k w) (F - F_req(x)),
 * H the receptance of the substructure's linear part. Where F = F_req(x) the sides agree, so the
 * zero problem's solutions are the hybrid's; on a linear substructure this is exactly the linear
 * conversion. The standard errors: H carries the force's (as the linear form), the physical
 * side's add. */
static int convert_nonlinear(rths_fourier *num, rths_fourier *num_se, const rths_fourier *phys,
                             const rths_fourier *phys_se, double frequency_hz, double amplitude_n,
                             rths_hb_substructure *hb, rths_error *err) {
    const double omega = 2 * M_PI * frequency_hz;
    if (!num_se) { /* a period's record: force-driven first */
        rths_fourier disp;
        rths_error ignored;
        if (!rths_hb_substructure_solve(hb, omega, amplitude_n, RTHS_MAX_HARMONICS, num->a, num->b,
                                        phys->a[0], disp.a, disp.b, NULL, &ignored)) {
            *num = disp;
            return RTHS_OK;
        }
    }
    rths_fourier need;
    int rc = rths_hb_substructure_force(hb, omega, amplitude_n, RTHS_MAX_HARMONICS, phys->a,
                                        phys->b, need.a, need.b, err);
    for (int k = 1; k <= RTHS_MAX_HARMONICS && !rc; k++) {
        double complex h, forced;
        rc = rths_hb_substructure_eval(hb, k * omega, &h, &forced, err);
        if (rc) break;
        double complex x = phasor(phys->a[k], phys->b[k]) +
                           h * phasor(num->a[k] - need.a[k], num->b[k] - need.b[k]);
        num->a[k] = creal(x);
        num->b[k] = -cimag(x);
        if (!num_se) continue;
        double hr2 = creal(h) * creal(h), hi2 = cimag(h) * cimag(h);
        double sa2 = num_se->a[k] * num_se->a[k], sb2 = num_se->b[k] * num_se->b[k];
        double pa = phys_se ? phys_se->a[k] : 0.0, pb = phys_se ? phys_se->b[k] : 0.0;
        num_se->a[k] = sqrt(hr2 * sa2 + hi2 * sb2 + pa * pa);
        num_se->b[k] = sqrt(hr2 * sb2 + hi2 * sa2 + pb * pb);
    }
    if (rc) return rc;
    num->a[0] = phys->a[0];
    if (num_se) num_se->a[0] = phys_se ? phys_se->a[0] : 0.0;
    return RTHS_OK;
}

int rths_frequency_convert(rths_fourier *num, rths_fourier *num_se, const rths_fourier *phys,
                           const rths_fourier *phys_se, double frequency_hz, double amplitude_n,
                           rths_receptance_fn receptance, void *receptance_ctx, rths_error *err) {
    if (receptance == rths_hb_substructure_eval)
        return convert_nonlinear(num, num_se, phys, phys_se, frequency_hz, amplitude_n,
                                 receptance_ctx, err);
    const double omega = 2 * M_PI * frequency_hz;
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
        double complex h, forced;
        int rc = receptance(receptance_ctx, k * omega, &h, &forced, err);
        if (rc) return rc;
        double complex x = h * phasor(num->a[k], num->b[k]);
        if (k == 1) x += forced * amplitude_n; /* the forcing is amplitude cos(theta) */
        num->a[k] = creal(x);
        num->b[k] = -cimag(x);
        if (!num_se) continue;
        /* a = Re h Fa + Im h Fb, b = Re h Fb - Im h Fa: independent errors of Fa and Fb */
        double hr2 = creal(h) * creal(h), hi2 = cimag(h) * cimag(h);
        double sa2 = num_se->a[k] * num_se->a[k], sb2 = num_se->b[k] * num_se->b[k];
        num_se->a[k] = sqrt(hr2 * sa2 + hi2 * sb2);
        num_se->b[k] = sqrt(hr2 * sb2 + hi2 * sa2);
    }
    /* static terms are discarded by the residual; the numerical interface's mean follows the
     * physical one, as the grounding control makes it do on the real-time form */
    num->a[0] = phys->a[0];
    if (num_se) num_se->a[0] = phys_se ? phys_se->a[0] : 0.0;
    return RTHS_OK;
}

int rths_frequency_evaluation_convert(rths_evaluation *ev, double amplitude_n,
                                      rths_receptance_fn receptance, void *receptance_ctx,
                                      rths_error *err) {
    return rths_frequency_convert(&ev->num, &ev->num_se, &ev->phys, &ev->phys_se, ev->frequency_hz,
                                  amplitude_n, receptance, receptance_ctx, err);
}

/* ---- the converting view of the rig: every call forwards, run_periods converts ---- */

static int view_set_forcing(void *self, double frequency_hz, double amplitude_n, rths_error *err) {
    rths_frequency_problem *fp = self;
    fp->amplitude_n = amplitude_n;
    return rths_rig_set_forcing(fp->rig, frequency_hz, amplitude_n, err);
}
static int view_set_target(void *self, int harmonics, const double *a, const double *b,
                           rths_error *err) {
    return rths_rig_set_target(((rths_frequency_problem *)self)->rig, harmonics, a, b, err);
}
static int view_run_periods(void *self, int count, rths_period *out, rths_error *err) {
    rths_frequency_problem *fp = self;
    int rc = rths_rig_run_periods(fp->rig, count, out, err);
    for (int i = 0; i < count && !rc; i++)
        rc = rths_frequency_convert(&out[i].num, NULL, &out[i].phys, NULL, out[i].frequency_hz,
                                    fp->amplitude_n, fp->receptance, fp->receptance_ctx, err);
    return rc;
}
static int view_record_trace(void *self, double duration_s, int max_samples, rths_trace_sample *out,
                             int *n_out, rths_error *err) {
    return rths_rig_record_trace(((rths_frequency_problem *)self)->rig, duration_s, max_samples,
                                 out, n_out, err);
}
static double view_time_s(void *self) {
    return rths_rig_time_s(((rths_frequency_problem *)self)->rig);
}
static rths_rig_fault view_fault(void *self) {
    return rths_rig_get_fault(((rths_frequency_problem *)self)->rig);
}
static int view_reset_fault(void *self, rths_error *err) {
    return rths_rig_reset_fault(((rths_frequency_problem *)self)->rig, err);
}
static double view_noise_level_m(void *self) {
    return rths_rig_noise_level_m(((rths_frequency_problem *)self)->rig);
}

static const rths_rig_ops view_ops = {.set_forcing = view_set_forcing,
                                      .set_target = view_set_target,
                                      .run_periods = view_run_periods,
                                      .record_trace = view_record_trace,
                                      .time_s = view_time_s,
                                      .fault = view_fault,
                                      .reset_fault = view_reset_fault,
                                      .noise_level_m = view_noise_level_m,
                                      .destroy = NULL};

int rths_frequency_problem_init(rths_zero_problem *problem, rths_frequency_problem *ctx,
                                rths_rig *rig, const rths_settle_options *settle, int harmonics,
                                double amplitude_n, rths_receptance_fn receptance,
                                void *receptance_ctx, rths_error *err) {
    *ctx = (rths_frequency_problem){.rig = rig,
                                    .amplitude_n = amplitude_n,
                                    .receptance = receptance,
                                    .receptance_ctx = receptance_ctx};
    ctx->view = rths_rig_create(&view_ops, ctx, rths_rig_description(rig));
    if (!ctx->view) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    rths_rig_problem_init(problem, &ctx->inner, ctx->view, settle, harmonics, amplitude_n);
    return RTHS_OK;
}

void rths_frequency_problem_release(rths_frequency_problem *ctx) {
    if (ctx->view) rths_rig_destroy(ctx->view);
    ctx->view = NULL;
}
