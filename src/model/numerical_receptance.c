/* The numerical substructure's interface response on the host, per frequency (reduce.h): two
 * right-hand sides of the substructure's dynamic stiffness, the interface force and the forcing.
 * A banded substructure (a meshed rod or beam) takes the FRF sweep's banded LU, O(n b^2) per
 * frequency; any other, dense solves (small ones, as the seed's). The sweep's modal and
 * complex-mode paths are not used: a numerical substructure usually floats freely (a rigid-body
 * mode at 0 rad/s, a Jordan block in the state space), which those paths do not resolve
 * (measured: the seed's at p = 0.33, real part of the receptance with the wrong sign). */
#include "rths/reduce.h"

#include <stdlib.h>
#include <string.h>

struct rths_numerical_receptance {
    rths_assembly model; /* the numerical substructure (copies): the sweeps point at it */
    rths_frf_sweep *interface, *forcing; /* banded sweeps, or NULL: dense solves */
    int forcing_index;                   /* forcing DoF in the substructure's order, or -1 */
    double complex *work;                /* n: a dense solve's response */
};

void rths_numerical_receptance_destroy(rths_numerical_receptance *r) {
    if (!r) return;
    rths_frf_sweep_destroy(r->interface);
    rths_frf_sweep_destroy(r->forcing);
    free(r->work);
    rths_assembly_free(&r->model);
    free(r);
}

/* Index of forcing_dof in the numerical substructure's order (interface, numerical), or -1. */
static int numerical_index(const rths_split *s, int forcing_dof) {
    for (int j = 0; j < s->n_int; j++)
        if (s->int_dofs[j] == forcing_dof) return j;
    for (int i = 0; i < s->n_num; i++)
        if (s->num_dofs[i] == forcing_dof) return s->n_int + i;
    return -1;
}

