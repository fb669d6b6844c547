/* rths model: the true assembly (M, C, K), its split into physical and numerical substructures,
 * modal analysis, analytic FRF, and discretisation of linear state-space models.
 *
 * Conventions: DoF indices are 0-based in the API (storey 1 is DoF 0); matrices are column-major
 * double arrays (see core.h); SI units throughout (kg, N s/m, N/m, m, s, rad/s). */
#ifndef RTHS_MODEL_H
#define RTHS_MODEL_H

#include "rths/config.h"
#include "rths/core.h"
#include "rths/sparse.h"

#include <complex.h>

typedef struct rths_assembly {
    int n;             /* DoFs of the true assembly */
    double *mass;      /* n x n, kg */
    double *damping;   /* n x n, N s/m */
    double *stiffness; /* n x n, N/m */
} rths_assembly;

/* Storey chain from the ground up: storey i has mass masses[i] and the leg below it has
 * damping dampings[i] and stiffness stiffnesses[i] (leg 0 connects storey 0 to the ground). */
int rths_assembly_from_chain(int n, const double *masses, const double *dampings,
                             const double *stiffnesses, rths_assembly *out, rths_error *err);
/* Copies the matrices; checks symmetry, positive definite M, finite entries. */
int rths_assembly_from_matrices(int n, const double *mass, const double *damping,
                                const double *stiffness, rths_assembly *out, rths_error *err);
void rths_assembly_free(rths_assembly *a);
/* Largest |i - j| of a nonzero entry of M, C or K: 1 for a storey chain or a rod. */
int rths_assembly_half_bandwidth(const rths_assembly *a);

/* ---- split into substructures ---- */

typedef enum {
    RTHS_DOF_PHYSICAL = 0,
    RTHS_DOF_INTERFACE = 1,
    RTHS_DOF_NUMERICAL = 2
} rths_dof_role;

typedef struct rths_split {
    int n;                    /* DoFs of the assembly */
    int n_phys, n_int, n_num; /* internal physical, interface, internal numerical */
    int *phys_dofs;           /* assembly indices of the internal physical DoFs */
    int *int_dofs;            /* assembly indices of the interface DoFs */
    int *num_dofs;            /* assembly indices of the internal numerical DoFs */
    double mass_ratio; /* p = numerical share of the interface mass (docs/method.md, "Errata of the
                          seed paper"); with one p per interface DoF, the first DoF's */
    double *mass_ratios; /* n_int: p of each interface DoF (all mass_ratio unless a list given) */
    int np;              /* n_phys + n_int: physical substructure size, order (phys, int) */
    int nn;              /* n_int + n_num: numerical substructure size, order (int, num) */
    double *mass_phys, *damping_phys, *stiffness_phys; /* np x np */
    double *mass_num, *damping_num, *stiffness_num;    /* nn x nn */
} rths_split;

/* Splits assembly a. role[i] gives each DoF's side. The interface mass block is divided as
 * M22_num = p M22, M22_phys = (1 - p) M22 with p = mass_ratio in (0, 1).
 * The interface damping and stiffness blocks are divided by the coupling rule unless given: the
 * numerical side gets exactly the elements joining each interface DoF to internal numerical DoFs
 * (diagonal entry (i, i) = minus the sum of row i's couplings to numerical DoFs); everything else
 * (ground, physical and interface-interface couplings) stays physical. For a storey chain this is
 * "the leg below the interface is physical, the leg above numerical". damping_int_phys /
 * stiffness_int_phys, when not NULL, give the physical shares of the n_int x n_int blocks. */
int rths_split_create(const rths_assembly *a, const rths_dof_role *role, double mass_ratio,
                      const double *damping_int_phys, const double *stiffness_int_phys,
                      rths_split *out, rths_error *err);
/* The same with one p per interface DoF (n_ratios == n_int; n_ratios 1: the same p for all):
 * M_II_num(i, j) = sqrt(p_i p_j) M_II(i, j), so a diagonal interface mass splits by each DoF's p
 * and the numerical block stays positive definite. */
