/* rths_setup_read on the sparse path (setup.h: setup->sparse) against the dense path on the same
 * Matrix Market files: issue 26's 482-DoF frame (tools/gen_frame3d.py --nx 4 --ny 4 --nz 5
 * --specimen 2000 3e5), split.numerical_solver: frequency, read once with model.solver: sparse and
 * once with model.solver: dense (rths_split_create on the dense assembly, the independent truth):
 *  - the sparse setup forms no dense matrix (assembly and numerical side NULL) and its split has
 *    the dense split's DoF lists, sizes and p;
 *  - its physical side equals the dense split's to 1e-12 relative (the same sums, in another
 *    order), with the coupling rule and with given interface shares of C and K;
 *  - the rig's interface mass and the controller's compensation equal the dense ones (full and
 *    physical_share), the force vector is the same;
 *  - the truth (sparse direct solves) at the reported DoFs equals the dense solve of the assembly
 *    to 1e-9 relative (LDL^T and LU round differently, ~1e-12 measured) at three frequencies;
 *  - the real-time form is read too, with no dense numerical side. */
#include "testlib.h"

#include "rths/config.h"
#include "rths/setup.h"
#include "rths/truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void load(const char *path, const char *solver, int shares, const char *mass_mode,
                 rths_setup *s) {
    char k1[64], k2[64];
    snprintf(k1, sizeof k1, "model.solver=%s", solver);
    snprintf(k2, sizeof k2, "rig.interface_mass=%s", mass_mode);
    const char *sets[] = {k1, "split.numerical_solver=frequency", k2,
                          "split.interface_stiffness_physical_n_per_m=[[3.0e5]]",
                          "split.interface_damping_physical_n_s_per_m=[[30.0]]"};
    rths_config *cfg;
    rths_error err;
    if (rths_config_load(path, sets, shares ? 5 : 3, &cfg, &err)) fail_msg("%s", err.msg);
    if (rths_setup_read(cfg, s, &err)) fail_msg("%s", err.msg);
    rths_config_free(cfg);
}

static void compare(const char *path, int shares, const char *mass_mode) {
    rths_setup sp, de;
    load(path, "sparse", shares, mass_mode, &sp);
    load(path, "dense", shares, mass_mode, &de);
    assert_non_null(sp.sparse);
    assert_null(de.sparse);
    assert_null(sp.assembly.mass);
    assert_null(sp.split.mass_num);
    const rths_split *a = &sp.split, *b = &de.split;
    assert_int_equal(sp.assembly.n, de.assembly.n);
    assert_int_equal(a->n_phys, b->n_phys);
    assert_int_equal(a->n_int, b->n_int);
    assert_int_equal(a->n_num, b->n_num);
    assert_int_equal(a->np, b->np);
    assert_int_equal(a->nn, b->nn);
    assert_close(a->mass_ratio, b->mass_ratio, 0);
    for (int i = 0; i < a->n_phys; i++)
        assert_int_equal(a->phys_dofs[i], b->phys_dofs[i]);
    assert_int_equal(a->int_dofs[0], b->int_dofs[0]);
    const double *pa[3] = {a->mass_phys, a->damping_phys, a->stiffness_phys},
                 *pb[3] = {b->mass_phys, b->damping_phys, b->stiffness_phys};
    for (int t = 0; t < 3; t++) {
        double scale = rths_mat_max_abs(pb[t], b->np, b->np);
        for (int e = 0; e < b->np * b->np; e++)
            assert_close(pa[t][e], pb[t][e], 1e-12 * scale);
    }
    assert_rel(rths_setup_rig_interface_mass(&sp, 0, 0), rths_setup_rig_interface_mass(&de, 0, 0),
               1e-14);
    assert_close(rths_setup_compensation_mass(&sp, 0, 0), rths_setup_compensation_mass(&de, 0, 0),
                 1e-12 * rths_setup_rig_interface_mass(&de, 0, 0));
    assert_int_equal(sp.forcing_dof, de.forcing_dof);
    for (int i = 0; i < de.assembly.n; i++)
        assert_close(sp.force[i], de.force[i], 0);
    int count = 0;
    int *dofs = rths_setup_output_dofs(&de, &count);
    double *amp[2] = {malloc(sizeof(double) * (size_t)count),
                      malloc(sizeof(double) * (size_t)count)};
    double *ph[2] = {malloc(sizeof(double) * (size_t)count),
                     malloc(sizeof(double) * (size_t)count)};
    const double freqs[3] = {0.5, 1.0911, 2.3};
    for (int f = 0; f < 3; f++) {
        assert_int_equal(rths_truth_linear_dofs_response(&sp, freqs[f], count, dofs, amp[0], ph[0]),
                         0);
        assert_int_equal(rths_truth_linear_dofs_response(&de, freqs[f], count, dofs, amp[1], ph[1]),
                         0);
        for (int i = 0; i < count; i++) {
            assert_rel(amp[0][i], amp[1][i], 1e-9);
            assert_close(ph[0][i], ph[1][i], 1e-9);
        }
    }
    for (int k = 0; k < 2; k++) {
        free(amp[k]);
        free(ph[k]);
    }
    free(dofs);
    rths_setup_free(&sp);
    rths_setup_free(&de);
}

static void test_sparse_setup_matches_dense(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_test_sparse_setup_XXXXXX", cmd[512], path[96];
    assert_non_null(mkdtemp(dir));
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 %s --nx 4 --ny 4 --nz 5 --seed 1 --specimen 2000 3e5 %s >/dev/null",
             rths_test_source_path("tools/gen_frame3d.py"), dir);
    assert_int_equal(system(cmd), 0);
    snprintf(path, sizeof path, "%s/frame.yaml", dir);
    compare(path, 0, "full");
    compare(path, 1, "full");
    compare(path, 1, "physical_share");
    /* the real-time form on the sparse path: read, with no dense numerical side (the controller
     * integrates its Krylov reduction: test_sparse_realtime.c) */
    const char *sets[] = {"model.solver=sparse", "split.numerical_solver=realtime"};
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (rths_config_load(path, sets, 2, &cfg, &err)) fail_msg("%s", err.msg);
    if (rths_setup_read(cfg, &s, &err)) fail_msg("%s", err.msg);
    assert_non_null(s.sparse);
    assert_null(s.split.mass_num);
    rths_setup_free(&s);
    rths_config_free(cfg);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sparse_setup_matches_dense),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
