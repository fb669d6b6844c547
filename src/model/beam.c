/* Euler-Bernoulli beam assembly (see beam.h): mesh, element matrices, supports, added masses,
 * modal or Rayleigh damping. One validation pass (check_spec) serves both the C API and the YAML
 * reader: it names the offending field and item, and the reader turns the field into its key so
 * the user sees FILE:LINE:COL. */
#include "rths/beam.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Dense matrices of n DoFs cost 3 n^2 doubles plus a modal analysis; 1000 elements (about 2000
 * DoFs, 32 MB a matrix) is far beyond what a hybrid test's numerical substructure needs. */
#define BEAM_MAX_ELEMENTS 1000

const char *rths_beam_dof_kind_name(rths_beam_dof_kind kind) {
    return kind == RTHS_BEAM_W ? "w" : "theta";
}

void rths_beam_free(rths_beam *b) {
    if (!b) return;
    rths_mat_free(b->mass);
    rths_mat_free(b->damping);
    rths_mat_free(b->stiffness);
    free(b->dofs);
    free(b->node_position_m);
    free(b->element_stiffness);
    free(b->element_mass);
    memset(b, 0, sizeof *b);
}

/* ---- validation: which field and item is wrong ---- */

typedef enum {
    F_SEG_LENGTH,
    F_SEG_ELEMENTS,
    F_SEG_EI,
    F_SEG_MASS,
    F_CLAMPED,
    F_PINNED,
    F_PM_POSITION,
    F_PM_MASS,
    F_PM_INERTIA,
    F_DAMP_RATIO,
    F_DAMP_RATIOS,
    F_DAMP_ALPHA,
    F_DAMP_BETA,
    F_SECTION,
    F_COUNT
} beam_field;

/* the YAML key of each field below the section key (docs/config/beam.md) */
static const char *const field_key[F_COUNT] = {"segments.length_m",
                                               "segments.elements",
                                               "segments.EI_n_m2",
                                               "segments.mass_per_length_kg_per_m",
                                               "clamped_m",
                                               "pinned_m",
                                               "point_masses.position_m",
                                               "point_masses.mass_kg",
                                               "point_masses.rotary_inertia_kg_m2",
                                               "damping.ratio",
                                               "damping.ratios",
                                               "damping.alpha_per_s",
                                               "damping.beta_s",
                                               ""};

typedef struct beam_fault {
    beam_field field;
    char what[512];
} beam_fault;