int rths_split_create_ratios(const rths_assembly *a, const rths_dof_role *role, int n_ratios,
                             const double *mass_ratios, const double *damping_int_phys,
                             const double *stiffness_int_phys, rths_split *out, rths_error *err);
void rths_split_free(rths_split *s);
/* Scatter-adds both substructures back into n x n matrices (must equal the assembly). */
void rths_split_recombine(const rths_split *s, double *mass, double *damping, double *stiffness);

/* ---- modal analysis ---- */

typedef struct rths_modes {
    int n;
    double *omega_rad_s;   /* undamped natural circular frequencies, ascending */
    double *frequency_hz;  /* omega / 2 pi */
    double *damping_ratio; /* phi^T C phi / (2 omega phi^T M phi): proportional approximation */
    double *shapes;        /* n x n, column r = mode r, mass-normalised (phi^T M phi = 1) */
} rths_modes;

/* Symmetric-definite generalised eigenproblem K phi = w^2 M phi: LAPACK dsbgvd on band storage
 * when the half-bandwidth is at most n / 8, dsygvd otherwise (both divide and conquer; 0.3 s at
 * n = 1000); eigenvalues refined as the shapes' Rayleigh quotients. */
int rths_modal_analysis(const rths_assembly *a, rths_modes *out, rths_error *err);
void rths_modes_free(rths_modes *m);

/* ---- analytic frequency response ---- */

/* Steady state of M q'' + C q' + K q = f cos(omega t): q = Re(X e^{i omega t}) with
 * X = (K - omega^2 M + i omega C)^{-1} f. Amplitude |X_i|, phase arg X_i; the Fourier
 * coefficients of q_i = A cos + B sin are A = Re X_i, B = -Im X_i. */
int rths_frf(int n, const double *mass, const double *damping, const double *stiffness,
             const double *force, double omega_rad_s, double complex *x_out, rths_error *err);

/* The same steady state over many frequencies without n^3 work per frequency, for the DoFs
 * out_dofs (0-based, n_out of them): prepared once from the modes, then per frequency
 *   banded complex LU (O(n b^2)) when M, C, K are banded with half-bandwidth b <= n / 8,
 *   else modal superposition (O(n n_out)) when the modes decouple C (proportional damping),
 *   else complex modes of the state space (O(n n_out)),
 *   dense solves only when those modes are near-defective (eigenvector matrix rcond < 1e-6).
 * Each equals rths_frf up to rounding. The sweep keeps a pointer to a: keep it alive. */
typedef enum {
    RTHS_FRF_MODAL = 0,
    RTHS_FRF_BANDED,
    RTHS_FRF_STATE_SPACE,
    RTHS_FRF_DENSE
} rths_frf_method;

typedef struct rths_frf_sweep rths_frf_sweep;

int rths_frf_sweep_create(const rths_assembly *a, const rths_modes *modes, const double *force,
                          int n_out, const int *out_dofs, rths_frf_sweep **out, rths_error *err);
/* x_out[o] = X at out_dofs[o] for circular frequency omega_rad_s. */
int rths_frf_sweep_eval(rths_frf_sweep *s, double omega_rad_s, double complex *x_out,
                        rths_error *err);
rths_frf_method rths_frf_sweep_method(const rths_frf_sweep *s);
const char *rths_frf_method_name(rths_frf_method m);
void rths_frf_sweep_destroy(rths_frf_sweep *s);

/* Frequencies (Hz, ascending, malloc'ed) for an FRF. With points > 1: uniform over [start, end].
 * With points == 0: a uniform background of 400 points plus 81 points across +-8 half-power
 * bandwidths of every mode inside the range, so each peak is resolved to well under 1 % of its
 * height. end_hz <= 0 means 1.25 x the highest natural frequency. */
int rths_frf_grid(const rths_modes *modes, double start_hz, double end_hz, int points,
                  double **freqs_hz, int *count, rths_error *err);

/* ---- state space and discretisation ---- */

/* x = (q, q'), x' = A x + B u with u the amplitudes of the inputs whose force directions are the
 * columns of input (n x n_inputs). A is 2n x 2n, B is 2n x n_inputs; both malloc'ed. */
