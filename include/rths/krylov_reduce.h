/* rths krylov_reduce: a real-time reduction of a large sparse numerical substructure that is
 * right in the tested band (docs/method.md, "Reduced numerical substructures";
 * docs/architecture.md, "Sparse algebra").
 *
 * Craig-Bampton with the lowest fixed-interface modes is not enough when the forcing acts away
 * from the interface: the forcing's load excites interior shapes that no low mode spans (issue
 * 26: a 482-DoF frame with the force on a roof node is 58-65 % off with 31 modes). This basis is
 * built from what the response in the band is made of:
 *     q = T r,  T = [[I, 0], [Psi, V]],  Psi = -K_ii^-1 K_ib (the interface constraint modes),
 *     V spans Re and Im of D_ii(w_j)^-1 [f_i, G, H] at frequencies w_j (0 and points of the band),
 *     D_ii(w) = K_ii + i w C_ii - w^2 M_ii, G = M_ib + M_ii Psi, H = C_ib + C_ii Psi,
 * f_i the loads' interior part: the interior's exact response to the loads and to the inertial and
 * damping loads of the constraint modes at each w_j, so the Galerkin projection reproduces the
 * interface response exactly at every w_j, with its derivative (rational Krylov / moment matching
 * of a symmetric system whose inputs and outputs the basis both spans). V is M_ii-orthonormal and
 * rotated to the Ritz vectors of (K_ii, M_ii), so the reduced interior is the Craig-Bampton form
 * with Ritz modes in place of modes (M_r's interior block I, K_r's diagonal). The w_j are chosen
 * greedily: each is the frequency of the check grid where the reduced model is furthest from the
 * full sparse solve, until it is within opt.max_error or the size bound is reached. */
#ifndef RTHS_KRYLOV_REDUCE_H
#define RTHS_KRYLOV_REDUCE_H

#include "rths/config.h"
#include "rths/model.h"
#include "rths/reduce.h"
#include "rths/sparse.h"

/* controller.reduction.max_error's default: the reduced model's interface response within
 * 0.1 % of the full model's over the band. */
#define RTHS_KRYLOV_MAX_ERROR_DEFAULT 1e-3
/* controller.reduction.check_points' default: full sparse solves over the band. */
#define RTHS_KRYLOV_CHECK_POINTS_DEFAULT 31

typedef struct rths_krylov_options {
    double start_hz, end_hz; /* the tested band (the sweep's), start < end, start >= 0 */
    int check_points; /* exact solves (one factorisation each), evenly over the band, ends in */
    double max_error; /* the largest relative interface response error accepted */
    int max_size;     /* reduced DoFs at most (interface included) */
    /* 1: once within max_error, go on adding the worst check point's solves up to max_size
     * (the check sees only its grid: between its points, at a lightly damped resonance, the
     * error can be larger, and the real-time step's cost is set by its bound anyway); 0: stop */
    int fill;
    rths_sparse_ordering ordering;
} rths_krylov_options;
/* band 0-0 (to be set), RTHS_KRYLOV_CHECK_POINTS_DEFAULT, RTHS_KRYLOV_MAX_ERROR_DEFAULT,
 * RTHS_REALTIME_MAX_DOFS, fill 1, SCOTCH. */
void rths_krylov_defaults(rths_krylov_options *opt);

/* Reads controller.reduction.max_error (relative, (0, 1]), .check_points (2..10000) and .fill
 * (bool) into opt (its values the defaults); the band is the caller's (the sweep's). */
int rths_krylov_config_read(rths_config *cfg, rths_krylov_options *opt, rths_error *err);

/* The rest of the assembly, attached at the interface (the physical side): dense matrices of
 * order nb + n_extra, the interface DoFs first (the same order as the numerical side's), so the
 * error is that of the assembly's interface response, the quantity a hybrid test converges to.
 * loads: (nb + n_extra) x n_loads, its share of each load (NULL: none). */
typedef struct rths_krylov_attachment {
    int n_extra;
    const double *mass, *damping, *stiffness;
    const double *loads;
} rths_krylov_attachment;

typedef struct rths_krylov_report {
    double max_error; /* worst relative interface response error over the check grid */
    double at_hz;     /* where */
    int check_points; /* full sparse solves made for the check */
    int shifts;       /* frequencies whose solves span V (0 Hz first) */
    double shift_hz[RTHS_REALTIME_MAX_DOFS];
    int basis;      /* interior vectors kept (the reduced size minus the interface) */
    double truth_s; /* seconds in the full sparse solves at the check points */
    double basis_s; /* seconds building the basis (interior factorisations and solves) */
} rths_krylov_report;

/* Reduces the numerical substructure (M, C, K of order nn in compressed sparse form, its first
 * n_boundary DoFs the interface, as rths_sparse_model_numerical_side orders it) loaded by the
 * n_loads columns of loads (nn x n_loads, column-major). out: the shape rths_reduce_craig_bampton
 * gives (n = nn, interface first and physical, n_modes = interior vectors, transform nn x nr,
 * dense mass / damping / stiffness nr x nr, mode_hz the Ritz frequencies of the interior,
 * first_dropped_hz INFINITY and dropped_mass_kg NAN: the modal bound does not apply).
 * The error, checked against the exact response at each check frequency (one complex LDL^T of
 * the interior D_ii(w) on one symbolic analysis, solved with [D_ib, f_i, G, H]: the numerical
 * side's interface response by the Schur complement S = D_bb - D_bi D_ii^-1 D_ib, exactly a full
 * solve's, and that point's candidate vectors kept, so choosing it as a shift costs nothing
 * more: memory nn x (n_loads + 2 nb) complex per check point), is, per check frequency and per
 * input column (a unit force on each interface DoF,
 * then each load), ||x_reduced - x|| / ||x|| of the interface displacements, x of the numerical
 * substructure alone or, with rest, of the assembly; its maximum over the grid goes to rep.
 * RTHS_EINPUT (out freed, rep filled) when it exceeds opt->max_error at opt->max_size. */
int rths_krylov_reduce(const rths_sparse_sym *mass, const rths_sparse_sym *damping,
                       const rths_sparse_sym *stiffness, int n_boundary, int n_loads,
                       const double *loads, const rths_krylov_attachment *rest,
                       const rths_krylov_options *opt, rths_reduced *out, rths_krylov_report *rep,
                       rths_error *err);

/* The same on a sparse model's numerical substructure (rths_sparse_model_numerical_side; its
 * assembly DoFs in *dofs_out, malloc'ed, when not NULL) with the model's force as the load and
 * its physical side attached (the model minus the numerical side's interface block), so the
 * error is the assembly's interface response against the full model's. */
int rths_sparse_model_krylov_reduce(const rths_sparse_model *m, const rths_krylov_options *opt,
                                    rths_reduced *out, int **dofs_out, rths_krylov_report *rep,
                                    rths_error *err);

/* The interface response (nb x (nb + n_loads), column-major: unit interface forces, then the
 * loads) at omega of a reduced model r (from either reduction) with its loads already projected
 * (reduced_loads, nr x n_loads = T^T loads), rest attached as above (may be NULL): what the check
 * compares, for callers and tests. */
int rths_krylov_interface_response(const rths_reduced *r, int n_loads, const double *reduced_loads,
                                   const rths_krylov_attachment *rest, double omega_rad_s,
                                   double complex *x_out, rths_error *err);

#endif
