/* The frequency form on a sparse model (model.h: rths_sparse_model_receptance; the truth by
 * rths_sparse_frf_direct), on issue 26's 482-DoF frame (tools/gen_frame3d.py --nx 4 --ny 4 --nz 5,
 * a two-storey specimen on the rig tied to ux of a roof node), with the force on the opposite
 * roof node and under base excitation, against dense LAPACK solves of the same matrices:
 *  - the numerical side's interface receptance h and the forcing's interface response per unit
 *    amplitude from one sparse complex solve: equal to the dense solves of the numerical side
 *    D_num x = e_b and D_num x = f_num to 1e-9 relative (both direct solves of one 480 x 480
 *    system; LDL^T and LU round differently, ~1e-12 measured);
 *  - the truth (the assembly's interface response, one sparse complex solve of the whole model
 *    per frequency): equal to the dense solve of the assembly to 1e-9;
 *  - what the frequency form converges to (the physical side, the model minus the numerical
 *    side, closed by the numerical side condensed on the interface, 1 / h, with its blocked force
 *    forced / h): equal to the truth to 1e-9, the hybrid test's target being exact;
 *  - the symbolic analysis runs once for every frequency. */
#include "testlib.h"

#include "rths/config.h"
#include "rths/model.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { POINTS = 9 };

static double rel(double complex a, double complex b) {
    return cabs(a - b) / cabs(b);
}