int rths_state_space(int n, const double *mass, const double *damping, const double *stiffness,
                     int n_inputs, const double *input, double **a_out, double **b_out,
                     rths_error *err);

typedef enum {
    RTHS_SCHEME_IMPLICIT_EULER = 0, /* the seed's: (I - hA)^{-1}(x_k + h B u_{k+1}) */
    RTHS_SCHEME_TRAPEZOIDAL,        /* Tustin, input averaged over the step */
    RTHS_SCHEME_EXACT_ZOH,          /* exact for u held at u_k over the step */
    RTHS_SCHEME_EXACT_FOH,          /* exact for u linear from u_k to u_{k+1} (triangle hold) */
    RTHS_SCHEME_COUNT
} rths_scheme;

#define RTHS_SCHEME_DEFAULT RTHS_SCHEME_EXACT_FOH

const char *rths_scheme_name(rths_scheme s); /* "implicit_euler", "trapezoidal", ... */
int rths_scheme_parse(const char *name, rths_scheme *out); /* 0 on success, -1 unknown */

/* x_{k+1} = ad x_k + b_prev u_k + b_curr u_{k+1}; every scheme has this form. */
typedef struct rths_discrete {
    int nx, nu;
    double h;
    rths_scheme scheme;
    double *ad;     /* nx x nx */
    double *b_prev; /* nx x nu, multiplies the input at the start of the step */
    double *b_curr; /* nx x nu, multiplies the input at the end of the step */
} rths_discrete;

int rths_discretise(int nx, int nu, const double *a, const double *b, double h, rths_scheme scheme,
                    rths_discrete *out, rths_error *err);
void rths_discrete_free(rths_discrete *d);
/* Largest |eigenvalue| of a real n x n matrix (LAPACK dgeev): a discrete map x_{k+1} = A x_k is
 * stable below 1. -1 on failure. */
double rths_spectral_radius(int n, const double *a);
/* The spectral radius of a discrete numerical substructure (inputs 0..ni-1: the interface forces)
 * under grounding control that acts one sample late: F = G1 xi_k + G0 xi_k-1 with
 * G1 = -(kp^ + kd^/h), G0 = kd^/h per interface DoF (the physical side held at rest), entering
 * the step as the next input; state [z_k, z_k-1, u_k]. The model is rths_discrete's form with
 * nx states, n_inputs inputs and step h, s; gkp, gkd: ni gains (N/m, N s/m). -1 on failure. The
 * controller refuses gains above 1; rths tune chooses them below. */
double rths_grounding_loop_radius(int nx, int n_inputs, const double *ad, const double *b_prev,
                                  const double *b_curr, double h, int ni, const double *gkp,
                                  const double *gkd);

/* ---- periodic response of the true assembly with a bilinear leg (shooting) ---- */

/* A leg whose stiffness is `stiffness_n_per_m` for extension (x_upper - x_lower >= 0) and
 * ratio * stiffness_n_per_m for compression; the assembly's K must contain the leg's extension
 * stiffness, the extra compression stiffness is added here. lower_dof = -1 means the ground. */
typedef struct rths_bilinear_leg {
    int lower_dof, upper_dof;
    double stiffness_n_per_m;
    double ratio;
} rths_bilinear_leg;

#define RTHS_PERIODIC_HARMONICS 3

/* One periodic solution: Fourier coefficients (k = 0..3, relative to the forcing cos(w t)) of
 * every DoF, and its stability from the Floquet multipliers. */
typedef struct rths_periodic_point {
    double omega_rad_s;
    double *cos_m;      /* n x (RTHS_PERIODIC_HARMONICS + 1): cos_m[i + k n] */
    double *sin_m;      /* same layout */
    double max_floquet; /* largest Floquet multiplier modulus: > 1 unstable */
    int stable;
} rths_periodic_point;

typedef struct rths_shooting_options {
    double start_hz, end_hz;
    int steps_per_period; /* RK4 steps per forcing period */
    double max_step;      /* pseudo-arclength step, scaled units */
    int max_points;
} rths_shooting_options;