static int fault(beam_fault *f, beam_field field, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static int fault(beam_fault *f, beam_field field, const char *fmt, ...) {
    f->field = field;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(f->what, sizeof f->what, fmt, ap);
    va_end(ap);
    return RTHS_EINPUT;
}

/* Node positions of the mesh (malloc'ed, n_nodes entries) and the shortest element. */
static double *mesh_nodes(const rths_beam_spec *spec, int *n_nodes, double *shortest_m) {
    int count = 1;
    for (int s = 0; s < spec->n_segments; s++)
        count += spec->segments[s].elements;
    double *x = malloc((size_t)count * sizeof *x);
    if (!x) return NULL;
    double start = 0, shortest = INFINITY;
    int k = 0;
    x[k++] = 0;
    for (int s = 0; s < spec->n_segments; s++) {
        const rths_beam_segment *g = &spec->segments[s];
        double h = g->length_m / g->elements;
        shortest = fmin(shortest, h);
        for (int e = 1; e <= g->elements; e++)
            x[k++] = e == g->elements ? start + g->length_m : start + e * h;
        start += g->length_m;
    }
    *n_nodes = count;
    *shortest_m = shortest;
    return x;
}

/* Node at x within tol, or -1; *nearest gets the closest node position either way. */
static int node_at(const double *nodes, int n_nodes, double x, double tol, double *nearest) {
    int best = 0;
    for (int i = 1; i < n_nodes; i++)
        if (fabs(nodes[i] - x) < fabs(nodes[best] - x)) best = i;
    *nearest = nodes[best];
    return fabs(nodes[best] - x) <= tol ? best : -1;
}

static int check_segments(const rths_beam_spec *spec, beam_fault *f) {
    if (spec->n_segments < 1) return fault(f, F_SEG_LENGTH, "needs at least one segment");
    long total = 0;
    for (int s = 0; s < spec->n_segments; s++) {
        const rths_beam_segment *g = &spec->segments[s];
        if (!(g->length_m > 0) || !isfinite(g->length_m))
            return fault(f, F_SEG_LENGTH, "segment %d: must be > 0 m (got %g)", s + 1, g->length_m);
        if (g->elements < 1)
            return fault(f, F_SEG_ELEMENTS, "segment %d: needs at least 1 element (got %d)", s + 1,
                         g->elements);
        total += g->elements;
        if (total > BEAM_MAX_ELEMENTS)
            return fault(f, F_SEG_ELEMENTS,
                         "segment %d: more than %d elements in all (dense matrices)", s + 1,
                         BEAM_MAX_ELEMENTS);
        if (!(g->ei_n_m2 > 0) || !isfinite(g->ei_n_m2))
            return fault(f, F_SEG_EI, "segment %d: must be > 0 N m^2 (got %g)", s + 1, g->ei_n_m2);
        /* a floor far below any beam a rig holds (a 1e-300 kg/m segment's modes overflow) */
        if (!(g->mass_per_length_kg_per_m >= 1e-6) || !isfinite(g->mass_per_length_kg_per_m))
            return fault(f, F_SEG_MASS, "segment %d: must be >= 1e-06 kg/m (got %g)", s + 1,
                         g->mass_per_length_kg_per_m);
    }
    return RTHS_OK;
}

/* Supports and point masses must sit on nodes; a node is clamped or pinned once at most. */
static int check_positions(const rths_beam_spec *spec, const double *nodes, int n_nodes, double tol,
                           beam_fault *f, rths_error *err) {
    const int counts[3] = {spec->n_clamped, spec->n_pinned, spec->n_point_masses};
    const beam_field fields[3] = {F_CLAMPED, F_PINNED, F_PM_POSITION};
    int *support = calloc((size_t)n_nodes, sizeof *support);
    if (!support) return rths_error_set(err, RTHS_EFAIL, "out of memory (beam)");
    int rc = RTHS_OK;
    for (int kind = 0; kind < 3 && !rc; kind++)
        for (int i = 0; i < counts[kind] && !rc; i++) {
            double x = kind == 0   ? spec->clamped_m[i]
                       : kind == 1 ? spec->pinned_m[i]
                                   : spec->point_masses[i].position_m;
            double nearest;
            int node = isfinite(x) ? node_at(nodes, n_nodes, x, tol, &nearest) : -1;
            if (node < 0)
                rc = fault(f, fields[kind],
                           "entry %d: no node at %g m (nearest node at %.9g m; nodes lie at the "
                           "segment ends and every length_m / elements inside a segment)",
                           i + 1, x, isfinite(x) ? nearest : NAN);
            else if (kind < 2 && support[node])
                rc = fault(f, fields[kind], "entry %d: the node at %g m is already %s", i + 1,
                           nodes[node], support[node] == 1 ? "clamped" : "pinned");
            else if (kind < 2)
                support[node] = kind + 1;
        }
    for (int i = 0; i < spec->n_point_masses && !rc; i++) {
        const rths_beam_point_mass *pm = &spec->point_masses[i];
        if (!(pm->mass_kg >= 0) || !isfinite(pm->mass_kg))
            rc = fault(f, F_PM_MASS, "entry %d: must be >= 0 kg (got %g)", i + 1, pm->mass_kg);
        else if (!(pm->rotary_inertia_kg_m2 >= 0) || !isfinite(pm->rotary_inertia_kg_m2))
            rc = fault(f, F_PM_INERTIA, "entry %d: must be >= 0 kg m^2 (got %g)", i + 1,
                       pm->rotary_inertia_kg_m2);
    }
    free(support);
    return rc;
}

static int check_damping(const rths_beam_damping *d, beam_fault *f) {
    switch (d->model) {
    case RTHS_BEAM_DAMPING_NONE:
        return RTHS_OK;
    case RTHS_BEAM_DAMPING_MODAL:
        /* the list first: a missing ratio defaults to its last entry */
        for (int r = 0; r < d->n_ratios; r++)
            if (!(d->ratios[r] >= 0 && d->ratios[r] < 1))
                return fault(f, F_DAMP_RATIOS, "mode %d: must be in [0, 1) (got %g)", r + 1,
                             d->ratios[r]);
        if (!(d->ratio >= 0 && d->ratio < 1))
            return fault(f, F_DAMP_RATIO, "must be in [0, 1) (got %g)", d->ratio);
        return RTHS_OK;
    case RTHS_BEAM_DAMPING_RAYLEIGH:
        if (!(d->alpha_per_s >= 0) || !isfinite(d->alpha_per_s))
            return fault(f, F_DAMP_ALPHA, "must be >= 0 1/s (got %g)", d->alpha_per_s);
        if (!(d->beta_s >= 0) || !isfinite(d->beta_s))
            return fault(f, F_DAMP_BETA, "must be >= 0 s (got %g)", d->beta_s);
        return RTHS_OK;
    }
    return fault(f, F_SECTION, "unknown damping model %d", (int)d->model);
}

/* ---- assembly ---- */

/* Element stiffness and consistent mass for (w1, theta1, w2, theta2), row-major 4 x 4. */
static void element_matrices(double l, double ei, double mu, double ke[16], double me[16]) {
    const double k[16] = {12,  6 * l,  -12, 6 * l,  6 * l, 4 * l * l, -6 * l, 2 * l * l,
                          -12, -6 * l, 12,  -6 * l, 6 * l, 2 * l * l, -6 * l, 4 * l * l};
    const double m[16] = {156, 22 * l, 54,  -13 * l, 22 * l,  4 * l * l,  13 * l,  -3 * l * l,
                          54,  13 * l, 156, -22 * l, -13 * l, -3 * l * l, -22 * l, 4 * l * l};
    double ks = ei / (l * l * l), ms = mu * l / 420;
    for (int i = 0; i < 16; i++) {
        ke[i] = ks * k[i];
        me[i] = ms * m[i];
    }
}

/* Global (2 n_nodes)^2 matrices of the unconstrained beam with its point masses; each element's
 * own matrices into ke_all, me_all (16 doubles per element). */
static void assemble_full(const rths_beam_spec *spec, const double *nodes, int n_nodes, double tol,
                          double *kg, double *mg, double *ke_all, double *me_all) {
    int nd = 2 * n_nodes, node = 0;
    for (int s = 0; s < spec->n_segments; s++) {
        const rths_beam_segment *g = &spec->segments[s];
        for (int e = 0; e < g->elements; e++, node++) {
            double ke[16], me[16];
            element_matrices(nodes[node + 1] - nodes[node], g->ei_n_m2, g->mass_per_length_kg_per_m,
                             ke, me);
            memcpy(ke_all + 16 * node, ke, sizeof ke);
            memcpy(me_all + 16 * node, me, sizeof me);
            for (int i = 0; i < 4; i++)
                for (int j = 0; j < 4; j++) {
                    RTHS_AT(kg, nd, 2 * node + i, 2 * node + j) += ke[4 * i + j];
                    RTHS_AT(mg, nd, 2 * node + i, 2 * node + j) += me[4 * i + j];
                }
        }
    }
    for (int i = 0; i < spec->n_point_masses; i++) {
        const rths_beam_point_mass *pm = &spec->point_masses[i];
        double nearest;
        int at = node_at(nodes, n_nodes, pm->position_m, tol, &nearest);
        RTHS_AT(mg, nd, 2 * at, 2 * at) += pm->mass_kg;
        RTHS_AT(mg, nd, 2 * at + 1, 2 * at + 1) += pm->rotary_inertia_kg_m2;
    }
}

/* fixed[d] for each of the 2 n_nodes DoFs from the clamps and pins. */
static void mark_fixed(const rths_beam_spec *spec, const double *nodes, int n_nodes, double tol,
                       int *fixed) {
    double nearest;
    for (int i = 0; i < spec->n_clamped; i++) {
        int at = node_at(nodes, n_nodes, spec->clamped_m[i], tol, &nearest);
        fixed[2 * at] = fixed[2 * at + 1] = 1;
    }
    for (int i = 0; i < spec->n_pinned; i++)
        fixed[2 * node_at(nodes, n_nodes, spec->pinned_m[i], tol, &nearest)] = 1;
}

/* C = M Phi diag(2 zeta_r omega_r) Phi^T M over the M-orthonormal undamped modes: Phi^T C Phi is
 * then diag(2 zeta_r omega_r), so each mode keeps its own ratio exactly. */
static int modal_damping(rths_beam *b, const rths_beam_damping *d, beam_fault *f, rths_error *err) {
    int n = b->n;
    if (d->n_ratios > n)
        return fault(f, F_DAMP_RATIOS, "lists %d ratios but the beam has only %d modes",
                     d->n_ratios, n);
    rths_assembly undamped = {n, b->mass, b->damping /* still zero */, b->stiffness};
    rths_modes modes;
    int rc = rths_modal_analysis(&undamped, &modes, err);
    if (rc) return rc;
    double *mphi = rths_mat_new(n, n), *scaled = rths_mat_new(n, n);
    if (!mphi || !scaled) {
        rths_mat_free(mphi);
        rths_mat_free(scaled);
        rths_modes_free(&modes);
        return rths_error_set(err, RTHS_EFAIL, "out of memory (modal damping)");
    }
    rths_mat_mul(n, n, n, 1.0, b->mass, 0, modes.shapes, 0, 0.0, mphi);
    for (int r = 0; r < n; r++) {
        double zeta = r < d->n_ratios ? d->ratios[r] : d->ratio;
        double g = 2 * zeta * modes.omega_rad_s[r];
        for (int i = 0; i < n; i++)
            RTHS_AT(scaled, n, i, r) = g * RTHS_AT(mphi, n, i, r);
    }
    rths_mat_mul(n, n, n, 1.0, scaled, 0, mphi, 1, 0.0, b->damping);
    /* exact symmetry (rounding of the product would otherwise differ in the last bits) */
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
            double s = 0.5 * (RTHS_AT(b->damping, n, i, j) + RTHS_AT(b->damping, n, j, i));
            RTHS_AT(b->damping, n, i, j) = RTHS_AT(b->damping, n, j, i) = s;
        }
    rths_mat_free(mphi);
    rths_mat_free(scaled);
    rths_modes_free(&modes);
    return RTHS_OK;
}

