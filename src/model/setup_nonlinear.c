/* Nonlinear elements of a test configuration (structure.bilinear, structure.nonlinear): each read
 * and checked against its key, placed on the side of the split its DoFs lie on. Part of setup.c's
 * reading (setup_internal.h). */
#include "rths/setup.h"

#include "setup_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The side of an element joining DoFs i and j (0-based, j = -1 the ground): numerical when it
 * touches a numerical DoF, physical when it touches a physical one (both: refused, an element
 * cannot bridge the split), else (interface DoFs and the ground only) side_key's choice, by
 * default physical. */
static int element_side(rths_config *cfg, const rths_setup *s, const char *key,
                        const char *side_key, int i, int j, int *numerical, rths_error *err) {
    int touches_num = 0, touches_phys = 0;
    int dofs[2] = {i, j};
    for (int k = 0; k < 2; k++) {
        if (dofs[k] < 0) continue;
        touches_num |= s->roles[dofs[k]] == RTHS_DOF_NUMERICAL;
        touches_phys |= s->roles[dofs[k]] == RTHS_DOF_PHYSICAL;
    }
    if (touches_num && touches_phys)
        return rths_config_error_at(cfg, key, err,
                                    "joins physical DoF and numerical DoF (%d and %d): an element "
                                    "lies on one side of the split; place the interface between "
                                    "them",
                                    i + 1, j + 1);
    static const char *const sides[] = {"physical", "numerical", NULL};
    int side = touches_num ? 1 : 0;
    if (side_key && rths_config_has(cfg, side_key)) {
        int rc = rths_config_get_choice(cfg, side_key, 0, side, sides, &side, err);
        if (rc) return rc;
        if ((touches_num && side != 1) || (touches_phys && side != 0))
            return rths_config_error_at(
                cfg, side_key, err, "the element touches a %s DoF, so it is on the %s side",
                touches_num ? "numerical" : "physical", touches_num ? "numerical" : "physical");
    }
    *numerical = side;
    return RTHS_OK;
}

/* The stiffness of the chain's leg below storey upper (0-based): minus the coupling term, or the
 * ground term for storey 1. */
static double chain_leg_stiffness(const rths_setup *s, int upper) {
    int n = s->assembly.n;
    return upper > 0 ? -RTHS_AT(s->assembly.stiffness, n, upper - 1, upper)
                     : RTHS_AT(s->assembly.stiffness, n, 0, 0) -
                           (n > 1 ? -RTHS_AT(s->assembly.stiffness, n, 0, 1) : 0.0);
}

int rths_setup_read_bilinear(rths_config *cfg, rths_setup *s, rths_error *err) {
    int n = s->assembly.n;
    s->static_force = calloc((size_t)n, sizeof *s->static_force);
    if (!s->static_force) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int enabled = 0;
    int rc = rths_config_get_bool(cfg, "structure.bilinear.enabled", 0, 0, &enabled, err);
    long storey = 0;
    double ratio = 2.0, preload = 26.68;
    /* defaults are the seed's: the leg below the (first) interface storey, twice as stiff in
     * compression, preloaded by 26.68 N so the static point sits on the stiff side */
    long def_storey = s->split.n_int > 0 ? s->split.int_dofs[0] + 1 : 1;
    if (!rc)
        rc = rths_config_get_int(cfg, "structure.bilinear.storey", 0, def_storey, 1, n, &storey,
                                 err);
    if (!rc)
        rc = rths_config_get_double(cfg, "structure.bilinear.compression_ratio", 0, 2.0, 1e-3, 1e3,
                                    &ratio, err);
    if (!rc)
        rc = rths_config_get_double(cfg, "structure.bilinear.preload_n", 0, 26.68, 0, 1e6, &preload,
                                    err);
    if (rc || !enabled) return rc;
    if (!s->chain)
        return rths_config_error_at(cfg, "structure.bilinear", err,
                                    "a bilinear leg needs the structure as a storey chain");
    int upper = (int)storey - 1, numerical = 0;
    rc = element_side(cfg, s, "structure.bilinear.storey", NULL, upper, upper - 1, &numerical, err);
    if (rc) return rc;
    s->has_bilinear = 1;
    s->leg.lower_dof = upper - 1;
    s->leg.upper_dof = upper;
    s->leg.stiffness_n_per_m = chain_leg_stiffness(s, upper);
    s->leg.ratio = ratio;
    s->preload_n = preload;
    s->nonlinear[0] = rths_nl_from_leg(&s->leg);
    s->nonlinear[0].numerical = numerical;
    s->n_nonlinear = 1;
    /* The preload pushes the leg's upper storey down, compressing the leg when ratio > 1 (stiff
     * side), stretching it when ratio < 1: either way toward the stiffer slope. On the physical
     * side it is the shaker's, on the interface (the seed's); on the numerical side a static
     * force on the leg's upper storey (on the interface it would leave that leg unstressed). */
    s->static_force[numerical ? upper : s->split.int_dofs[0]] = ratio >= 1 ? -preload : preload;
    return RTHS_OK;
}