/* Traces the periodic response of M q'' + C q' + K q + g(q) = static_force + force cos(w t) from
 * start_hz to end_hz by shooting with pseudo-arclength continuation, through folds. *out is
 * malloc'ed (free with rths_periodic_points_free). */
int rths_bilinear_frf(const rths_assembly *a, const rths_bilinear_leg *leg,
                      const double *static_force, const double *force,
                      const rths_shooting_options *opt, rths_periodic_point **out, int *n_out,
                      rths_error *err);
void rths_periodic_points_free(rths_periodic_point *pts, int n);
/* Static equilibrium under static_force (Newton on the piecewise-linear restoring force). */
int rths_bilinear_static(const rths_assembly *a, const rths_bilinear_leg *leg,
                         const double *static_force, double *q_out, rths_error *err);

/* ---- large sparse models (docs/architecture.md, "Sparse algebra") ----
 *
 * `rths model` on a structure given as Matrix Market files too large or too scattered for the
 * dense and banded paths: the matrices stay in compressed sparse form (sparse.h), the lowest
 * modes come from shift-invert Lanczos, the FRF from those modes plus the static response of the
 * rest (or one sparse complex solve per frequency). */

/* auto: models up to this many DoFs take the dense / banded path (all modes, exact FRF), as
 * before sparse models existed. */
#define RTHS_MODEL_DENSE_UP_TO 1000

typedef enum {
    RTHS_MODEL_SOLVER_DENSE = 0, /* dsygvd on the dense matrices */
    RTHS_MODEL_SOLVER_BANDED,    /* dsbgvd on band storage (half-bandwidth <= n / 8) */
    RTHS_MODEL_SOLVER_SPARSE     /* MUMPS + ARPACK on compressed sparse matrices */
} rths_model_solver;
const char *rths_model_solver_name(rths_model_solver s);

typedef struct rths_model_choice {
    rths_model_solver solver;
    int n;              /* DoFs (0 until known) */
    int half_bandwidth; /* of the stiffness pattern, -1 when not measured */
    char reason[320];   /* why, in words, for the console and run.log */
    /* the stiffness read while choosing (sparse only; taken over by rths_sparse_model_read) */
    rths_sparse_sym stiffness;
} rths_model_choice;

/* Chooses the path for `rths model` from model.solver (auto | dense | sparse) and, for a
 * structure.matrices given as Matrix Market files, the declared order and the stiffness's
 * half-bandwidth: auto takes sparse when n > RTHS_MODEL_DENSE_UP_TO and the pattern is not
 * banded (half-bandwidth > n / 8) or n > RTHS_MTX_MAX_DIM; dense / banded otherwise (decided on
 * the assembly by rths_model_choice_dense). Nothing of the declared size is read for dense. */
int rths_model_choose_solver(rths_config *cfg, rths_model_choice *out, rths_error *err);
/* The dense path's choice on an assembly (the one rths_modal_analysis makes), why in out. */
void rths_model_choice_dense(const rths_assembly *a, const char *why, rths_model_choice *out);
void rths_model_choice_free(rths_model_choice *c);

/* A structure given as Matrix Market files, kept sparse, with its split, forcing and ranges read
 * from the same keys as rths_setup_read (structure.matrices, split.interface / physical /
 * numerical / mass_ratio, forcing, model.frf) plus model.modes (how many lowest modes, default
 * 20) and model.frf.solver (modal | direct), model.frf.check_points. */
