/* Between the files of src/tune/. */
#ifndef RTHS_TUNE_INTERNAL_H
#define RTHS_TUNE_INTERNAL_H

#include "rths/tune.h"

/* The PD gains the rule picks (pd_loop.c); RTHS_EFAIL, named, when none meets it. */
int rths_pd_loop_best(const rths_pd_loop *loop, double min_gm_db, double min_pm_deg, double *kp,
                      double *kd, rths_loop_margins *best, rths_error *err);
/* The same for interface DoF d with the other loops closed at kp, kd (its own entries are
 * overwritten with the pick); the coupled loop's spectral radius checked when check_radius, at
 * the gains and (margin_factor > 0) at margin_factor times all of them. */
int rths_pd_loop_best_dof(const rths_pd_loop *loop, int d, double *kp, double *kd, int check_radius,
                          double margin_factor, double min_gm_db, double min_pm_deg,
                          rths_loop_margins *best, rths_error *err);

/* Several DoFs: the pick among the pairs meeting both margins with the coupled loop stable at the
 * gains and at margin_factor times them, the widest bandwidth among those whose coupled loop's
 * slowest transient decays at decay_fraction of the fastest rate found (pd_loop.c). */
int rths_pd_loop_best_decay_dof(const rths_pd_loop *loop, int d, double *kp, double *kd,
                                double margin_factor, double decay_fraction, double min_gm_db,
                                double min_pm_deg, rths_loop_margins *best, rths_error *err);

#endif
