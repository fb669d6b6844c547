/* The parts of rths_setup_read kept in their own files: the dense matrices and the numerical
 * solver (setup.c), the sparse path (setup_sparse.c), the nonlinear elements (setup_nonlinear.c).
 * Each reads keys of cfg into s and names the key of any mistake. */
#ifndef RTHS_SETUP_INTERNAL_H
#define RTHS_SETUP_INTERNAL_H

#include "rths/setup.h"

int rths_setup_read_matrices(rths_config *cfg, rths_setup *s, rths_error *err);
int rths_setup_read_numerical_solver(rths_config *cfg, rths_setup *s, rths_error *err);

int rths_setup_read_matrices_or_sparse(rths_config *cfg, rths_setup *s, rths_error *err);
int rths_setup_read_sparse_rest(rths_config *cfg, rths_setup *s, rths_error *err);

int rths_setup_read_bilinear(rths_config *cfg, rths_setup *s, rths_error *err);
int rths_setup_read_nonlinear(rths_config *cfg, rths_setup *s, rths_error *err);
int rths_setup_check_solver_nonlinear(rths_config *cfg, const rths_setup *s, rths_error *err);

#endif
