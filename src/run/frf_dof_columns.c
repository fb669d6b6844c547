/* output.dofs' columns of frf.csv and truth.csv (see frf_dof_columns.h). */
#include "run/frf_dof_columns.h"

#include "rths/truth.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

void frf_dof_columns_init(frf_dof_columns *cols, const rths_controller_options *copt) {
    static const char *const suffix[FRF_DOF_COLUMNS_PER_DOF] = {"amplitude_m", "phase_rad",
                                                                "amplitude_se_m"};
    memset(cols, 0, sizeof *cols);
    cols->dofs =
        copt->output_dofs > 0 && copt->output_dofs <= RTHS_MAX_OUTPUT_DOFS ? copt->output_dofs : 0;
    cols->count = FRF_DOF_COLUMNS_PER_DOF * cols->dofs;
    for (int j = 0; j < cols->dofs; j++) {
        cols->dof[j] = copt->output_dof[j];
        for (int c = 0; c < FRF_DOF_COLUMNS_PER_DOF; c++)
            snprintf(cols->names[FRF_DOF_COLUMNS_PER_DOF * j + c], sizeof cols->names[0], "x%d_%s",
                     cols->dof[j] + 1, suffix[c]);
    }
}

const char *frf_dof_column_name(const frf_dof_columns *cols, int i) {
    return i >= 0 && i < cols->count ? cols->names[i] : NULL;
}

/* The standard error of |c| = hypot(a, b) from those of a and b (first order): the projection
 * of (se_a, se_b) on c's direction; at c = 0 the larger of the two. */
static double amplitude_se(double a, double b, double se_a, double se_b) {
    double r = hypot(a, b);
    if (!(r > 0)) return fmax(se_a, se_b);
    return hypot(a * se_a, b * se_b) / r;
}

/* The zero-mismatch extrapolation of the interface carried to every DoF: the complex ratio of
 * the interface's matched fundamental to its measured one (c = a - i b, x = Re(c e^{i w t})),
 * and the ratio's relative standard error; 1 and 0 when the point reports the measurement (no
 * matched estimate, the paper strategy, several interface DoFs). */
static double complex matched_ratio(const rths_point *pt, double *rel_se) {
    const rths_solution *s = &pt->sol;
    const rths_fourier *ph = &s->eval.phys;
    const double complex measured = ph->a[1] - I * ph->b[1];
    *rel_se = 0;
    /* as frf.csv's amplitude_m: the matched estimate where the strategy reports it */
    int matched = s->have_matched && s->amplitude_m == s->matched_amplitude_m;
    if (!matched || s->eval.interface_dofs > 1 || !(cabs(measured) > 0)) return 1;
    if (s->matched_amplitude_m > 0) *rel_se = s->matched_amplitude_se_m / s->matched_amplitude_m;
    return (s->matched_a[0] - I * s->matched_b[0]) / measured;
}

void frf_dof_columns_row(const frf_dof_columns *cols, const rths_point *pt, double *row) {
    const rths_evaluation *ev = &pt->sol.eval;
    double ratio_rel_se;
    const double complex ratio = matched_ratio(pt, &ratio_rel_se);
    for (int j = 0; j < cols->dofs; j++) {
        double *r = row + FRF_DOF_COLUMNS_PER_DOF * j;
        if (ev->output_dofs != cols->dofs) {
            r[0] = r[1] = r[2] = NAN;
            continue;
        }
        const rths_fourier *x = &ev->output_dof[j], *se = &ev->output_dof_se[j];
        const double complex c = ratio * (x->a[1] - I * x->b[1]);
        r[0] = cabs(c);
        /* x = Re(c e^{i w t}) = |c| cos(w t + arg c), as frf.csv's phase_rad */
        r[1] = carg(c);
        /* the measurement's scatter, scaled, and the interface extrapolation's own */
        r[2] = hypot(cabs(ratio) * amplitude_se(x->a[1], x->b[1], se->a[1], se->b[1]),
                     r[0] * ratio_rel_se);
    }
}

void frf_dof_columns_truth_row(const frf_dof_columns *cols, const rths_setup *setup, double f_hz,
                               double *row) {
    double amp[RTHS_MAX_OUTPUT_DOFS], phase[RTHS_MAX_OUTPUT_DOFS];
    rths_truth_linear_dofs_response(setup, f_hz, cols->dofs, cols->dof, amp, phase);
    for (int j = 0; j < cols->dofs; j++) {
        double *r = row + FRF_DOF_COLUMNS_PER_DOF * j;
        r[0] = amp[j];
        r[1] = phase[j];
        r[2] = isfinite(amp[j]) ? 0.0 : NAN;
    }
}