/* Copies the free rows and columns of the full matrices and lists the free DoFs. */
static int reduce(rths_beam *b, const double *kg, const double *mg, const int *fixed, beam_fault *f,
                  rths_error *err) {
    int nd = 2 * b->n_nodes, n = 0;
    for (int d = 0; d < nd; d++)
        n += !fixed[d];
    if (n == 0) return fault(f, F_SECTION, "every DoF is fixed: nothing left to move");
    b->n = n;
    b->mass = rths_mat_new(n, n);
    b->damping = rths_mat_new(n, n);
    b->stiffness = rths_mat_new(n, n);
    b->dofs = calloc((size_t)n, sizeof *b->dofs);
    if (!b->mass || !b->damping || !b->stiffness || !b->dofs)
        return rths_error_set(err, RTHS_EFAIL, "out of memory (beam)");
    for (int d = 0, i = 0; d < nd; d++) {
        if (fixed[d]) continue;
        b->dofs[i] = (rths_beam_dof){d / 2, d % 2 ? RTHS_BEAM_THETA : RTHS_BEAM_W,
                                     b->node_position_m[d / 2]};
        for (int e = 0, j = 0; e < nd; e++) {
            if (fixed[e]) continue;
            RTHS_AT(b->stiffness, n, i, j) = RTHS_AT(kg, nd, d, e);
            RTHS_AT(b->mass, n, i, j) = RTHS_AT(mg, nd, d, e);
            j++;
        }
        i++;
    }
    return RTHS_OK;
}

