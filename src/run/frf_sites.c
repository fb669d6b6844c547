/* The host-side numerical substructure over several interface DoFs (frf_sites.h). Dense solves
 * of the substructure's dynamic stiffness, one per interface DoF and one for the forcing, per
 * harmonic and frequency (cached: a run changes frequency once per point, every period of an
 * evaluation reuses them). The evaluation's steady-state test, averaging and standard errors
 * then work on displacements, as on the one-DoF frequency form (iterate.h,
 * rths_frequency_problem). */
#include "run/frf_sites.h"

#include "rths/model.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NI RTHS_MAX_INTERFACE_DOFS

struct frf_host_numerical {
    rths_rig *rig;
    int n_int, nn, forcing_index; /* forcing DoF in the substructure's order (int, num), or -1 */
    const double *mass, *damping, *stiffness; /* the split's nn x nn numerical substructure */
    double amplitude_n;
    double cached_hz;                                  /* the frequency h and forced hold */
    double complex h[RTHS_MAX_HARMONICS + 1][NI * NI]; /* h[k][d + e * NI] */
    double complex forced[NI];                         /* fundamental, per newton */
    double *unit;
    double complex *x;
};

/* H(k w) and X_forced(w) at frequency_hz. */
static int receptances(frf_host_numerical *h, double frequency_hz, rths_error *err) {
    if (frequency_hz == h->cached_hz) return RTHS_OK;
    const double w = 2 * M_PI * frequency_hz;
    int rc = RTHS_OK;
    for (int k = 1; k <= RTHS_MAX_HARMONICS && !rc; k++)
        for (int e = 0; e < h->n_int + (k == 1 && h->forcing_index >= 0) && !rc; e++) {
            memset(h->unit, 0, sizeof(double) * (size_t)h->nn);
            h->unit[e < h->n_int ? e : h->forcing_index] = 1.0;
            rc = rths_frf(h->nn, h->mass, h->damping, h->stiffness, h->unit, k * w, h->x, err);
            for (int d = 0; d < h->n_int && !rc; d++) {
                if (e < h->n_int)
                    h->h[k][d + e * NI] = h->x[d];
                else
                    h->forced[d] = h->x[d];
            }
        }
    if (!rc) h->cached_hz = frequency_hz;
    return rc;
}

/* x = a cos + b sin = Re((a - i b) e^{i k w t}) */
static void convert(frf_host_numerical *h, rths_period *p) {
    rths_fourier force[NI];
    for (int d = 0; d < h->n_int; d++)
        force[d] = p->num_dof[d];
    for (int d = 0; d < h->n_int; d++) {
        rths_fourier *x = &p->num_dof[d];
        for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
            double complex v = k == 1 ? h->forced[d] * h->amplitude_n : 0;
            for (int e = 0; e < h->n_int; e++)
                v += h->h[k][d + e * NI] * (force[e].a[k] - I * force[e].b[k]);
            x->a[k] = creal(v);
            x->b[k] = -cimag(v);
        }
        /* the static term follows the physical side, as on the one-DoF form */
        x->a[0] = p->phys_dof[d].a[0];
    }
    p->num = p->num_dof[0];
}

static int v_set_forcing(void *self, double frequency_hz, double amplitude_n, rths_error *err) {
    frf_host_numerical *h = self;
    h->amplitude_n = amplitude_n;
    return rths_rig_set_forcing(h->rig, frequency_hz, amplitude_n, err);
}
static int v_set_target(void *self, int harmonics, const double *a, const double *b,
                        rths_error *err) {
    return rths_rig_set_target(((frf_host_numerical *)self)->rig, harmonics, a, b, err);
}
static int v_set_target_dofs(void *self, int dofs, int harmonics, const double *a, const double *b,
                             rths_error *err) {
    return rths_rig_set_target_dofs(((frf_host_numerical *)self)->rig, dofs, harmonics, a, b, err);
}
static int v_interface_dofs(void *self) {
    return rths_rig_interface_dofs(((frf_host_numerical *)self)->rig);
}
static int v_run_periods(void *self, int count, rths_period *out, rths_error *err) {
    frf_host_numerical *h = self;
    int rc = rths_rig_run_periods(h->rig, count, out, err);
    for (int i = 0; i < count && !rc; i++) {
        rc = receptances(h, out[i].frequency_hz, err);
        if (!rc) convert(h, &out[i]);
    }
    return rc;
}
static int v_record_trace(void *self, double duration_s, int max_samples, rths_trace_sample *out,
                          int *n_out, rths_error *err) {
    return rths_rig_record_trace(((frf_host_numerical *)self)->rig, duration_s, max_samples, out,
                                 n_out, err);
}
static double v_time_s(void *self) {
    return rths_rig_time_s(((frf_host_numerical *)self)->rig);
}
static rths_rig_fault v_fault(void *self) {
    return rths_rig_get_fault(((frf_host_numerical *)self)->rig);
}
static int v_reset_fault(void *self, rths_error *err) {
    return rths_rig_reset_fault(((frf_host_numerical *)self)->rig, err);
}
static double v_noise_level_m(void *self) {
    return rths_rig_noise_level_m(((frf_host_numerical *)self)->rig);
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

void frf_host_numerical_destroy(frf_host_numerical *h, rths_rig *view) {
    if (view) rths_rig_destroy(view);
    if (!h) return;
    free(h->unit);
    free(h->x);
    free(h);
}

int frf_host_numerical_create(const rths_setup *setup, rths_rig *rig, frf_host_numerical **out,
                              rths_rig **view, rths_error *err) {
    *out = NULL;
    *view = NULL;
    const rths_split *s = &setup->split;
    if (s->n_int < 1 || s->n_int > NI)
        return rths_error_set(err, RTHS_EINPUT, "%d interface DoFs: 1 to %d supported", s->n_int,
                              NI);
    frf_host_numerical *h = calloc(1, sizeof *h);
    if (!h) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    h->rig = rig;
    h->n_int = s->n_int;
    h->nn = s->nn;
    h->mass = s->mass_num;
    h->damping = s->damping_num;
    h->stiffness = s->stiffness_num;
    h->cached_hz = -1;
    h->forcing_index = -1;
    for (int d = 0; d < s->n_int; d++)
        if (s->int_dofs[d] == setup->forcing_dof) h->forcing_index = d;
    for (int i = 0; i < s->n_num; i++)
        if (s->num_dofs[i] == setup->forcing_dof) h->forcing_index = s->n_int + i;
    h->unit = malloc(sizeof(double) * (size_t)s->nn);
    h->x = malloc(sizeof(double complex) * (size_t)s->nn);
    if (h->unit && h->x) *view = rths_rig_create(&view_ops, h, rths_rig_description(rig));
    if (!*view) {
        frf_host_numerical_destroy(h, NULL);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    *out = h;
    return RTHS_OK;
}
