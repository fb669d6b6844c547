/* Between the files of src/tune/. */
#ifndef RTHS_TUNE_INTERNAL_H
#define RTHS_TUNE_INTERNAL_H

#include "rths/tune.h"

/* The PD gains the rule picks (pd_loop.c); RTHS_EFAIL, named, when none meets it. */
int rths_pd_loop_best(const rths_pd_loop *loop, double min_gm_db, double min_pm_deg, double *kp,
                      double *kd, rths_loop_margins *best, rths_error *err);

#endif