static int apply_damping(rths_beam *b, const rths_beam_damping *d, beam_fault *f, rths_error *err) {
    b->damping_model = d->model;
    if (d->model == RTHS_BEAM_DAMPING_MODAL) return modal_damping(b, d, f, err);
    if (d->model == RTHS_BEAM_DAMPING_RAYLEIGH) {
        b->rayleigh_alpha_per_s = d->alpha_per_s;
        b->rayleigh_beta_s = d->beta_s;
        for (size_t k = 0; k < (size_t)b->n * (size_t)b->n; k++)
            b->damping[k] = d->alpha_per_s * b->mass[k] + d->beta_s * b->stiffness[k];
    }
    return RTHS_OK;
}

/* The work of rths_beam_assemble; a bad value fills *f (and returns RTHS_EINPUT), any other
 * failure fills err. */
static int assemble(const rths_beam_spec *spec, rths_beam *out, beam_fault *f, rths_error *err) {
    memset(out, 0, sizeof *out);
    f->what[0] = 0;
    int rc = check_segments(spec, f);
    if (!rc) rc = check_damping(&spec->damping, f);
    if (rc) return rc;
    double tol;
    out->node_position_m = mesh_nodes(spec, &out->n_nodes, &tol);
    if (!out->node_position_m) return rths_error_set(err, RTHS_EFAIL, "out of memory (beam)");
    /* a node typed as a decimal (0.17) and one summed from lengths differ in the last bits only */
    tol *= 1e-6;
    out->length_m = out->node_position_m[out->n_nodes - 1];
    rc = check_positions(spec, out->node_position_m, out->n_nodes, tol, f, err);
    if (rc) return rc;
    int nd = 2 * out->n_nodes;
    double *kg = rths_mat_new(nd, nd), *mg = rths_mat_new(nd, nd);
    int *fixed = calloc((size_t)nd, sizeof *fixed);
    out->n_elements = out->n_nodes - 1;
    out->element_stiffness = calloc(16 * (size_t)out->n_elements, sizeof(double));
    out->element_mass = calloc(16 * (size_t)out->n_elements, sizeof(double));
    if (!kg || !mg || !fixed || !out->element_stiffness || !out->element_mass) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory (beam)");
    } else {
        assemble_full(spec, out->node_position_m, out->n_nodes, tol, kg, mg, out->element_stiffness,
                      out->element_mass);
        mark_fixed(spec, out->node_position_m, out->n_nodes, tol, fixed);
        rc = reduce(out, kg, mg, fixed, f, err);
    }
    rths_mat_free(kg);
    rths_mat_free(mg);
    free(fixed);
    if (!rc) rc = apply_damping(out, &spec->damping, f, err);
    return rc;
}