/* "structure.nonlinear.<index>.<name>" into buf (96 bytes) */
static void item_key(char *buf, int index, const char *name) {
    snprintf(buf, 96, "structure.nonlinear.%d.%.40s", index, name);
}

/* structure.nonlinear.N.nodes_m: an element of a structure.beam placed by its nodes' positions
 * (m from x = 0), [x_i, x_j] or [x_i] (to the ground), on the DoF node_dof (w, default, or theta)
 * of each: *dofs becomes the 1-based DoFs [i, j] (j = 0: the ground), as the key dofs gives
 * them (docs/config.md, "Nonlinear elements"). */
static int read_element_nodes(rths_config *cfg, const rths_setup *s, const char *k_nodes,
                              const char *k_kind, int **dofs, int *count, rths_error *err) {
    static const char *const kinds[] = {"w", "theta", NULL};
    if (!s->beam)
        return rths_config_error_at(cfg, k_nodes, err,
                                    "places an element by beam node positions: the structure "
                                    "must be a structure.beam (else give dofs: [i, j])");
    int kind = 0, n_pos = 0;
    double *pos = NULL;
    int rc = rths_config_get_choice(cfg, k_kind, 0, 0, kinds, &kind, err);
    if (!rc) rc = rths_config_get_double_list(cfg, k_nodes, 1, &pos, &n_pos, err);
    if (!rc && (n_pos < 1 || n_pos > 2))
        rc = rths_config_error_at(cfg, k_nodes, err,
                                  "lists %d positions: give [x_i, x_j] (m), or [x_i] for an "
                                  "element to the ground",
                                  n_pos);
    *count = 2;
    *dofs = rc ? NULL : calloc(2, sizeof(int));
    if (!rc && !*dofs) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int t = 0; t < n_pos && !rc; t++) {
        int dof = rths_beam_find_dof(s->beam, pos[t], kind ? RTHS_BEAM_THETA : RTHS_BEAM_W);
        if (dof >= 0) {
            (*dofs)[t] = dof + 1;
            continue;
        }
        const rths_beam *b = s->beam;
        int near = 0;
        for (int i = 1; i < b->n_nodes; i++)
            if (fabs(b->node_position_m[i] - pos[t]) < fabs(b->node_position_m[near] - pos[t]))
                near = i;
        rc = rths_config_error_at(cfg, k_nodes, err,
                                  "entry %d: no free %s DoF at %g m (nearest node at %g m; a "
                                  "clamp fixes w and theta, a pin w)",
                                  t + 1, kinds[kind], pos[t], b->node_position_m[near]);
    }
    free(pos);
    if (rc) {
        free(*dofs);
        *dofs = NULL;
    }
    return rc;
}

