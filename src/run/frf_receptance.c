/* The receptance columns of frf.csv and truth.csv (see frf_receptance.h). */
#include "run/frf_receptance.h"

#include "rths/truth.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static int reported_dofs(const rths_setup *s) {
    return s->split.n_int < RTHS_MAX_INTERFACE_DOFS ? s->split.n_int : RTHS_MAX_INTERFACE_DOFS;
}

void frf_receptance_columns_init(frf_receptance_columns *cols, const rths_setup *s) {
    memset(cols, 0, sizeof *cols);
    cols->dofs = reported_dofs(s);
    cols->count = FRF_RECEPTANCE_PER_DOF * cols->dofs;
    for (int d = 0; d < cols->dofs; d++) {
        int rot = rths_setup_dof_is_rotation(s, s->split.int_dofs[d]);
        const char *num = rot ? "rad" : "m";
        snprintf(cols->unit[d], sizeof cols->unit[d], "%s/%s", num,
                 s->base_excitation ? "(m/s^2)" : "N");
        char prefix[16] = "";
        if (cols->dofs > 1) snprintf(prefix, sizeof prefix, "dof%d_", d + 1);
        const char *den = s->base_excitation ? "m_per_s2" : "n";
        snprintf(cols->names[2 * d], sizeof cols->names[0], "%sreceptance_real_%s_per_%s", prefix,
                 num, den);
        snprintf(cols->names[2 * d + 1], sizeof cols->names[0], "%sreceptance_imag_%s_per_%s",
                 prefix, num, den);
    }
}

int frf_receptance_point(const rths_setup *s, const rths_point *pt, int d, double complex *h,
                         double *se) {
    const rths_solution *sol = &pt->sol;
    const rths_evaluation *ev = &sol->eval;
    double force = s->forcing_amplitude_n;
    int dofs = reported_dofs(s);
    *h = NAN;
    *se = NAN;
    if (d < 0 || d >= dofs || !(force != 0)) return -1;
    /* as frf.csv's amplitude_m / dof<d>_amplitude_m: the matched estimate where reported */
    int matched = sol->have_matched && sol->amplitude_m == sol->matched_amplitude_m;
    double a, b, amp_se;
    if (dofs == 1) {
        a = matched ? sol->matched_a[0] : ev->phys.a[1];
        b = matched ? sol->matched_b[0] : ev->phys.b[1];
        amp_se = sol->amplitude_se_m;
    } else {
        if (ev->interface_dofs != dofs) return -1;
        int j = d * (sol->harmonics / dofs); /* DoF d's fundamental (iterate.h) */
        a = matched ? sol->matched_a[j] : ev->phys_dof[d].a[1];
        b = matched ? sol->matched_b[j] : ev->phys_dof[d].b[1];
        amp_se = sol->interface_dofs == dofs ? sol->dof_amplitude_se_m[d] : NAN;
    }
    /* x = A cos + B sin = Re((A - i B) e^{i w t}) */
    *h = (a - I * b) / force;
    *se = amp_se / fabs(force);
    return 0;
}

void frf_receptance_row(const frf_receptance_columns *cols, const rths_setup *s,
                        const rths_point *pt, double *row) {
    for (int d = 0; d < cols->dofs; d++) {
        double complex h;
        double se;
        frf_receptance_point(s, pt, d, &h, &se);
        row[2 * d] = creal(h);
        row[2 * d + 1] = cimag(h);
    }
}

int frf_receptance_truth_all(const rths_setup *s, double f_hz, double complex *h) {
    int dofs = reported_dofs(s);
    double amp[RTHS_MAX_INTERFACE_DOFS], phase[RTHS_MAX_INTERFACE_DOFS];
    for (int d = 0; d < dofs; d++)
        h[d] = NAN;
    /* one solve of the assembly for every DoF: on a 1000-DoF model it is the dominant cost */
    if (!(s->forcing_amplitude_n != 0) ||
        rths_truth_linear_dofs_response(s, f_hz, dofs, s->split.int_dofs, amp, phase))
        return -1;
    for (int d = 0; d < dofs; d++)
        h[d] = amp[d] * cexp(I * phase[d]) / s->forcing_amplitude_n;
    return 0;
}

void frf_receptance_truth_row(const frf_receptance_columns *cols, const rths_setup *s, double f_hz,
                              double *row) {
    double complex h[RTHS_MAX_INTERFACE_DOFS];
    frf_receptance_truth_all(s, f_hz, h);
    for (int d = 0; d < cols->dofs; d++) {
        row[2 * d] = creal(h[d]);
        row[2 * d + 1] = cimag(h[d]);
    }
}