int rths_beam_assemble(const rths_beam_spec *spec, rths_beam *out, rths_error *err) {
    beam_fault f;
    int rc = assemble(spec, out, &f, err);
    if (rc && f.what[0]) {
        const char *k = field_key[f.field];
        rths_error_set(err, rc, "beam%s%s: %s", *k ? " " : "", k, f.what);
    }
    if (rc) rths_beam_free(out);
    return rc;
}

int rths_beam_rayleigh_from_pairs(double f1_hz, double zeta1, double f2_hz, double zeta2,
                                  double *alpha_per_s, double *beta_s, rths_error *err) {
    if (!(f1_hz > 0 && f2_hz > 0) || !isfinite(f1_hz) || !isfinite(f2_hz) || f1_hz == f2_hz)
        return rths_error_set(err, RTHS_EINPUT,
                              "two different frequencies > 0 Hz are needed (got %g and %g)", f1_hz,
                              f2_hz);
    if (!(zeta1 >= 0 && zeta1 < 1 && zeta2 >= 0 && zeta2 < 1))
        return rths_error_set(err, RTHS_EINPUT, "ratios must be in [0, 1) (got %g and %g)", zeta1,
                              zeta2);
    double w1 = 2 * M_PI * f1_hz, w2 = 2 * M_PI * f2_hz, den = w2 * w2 - w1 * w1;
    /* zeta_k = alpha / (2 w_k) + beta w_k / 2 for k = 1, 2, solved for alpha and beta */
    double alpha = 2 * w1 * w2 * (zeta1 * w2 - zeta2 * w1) / den;
    double beta = 2 * (zeta2 * w2 - zeta1 * w1) / den;
    /* a rounding-level negative (equal ratios proportional to frequency) is zero */
    if (alpha < 0 && alpha > -1e-12 * fabs(2 * w1 * zeta1)) alpha = 0;
    if (beta < 0 && beta > -1e-12 * fabs(2 * zeta1 / w1)) beta = 0;
    if (alpha < 0 || beta < 0)
        return rths_error_set(err, RTHS_EINPUT,
                              "(%g Hz, %g) and (%g Hz, %g) need %s < 0, which damps negatively "
                              "%s: choose ratios closer together",
                              f1_hz, zeta1, f2_hz, zeta2, alpha < 0 ? "alpha" : "beta",
                              alpha < 0 ? "at low frequency" : "at high frequency");
    *alpha_per_s = alpha;
    *beta_s = beta;
    return RTHS_OK;
}

