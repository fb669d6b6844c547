/* The nonlinear numerical substructure on the host (frf_hb_numerical.h): every period the rig
 * publishes is converted to the numerical interface motion by harmonic balance of the
 * substructure under the measured interface force and the real-time form's grounding control
 * toward the measured physical motion (docs/method.md, "Nonlinear elements in the frequency
 * form"). The evaluation's steady-state test, averaging and standard errors then work on
 * displacements, as on the linear frequency form. */
#include "run/frf_hb_numerical.h"

#include "rths/model.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NI RTHS_MAX_INTERFACE_DOFS

struct frf_hb_numerical {
    rths_rig *rig;
    rths_hb_substructure *hb;
    int n_int;
    double kp, kd; /* the first interface DoF's grounding, for run.log */
    double amplitude_n;
    long periods;     /* converted */
    long newton;      /* Newton steps over them */
    int worst_newton; /* in one conversion */
};

static int convert(frf_hb_numerical *h, rths_period *p, rths_error *err) {
    const int ni = h->n_int, several = p->interface_dofs > 0;
    rths_fourier x[NI], force[NI], disp[NI];
    for (int d = 0; d < ni; d++) {
        x[d] = several ? p->phys_dof[d] : p->phys;
        force[d] = several ? p->num_dof[d] : p->num;
    }
    const double w = 2 * M_PI * p->frequency_hz;
    int rc = rths_hb_substructure_solve_dofs(h->hb, w, h->amplitude_n, force, x, disp, err);
    if (rc) return rc;
    int steps = 0;
    rths_hb_substructure_counts(h->hb, &steps, NULL);
    h->periods++;
    h->newton += steps;
    if (steps > h->worst_newton) h->worst_newton = steps;
    for (int d = 0; d < ni; d++)
        if (several) p->num_dof[d] = disp[d];
    p->num = disp[0];
    return RTHS_OK;
}

static int v_set_forcing(void *self, double frequency_hz, double amplitude_n, rths_error *err) {
    frf_hb_numerical *h = self;
    h->amplitude_n = amplitude_n;
    return rths_rig_set_forcing(h->rig, frequency_hz, amplitude_n, err);
}
static int v_set_target(void *self, int harmonics, const double *a, const double *b,
                        rths_error *err) {
    return rths_rig_set_target(((frf_hb_numerical *)self)->rig, harmonics, a, b, err);
}
static int v_set_target_dofs(void *self, int dofs, int harmonics, const double *a, const double *b,
                             rths_error *err) {
    return rths_rig_set_target_dofs(((frf_hb_numerical *)self)->rig, dofs, harmonics, a, b, err);
}
static int v_interface_dofs(void *self) {
    return rths_rig_interface_dofs(((frf_hb_numerical *)self)->rig);
}
static int v_run_periods(void *self, int count, rths_period *out, rths_error *err) {
    frf_hb_numerical *h = self;
    int rc = rths_rig_run_periods(h->rig, count, out, err);
    for (int i = 0; i < count && !rc; i++)
        rc = convert(h, &out[i], err);
    return rc;
}
static int v_record_trace(void *self, double duration_s, int max_samples, rths_trace_sample *out,
                          int *n_out, rths_error *err) {
    return rths_rig_record_trace(((frf_hb_numerical *)self)->rig, duration_s, max_samples, out,
                                 n_out, err);
}
static double v_time_s(void *self) {
    return rths_rig_time_s(((frf_hb_numerical *)self)->rig);
}
static rths_rig_fault v_fault(void *self) {
    return rths_rig_get_fault(((frf_hb_numerical *)self)->rig);
}
static int v_reset_fault(void *self, rths_error *err) {
    return rths_rig_reset_fault(((frf_hb_numerical *)self)->rig, err);
}
static double v_noise_level_m(void *self) {
    return rths_rig_noise_level_m(((frf_hb_numerical *)self)->rig);
}

static const rths_rig_ops view_ops = {.set_forcing = v_set_forcing,
                                      .set_target = v_set_target,
                                      .run_periods = v_run_periods,
                                      .record_trace = v_record_trace,
                                      .time_s = v_time_s,
                                      .fault = v_fault,
                                      .reset_fault = v_reset_fault,
                                      .noise_level_m = v_noise_level_m,
                                      .destroy = NULL,
                                      .set_target_dofs = v_set_target_dofs,
                                      .interface_dofs = v_interface_dofs};

void frf_hb_numerical_destroy(frf_hb_numerical *h, rths_rig *view) {
    if (view) rths_rig_destroy(view);
    if (!h) return;
    rths_hb_substructure_destroy(h->hb);
    free(h);
}

int frf_hb_numerical_create(const rths_setup *setup, rths_rig *rig, const double *grounding_kp,
                            const double *grounding_kd, frf_hb_numerical **out, rths_rig **view,
                            rths_error *err) {
    *out = NULL;
    *view = NULL;
    const rths_split *s = &setup->split;
    if (s->n_int < 1 || s->n_int > NI)
        return rths_error_set(err, RTHS_EINPUT, "%d interface DoFs: 1 to %d supported", s->n_int,
                              NI);
    frf_hb_numerical *h = calloc(1, sizeof *h);
    if (!h) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    h->rig = rig;
    h->n_int = s->n_int;
    int rc =
        rths_hb_substructure_create(s, setup->n_nonlinear, setup->nonlinear, setup->static_force,
                                    setup->forcing_dof, NULL, &h->hb, err);
    if (!rc) rc = rths_hb_substructure_set_grounding(h->hb, grounding_kp, grounding_kd, err);
    if (rc) {
        frf_hb_numerical_destroy(h, NULL);
        return rc;
    }
    h->kp = grounding_kp[0], h->kd = grounding_kd[0];
    *view = rths_rig_create(&view_ops, h, rths_rig_description(rig));
    if (!*view) {
        frf_hb_numerical_destroy(h, NULL);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    *out = h;
    return RTHS_OK;
}

void frf_hb_numerical_describe(const frf_hb_numerical *h, int counts, char *buf, size_t size) {
    char hb[256];
    rths_hb_substructure_describe(h->hb, hb, sizeof hb);
    if (!counts) {
        snprintf(buf, size,
                 "%s; driven by the measured force on %d interface DoF(s), grounded to the "
                 "physical interface by %g N/m and %g N s/m (the first DoF's)",
                 hb, h->n_int, h->kp, h->kd);
        return;
    }
    snprintf(buf, size, "%s; %ld periods converted, %.2f Newton steps per period (at most %d)", hb,
             h->periods, h->periods ? (double)h->newton / (double)h->periods : 0.0,
             h->worst_newton);
}
