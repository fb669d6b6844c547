/* The nonlinear numerical substructure on the host (split.numerical_solver: frequency with
 * nonlinear elements on the numerical side; docs/method.md, "Nonlinear elements in the frequency
 * form"): a view of the rig whose periods carry the numerical interface displacement, solved by
 * harmonic balance. Private to src/run. */
#ifndef RTHS_RUN_FRF_HB_NUMERICAL_H
#define RTHS_RUN_FRF_HB_NUMERICAL_H

#include "rths/harmonic_balance.h"
#include "rths/rig.h"
#include "rths/setup.h"

typedef struct frf_hb_numerical frf_hb_numerical;

/* The view over rig (which it does not own). Every period's num_dof[d] (the force F_d on the
 * numerical substructure's interface DoF d, N) becomes that DoF's displacement: the periodic
 * response of the numerical substructure with its elements, by harmonic balance
 * (rths_hb_substructure_solve_dofs), under F and the grounding control of the real-time form,
 * grounding_kp[d] (x_d - xi_d) + grounding_kd[d] (x_d' - xi_d'), x_d the measured physical
 * interface motion (phys_dof), its mean prescribed as x_d's. Each period starts from the last
 * one's solution, as the real-time form's state carries over. */
int frf_hb_numerical_create(const rths_setup *setup, rths_rig *rig, const double *grounding_kp,
                            const double *grounding_kd, frf_hb_numerical **out, rths_rig **view,
                            rths_error *err);
void frf_hb_numerical_destroy(frf_hb_numerical *h, rths_rig *view);
/* For run.log: the harmonic balance's harmonics, time samples, kept DoFs, and with counts the
 * periods converted and their Newton steps. */
void frf_hb_numerical_describe(const frf_hb_numerical *h, int counts, char *buf, size_t size);

#endif