static void run_case(const char *dir, int base) {
    char path[160];
    snprintf(path, sizeof path, "%s/%s", dir, base ? "base.yaml" : "frame.yaml");
    const char *sets[] = {"model.solver=sparse"};
    rths_config *cfg;
    rths_model_choice choice;
    rths_sparse_model m;
    rths_error err;
    if (rths_config_load(path, sets, 1, &cfg, &err)) fail_msg("%s", err.msg);
    if (rths_model_choose_solver(cfg, &choice, &err)) fail_msg("%s", err.msg);
    if (rths_sparse_model_read(cfg, &choice, &m, &err)) fail_msg("%s", err.msg);
    assert_int_equal(m.base_excitation, base);
    const int n = m.n, b = m.int_dofs[0];
    const double amp = m.forcing_amplitude_n;

    rths_sparse_model_receptance *rec;
    if (rths_sparse_model_receptance_create(&m, &rec, &err)) fail_msg("%s", err.msg);
    rths_sparse_frf *truth;
    if (rths_sparse_frf_create(&m, NULL, 1, &b, &truth, &err)) fail_msg("%s", err.msg);

    /* dense: the assembly, the numerical side (its order), the numerical side's load */
    double *full[3] = {rths_sparse_to_dense(&m.mass), rths_sparse_to_dense(&m.damping),
                       rths_sparse_to_dense(&m.stiffness)};
    rths_sparse_sym ns[3];
    int *dofs, nn;
    if (rths_sparse_model_numerical_side(&m, &ns[0], &ns[1], &ns[2], &dofs, &nn, &err))
        fail_msg("%s", err.msg);
    double *num[3];
    for (int t = 0; t < 3; t++)
        num[t] = rths_sparse_to_dense(&ns[t]);
    double *f_num = calloc((size_t)nn, sizeof(double));
    for (int i = 0; i < nn; i++)
        if (base)
            for (int j = 0; j < nn; j++)
                f_num[i] -= RTHS_AT(num[0], nn, i, j);
        else
            f_num[i] = dofs[i] == m.forcing_dof;
    /* the physical side: [interface, physical DoFs] of the model minus the numerical side */
    int ad[8], na = 0;
    ad[na++] = b;
    for (int i = 0; i < n; i++)
        if (m.roles[i] == RTHS_DOF_PHYSICAL) ad[na++] = i;
    assert_int_equal(na, 3);
    double rest[3][9], f_rest[3];
    for (int t = 0; t < 3; t++)
        for (int j = 0; j < na; j++)
            for (int i = 0; i < na; i++)
                rest[t][i + 3 * j] = RTHS_AT(full[t], n, ad[i], ad[j]) -
                                     (i == 0 && j == 0 ? RTHS_AT(num[t], nn, 0, 0) : 0);
    for (int i = 0; i < na; i++)
        f_rest[i] = m.force[ad[i]] - (i == 0 ? amp * f_num[0] : 0);

    /* the physical side as the dense split makes it (rths_split_create on the dense assembly),
     * order (physical, interface): rths_sparse_model_physical_side gives the same sums */
    {
        rths_assembly a;
        if (rths_assembly_from_matrices(n, full[0], full[1], full[2], &a, &err))
            fail_msg("%s", err.msg);
        rths_split split;
        if (rths_split_create(&a, m.roles, m.mass_ratio, NULL, NULL, &split, &err))
            fail_msg("%s", err.msg);
        double *pm[3];
        int np;
        if (rths_sparse_model_physical_side(&m, 100, &pm[0], &pm[1], &pm[2], &np, &err))
            fail_msg("%s", err.msg);
        assert_int_equal(np, split.np);
        const double *want[3] = {split.mass_phys, split.damping_phys, split.stiffness_phys};
        for (int t = 0; t < 3; t++) {
            double scale = rths_mat_max_abs(want[t], np, np);
            for (int e = 0; e < np * np; e++)
                if (fabs(pm[t][e] - want[t][e]) > 1e-14 * scale)
                    fail_msg("physical side %d entry %d: %.17g, dense split %.17g", t, e, pm[t][e],
                             want[t][e]);
            free(pm[t]);
        }
        assert_int_equal(rths_sparse_model_physical_side(&m, 2, &pm[0], &pm[1], &pm[2], &np, &err),
                         RTHS_EINPUT);
        assert_non_null(strstr(err.msg, "split.physical"));
        rths_split_free(&split);
        rths_assembly_free(&a);
    }
    double complex *d = malloc(sizeof *d * (size_t)n * n), *x = malloc(sizeof *x * (size_t)n);
    double worst[4] = {0};
    for (int p = 0; p < POINTS; p++) {
        double w = 2 * M_PI * (0.4 + 0.25 * p); /* 0.4-2.4 Hz: the frame's modes 1-11 */
        double complex h, forced, t_sparse;
        if (rths_sparse_model_receptance_eval(rec, w, &h, &forced, &err)) fail_msg("%s", err.msg);
        if (rths_sparse_frf_direct(truth, w, &t_sparse, &err)) fail_msg("%s", err.msg);
        /* dense numerical side: e_b and f_num */
        for (int rhs = 0; rhs < 2; rhs++) {
            for (size_t e = 0; e < (size_t)nn * nn; e++)
                d[e] = num[2][e] + I * w * num[1][e] - w * w * num[0][e];
            for (int i = 0; i < nn; i++)
                x[i] = rhs ? f_num[i] : (i == 0);
            assert_int_equal(rths_cmat_solve(nn, 1, d, x), 0);
            double e = rel(rhs ? forced : h, x[0]);
            if (e > worst[rhs]) worst[rhs] = e;
        }
        /* dense assembly */
        for (size_t e = 0; e < (size_t)n * n; e++)
            d[e] = full[2][e] + I * w * full[1][e] - w * w * full[0][e];
        for (int i = 0; i < n; i++)
            x[i] = m.force[i];
        assert_int_equal(rths_cmat_solve(n, 1, d, x), 0);
        double complex t_dense = x[b];
        if (rel(t_sparse, t_dense) > worst[2]) worst[2] = rel(t_sparse, t_dense);
        /* the frequency form's fixed point: the physical side closed by 1 / h */
        double complex dr[9], xr[3];
        for (int e = 0; e < 9; e++)
            dr[e] = rest[2][e] + I * w * rest[1][e] - w * w * rest[0][e];
        dr[0] += 1.0 / h;
        for (int i = 0; i < na; i++)
            xr[i] = f_rest[i];
        xr[0] += forced * amp / h;
        assert_int_equal(rths_cmat_solve(na, 1, dr, xr), 0);
        if (rel(xr[0], t_dense) > worst[3]) worst[3] = rel(xr[0], t_dense);
    }
    print_message("%s: receptance %.2g, forced %.2g, truth %.2g, frequency form %.2g\n",
                  base ? "base" : "force", worst[0], worst[1], worst[2], worst[3]);
    for (int k = 0; k < 4; k++)
        assert_true(worst[k] < 1e-9);
    int analyses = 0;
    rths_sparse_model_receptance_s(rec, &analyses);
    assert_int_equal(analyses, 1);

    free(d), free(x), free(f_num), free(dofs);
    for (int t = 0; t < 3; t++)
        free(full[t]), free(num[t]), rths_sparse_free(&ns[t]);
    rths_sparse_frf_destroy(truth);
    rths_sparse_model_receptance_destroy(rec);
    rths_sparse_model_free(&m);
    rths_model_choice_free(&choice);
    rths_config_free(cfg);
}

static void test_frame_frequency_form(void **state) {
    (void)state;
    if (system("/usr/bin/python3 -c 'import numpy' 2>/dev/null")) {
        skip();
        return;
    }
    char dir[] = "/tmp/rths_test_sparse_ff_XXXXXX", cmd[512];
    assert_non_null(mkdtemp(dir));
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 %s --nx 4 --ny 4 --nz 5 --seed 1 --specimen 2000 3e5 %s "
             ">/dev/null && sed -e '/^forcing:/,$d' %s/frame.yaml > %s/base.yaml && printf "
             "'forcing:\\n  type: base\\n  amplitude_m_s2: 2.0\\n' >> %s/base.yaml",
             rths_test_source_path("tools/gen_frame3d.py"), dir, dir, dir, dir);
    assert_int_equal(system(cmd), 0);
    run_case(dir, 0);
    run_case(dir, 1);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

static void test_refuses_two_interface_dofs(void **state) {
    (void)state;
    rths_sparse_model m = {.n_int = 2};
    rths_sparse_model_receptance *rec;
    rths_error err;
    assert_int_equal(rths_sparse_model_receptance_create(&m, &rec, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "split.interface"));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_frame_frequency_form),
        cmocka_unit_test(test_refuses_two_interface_dofs),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