int rths_beam_find_dof(const rths_beam *b, double position_m, rths_beam_dof_kind kind) {
    if (!b->n_nodes || !isfinite(position_m)) return -1;
    double shortest = INFINITY, nearest;
    for (int i = 1; i < b->n_nodes; i++)
        shortest = fmin(shortest, b->node_position_m[i] - b->node_position_m[i - 1]);
    if (!isfinite(shortest)) shortest = 1.0;
    int node = node_at(b->node_position_m, b->n_nodes, position_m, 1e-6 * shortest, &nearest);
    for (int i = 0; node >= 0 && i < b->n; i++)
        if (b->dofs[i].node == node && b->dofs[i].kind == kind) return i;
    return -1;
}

/* Free-DoF index of each of element e's four DoFs (-1: fixed). */
static void element_dofs(const rths_beam *b, int e, int idx[4]) {
    for (int k = 0; k < 4; k++)
        idx[k] = -1;
    for (int i = 0; i < b->n; i++) {
        int local = 2 * (b->dofs[i].node - e) + (b->dofs[i].kind == RTHS_BEAM_THETA);
        if (local >= 0 && local < 4) idx[local] = i;
    }
}

int rths_beam_interface_shares(const rths_beam *b, const rths_dof_role *roles, int n_int,
                               const int *int_dofs, double *damping_phys, double *stiffness_phys) {
    int damping = b->damping_model != RTHS_BEAM_DAMPING_MODAL;
    memset(stiffness_phys, 0, sizeof(double) * (size_t)n_int * (size_t)n_int);
    memset(damping_phys, 0, sizeof(double) * (size_t)n_int * (size_t)n_int);
    for (int e = 0; e < b->n_elements; e++) {
        int idx[4], numerical = 0;
        element_dofs(b, e, idx);
        for (int k = 0; k < 4; k++)
            numerical |= idx[k] >= 0 && roles[idx[k]] == RTHS_DOF_NUMERICAL;
        if (numerical) continue;
        const double *ke = b->element_stiffness + 16 * e, *me = b->element_mass + 16 * e;
        for (int i = 0; i < n_int; i++)
            for (int j = 0; j < n_int; j++)
                for (int r = 0; r < 4; r++)
                    for (int c = 0; c < 4; c++) {
                        if (idx[r] != int_dofs[i] || idx[c] != int_dofs[j]) continue;
                        double k = ke[4 * r + c];
                        RTHS_AT(stiffness_phys, n_int, i, j) += k;
                        if (damping)
                            RTHS_AT(damping_phys, n_int, i, j) +=
                                b->rayleigh_alpha_per_s * me[4 * r + c] + b->rayleigh_beta_s * k;
                    }
    }
    return damping;
}

int rths_beam_to_assembly(const rths_beam *b, rths_assembly *out, rths_error *err) {
    return rths_assembly_from_matrices(b->n, b->mass, b->damping, b->stiffness, out, err);
}

/* ---- YAML ---- */

#define KEY_LEN 256

static void subkey(char *buf, const char *key, const char *suffix) {
    snprintf(buf, KEY_LEN, "%s%s%s", key, *suffix ? "." : "", suffix);
}

typedef struct beam_input {
    rths_beam_segment *segments;
    double *clamped, *pinned;
    rths_beam_point_mass *point_masses;
    double *ratios;
    rths_beam_spec spec;
} beam_input;

static void beam_input_free(beam_input *in) {
    free(in->segments);
    free(in->clamped);
    free(in->pinned);
    free(in->point_masses);
    free(in->ratios);
}

