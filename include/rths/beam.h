/* rths beam: Euler-Bernoulli beam structures assembled from segments, so users need not type
 * matrices (model module; YAML keys in docs/config/beam.md).
 *
 * The beam lies along x from 0 (the first segment's start) to its total length. Each segment is
 * meshed into equal two-node elements with cubic Hermite shape functions: per node a transverse
 * displacement w (m) and a rotation theta = dw/dx (rad). Element stiffness EI/l^3 [12 6l -12 6l;
 * 6l 4l^2 -6l 2l^2; ...] and consistent mass (m l / 420) [156 22l 54 -13l; ...] (the standard
 * Hermite beam element, e.g. Przemieniecki, "Theory of matrix structural analysis", 1968). Clamps
 * fix w and theta at a node, pins fix w only; fixed DoFs are removed, so M, C, K are over the free
 * DoFs, listed in `dofs` from the root up (node order, w before theta at each node). Added point
 * masses load w, rotary inertias load theta. Damping is modal (C = M Phi diag(2 zeta_r omega_r)
 * Phi^T M with Phi the M-orthonormal undamped modes, so mode r has exactly ratio zeta_r) or
 * Rayleigh (alpha M + beta K). Modal damping's C is full, so no split can share it between
 * substructures: a beam that is to be split takes Rayleigh damping (docs/config/beam.md,
 * "Splitting a beam"). Matrices column-major (core.h), SI units. */
#ifndef RTHS_BEAM_H
#define RTHS_BEAM_H

#include "rths/config.h"
#include "rths/model.h"

typedef enum { RTHS_BEAM_W = 0, RTHS_BEAM_THETA = 1 } rths_beam_dof_kind;

const char *rths_beam_dof_kind_name(rths_beam_dof_kind kind); /* "w", "theta" */

typedef struct rths_beam_segment {
    double length_m;
    int elements; /* mesh count: equal elements of length_m / elements */
    double ei_n_m2;
    double mass_per_length_kg_per_m;
} rths_beam_segment;

typedef struct rths_beam_point_mass {
    double position_m;           /* must be a node */
    double mass_kg;              /* on w */
    double rotary_inertia_kg_m2; /* on theta */
} rths_beam_point_mass;

typedef enum {
    RTHS_BEAM_DAMPING_NONE = 0,
    RTHS_BEAM_DAMPING_MODAL,
    RTHS_BEAM_DAMPING_RAYLEIGH
} rths_beam_damping_model;

typedef struct rths_beam_damping {
    rths_beam_damping_model model;
    /* modal: mode r (ascending frequency, 0-based) gets ratios[r] for r < n_ratios, else ratio */
    int n_ratios;
    const double *ratios;
    double ratio;
    /* Rayleigh: C = alpha M + beta K (rths_beam_rayleigh_from_pairs turns two (f, zeta) pairs
     * into these) */
    double alpha_per_s, beta_s;
} rths_beam_damping;

typedef struct rths_beam_spec {
    int n_segments;
    const rths_beam_segment *segments; /* from x = 0 up */
    int n_clamped, n_pinned;
    const double *clamped_m, *pinned_m; /* node positions */
    int n_point_masses;
    const rths_beam_point_mass *point_masses;
    rths_beam_damping damping;
} rths_beam_spec;

typedef struct rths_beam_dof {
    int node; /* 0-based node index from x = 0 */
    rths_beam_dof_kind kind;
    double position_m; /* the node's x */
} rths_beam_dof;

typedef struct rths_beam {
    int n;                              /* free DoFs */
    double *mass, *damping, *stiffness; /* n x n: kg / kg m^2, N s/m, N/m (theta rows in N m) */
    rths_beam_dof *dofs;                /* n */
    int n_nodes;
    double *node_position_m; /* n_nodes, ascending */
    double length_m;
    /* the Rayleigh coefficients in use (0 unless the damping is Rayleigh) */
    double rayleigh_alpha_per_s, rayleigh_beta_s;
    rths_beam_damping_model damping_model;
    /* element e joins nodes e and e + 1: its stiffness and consistent mass, 4 x 4 row-major over
       (w_e, theta_e, w_e+1, theta_e+1), 16 doubles each (point masses not included) */
    int n_elements;
    double *element_stiffness, *element_mass;
} rths_beam;

/* Assembles spec; every problem (non-positive length, EI or mass per length, a clamp, pin or
 * point mass off the nodes, ratios outside [0, 1), more ratios than modes, nothing left free) is
 * RTHS_EINPUT naming the item. */
int rths_beam_assemble(const rths_beam_spec *spec, rths_beam *out, rths_error *err);
void rths_beam_free(rths_beam *b);

/* Rayleigh coefficients giving ratio zeta1 at f1_hz and zeta2 at f2_hz:
 * zeta(omega) = alpha / (2 omega) + beta omega / 2. Refuses equal frequencies and pairs that need
 * a negative coefficient (negative damping somewhere). */
int rths_beam_rayleigh_from_pairs(double f1_hz, double zeta1, double f2_hz, double zeta2,
                                  double *alpha_per_s, double *beta_s, rths_error *err);

/* Index of the free DoF of `kind` at the node at position_m (within 1e-6 of the shortest
 * element), -1 when there is no node there or that DoF is fixed. */
int rths_beam_find_dof(const rths_beam *b, double position_m, rths_beam_dof_kind kind);

/* The element-wise split of a beam (docs/config/beam.md, "Splitting a beam"): every element
 * belongs to one substructure, the numerical one when one of its free DoFs has role
 * RTHS_DOF_NUMERICAL, else the physical one (an element joining physical to numerical DoFs is
 * refused by rths_split_create anyway). Fills the physical shares of the interface blocks of K
 * and, for Rayleigh damping or none, of C (n_int x n_int, column-major, in the order int_dofs;
 * int_dofs are free-DoF indices): what the physical elements contribute. Returns 1 when the
 * damping share was filled, 0 for modal damping (its C is full: no element owns it). */
int rths_beam_interface_shares(const rths_beam *b, const rths_dof_role *roles, int n_int,
                               const int *int_dofs, double *damping_phys, double *stiffness_phys);

/* A copy of the matrices as an rths_assembly (rths_assembly_free releases it). */
int rths_beam_to_assembly(const rths_beam *b, rths_assembly *out, rths_error *err);

/* Reads the section at key (normally "structure.beam"; keys in docs/config/beam.md) and
 * assembles it. Every bad value is RTHS_EINPUT with FILE:LINE:COL and the key, e.g. "key
 * 'structure.beam.segments.EI_n_m2': segment 2: must be > 0 (got -1)". */
int rths_beam_config_read(rths_config *cfg, const char *key, rths_beam *out, rths_error *err);

#endif
