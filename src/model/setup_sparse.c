/* The sparse path of a test configuration's structure: a model too large for dense algebra is read
 * in compressed form with its split, forcing and model.frf (sparse_model.c), and what that path
 * does not carry is refused by its key. Part of setup.c's reading (setup_internal.h). */
#include "rths/setup.h"

#include "setup_internal.h"

#include "rths/signals.h"

#include <stdlib.h>
#include <string.h>

/* structure.matrices: dense (read_matrices) unless rths_model_choose_solver takes the sparse
 * path (model.solver: sparse, or auto on a large unbanded Matrix Market model; the reason is
 * `rths model`'s): then the model is read sparse with its split, forcing and model.frf
 * (rths_sparse_model_read) and no dense matrix of its order is ever formed. */
int rths_setup_read_matrices_or_sparse(rths_config *cfg, rths_setup *s, rths_error *err) {
    rths_model_choice choice;
    int rc = rths_model_choose_solver(cfg, &choice, err);
    if (rc) return rc;
    if (choice.solver != RTHS_MODEL_SOLVER_SPARSE) {
        rths_model_choice_free(&choice);
        return rths_setup_read_matrices(cfg, s, err);
    }
    s->sparse = calloc(1, sizeof *s->sparse);
    if (!s->sparse) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_sparse_model_read(cfg, &choice, s->sparse, err);
    rths_model_choice_free(&choice);
    if (rc) {
        free(s->sparse);
        s->sparse = NULL;
    }
    s->chain = 0;
    return rc;
}

/* The rest of a sparse setup from its model: the split's DoF lists and dense physical side (the
 * rig's side is small), the forcing, the model.frf range; what the sparse path does not carry is
 * refused by its key. The numerical side stays sparse in both forms: the host solves it per
 * harmonic (frequency), or the controller integrates its band-exact Krylov reduction (realtime,
 * rths_controller_create). */
int rths_setup_read_sparse_rest(rths_config *cfg, rths_setup *s, rths_error *err) {
    const rths_sparse_model *m = s->sparse;
    int n = m->n;
    static const char *const nonlinear_keys[] = {"structure.nonlinear", "structure.bilinear"};
    for (int k = 0; k < 2; k++)
        if (rths_config_has(cfg, nonlinear_keys[k]))
            return rths_config_error_at(cfg, nonlinear_keys[k], err,
                                        "a sparse model (model.solver: %s, %d DoFs) is linear: "
                                        "nonlinear elements need the dense path (model.solver: "
                                        "dense, a model of a few thousand DoFs at most)",
                                        "sparse", n);
    int rc = rths_setup_read_numerical_solver(cfg, s, err);
    if (rc) return rc;
    /* both forms take one interface DoF: the frequency form's sparse receptance is scalar, and
     * the real-time form's reduction (the controller's, krylov_reduce.h) is tested with one */
    if (m->n_int != 1)
        return rths_config_error_at(cfg, "split.interface", err,
                                    "lists %d interface DoFs; a sparse model takes one (both "
                                    "split.numerical_solver forms)",
                                    m->n_int);
    s->assembly.n = n;
    rths_split *sp = &s->split;
    sp->n = n;
    s->roles = malloc(sizeof *s->roles * (size_t)n);
    sp->phys_dofs = malloc(sizeof(int) * (size_t)n);
    sp->num_dofs = malloc(sizeof(int) * (size_t)n);
    sp->int_dofs = malloc(sizeof(int) * (size_t)m->n_int);
    sp->mass_ratios = malloc(sizeof(double) * (size_t)m->n_int);
    s->force = malloc(sizeof(double) * (size_t)n);
    s->forcing_shape = malloc(sizeof(double) * (size_t)n);
    s->static_force = calloc((size_t)n, sizeof(double));
    if (!s->roles || !sp->phys_dofs || !sp->num_dofs || !sp->int_dofs || !sp->mass_ratios ||
        !s->force || !s->forcing_shape || !s->static_force)
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    memcpy(s->roles, m->roles, sizeof *s->roles * (size_t)n);
    for (int i = 0; i < n; i++) {
        if (m->roles[i] == RTHS_DOF_PHYSICAL) sp->phys_dofs[sp->n_phys++] = i;
        if (m->roles[i] == RTHS_DOF_NUMERICAL) sp->num_dofs[sp->n_num++] = i;
    }
    sp->n_int = m->n_int;
    for (int d = 0; d < m->n_int; d++) {
        sp->int_dofs[d] = m->int_dofs[d];
        sp->mass_ratios[d] = m->mass_ratio;
    }
    sp->mass_ratio = m->mass_ratio;
    sp->nn = sp->n_int + sp->n_num;
    rths_error local;
    rc = rths_sparse_model_physical_side(m, RTHS_MAX_SENSED_DOFS, &sp->mass_phys, &sp->damping_phys,
                                         &sp->stiffness_phys, &sp->np, &local);
    if (rc == RTHS_EINPUT) return rths_config_error_at(cfg, "split.physical", err, "%s", local.msg);
    if (rc) {
        *err = local;
        return rc;
    }
    s->forcing_dof = m->forcing_dof;
    s->forcing_amplitude_n = m->forcing_amplitude_n;
    s->base_excitation = m->base_excitation;
    for (int i = 0; i < n; i++) {
        s->force[i] = m->force[i];
        s->forcing_shape[i] = m->force[i] / m->forcing_amplitude_n;
    }
    s->frf_start_hz = m->frf_start_hz;
    s->frf_end_hz = m->frf_end_hz;
    s->frf_points = m->frf_points;
    int n_out = 0;
    int *out_dofs = rths_setup_output_dofs(s, &n_out);
    if (!out_dofs) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    rc = rths_sparse_truth_create(m, n_out, out_dofs, &s->sparse_truth, err);
    free(out_dofs);
    return rc;
}

int rths_setup_require_dense(const rths_setup *s, const char *command, rths_error *err) {
    if (!s->sparse) return RTHS_OK;
    return rths_error_set(err, RTHS_EINPUT,
                          "model.solver: this structure takes the sparse path (%d DoFs), and %s "
                          "needs its dense matrices: set model.solver: dense (a model of a few "
                          "thousand DoFs at most), or use rths frf, rths model or rths fidelity",
                          s->assembly.n, command);
}
