/* What the files of the FRF test's outputs share beyond frf_internal.h: frf_outputs.c (frf.csv,
 * truth.csv) and frf_summary.c (summary.json). Not installed. */
#ifndef RTHS_RUN_FRF_OUTPUTS_INTERNAL_H
#define RTHS_RUN_FRF_OUTPUTS_INTERNAL_H

#include "run/frf_internal.h"

/* The experimental Floquet estimate of point i, NULL where it was not measured. */
static inline const frf_floquet_point *frf_measured_floquet_point(const frf_state *run, int i) {
    return run->floquet_pts && i < run->cap && run->floquet_pts[i].measured ? &run->floquet_pts[i]
                                                                            : NULL;
}

#endif
