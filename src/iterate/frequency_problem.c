/* The zero problem with the numerical substructure solved on the host, per harmonic (see
 * iterate.h, rths_frequency_problem; docs/method.md, "Numerical substructure integration"). The
 * rig's evaluation is the real-time form's (steady state, averaging); only the numerical side's
 * coefficients come from the measured interface force instead of the controller's model. */
#include "rths/iterate.h"

#include <math.h>
#include <string.h>

/* x = a cos + b sin = Re((a - i b) e^{i k w t}): the complex amplitude of a coefficient pair */
static double complex phasor(double a, double b) {
    return a - I * b;
}

int rths_frequency_evaluation_convert(rths_evaluation *ev, double amplitude_n,
                                      rths_receptance_fn receptance, void *receptance_ctx,
                                      rths_error *err) {
    const double omega = 2 * M_PI * ev->frequency_hz;
    const rths_fourier force = ev->num, force_se = ev->num_se;
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
        double complex h, forced;
        int rc = receptance(receptance_ctx, k * omega, &h, &forced, err);
        if (rc) return rc;
        double complex x = h * phasor(force.a[k], force.b[k]);
        if (k == 1) x += forced * amplitude_n; /* the forcing is amplitude cos(theta) */
        ev->num.a[k] = creal(x);
        ev->num.b[k] = -cimag(x);
        /* a = Re h Fa + Im h Fb, b = Re h Fb - Im h Fa: independent errors of Fa and Fb */
        double hr2 = creal(h) * creal(h), hi2 = cimag(h) * cimag(h);
        double sa2 = force_se.a[k] * force_se.a[k], sb2 = force_se.b[k] * force_se.b[k];
        ev->num_se.a[k] = sqrt(hr2 * sa2 + hi2 * sb2);
        ev->num_se.b[k] = sqrt(hr2 * sb2 + hi2 * sa2);
    }
    /* static terms are discarded by the residual; the numerical interface's mean follows the
     * physical one, as the grounding control makes it do on the real-time form */
    ev->num.a[0] = ev->phys.a[0];
    ev->num_se.a[0] = ev->phys_se.a[0];
    return RTHS_OK;
}

static int frequency_problem_eval(void *ctx, const double *u, double omega_rad_s,
                                  rths_residual *out, rths_error *err) {
    const rths_frequency_problem *fp = ctx;
    int N = fp->harmonics;
    double a[RTHS_MAX_HARMONICS], b[RTHS_MAX_HARMONICS];
    for (int k = 0; k < N; k++) {
        a[k] = u[k];
        b[k] = u[N + k];
    }
    rths_evaluation ev;
    int rc = rths_evaluate(fp->rig, fp->settle, N, omega_rad_s / (2 * M_PI), fp->amplitude_n, a, b,
                           &ev, err);
    if (!rc)
        rc = rths_frequency_evaluation_convert(&ev, fp->amplitude_n, fp->receptance,
                                               fp->receptance_ctx, err);
    memset(out, 0, sizeof *out);
    if (rc) {
        out->rig_time_s = ev.rig_time_s;
        out->eval = ev;
        return rc;
    }
    rths_residual_from_evaluation(&ev, out);
    return RTHS_OK;
}

void rths_frequency_problem_init(rths_zero_problem *problem, rths_frequency_problem *ctx,
                                 rths_rig *rig, const rths_settle_options *settle, int harmonics,
                                 double amplitude_n, rths_receptance_fn receptance,
                                 void *receptance_ctx) {
    *ctx = (rths_frequency_problem){.rig = rig,
                                    .settle = settle,
                                    .harmonics = harmonics,
                                    .amplitude_n = amplitude_n,
                                    .receptance = receptance,
                                    .receptance_ctx = receptance_ctx};
    *problem = (rths_zero_problem){
        .n = 2 * harmonics, .harmonics = harmonics, .eval = frequency_problem_eval, .ctx = ctx};
}