/* structure.nonlinear.N: one element (nonlinear.h). */
static int read_element(rths_config *cfg, rths_setup *s, int index, rths_error *err) {
    static const char *const types[] = {"bilinear", "cubic", "gap", "friction", NULL};
    int n = s->assembly.n;
    char key[96], k_dofs[96], k_side[96], k_a[96], k_b[96], k_c[96];
    snprintf(key, sizeof key, "structure.nonlinear.%d", index);
    item_key(k_dofs, index, "dofs");
    item_key(k_side, index, "side");
    int type = 0, *dofs = NULL, count = 0;
    item_key(k_a, index, "type");
    int rc = rths_config_get_choice(cfg, k_a, 1, 0, types, &type, err);
    char k_nodes[96];
    item_key(k_nodes, index, "nodes_m");
    item_key(k_b, index, "node_dof");
    int by_node = rths_config_has(cfg, k_nodes);
    if (!rc && by_node && rths_config_has(cfg, k_dofs))
        rc = rths_config_error_at(cfg, k_nodes, err,
                                  "and %s both place the element: give one of them", k_dofs);
    else if (!rc && !by_node && rths_config_has(cfg, k_b))
        rc = rths_config_error_at(cfg, k_b, err, "needs %s (beam node positions)", k_nodes);
    if (!rc && by_node) {
        rc = read_element_nodes(cfg, s, k_nodes, k_b, &dofs, &count, err);
        snprintf(k_dofs, sizeof k_dofs, "%s", k_nodes); /* later messages name the key given */
    } else if (!rc)
        rc = rths_config_get_int_list(cfg, k_dofs, 1, &dofs, &count, err);
    if (!rc && count != 2)
        rc = rths_config_error_at(cfg, k_dofs, err,
                                  "lists %d DoFs: give two, [i, j] (1-based; j = 0 for the "
                                  "ground)",
                                  count);
    if (!rc && (dofs[0] < 1 || dofs[0] > n || dofs[1] < 0 || dofs[1] > n))
        rc = rths_config_error_at(cfg, k_dofs, err,
                                  "[%d, %d]: i must be in 1..%d and j in 0..%d (0: the ground)",
                                  dofs[0], dofs[1], n, n);
    if (!rc && dofs[0] == dofs[1])
        rc = rths_config_error_at(cfg, k_dofs, err, "joins DoF %d to itself", dofs[0]);
    if (rc) {
        free(dofs);
        return rc;
    }
    if (s->n_nonlinear >= RTHS_MAX_NONLINEAR) {
        free(dofs);
        return rths_config_error_at(cfg, key, err,
                                    "more than %d nonlinear elements (RTHS_MAX_NONLINEAR in "
                                    "nonlinear.h; structure.bilinear counts as one)",
                                    RTHS_MAX_NONLINEAR);
    }
    rths_nl_element e = {.type = (rths_nl_type)type, .dof_i = dofs[0] - 1, .dof_j = dofs[1] - 1};
    free(dofs);
    rc = element_side(cfg, s, k_dofs, k_side, e.dof_i, e.dof_j, &e.numerical, err);
    double preload = 0;
    switch (e.type) {
    case RTHS_NL_BILINEAR: {
        /* the extension stiffness is part of the structure: a chain's leg when the element joins
         * adjacent storeys (or storey 1 and the ground), else given */
        int chain_leg = s->chain && (e.dof_j == e.dof_i - 1);
        item_key(k_a, index, "stiffness_n_per_m");
        item_key(k_b, index, "compression_ratio");
        item_key(k_c, index, "preload_n");
        double k_leg = chain_leg ? chain_leg_stiffness(s, e.dof_i) : 0, ratio = 2.0;
        if (!rc && !chain_leg && !rths_config_has(cfg, k_a))
            rc = rths_config_error_at(cfg, key, err,
                                      "a bilinear element between DoFs %d and %d needs "
                                      "stiffness_n_per_m (its extension stiffness, part of the "
                                      "structure's K); only a chain's leg between adjacent storeys "
                                      "takes it from the chain",
                                      e.dof_i + 1, e.dof_j + 1);
        if (!rc)
            rc = rths_config_get_double_ex(cfg, k_a, 0, k_leg, 0, 1e12, RTHS_CONFIG_LO_OPEN, &k_leg,
                                           err);
        if (!rc) rc = rths_config_get_double(cfg, k_b, 0, 2.0, 1e-3, 1e3, &ratio, err);
        if (!rc) rc = rths_config_get_double(cfg, k_c, 0, 0.0, 0, 1e6, &preload, err);
        e.leg_stiffness_n_per_m = k_leg;
        e.ratio = ratio;
        e.k = (ratio - 1) * k_leg;
        if (ratio < 1) preload = -preload; /* toward the stiffer slope: stretching */
        break;
    }
    case RTHS_NL_CUBIC:
        item_key(k_a, index, "stiffness_n_per_m3");
        if (!rc) rc = rths_config_get_double(cfg, k_a, 1, 0, -1e18, 1e18, &e.k, err);
        if (!rc && e.k == 0) rc = rths_config_error_at(cfg, k_a, err, "must not be 0");
        break;
    case RTHS_NL_GAP:
        item_key(k_a, index, "stiffness_n_per_m");
        item_key(k_b, index, "clearance_m");
        if (!rc)
            rc = rths_config_get_double_ex(cfg, k_a, 1, 0, 0, 1e12, RTHS_CONFIG_LO_OPEN, &e.k, err);
        if (!rc) rc = rths_config_get_double(cfg, k_b, 1, 0, 0, 1, &e.clearance_m, err);
        break;
    case RTHS_NL_FRICTION:
        item_key(k_a, index, "slip_force_n");
        item_key(k_b, index, "regularisation_m_s");
        if (!rc)
            rc = rths_config_get_double_ex(cfg, k_a, 1, 0, 0, 1e6, RTHS_CONFIG_LO_OPEN, &e.force_n,
                                           err);
        if (!rc) /* below 1e-9 m/s the smoothed sign is a step no integrator resolves */
            rc = rths_config_get_double(cfg, k_b, 0, 1e-3, 1e-9, 1e3, &e.v_reg_m_s, err);
        break;
    default:
        break;
    }
    if (rc) return rc;
    /* a preload pushes DoF i toward j (compressing the element) */
    s->static_force[e.dof_i] -= preload;
    if (e.dof_j >= 0) s->static_force[e.dof_j] += preload;
    s->nonlinear[s->n_nonlinear++] = e;
    s->has_bilinear = 1;
    return RTHS_OK;
}

int rths_setup_read_nonlinear(rths_config *cfg, rths_setup *s, rths_error *err) {
    int count = 0;
    int rc = rths_config_get_count(cfg, "structure.nonlinear", &count, err);
    for (int i = 0; i < count && !rc; i++)
        rc = read_element(cfg, s, i, err);
    return rc;
}

int rths_setup_nonlinear_count(const rths_setup *s, int numerical) {
    int count = 0;
    for (int e = 0; e < s->n_nonlinear; e++)
        count += s->nonlinear[e].numerical == numerical;
    return count;
}

/* split.numerical_solver: frequency takes nonlinear elements on the numerical side: the host
 * solves the substructure by harmonic balance, motion-to-force (docs/method.md, "Nonlinear
 * elements in the frequency form"); nothing left to refuse here (the sparse path refuses
 * elements when it reads the structure). */
int rths_setup_check_solver_nonlinear(rths_config *cfg, const rths_setup *s, rths_error *err) {
    (void)cfg, (void)s, (void)err;
    return RTHS_OK;
}
