/* `rths fidelity` on a sparse model (setup->sparse; docs/method.md, "Numerical substructure
 * integration", and docs/architecture.md, "Sparse algebra"): the real-time reduction's own error.
 */
#ifndef RTHS_API_FIDELITY_SPARSE_H
#define RTHS_API_FIDELITY_SPARSE_H

#include "api/api_internal.h"

/* Builds the Krylov reduction the controller would integrate (rths_controller_config_read's
 * controller.reduction options and band: the sweep's continuation.start_hz..end_hz widened by
 * RTHS_CONTROLLER_KRYLOV_BAND_MARGIN; refused, RTHS_EINPUT, above controller.reduction.max_error
 * or without a band) and tabulates, over fidelity.start_hz..end_hz (default: that band) at
 * fidelity.points frequencies (default: twice the check points less one, so every check point
 * and every midpoint between two), the numerical side's interface receptance and its interface
 * response to the forcing, reduced and exact (sparse factorisations of the full numerical side,
 * rths_sparse_model_receptance_eval: independent of the reduction), with their relative errors;
 * summary "reduction" and a run.log line. The fidelity and controller sections are checked. */
int rths_api_fidelity_sparse(rths_config *cfg, const rths_setup *setup, const char *config_path,
                             const char *const *overrides, int n_overrides, rths_result **out,
                             rths_error *err);

/* rths_config_check_sections for `rths fidelity`, the continuation section accepted whole:
 * fidelity reads none of it but the band the controller's reader asks for. */
int rths_api_fidelity_check_sections(rths_config *cfg, const char *const *own, rths_error *err);

#endif
