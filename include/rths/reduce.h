/* rths reduce: a numerical substructure of any size reduced to its interface and the
 * fixed-interface modes that matter, so the real-time step stays small (docs/method.md,
 * "Numerical substructure integration", "Reduced numerical substructures").
 *
 * Craig-Bampton: the boundary (interface) DoFs b stay physical coordinates; the interior i is
 * spanned by the static constraint modes Psi = -K_ii^{-1} K_ib and the fixed-interface modes Phi
 * (K_ii phi = w^2 M_ii phi, mass-normalised) up to a cutoff:
 *     q = T r,  T = [[I, 0], [Psi, Phi_kept]],   M_r = T^T M T, C_r = T^T C T, K_r = T^T K T.
 * The interface dynamic stiffness S(w) = D_bb - D_bi D_ii^{-1} D_ib (D = K - w^2 M + i w C) of the
 * reduced model is exact at w = 0 (static condensation); without damping, keeping the modes below
 * w_c changes it by
 *     |S_r(w) - S(w)| = w^4 |sum_{dropped j} m_j m_j^T / (w_j^2 - w^2)|
 *                    <= w^4 tr(M_dropped) / (w_1st dropped^2 - w^2)  for w below the first dropped,
 * where m_j = phi_j^T (M_ib + M_ii Psi) and M_dropped = sum over the dropped modes of m_j m_j^T,
 * computed exactly as G^T M_ii^{-1} G - sum_kept m_j m_j^T (G = M_ib + M_ii Psi): what the
 * dropped modes would add to the interface's apparent mass. Damping that the fixed-interface
 * modes decouple only enlarges the denominators, so the bound holds for it too. */
#ifndef RTHS_REDUCE_H
#define RTHS_REDUCE_H

#include "rths/config.h"
#include "rths/core.h"
#include "rths/model.h"

#include <complex.h>

/* The real-time step's bound on the numerical substructure it integrates (full or reduced). */
#define RTHS_REALTIME_MAX_DOFS 32
/* auto: numerical substructures up to this size run unreduced (the seed's, bit for bit). */
#define RTHS_REDUCE_FULL_UP_TO 16

typedef enum {
    RTHS_REDUCTION_AUTO = 0, /* none up to RTHS_REDUCE_FULL_UP_TO DoFs, else craig_bampton */
    RTHS_REDUCTION_NONE,
    RTHS_REDUCTION_CRAIG_BAMPTON
} rths_reduction_method;

typedef struct rths_reduction_options {
    rths_reduction_method method;
    /* Keep every fixed-interface mode up to this frequency, Hz. <= 0 (auto): a twentieth of the
     * sample rate (500 Hz at 10 kHz), lowered to the highest mode that fits the real-time bound
     * when more modes lie below; an explicit cutoff with too many modes below is refused. */
    double cutoff_hz;
} rths_reduction_options;

void rths_reduction_defaults(rths_reduction_options *opt);
/* Reads controller.reduction {method: auto|none|craig_bampton, cutoff_hz: auto|number}. */
int rths_reduction_config_read(rths_config *cfg, rths_reduction_options *opt, rths_error *err);
/* The cutoff opt asks for at sample_rate_hz, Hz (auto resolved, before the size bound). */
double rths_reduction_cutoff_hz(const rths_reduction_options *opt, double sample_rate_hz);
/* 1 when a numerical substructure of n DoFs is reduced under opt. */
int rths_reduction_applies(const rths_reduction_options *opt, int n);

typedef struct rths_reduced {
    int n;          /* DoFs of the full model */
    int n_boundary; /* its first n_boundary DoFs: the interface, kept as they are */
    int n_modes;    /* fixed-interface modes kept */
    int nr;         /* n_boundary + n_modes: the reduced size */
    double cutoff_hz;
    double *transform;                  /* n x nr: q = T r */
    double *mass, *damping, *stiffness; /* nr x nr: T^T M T, T^T C T, T^T K T */
    double *mode_hz;                    /* n_modes: the kept fixed-interface modes, ascending */
    double first_dropped_hz;            /* lowest dropped fixed-interface mode; INFINITY if none */
    double dropped_mass_kg;             /* tr(M_dropped), kg (see above) */
} rths_reduced;

