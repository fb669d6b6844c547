/* The numerical substructure on the host over several interface DoFs (split.numerical_solver:
 * frequency with n > 1 interface DoFs, e.g. a multi-site test; docs/method.md, "Multi-site
 * tests"): a view of the rig whose periods carry every DoF's numerical interface displacement,
 * turned from the interface forces the controllers measure. Private to src/run. */
#ifndef RTHS_RUN_FRF_SITES_H
#define RTHS_RUN_FRF_SITES_H

#include "rths/rig.h"
#include "rths/setup.h"

typedef struct frf_host_numerical frf_host_numerical;

/* The view over rig (which it does not own): every period's num_dof[d] (the force on the
 * numerical substructure's interface DoF d, N) becomes its displacement,
 *   x_num(k w) = H(k w) F(k w) + [k = 1] X_forced(w) amplitude,
 * H the numerical substructure's n x n interface receptance (m/N), X_forced its interface
 * response per newton of forcing amplitude when the forcing acts on its DoFs (else 0). */
int frf_host_numerical_create(const rths_setup *setup, rths_rig *rig, frf_host_numerical **out,
                              rths_rig **view, rths_error *err);
void frf_host_numerical_destroy(frf_host_numerical *h, rths_rig *view);

#endif
