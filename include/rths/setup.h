/* rths setup: the structural part of a test configuration (model module), read from YAML.
 *
 *   structure:   storeys {mass_kg, damping_n_s_per_m, stiffness_n_per_m} (lists, ground up)
 *                or matrices {mass_kg, damping_n_s_per_m, stiffness_n_per_m}, each n x n rows
 *                or the path of a Matrix Market file (mtx.h), relative to the config's folder;
 *                bilinear {enabled, storey, compression_ratio, preload_n} (optional);
 *                nonlinear: a list of elements {type: bilinear | cubic | gap | friction,
 *                dofs: [i, j] (1-based, j = 0 the ground), side (only for an element between
 *                interface DoFs or an interface DoF and the ground), parameters in SI}
 *                (nonlinear.h; docs/config.md, "Nonlinear elements")
 *   split:       interface (1-based DoF list), mass_ratio p in (0, 1) (docs/method.md, "Errata of
 *                the seed paper", erratum 1) or a list of one p per interface DoF, physical /
 *                numerical (1-based lists, physical may be empty; for a chain
 *                default: below / above; with matrices the absent one takes every other DoF),
 *                numerical_solver: realtime (default: the controller integrates the numerical
 *                substructure every sample) | frequency (the host solves it per harmonic from its
 *                dynamic stiffness; docs/method.md, "Numerical substructure integration"); a
 *                structure.beam splits element by element (beam.h)
 *   forcing:     dof (1-based), amplitude_n; or type: base, amplitude_m_s2 (a harmonic ground
 *                acceleration: every DoF is driven through its inertia, -M 1 a_g(t), and
 *                displacements are relative to the ground)
 *   model:       frf {start_hz, end_hz, points} for the analytic FRF (default resolves every mode)
 *   rig.interface_mass: full (default) | physical_share: what the rig carries of the interface
 *                mass block (rths_interface_mass)
 *   rig.actuators, rig.lasers: where the actuators push and the lasers read, as offsets from the
 *                cut of a beam or as transform matrices (docs/config/rig.md, "Actuator and
 *                sensor transforms"); absent: one of each per interface DoF, acting on and
 *                reading that DoF itself
 *
 * Other sections (rig, controller, iteration, continuation, stability, output) are read by their
 * own modules from the same rths_config. */
#ifndef RTHS_SETUP_H
#define RTHS_SETUP_H

#include "rths/beam.h"
#include "rths/config.h"
#include "rths/model.h"
#include "rths/nonlinear.h"
#include <stddef.h>

/* Where the numerical substructure is solved (split.numerical_solver). */
typedef enum {
    RTHS_NUMERICAL_REALTIME = 0, /* integrated by the controller, sample by sample */
    RTHS_NUMERICAL_FREQUENCY = 1 /* on the host, per harmonic (periodic tests, linear model) */
} rths_numerical_solver;

/* What the rig carries of the interface mass block (rig.interface_mass; docs/method.md, "The
 * interface mass on the rig"). */
typedef enum {
    /* the seed's lab: the rig's interface storey is the assembly's whole M_II; the controller
     * compensates the numerical share p M_II from the measured accelerations */
    RTHS_INTERFACE_MASS_FULL = 0,
    /* a light specimen: the rig carries (1 - p) M_II (plus the actuator's moving mass), the
     * numerical side's p M_II is its own mass and nothing is compensated */
    RTHS_INTERFACE_MASS_PHYSICAL_SHARE = 1
} rths_interface_mass;