/* Craig-Bampton reduction of (M, C, K) (n x n, column-major, boundary DoFs first) keeping the
 * fixed-interface modes up to cutoff_hz, at most max_modes of them: more below the cutoff are
 * refused (RTHS_EINPUT naming the count) unless clip is 1, which keeps the lowest max_modes and
 * lowers cutoff_hz to the highest kept one. */
int rths_reduce_craig_bampton(int n, int n_boundary, const double *mass, const double *damping,
                              const double *stiffness, double cutoff_hz, int max_modes, int clip,
                              rths_reduced *out, rths_error *err);
/* The same keeping further DoFs as boundary coordinates (docs/method.md, "Nonlinear elements in
 * the real-time step"): the DoFs a nonlinear element touches must stay physical coordinates of
 * the reduced model, or the element's deformation would be a combination of modes. The boundary
 * is the first n_interface DoFs, then keep[0..n_keep-1] (0-based, not interface DoFs, unique):
 * keep[m] is reduced coordinate n_interface + m; out->n_boundary = n_interface + n_keep and
 * out->transform stays in the substructure's own DoF order (row i: DoF i). */
int rths_reduce_craig_bampton_keeping(int n, int n_interface, const double *mass,
                                      const double *damping, const double *stiffness, int n_keep,
                                      const int *keep, double cutoff_hz, int max_modes, int clip,
                                      rths_reduced *out, rths_error *err);
void rths_reduced_free(rths_reduced *r);

/* The bound above on |S_r(w) - S(w)| (N/m); INFINITY at or above the first dropped mode. */
double rths_reduced_stiffness_error_bound(const rths_reduced *r, double omega_rad_s);

/* The interface dynamic stiffness S(w) (n_boundary x n_boundary complex, column-major, N/m) of
 * (M, C, K) with the boundary DoFs first: dense, for checks and the fidelity report. */
int rths_interface_dynamic_stiffness(int n, int n_boundary, const double *mass,
                                     const double *damping, const double *stiffness,
                                     double omega_rad_s, double complex *s_out, rths_error *err);

/* ---- the numerical substructure solved on the host (split.numerical_solver: frequency) ----
 *
 * The steady state of the numerical substructure M q'' + C q' + K q = e_int F + f Phi at one
 * frequency, from its dynamic stiffness by the FRF sweep's exact solves (banded at any size):
 * its interface receptance H(w) (m/N) and its interface displacement per newton of forcing
 * amplitude when forcing_dof is an interface or numerical DoF (else 0). One interface DoF. */
typedef struct rths_numerical_receptance rths_numerical_receptance;

int rths_numerical_receptance_create(const rths_split *s, int forcing_dof,
                                     rths_numerical_receptance **out, rths_error *err);
/* An rths_receptance_fn (iterate.h) with ctx the object. */
int rths_numerical_receptance_eval(void *ctx, double omega_rad_s,
                                   double complex *receptance_m_per_n,
                                   double complex *forced_m_per_n, rths_error *err);
void rths_numerical_receptance_destroy(rths_numerical_receptance *r);

/* The same for a large sparse numerical substructure (M, C, K of order nn in compressed sparse
 * form, e.g. from rths_sparse_model_numerical_side): one sparse complex symmetric LDL^T per
 * frequency on one symbolic analysis, one solve with the interface's unit force; the forcing's
 * response by reciprocity from the same solve. interface_index, forcing_index: in the matrices'
 * order (forcing_index -1: none). The matrices are copied. */
typedef struct rths_sparse_receptance rths_sparse_receptance;
int rths_sparse_receptance_create(const rths_sparse_sym *mass, const rths_sparse_sym *damping,
                                  const rths_sparse_sym *stiffness, int interface_index,
                                  int forcing_index, rths_sparse_receptance **out, rths_error *err);
/* An rths_receptance_fn (iterate.h) with ctx the object. */
int rths_sparse_receptance_eval(void *ctx, double omega_rad_s, double complex *receptance_m_per_n,
                                double complex *forced_m_per_n, rths_error *err);
void rths_sparse_receptance_destroy(rths_sparse_receptance *r);

#endif
