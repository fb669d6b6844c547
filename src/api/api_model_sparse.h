/* `rths model` on the sparse path (model.h, "large sparse models"): the tables and summary of
 * rths_api_model_compute for a model that never becomes dense. Used by the command (src/cli). */
#ifndef RTHS_API_MODEL_SPARSE_H
#define RTHS_API_MODEL_SPARSE_H

#include "rths/model.h"
#include "rths/rths.h"

/* Wall seconds of each stage and what the checks found. */
typedef struct rths_api_sparse_model_timing {
    double read_s;      /* the three Matrix Market files (the stiffness while choosing the path) */
    double order_s;     /* symbolic analysis (fill-reducing ordering) of K - shift M */
    double factor_s;    /* its numerical LDL^T */
    double eigen_s;     /* shift-invert Lanczos */
    double check_s;     /* residuals, Sturm count, modal damping */
    double frf_s;       /* static solve and the FRF over the grid */
    double frf_check_s; /* direct sparse complex solves checking the FRF */
    double peak_memory_mb;
    int frf_points, frf_dofs, modes;
    long factor_entries;
    int frf_checks;             /* direct solves done */
    double frf_check_max_error; /* max relative |x_modal - x_direct| / max |x_direct| */
    double frf_check_worst_hz;
    char frf_method[64];
    /* the modes' checks (rths_sparse_modes) */
    double modes_max_residual, damping_coupling, sturm_shift;
    int sturm_below;
    char ordering[16];
    double highest_mode_hz, frf_end_hz; /* the modal FRF leaves out modes between these */
} rths_api_sparse_model_timing;

/* Tables "modes" (the lowest model.modes modes) and "true_frf", the summary (with the path's
 * choice, the checks, the stage times and the peak memory). choice_read_s: seconds the choice
 * spent reading the stiffness, added to read_s. */
int rths_api_model_compute_sparse(const rths_sparse_model *m, const rths_model_choice *choice,
                                  double choice_read_s, const char *config_path,
                                  const char *const *overrides, int n_overrides, rths_result **out,
                                  rths_api_sparse_model_timing *timing, rths_error *err);

#endif