typedef struct rths_sparse_model {
    int n;
    rths_sparse_sym mass, damping, stiffness; /* lower triangles */
    rths_dof_role *roles;                     /* n */
    int n_int, *int_dofs;                     /* ascending, 0-based */
    double mass_ratio;                        /* the first interface DoF's p */
    int forcing_dof;                          /* 0-based; n - 1 for base excitation */
    double forcing_amplitude_n;               /* N, or m/s^2 for base excitation */
    int base_excitation;
    double *force; /* n: the forcing's load vector, N */
    double frf_start_hz, frf_end_hz;
    int frf_points;
    int modes_wanted;       /* model.modes: how many lowest modes (default 20) */
    double modes_below_hz;  /* > 0 (model.frf.end_hz given, model.modes not): every mode below
                               this instead, at most RTHS_SPARSE_MODEL_MAX_MODES */
    int frf_direct;         /* model.frf.solver: direct (one complex solve per frequency) */
    int frf_check_points;   /* model.frf.check_points: direct solves checking the modal FRF */
    double read_matrices_s; /* seconds spent reading the three files */
    /* split.interface_damping_physical_n_s_per_m / split.interface_stiffness_physical_n_per_m:
     * the physical shares of the interface C and K blocks, n_int x n_int column-major over
     * int_dofs (rths_split_create's damping_int_phys / stiffness_int_phys); NULL: the coupling
     * rule. A beam frame's rotations make the coupling rule's physical share of K_II negative
     * (a roof node's ux: -5.3e7 N/m on the 482-DoF frame), which no rig can carry. */
    double *interface_damping_phys, *interface_stiffness_phys;
} rths_sparse_model;

/* The most modes the sparse path computes (Lanczos basis of twice as many vectors of n). */
#define RTHS_SPARSE_MODEL_MAX_MODES 400
/* With model.frf.end_hz and no model.modes: every mode below this multiple of the band's end,
 * so the modes above the band respond almost statically (amplification 1 / (1 - 1 / 1.5^2) = 1.8
 * at the band's end, and their static part is exact: rths_sparse_frf). */
#define RTHS_SPARSE_MODEL_MODES_MARGIN 1.5

/* model.frf.check_points' default: 1 up to this many DoFs, 0 above (each check is a direct
 * complex solve, as costly as the modes' factorisations together). */
#define RTHS_SPARSE_MODEL_CHECK_UP_TO 20000

/* Reads the model; choice->stiffness is taken over (emptied). Errors as rths_setup_read's. */
int rths_sparse_model_read(rths_config *cfg, rths_model_choice *choice, rths_sparse_model *out,
                           rths_error *err);
void rths_sparse_model_free(rths_sparse_model *m);
/* The DoFs a model's tables report (rths_setup_output_dofs's rule), malloc'ed. */
int *rths_sparse_model_output_dofs(const rths_sparse_model *m, int *count);
void rths_sparse_model_forcing_text(const rths_sparse_model *m, char *buf, size_t size);

/* The lowest modes_wanted modes, mass-normalised, with their checks. */
typedef struct rths_sparse_modes {
    int n, count;
    double *omega_rad_s, *frequency_hz, *damping_ratio; /* count */
    double *shapes;                                     /* n x count */
    double max_residual; /* max over modes of ||K phi - lambda M phi|| / ||K phi|| */
    int sturm_below;     /* eigenvalues below the midpoint past the last mode (LDL^T inertia) */
    double sturm_shift;  /* that midpoint, rad^2/s^2 */
    double max_damping_coupling; /* max |phi_r^T C phi_s| / sqrt(c_rr c_ss), r != s */
    double *static_x, *static_y; /* n: K^-1 f and K^-1 M K^-1 f (the model's force) */
    rths_sparse_eigs_stats stats;
    double check_s; /* residuals, Sturm count and damping */
} rths_sparse_modes;

/* Modes of m, their checks and the static responses to m's force; *k_factor (when not NULL)
 * receives the factor of K (terms K, M; refactorised at shift 0) for further solves. */
int rths_sparse_model_modes(const rths_sparse_model *m, rths_sparse_modes *out,
                            rths_sparse_factor **k_factor, rths_error *err);
void rths_sparse_modes_free(rths_sparse_modes *m);

