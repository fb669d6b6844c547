/* The receptance of the hybrid test and of the truth (docs/method.md, "Complex FRF and modal
 * identification"): the complex fundamental of each interface DoF over the forcing amplitude,
 * H = X / F with x = Re(X e^{i w t}) against the forcing's cos(w t): m/N for a force (rad/N on
 * a rotation), m/(m/s^2) for base excitation (the displacement relative to the ground per unit
 * ground acceleration). frf.csv and truth.csv carry its real and imaginary parts as new columns
 * after every other one, so no existing column moves. */
#ifndef RTHS_RUN_FRF_RECEPTANCE_H
#define RTHS_RUN_FRF_RECEPTANCE_H

#include "rths/continuation.h"
#include "rths/setup.h"

#include <complex.h>

#define FRF_RECEPTANCE_PER_DOF 2
#define FRF_RECEPTANCE_MAX_COLUMNS (FRF_RECEPTANCE_PER_DOF * RTHS_MAX_INTERFACE_DOFS)

typedef struct frf_receptance_columns {
    int dofs;  /* interface DoFs reported (the split's, at most RTHS_MAX_INTERFACE_DOFS) */
    int count; /* FRF_RECEPTANCE_PER_DOF * dofs */
    char names[FRF_RECEPTANCE_MAX_COLUMNS][64];
    char unit[RTHS_MAX_INTERFACE_DOFS][24]; /* "m/N", "rad/N", "m/(m/s^2)", "rad/(m/s^2)" */
} frf_receptance_columns;

/* One interface DoF: receptance_real_<unit>, receptance_imag_<unit>; several:
 * dof<d>_receptance_real_<unit>, ... (unit m_per_n, rad_per_n, m_per_m_per_s2, rad_per_m_per_s2).
 */
void frf_receptance_columns_init(frf_receptance_columns *cols, const rths_setup *s);

/* Interface DoF d's receptance at an accepted point (the reported estimate: the matched one where
 * the strategy reports it, else the measurement, as frf.csv's amplitude columns) and the standard
 * error of each of its parts (the amplitude's standard error over F: the noise taken as circular
 * in the complex plane). 0, or -1 when the point carries no such DoF (NaN then). */
int frf_receptance_point(const rths_setup *s, const rths_point *pt, int d, double complex *h,
                         double *se);

/* frf.csv's and truth.csv's cells (cols->count of them; NaN where not available: a bilinear leg's
 * truth). */
void frf_receptance_row(const frf_receptance_columns *cols, const rths_setup *s,
                        const rths_point *pt, double *row);
void frf_receptance_truth_row(const frf_receptance_columns *cols, const rths_setup *s, double f_hz,
                              double *row);
/* The truth's receptance of every reported interface DoF at f_hz, from one solve (NaN and -1 with
 * a bilinear leg). */
int frf_receptance_truth_all(const rths_setup *s, double f_hz, double complex *h);

#endif
