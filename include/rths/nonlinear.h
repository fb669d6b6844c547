/* rths nonlinear elements (model module): forces between two DoFs (or a DoF and the ground) on
 * top of the linear assembly (M, C, K), and the periodic response of the assembly with them by
 * shooting with pseudo-arclength continuation and Floquet stability (docs/method.md, "Nonlinear
 * elements").
 *
 * An element acts on the deformation d = q_i - q_j (q_j = 0 for the ground) or on its rate: it
 * pulls DoF i with -g and pushes DoF j with +g, where g is the element's force:
 *   kink (bilinear leg, gap):  g = k (d + c) when d + c < 0, else 0 (k: the stiffness added
 *                              in contact; c: the clearance, 0 for the bilinear leg, whose
 *                              extension stiffness is part of K and k = (ratio - 1) k_leg)
 *   cubic (Duffing):           g = k3 d^3
 *   friction (regularised):    g = F tanh(d' / v_reg) (Coulomb's sign(d') F smoothed over
 *                              |d'| ~ v_reg) */
#ifndef RTHS_NONLINEAR_H
#define RTHS_NONLINEAR_H

#include "rths/model.h"

typedef enum {
    RTHS_NL_BILINEAR = 0,
    RTHS_NL_CUBIC,
    RTHS_NL_GAP,
    RTHS_NL_FRICTION,
    RTHS_NL_TYPE_COUNT
} rths_nl_type;

/* At most this many elements in a configuration (the controller's per-sample Newton solves a
 * system of this size without LAPACK). */
#define RTHS_MAX_NONLINEAR 8

typedef struct rths_nl_element {
    rths_nl_type type;
    int dof_i, dof_j; /* 0-based assembly DoFs; dof_j = -1: the ground */
    int numerical;    /* 1: on the numerical side of the split, 0: on the physical side */
    /* kink: added contact stiffness k (N/m) and clearance c (m); cubic: k3 (N/m^3) in k;
     * friction: slip force F (N) and regularisation velocity v_reg (m/s) */
    double k, clearance_m, force_n, v_reg_m_s;
    /* bilinear: the leg's extension stiffness (in K) and its compression ratio, for reports */
    double leg_stiffness_n_per_m, ratio;
} rths_nl_element;

const char *rths_nl_type_name(rths_nl_type t); /* "bilinear", "cubic", "gap", "friction" */

/* 1 when the element's force depends on the deformation's rate (friction), 0 on the deformation */
int rths_nl_on_rate(const rths_nl_element *e);
/* The element's force g at deformation (or rate) y, and dg/dy in *slope (may be NULL). */
double rths_nl_force(const rths_nl_element *e, double y, double *slope);

/* Static equilibrium K q + sum_e g_e b_e = static_force (friction carries nothing at rest):
 * Newton on the restoring force, which is piecewise linear or smooth. */
int rths_nonlinear_static(const rths_assembly *a, int count, const rths_nl_element *el,
                          const double *static_force, double *q_out, rths_error *err);

/* Traces the periodic response of M q'' + C q' + K q + sum_e g_e b_e = static_force +
 * force cos(w t) from start_hz to end_hz by shooting (RK4, steps_per_period) with
 * pseudo-arclength continuation, through folds; every point's Floquet multipliers from its
 * monodromy matrix. *out is malloc'ed (rths_periodic_points_free). */
int rths_nonlinear_frf(const rths_assembly *a, int count, const rths_nl_element *el,
                       const double *static_force, const double *force,
                       const rths_shooting_options *opt, rths_periodic_point **out, int *n_out,
                       rths_error *err);

/* The element a bilinear leg is: its extra compression stiffness as a kink at 0. */
rths_nl_element rths_nl_from_leg(const rths_bilinear_leg *leg);

#endif