/* The four segment lists, one entry per segment, must agree in length. */
static int read_segments(rths_config *cfg, const char *key, beam_input *in, rths_error *err) {
    static const char *const names[4] = {"segments.length_m", "segments.elements",
                                         "segments.EI_n_m2", "segments.mass_per_length_kg_per_m"};
    char k[4][KEY_LEN];
    double *v[3] = {NULL, NULL, NULL};
    int *elements = NULL, count[4] = {0, 0, 0, 0};
    for (int i = 0; i < 4; i++)
        subkey(k[i], key, names[i]);
    int rc = rths_config_get_double_list(cfg, k[0], 1, &v[0], &count[0], err);
    if (!rc) rc = rths_config_get_int_list(cfg, k[1], 1, &elements, &count[1], err);
    if (!rc) rc = rths_config_get_double_list(cfg, k[2], 1, &v[1], &count[2], err);
    if (!rc) rc = rths_config_get_double_list(cfg, k[3], 1, &v[2], &count[3], err);
    if (!rc && count[0] < 1)
        rc = rths_config_error_at(cfg, k[0], err, "needs at least one segment");
    for (int i = 1; i < 4 && !rc; i++)
        if (count[i] != count[0])
            rc = rths_config_error_at(cfg, k[i], err,
                                      "has %d entries but %s has %d: one per segment", count[i],
                                      k[0], count[0]);
    if (!rc) {
        in->segments = calloc((size_t)count[0], sizeof *in->segments);
        if (!in->segments) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int s = 0; s < count[0] && !rc; s++)
        in->segments[s] = (rths_beam_segment){v[0][s], elements[s], v[1][s], v[2][s]};
    if (!rc) in->spec.n_segments = count[0], in->spec.segments = in->segments;
    for (int i = 0; i < 3; i++)
        free(v[i]);
    free(elements);
    return rc;
}

static int read_supports(rths_config *cfg, const char *key, beam_input *in, rths_error *err) {
    char k[KEY_LEN];
    subkey(k, key, "clamped_m");
    int rc = rths_config_get_double_list(cfg, k, 0, &in->clamped, &in->spec.n_clamped, err);
    subkey(k, key, "pinned_m");
    if (!rc) rc = rths_config_get_double_list(cfg, k, 0, &in->pinned, &in->spec.n_pinned, err);
    in->spec.clamped_m = in->clamped;
    in->spec.pinned_m = in->pinned;
    return rc;
}

static int read_point_masses(rths_config *cfg, const char *key, beam_input *in, rths_error *err) {
    static const char *const names[3] = {"point_masses.position_m", "point_masses.mass_kg",
                                         "point_masses.rotary_inertia_kg_m2"};
    char k[3][KEY_LEN];
    double *v[3] = {NULL, NULL, NULL};
    int count[3] = {0, 0, 0}, rc = RTHS_OK;
    for (int i = 0; i < 3; i++)
        subkey(k[i], key, names[i]);
    char section[KEY_LEN];
    subkey(section, key, "point_masses");
    int present = rths_config_has(cfg, section);
    for (int i = 0; i < 3 && !rc; i++)
        rc = rths_config_get_double_list(cfg, k[i], i == 0 && present, &v[i], &count[i], err);
    if (!rc && present && count[1] == 0 && count[2] == 0)
        rc = rths_config_error_at(cfg, section, err,
                                  "give mass_kg or rotary_inertia_kg_m2 (one per position_m)");
    for (int i = 1; i < 3 && !rc; i++)
        if (count[i] && count[i] != count[0])
            rc = rths_config_error_at(cfg, k[i], err,
                                      "has %d entries but %s has %d: one per point mass", count[i],
                                      k[0], count[0]);
    if (!rc && count[0]) {
        in->point_masses = calloc((size_t)count[0], sizeof *in->point_masses);
        if (!in->point_masses) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int i = 0; i < count[0] && !rc; i++)
        in->point_masses[i] =
            (rths_beam_point_mass){v[0][i], count[1] ? v[1][i] : 0.0, count[2] ? v[2][i] : 0.0};
    if (!rc) in->spec.n_point_masses = count[0], in->spec.point_masses = in->point_masses;
    for (int i = 0; i < 3; i++)
        free(v[i]);
    return rc;
}

