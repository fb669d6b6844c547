/* output.dofs' columns of frf.csv and truth.csv (docs/method.md, "Outputs"): for each listed
 * assembly DoF d, x<d>_amplitude_m (m, or rad for a rotation), x<d>_phase_rad and
 * x<d>_amplitude_se_m, appended after every other column; none without output.dofs, so a run
 * without it writes both files as before, byte for byte. */
#ifndef RTHS_RUN_FRF_DOF_COLUMNS_H
#define RTHS_RUN_FRF_DOF_COLUMNS_H

#include "rths/continuation.h"
#include "rths/controller.h"
#include "rths/setup.h"

#define FRF_DOF_COLUMNS_PER_DOF 3
#define FRF_DOF_MAX_COLUMNS (FRF_DOF_COLUMNS_PER_DOF * RTHS_MAX_OUTPUT_DOFS)

typedef struct frf_dof_columns {
    int dofs;                      /* listed DoFs, 0 without output.dofs */
    int dof[RTHS_MAX_OUTPUT_DOFS]; /* 0-based assembly DoFs, the list's order */
    int count;                     /* columns: FRF_DOF_COLUMNS_PER_DOF * dofs */
    char names[FRF_DOF_MAX_COLUMNS][40];
} frf_dof_columns;

/* From the controller options the rig was built with (rths_controller_config_read reads
 * output.dofs; rths_controller_create checked the DoFs against the setup). */
void frf_dof_columns_init(frf_dof_columns *cols, const rths_controller_options *copt);
/* Column i's name (0 <= i < count), NULL beyond. */
const char *frf_dof_column_name(const frf_dof_columns *cols, int i);
/* frf.csv: a point's count values from its measurement (rths_evaluation.output_dof): the
 * fundamental's amplitude, its phase against the forcing (x = A cos(w t + phase), as frf.csv's
 * phase_rad), and the amplitude's standard error (the periods' scatter and, when extrapolated,
 * the interface extrapolation's); NaN where the record carries no output DoFs (a producer
 * without them). Where frf.csv's amplitude_m is the matched estimate (one interface DoF), every
 * DoF is extrapolated to zero mismatch with it: its measured fundamental times the interface's
 * matched-over-measured complex ratio (exact for a physical DoF that no force acts on, which
 * follows the interface displacement alone; near a resonance, where one mode carries the
 * response and the mismatch's error is that mode's amplitude, for every DoF to first order);
 * the interface DoF's column is then amplitude_m itself. */
void frf_dof_columns_row(const frf_dof_columns *cols, const rths_point *pt, double *row);
/* truth.csv: the analytic FRF's values at f_hz (standard error 0); NaN with a bilinear leg. */
void frf_dof_columns_truth_row(const frf_dof_columns *cols, const rths_setup *setup, double f_hz,
                               double *row);

#endif