typedef struct rths_setup {
    rths_assembly assembly;
    rths_dof_role *roles; /* per DoF */
    rths_split split;
    int forcing_dof; /* 0-based; for base excitation the top DoF (n - 1), for reports only */
    double forcing_amplitude_n; /* N; for base excitation the ground acceleration's, m/s^2 */
    double *force;              /* n: forcing_amplitude_n x forcing_shape, N */
    int base_excitation;        /* forcing.type: base */
    double *forcing_shape;      /* n: force per unit forcing amplitude: 1 at forcing_dof (force), or
                                   -M 1 (base: N per m/s^2 of ground acceleration) */
    int chain;                  /* 1 when the structure was given as a storey chain */
    /* 1 when the structure has any nonlinear element (structure.bilinear or structure.nonlinear,
     * on either side): its truth is the shooting solution, not the analytic FRF. The name is the
     * historical one (the bilinear leg was the only nonlinearity). */
    int has_bilinear;
    /* structure.bilinear: the leg below `leg.upper_dof`, extension stiffness from the chain (also
     * nonlinear[0] when enabled) */
    rths_bilinear_leg leg;
    double preload_n;     /* structure.bilinear's static force, N */
    double *static_force; /* n: every element's preload (structure.bilinear's on the interface
                             DoF when the leg is physical, on its upper storey when numerical), N */
    /* Every nonlinear element, structure.bilinear's first; each on one side of the split. */
    int n_nonlinear;
    rths_nl_element nonlinear[RTHS_MAX_NONLINEAR];
    double frf_start_hz, frf_end_hz;
    int frf_points;
    rths_numerical_solver numerical_solver;
    rths_beam *beam; /* structure.beam as assembled (NULL for storeys and matrices) */
    /* Actuator and sensor transforms, n_int x n_int column-major over the split's interface
     * order; NULL: the identity (one actuator and one laser per interface DoF, on the DoF).
     * actuator_transform column a: the interface efforts (N on a displacement, N m on a
     * rotation) of 1 N from actuator a; its transpose maps interface motion to the motion of
     * each actuator's point (where its load cell and accelerometer sit). sensor_transform row s:
     * laser s reads sum_d S(s, d) q_d (m). Both invertible (checked at read). */
    double *actuator_transform;
    double *sensor_transform;
    rths_interface_mass interface_mass; /* rig.interface_mass: full (default) | physical_share */
    /* structure.matrices as Matrix Market files for which rths_model_choose_solver chose the
     * sparse path (model.solver; docs/architecture.md, "Sparse algebra"): the model kept sparse.
     * Then assembly holds only n (no dense matrices: 60 000 DoFs would take 29 GB), the split
     * only its DoF lists and its small dense physical side (mass_num, damping_num, stiffness_num
     * NULL), and only split.numerical_solver: frequency with one interface DoF is accepted. */
    rths_sparse_model *sparse;
    /* the truth's sparse solves at the reported DoFs (truth.c), NULL without sparse */
    struct rths_sparse_truth *sparse_truth;
} rths_setup;

/* The cache of the truth's sparse direct solves (truth.c): one symbolic analysis, then one
 * complex LDL^T per frequency, the last frequency's response at out_dofs kept. */
typedef struct rths_sparse_truth {
    rths_sparse_frf *frf;
    int n_out, *out_dofs; /* ascending assembly DoFs: rths_setup_output_dofs */
    double last_omega_rad_s;
    double complex *last_x; /* n_out, at last_omega_rad_s (NAN omega: none yet) */
} rths_sparse_truth;
int rths_sparse_truth_create(const rths_sparse_model *m, int n_out, const int *out_dofs,
                             rths_sparse_truth **out, rths_error *err);
void rths_sparse_truth_free(rths_sparse_truth *t);

/* Reads structure, split, forcing and model.frf; every problem is RTHS_EINPUT with the key's
 * location, including a structure without physical sense (non-finite or huge entries, M or K not
 * positive definite, C not positive semi-definite): nothing downstream sees one. Does not call
 * rths_config_check_unknown (the command does, after all sections). */
int rths_setup_read(rths_config *cfg, rths_setup *out, rths_error *err);
void rths_setup_free(rths_setup *s);

/* Models up to this many DoFs report every DoF; larger ones only what the test sees (physical
 * substructure, interface, forcing), so modes.csv and true_frf.csv stay small at any n. */
#define RTHS_SETUP_ALL_DOFS_UP_TO 64
/* The forcing in words for titles and logs: "1 N on DoF 4" or "ground acceleration 1 m/s^2". */
void rths_setup_forcing_text(const rths_setup *s, char *buf, size_t size);

/* 1 when assembly DoF dof (0-based) is a rotation (a beam node's theta: its amplitudes are in
 * rad, its efforts in N m), 0 for a displacement (m). */
int rths_setup_dof_is_rotation(const rths_setup *s, int dof);

/* The interface mass block the rig carries, element (d, e) over the split's interface order, kg
 * (kg m or kg m^2 on rotations), the actuators' moving mass not included: the assembly's M_II
 * (full) or the physical share (1 - p) M_II (physical_share). */
double rths_setup_rig_interface_mass(const rths_setup *s, int d, int e);
/* The inertial compensation the controller applies to the measured interface accelerations,
 * element (d, e), kg: the numerical share p M_II (full), 0 (physical_share). Whatever the mode,
 * rig + numerical - compensated = M_II: the hybrid test's interface mass is the assembly's. */
double rths_setup_compensation_mass(const rths_setup *s, int d, int e);
const char *rths_interface_mass_name(rths_interface_mass mode);

/* RTHS_EINPUT naming model.solver when s is sparse (setup->sparse): for the commands that need
 * the dense assembly (simulate, chart, tune: they read assembly's matrices, NULL on the sparse
 * path; fidelity takes a sparse model its own way, api_fidelity_sparse.c); RTHS_OK otherwise. */
int rths_setup_require_dense(const rths_setup *s, const char *command, rths_error *err);

/* Nonlinear elements on the numerical (numerical = 1) or physical (0) side. */
int rths_setup_nonlinear_count(const rths_setup *s, int numerical);

/* The DoFs a model's tables report, ascending, 0-based (malloc'ed; NULL when out of memory). */
int *rths_setup_output_dofs(const rths_setup *s, int *count);

#endif