/* The FRF of a sparse model at out_dofs: modal (the modes' dynamic response plus the static
 * response of every mode not computed and its first dynamic correction:
 * x = sum_r phi_r p_r / (w_r^2 - w^2 + 2 i z_r w_r w) + R0 f + w^2 R1 f, p_r = phi_r^T f,
 * R0 = K^-1 - sum_r phi_r phi_r^T / w_r^2, R1 = K^-1 M K^-1 - sum_r phi_r phi_r^T / w_r^4:
 * exact for damping the modes decouple up to (w / w_first dropped)^4 of the dropped modes'
 * static share) or direct (one complex symmetric LDL^T of
 * K + i w C - w^2 M per frequency, one symbolic analysis). */
typedef struct rths_sparse_frf rths_sparse_frf;
int rths_sparse_frf_create(const rths_sparse_model *m, const rths_sparse_modes *modes, int n_out,
                           const int *out_dofs, rths_sparse_frf **out, rths_error *err);
int rths_sparse_frf_eval(rths_sparse_frf *s, double omega_rad_s, double complex *x_out,
                         rths_error *err);
int rths_sparse_frf_direct(rths_sparse_frf *s, double omega_rad_s, double complex *x_out,
                           rths_error *err);
/* Seconds spent in direct solves so far (symbolic analysis, factorisations, solves). */
double rths_sparse_frf_direct_s(const rths_sparse_frf *s);
void rths_sparse_frf_destroy(rths_sparse_frf *s);

/* The numerical substructure of a sparse model, as rths_split_create makes it (order: interface
 * DoFs, then internal numerical ones, each ascending; *dofs_out their assembly indices, nn of
 * them): the interface mass block times the model's p (one p for every interface DoF), of C and K
 * the interface diagonal minus the couplings to numerical DoFs (the coupling rule), every other
 * entry among these DoFs as it is. */
int rths_sparse_model_numerical_side(const rths_sparse_model *m, rths_sparse_sym *mass,
                                     rths_sparse_sym *damping, rths_sparse_sym *stiffness,
                                     int **dofs_out, int *nn_out, rths_error *err);

/* The physical substructure of a sparse model as rths_split_create makes it (order: internal
 * physical DoFs, then the interface, each ascending; np of them, dense np x np: the rig's side is
 * small): the model minus the numerical side's interface block ((1 - p) M_II, and of C and K
 * what is not the numerical side's by the coupling rule). RTHS_EINPUT above max_np DoFs. */
int rths_sparse_model_physical_side(const rths_sparse_model *m, int max_np, double **mass,
                                    double **damping, double **stiffness, int *np_out,
                                    rths_error *err);

/* The frequency form's numerical substructure of a sparse model (split.numerical_solver:
 * frequency; docs/method.md, "Numerical substructure integration"): per harmonic, the interface
 * receptance h = e_b^T D(w)^-1 e_b of the numerical side (rths_sparse_model_numerical_side, one
 * interface DoF) and the interface's response to the forcing per unit forcing amplitude,
 * x_b = e_b^T D(w)^-1 f = x^T f by reciprocity (D complex symmetric), from the same solve: one
 * complex symmetric LDL^T and one solve per frequency on one symbolic analysis. f is what the
 * numerical side carries of the forcing: a unit force where forcing.dof is an interface or
 * numerical DoF (none on a physical one: the rig applies it), -M_num 1 under base excitation
 * (the numerical side's own inertia, relative coordinates). An rths_receptance_fn (iterate.h)
 * with ctx the object, for rths_frequency_problem_init. */
typedef struct rths_sparse_model_receptance rths_sparse_model_receptance;
int rths_sparse_model_receptance_create(const rths_sparse_model *m,
                                        rths_sparse_model_receptance **out, rths_error *err);
int rths_sparse_model_receptance_eval(void *ctx, double omega_rad_s,
                                      double complex *receptance_m_per_n,
                                      double complex *forced_m_per_n, rths_error *err);
/* Seconds in its factorisations and solves so far, and how many symbolic analyses ran (1 once
 * any frequency was evaluated: every frequency reuses it). */
double rths_sparse_model_receptance_s(const rths_sparse_model_receptance *r, int *analyses);
void rths_sparse_model_receptance_destroy(rths_sparse_model_receptance *r);

/* Peak resident memory of the process so far, MB (getrusage ru_maxrss). */
double rths_peak_memory_mb(void);

#endif
