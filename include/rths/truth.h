/* rths truth: the true assembly's interface response, computed without the hybrid loop, against
 * which a hybrid test is judged: the analytic FRF for a linear structure, shooting with
 * pseudo-arclength through the folds with a bilinear leg. */
#ifndef RTHS_TRUTH_H
#define RTHS_TRUTH_H

#include "rths/setup.h"

typedef struct rths_truth_curve {
    int n;
    double *freq_hz;
    double *amp_m, *amp_h2_m, *amp_h3_m; /* interface displacement amplitude per harmonic, m */
    int *stable;                         /* 0 where the periodic solution is unstable */
    double *max_floquet; /* the shooting solution's largest Floquet multiplier modulus at each
                            point; NULL for the analytic curve */
    int exact;           /* 1: the analytic FRF (linear structure), 0: the shooting solution */
    /* several interface DoFs (linear structure, or the shooting curve): the fundamental amplitude
       of each, m, amp_dof_m[d * n + j] for DoF d at freq_hz[j]; dofs 0 and NULL otherwise */
    int dofs;
    double *amp_dof_m;
} rths_truth_curve;

/* The curve over [lo_hz, hi_hz] (analytic: the modal grid; shooting: its continuation points). */
int rths_truth_compute(const rths_setup *s, double lo_hz, double hi_hz, rths_truth_curve *t,
                       rths_error *err);
void rths_truth_free(rths_truth_curve *t);

/* Linear structure: the analytic interface amplitude at f_hz, m (NAN with a bilinear leg or when
 * the FRF cannot be evaluated). */
double rths_truth_linear_amplitude_m(const rths_setup *s, double f_hz);
/* Linear structure: the analytic fundamental amplitude of every interface DoF at f_hz (m, or rad
 * for a rotation) into amp_m[0..split.n_int-1]; NAN and -1 with a bilinear leg or on failure. */
int rths_truth_linear_dof_amplitudes_m(const rths_setup *s, double f_hz, double *amp_m);

/* Linear structure: the analytic steady response of assembly DoFs dofs[0..count-1] (0-based) at
 * f_hz, x(t) = amp cos(w t + phase) against the forcing's cos(w t) (a force, or the ground
 * acceleration: then displacements relative to the ground, as the hybrid test reports them):
 * amp_m[i] in m (rad for a rotation), phase_rad[i] in (-pi, pi] (may be NULL); NAN and -1 with
 * a bilinear leg, a DoF out of range or on failure. output.dofs' truth (docs/method.md,
 * "Outputs"). */
int rths_truth_linear_dofs_response(const rths_setup *s, double f_hz, int count, const int *dofs,
                                    double *amp_m, double *phase_rad);

/* Distance of (f_hz, amp_m) from the curve in the plane (10 ln f, ln A), so a 1 % amplitude error
 * and a 0.1 % frequency offset count alike: the vertical relative error where the curve is flat,
 * still meaningful where a folded curve is steep or multi-valued. INFINITY for a non-positive
 * point. */
double rths_truth_curve_distance(const rths_truth_curve *t, double f_hz, double amp_m);

/* Relative error of a hybrid point against the truth: linear, |A - A_true(f)| / A_true(f) at its
 * own frequency; bilinear, rths_truth_curve_distance. */
double rths_truth_relative_error(const rths_setup *s, const rths_truth_curve *t, double f_hz,
                                 double amp_m);

/* The true amplitude at f_hz on the branch of a measured point (amp_m, m): linear, the analytic
 * FRF; bilinear, of the curve's pieces spanning f_hz the one nearest amp_m (linear
 * interpolation), with its Floquet stability in *stable (may be NULL). NAN when no piece spans
 * f_hz. */
double rths_truth_branch_amplitude_m(const rths_setup *s, const rths_truth_curve *t, double f_hz,
                                     double amp_m, int *stable);

/* Bilinear: the largest Floquet multiplier modulus at f_hz on the branch of a measured point
 * (amp_m), interpolated linearly on the piece rths_truth_branch_amplitude_m picks; NAN for the
 * analytic curve or when no piece spans f_hz. */
double rths_truth_branch_max_floquet(const rths_truth_curve *t, double f_hz, double amp_m);

/* Distance in frequency from f_hz to the nearest change of the curve's stability (a fold of the
 * true assembly), Hz; INFINITY when the curve has none. */
double rths_truth_fold_distance_hz(const rths_truth_curve *t, double f_hz);

#endif