/* Rayleigh damping as (alpha_per_s, beta_s) or as two (frequencies_hz, ratios) pairs. */
static int read_rayleigh(rths_config *cfg, const char *key, beam_input *in, rths_error *err) {
    char ka[KEY_LEN], kb[KEY_LEN], kf[KEY_LEN], kr[KEY_LEN];
    subkey(ka, key, "damping.alpha_per_s");
    subkey(kb, key, "damping.beta_s");
    subkey(kf, key, "damping.frequencies_hz");
    subkey(kr, key, "damping.ratios");
    rths_beam_damping *d = &in->spec.damping;
    int coefficients = rths_config_has(cfg, ka) || rths_config_has(cfg, kb);
    if (coefficients && rths_config_has(cfg, kf))
        return rths_config_error_at(cfg, kf, err,
                                    "give either alpha_per_s and beta_s or frequencies_hz and "
                                    "ratios, not both");
    if (coefficients) {
        int rc = rths_config_get_double(cfg, ka, 0, 0, 0, INFINITY, &d->alpha_per_s, err);
        if (!rc) rc = rths_config_get_double(cfg, kb, 0, 0, 0, INFINITY, &d->beta_s, err);
        return rc;
    }
    double *f = NULL;
    int nf = 0, nr = 0;
    int rc = rths_config_get_double_list(cfg, kf, 1, &f, &nf, err);
    if (!rc) rc = rths_config_get_double_list(cfg, kr, 1, &in->ratios, &nr, err);
    if (!rc && nf != 2)
        rc = rths_config_error_at(cfg, kf, err, "needs exactly 2 frequencies (got %d)", nf);
    if (!rc && nr != 2)
        rc = rths_config_error_at(cfg, kr, err,
                                  "needs exactly 2 ratios, one per frequency (got %d)", nr);
    if (!rc) {
        rths_error local;
        if (rths_beam_rayleigh_from_pairs(f[0], in->ratios[0], f[1], in->ratios[1], &d->alpha_per_s,
                                          &d->beta_s, &local))
            rc = rths_config_error_at(cfg, kf, err, "%s", local.msg);
    }
    free(f);
    return rc;
}

static int read_damping(rths_config *cfg, const char *key, beam_input *in, rths_error *err) {
    static const char *const models[] = {"none", "modal", "rayleigh", NULL};
    char km[KEY_LEN], kz[KEY_LEN], kr[KEY_LEN];
    subkey(km, key, "damping.model");
    subkey(kz, key, "damping.ratio");
    subkey(kr, key, "damping.ratios");
    int model = 0;
    rths_beam_damping *d = &in->spec.damping;
    int rc = rths_config_get_choice(cfg, km, 0, 0, models, &model, err);
    if (rc) return rc;
    d->model = (rths_beam_damping_model)model;
    if (d->model == RTHS_BEAM_DAMPING_RAYLEIGH) return read_rayleigh(cfg, key, in, err);
    if (d->model != RTHS_BEAM_DAMPING_MODAL) return RTHS_OK;
    int has_ratio = rths_config_has(cfg, kz);
    rc = rths_config_get_double_list(cfg, kr, 0, &in->ratios, &d->n_ratios, err);
    d->ratios = in->ratios;
    if (!rc && !has_ratio && d->n_ratios == 0)
        rc = rths_config_error_at(cfg, km, err,
                                  "modal damping needs damping.ratio (every mode) or "
                                  "damping.ratios (one per mode from the lowest)");
    /* modes past the list keep the last listed ratio unless damping.ratio says otherwise */
    double def = d->n_ratios ? d->ratios[d->n_ratios - 1] : 0.0;
    if (!rc) rc = rths_config_get_double(cfg, kz, 0, def, -INFINITY, INFINITY, &d->ratio, err);
    return rc;
}

int rths_beam_config_read(rths_config *cfg, const char *key, rths_beam *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    if (!rths_config_has(cfg, key))
        return rths_config_error_at(cfg, key, err,
                                    "is required but missing (segments, clamped_m, ...: see "
                                    "docs/config/beam.md)");
    beam_input in;
    memset(&in, 0, sizeof in);
    int rc = read_segments(cfg, key, &in, err);
    if (!rc) rc = read_supports(cfg, key, &in, err);
    if (!rc) rc = read_point_masses(cfg, key, &in, err);
    if (!rc) rc = read_damping(cfg, key, &in, err);
    if (!rc) {
        beam_fault f;
        rc = assemble(&in.spec, out, &f, err);
        if (rc && f.what[0]) {
            char k[KEY_LEN];
            subkey(k, key, field_key[f.field]);
            rc = rths_config_error_at(cfg, k, err, "%s", f.what);
        }
        if (rc) rths_beam_free(out);
    }
    beam_input_free(&in);
    return rc;
}