int rths_numerical_receptance_create(const rths_split *s, int forcing_dof,
                                     rths_numerical_receptance **out, rths_error *err) {
    *out = NULL;
    if (s->n_int != 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "the host-side numerical substructure takes one interface DoF; this "
                              "split has %d",
                              s->n_int);
    rths_numerical_receptance *r = calloc(1, sizeof *r);
    double *unit = calloc((size_t)s->nn, sizeof(double));
    if (!r || !unit) {
        free(r), free(unit);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    int n = s->nn, rc = RTHS_OK, at = numerical_index(s, forcing_dof), zero = 0;
    r->model = (rths_assembly){.n = n,
                               .mass = rths_mat_dup(s->mass_num, n, n),
                               .damping = rths_mat_dup(s->damping_num, n, n),
                               .stiffness = rths_mat_dup(s->stiffness_num, n, n)};
    r->forcing_index = at;
    r->work = malloc(sizeof *r->work * (size_t)n);
    if (!r->model.mass || !r->model.damping || !r->model.stiffness || !r->work)
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    /* banded: the sweep needs no modes on that path (rths_frf_sweep_create) */
    else if (n > 8 && rths_assembly_half_bandwidth(&r->model) <= n / 8) {
        rths_modes none = {0};
        unit[0] = 1.0;
        rc = rths_frf_sweep_create(&r->model, &none, unit, 1, &zero, &r->interface, err);
        if (!rc && at >= 0) {
            memset(unit, 0, sizeof(double) * (size_t)n);
            unit[at] = 1.0;
            rc = rths_frf_sweep_create(&r->model, &none, unit, 1, &zero, &r->forcing, err);
        }
        if (!rc && rths_frf_sweep_method(r->interface) != RTHS_FRF_BANDED)
            rc = rths_error_set(err, RTHS_EFAIL, "the banded FRF sweep was not chosen");
    }
    free(unit);
    if (rc) {
        rths_numerical_receptance_destroy(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}

/* x[0] of D(w) x = e_at (dense) */
static int dense_interface(rths_numerical_receptance *r, double w, int at, double complex *x0,
                           rths_error *err) {
    int n = r->model.n;
    double *unit = calloc((size_t)n, sizeof(double));
    if (!unit) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    unit[at] = 1.0;
    int rc =
        rths_frf(n, r->model.mass, r->model.damping, r->model.stiffness, unit, w, r->work, err);
    free(unit);
    if (!rc) *x0 = r->work[0];
    return rc;
}

int rths_numerical_receptance_eval(void *ctx, double omega_rad_s,
                                   double complex *receptance_m_per_n,
                                   double complex *forced_m_per_n, rths_error *err) {
    rths_numerical_receptance *r = ctx;
    *forced_m_per_n = 0;
    if (!r->interface) {
        int rc = dense_interface(r, omega_rad_s, 0, receptance_m_per_n, err);
        if (!rc && r->forcing_index >= 0)
            rc = dense_interface(r, omega_rad_s, r->forcing_index, forced_m_per_n, err);
        return rc;
    }
    int rc = rths_frf_sweep_eval(r->interface, omega_rad_s, receptance_m_per_n, err);
    if (!rc && r->forcing) rc = rths_frf_sweep_eval(r->forcing, omega_rad_s, forced_m_per_n, err);
    return rc;
}

/* ---- a large sparse numerical substructure (reduce.h) ---- */

struct rths_sparse_receptance {
    rths_sparse_sym mass, damping, stiffness; /* copies: the factor points at them */
    const rths_sparse_sym *terms[3];
    rths_sparse_factor *factor;
    int interface_index, forcing_index;
    double complex *x; /* n */
};

void rths_sparse_receptance_destroy(rths_sparse_receptance *r) {
    if (!r) return;
    rths_sparse_factor_destroy(r->factor);
    rths_sparse_free(&r->mass);
    rths_sparse_free(&r->damping);
    rths_sparse_free(&r->stiffness);
    free(r->x);
    free(r);
}

static int sparse_copy(const rths_sparse_sym *a, rths_sparse_sym *out) {
    int n = a->n, nnz = a->colptr[n];
    out->n = n;
    out->colptr = malloc(sizeof(int) * (size_t)(n + 1));
    out->rowidx = malloc(sizeof(int) * (size_t)(nnz > 0 ? nnz : 1));
    out->value = malloc(sizeof(double) * (size_t)(nnz > 0 ? nnz : 1));
    if (!out->colptr || !out->rowidx || !out->value) return -1;
    memcpy(out->colptr, a->colptr, sizeof(int) * (size_t)(n + 1));
    memcpy(out->rowidx, a->rowidx, sizeof(int) * (size_t)nnz);
    memcpy(out->value, a->value, sizeof(double) * (size_t)nnz);
    return 0;
}

int rths_sparse_receptance_create(const rths_sparse_sym *mass, const rths_sparse_sym *damping,
                                  const rths_sparse_sym *stiffness, int interface_index,
                                  int forcing_index, rths_sparse_receptance **out,
                                  rths_error *err) {
    *out = NULL;
    int n = stiffness->n;
    if (mass->n != n || damping->n != n)
        return rths_error_set(err, RTHS_EINPUT,
                              "sparse receptance: M, C, K of orders %d, %d, %d differ", mass->n,
                              damping->n, n);
    if (interface_index < 0 || interface_index >= n || forcing_index >= n)
        return rths_error_set(err, RTHS_EINPUT,
                              "sparse receptance: interface index %d or forcing index %d outside "
                              "0..%d",
                              interface_index, forcing_index, n - 1);
    rths_sparse_receptance *r = calloc(1, sizeof *r);
    if (!r) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    r->interface_index = interface_index;
    r->forcing_index = forcing_index;
    r->x = malloc(sizeof(double complex) * (size_t)n);
    int rc = r->x && !sparse_copy(mass, &r->mass) && !sparse_copy(damping, &r->damping) &&
                     !sparse_copy(stiffness, &r->stiffness)
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    r->terms[0] = &r->stiffness;
    r->terms[1] = &r->damping;
    r->terms[2] = &r->mass;
    if (!rc) rc = rths_sparse_factor_create(3, r->terms, RTHS_SPARSE_ORDER_AUTO, &r->factor, err);
    if (rc) {
        rths_sparse_receptance_destroy(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}

/* One complex symmetric LDL^T of D(w) = K + i w C - w^2 M (the symbolic analysis made at the
 * first call is reused) and one solve D x = e_interface: the receptance is x at the interface
 * and, D being symmetric (reciprocity), the interface's response to a unit force at the forcing
 * DoF is x at the forcing DoF. */
int rths_sparse_receptance_eval(void *ctx, double omega_rad_s, double complex *receptance_m_per_n,
                                double complex *forced_m_per_n, rths_error *err) {
    rths_sparse_receptance *r = ctx;
    double w = omega_rad_s;
    double complex coef[3] = {1, I * w, -w * w};
    int rc = rths_sparse_factor_complex(r->factor, coef, err);
    if (rc) return rc;
    memset(r->x, 0, sizeof(double complex) * (size_t)r->stiffness.n);
    r->x[r->interface_index] = 1;
    rc = rths_sparse_solve_complex(r->factor, r->x, 1, err);
    if (rc) return rc;
    *receptance_m_per_n = r->x[r->interface_index];
    *forced_m_per_n = r->forcing_index >= 0 ? r->x[r->forcing_index] : 0;
    return RTHS_OK;
}
