/* Nonlinear elements of a structure.beam placed by node (structure.nonlinear.N.nodes_m, issue 27;
 * docs/config.md, "Nonlinear elements"): on examples/cantilever_strip.yaml (clamped at x = 0,
 * 10 mm elements, the cut at 0.17 m) an element given by node positions lands on the DoFs
 * rths_beam_find_dof names (w by default, theta with node_dof: theta; one position: to the ground)
 * and on the side those DoFs lie on, exactly as the same element given by dofs; positions off the
 * nodes, on the clamp, on a storey chain, and both keys at once are refused naming the key. */
#include "testlib.h"

#include "rths/setup.h"

#include <string.h>

static int load(const char *override, rths_config **cfg, rths_setup *s, rths_error *err) {
    const char *ov[] = {override};
    int rc =
        rths_config_load(rths_test_source_path("examples/cantilever_strip.yaml"), ov, 1, cfg, err);
    if (rc) return rc;
    rc = rths_setup_read(*cfg, s, err);
    if (rc) rths_config_free(*cfg);
    return rc;
}

static void test_placed_by_node(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    /* a cubic spring between the nodes at 0.3 and 0.35 m (physical part), a friction element on
     * the rotations at 0.05 and 0.1 m (numerical part), a gap from the node at 0.12 m to the
     * ground */
    if (load("structure.nonlinear=[{type: cubic, nodes_m: [0.3, 0.35], stiffness_n_per_m3: 1e9}, "
             "{type: friction, nodes_m: [0.05, 0.1], node_dof: theta, slip_force_n: 0.01}, "
             "{type: gap, nodes_m: [0.12], stiffness_n_per_m: 1e4, clearance_m: 1e-3}]",
             &cfg, &s, &err))
        fail_msg("%s", err.msg);
    assert_int_equal(s.n_nonlinear, 3);
    assert_non_null(s.beam);
    /* clamped at 0: node i at x = 0.01 i has w = DoF 2i - 1, theta = DoF 2i (1-based) */
    rths_nl_element e[3];
    memcpy(e, s.nonlinear, sizeof e);
    assert_int_equal(e[0].dof_i, rths_beam_find_dof(s.beam, 0.3, RTHS_BEAM_W));
    assert_int_equal(e[0].dof_i, 2 * 30 - 2);
    assert_int_equal(e[0].dof_j, 2 * 35 - 2);
    assert_int_equal(e[0].numerical, 0); /* beyond the cut at 0.17 m: physical */
    assert_int_equal(e[1].dof_i, 2 * 5 - 1);
    assert_int_equal(e[1].dof_j, 2 * 10 - 1);
    assert_int_equal(e[1].numerical, 1);
    assert_int_equal(e[2].dof_i, 2 * 12 - 2);
    assert_int_equal(e[2].dof_j, -1);
    assert_int_equal(e[2].numerical, 1);
    rths_setup_free(&s);
    rths_config_free(cfg);
    /* the same elements by dofs give the same setup */
    rths_setup t;
    if (load("structure.nonlinear=[{type: cubic, dofs: [59, 69], stiffness_n_per_m3: 1e9}, "
             "{type: friction, dofs: [10, 20], slip_force_n: 0.01}, "
             "{type: gap, dofs: [23, 0], stiffness_n_per_m: 1e4, clearance_m: 1e-3}]",
             &cfg, &t, &err))
        fail_msg("%s", err.msg);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(t.nonlinear[i].dof_i, e[i].dof_i);
        assert_int_equal(t.nonlinear[i].dof_j, e[i].dof_j);
        assert_int_equal(t.nonlinear[i].numerical, e[i].numerical);
    }
    rths_setup_free(&t);
    rths_config_free(cfg);
}

static void expect_refused(const char *path, const char *override, const char *fragment) {
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    const char *ov[] = {override};
    int rc = rths_config_load(rths_test_source_path(path), ov, 1, &cfg, &err);
    assert_int_equal(rc, RTHS_OK);
    rc = rths_setup_read(cfg, &s, &err);
    print_message("%s -> %s\n", override, err.msg);
    assert_int_equal(rc, RTHS_EINPUT);
    if (!strstr(err.msg, fragment)) fail_msg("'%s' not in '%s'", fragment, err.msg);
    rths_config_free(cfg);
}

static void test_refusals(void **state) {
    (void)state;
    const char *beam = "examples/cantilever_strip.yaml";
    expect_refused(beam,
                   "structure.nonlinear=[{type: cubic, nodes_m: [0.305, 0.35], "
                   "stiffness_n_per_m3: 1e9}]",
                   "key 'structure.nonlinear.0.nodes_m': entry 1: no free w DoF at 0.305 m "
                   "(nearest node at 0.3");
    expect_refused(beam,
                   "structure.nonlinear=[{type: cubic, nodes_m: [0, 0.35], "
                   "stiffness_n_per_m3: 1e9}]",
                   "entry 1: no free w DoF at 0 m");
    expect_refused(beam,
                   "structure.nonlinear=[{type: cubic, nodes_m: [0.3, 0.35], dofs: [59, 69], "
                   "stiffness_n_per_m3: 1e9}]",
                   "give one of them");
    expect_refused(beam,
                   "structure.nonlinear=[{type: cubic, nodes_m: [0.1, 0.2, 0.3], "
                   "stiffness_n_per_m3: 1e9}]",
                   "lists 3 positions");
    expect_refused(beam,
                   "structure.nonlinear=[{type: cubic, nodes_m: [0.1, 0.3], "
                   "stiffness_n_per_m3: 1e9}]",
                   "joins physical DoF and numerical DoF");
    expect_refused(beam,
                   "structure.nonlinear=[{type: cubic, dofs: [59, 69], node_dof: theta, "
                   "stiffness_n_per_m3: 1e9}]",
                   "key 'structure.nonlinear.0.node_dof': needs");
    expect_refused("examples/four_storey.yaml",
                   "structure.nonlinear=[{type: cubic, nodes_m: [0.3, 0.35], "
                   "stiffness_n_per_m3: 1e9}]",
                   "must be a structure.beam");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_placed_by_node),
        cmocka_unit_test(test_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
