/* The real-time form on a sparse model (issue 26; docs/architecture.md, "Sparse algebra"): the
 * controller built from a sparse setup (split.numerical_solver: realtime) integrates the
 * band-exact Krylov reduction of the sparse numerical side (krylov_reduce.h), never a dense matrix
 * of its order. On the 482-DoF frame of tools/gen_frame3d.py (--nx 4 --ny 4 --nz 5 --specimen
 * 2 2e3, the specimen's spring and damper given as the interface's physical shares), swept
 * 1.0-1.12 Hz:
 *  - the setup is read (no longer refused) and forms no dense numerical side;
 *  - the controller integrates at most RTHS_REALTIME_MAX_DOFS DoFs, its report gives the band
 *    (the sweep widened by 5 % of its width each side: 0.994-1.126 Hz), 31 check points and an
 *    interface FRF error within controller.reduction.max_error (0.1 %; measured ~1e-12), and the
 *    run.log line names the sizes and the error;
 *  - a max_error the reduction cannot meet (1e-16) and a missing sweep are refused (RTHS_EINPUT)
 *    naming their keys; a dense setup's controller reports no Krylov reduction.
 * The reduced model's accuracy end to end (every point of a noise-free run within 0.5 % of
 * numpy's dense solve of the assembly) is tests/cli/frf_sparse_realtime.sh's. */
#include "testlib.h"

#include "rths/config.h"
#include "rths/controller.h"
#include "rths/setup.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char dir[] = "/tmp/rths_test_sparse_realtime_XXXXXX";
static char path[128];

/* the configuration with the given overrides after the common ones; RTHS_OK or the error of
 * reading the setup or creating the controller (c then NULL) */
static int build(const char *const *extra, int n_extra, int with_sweep, rths_setup *s,
                 rths_controller **c, rths_error *err) {
    const char *sets[16] = {"split.numerical_solver=realtime",
                            "split.mass_ratio=0.999",
                            "split.interface_stiffness_physical_n_per_m=[[2.0e3]]",
                            "split.interface_damping_physical_n_s_per_m=[[0.2]]",
                            "forcing.amplitude_n=100",
                            "rig.interface_mass=physical_share"};
    int n = 6;
    if (with_sweep) sets[n++] = "continuation.start_hz=1.0", sets[n++] = "continuation.end_hz=1.12";
    for (int i = 0; i < n_extra; i++)
        sets[n++] = extra[i];
    rths_config *cfg;
    *c = NULL;
    if (rths_config_load(path, sets, n, &cfg, err)) fail_msg("%s", err->msg);
    rths_controller_options opt;
    rths_controller_defaults(&opt);
    int rc = rths_controller_config_read(cfg, &opt, err);
    if (!rc) rc = rths_setup_read(cfg, s, err);
    rths_config_free(cfg);
    if (rc) return rc;
    rc = rths_controller_create(s, &opt, c, err);
    if (rc) rths_setup_free(s);
    return rc;
}

static void test_sparse_realtime(void **state) {
    (void)state;
    char cmd[512];
    assert_non_null(mkdtemp(dir));
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 %s --nx 4 --ny 4 --nz 5 --seed 1 --specimen 2 2e3 %s >/dev/null",
             rths_test_source_path("tools/gen_frame3d.py"), dir);
    assert_int_equal(system(cmd), 0);
    snprintf(path, sizeof path, "%s/frame.yaml", dir);

    rths_setup s;
    rths_controller *c;
    rths_error err;
    const char *sparse[] = {"model.solver=sparse"};
    if (build(sparse, 1, 1, &s, &c, &err)) fail_msg("%s", err.msg);
    assert_non_null(s.sparse);
    assert_null(s.split.mass_num);
    int nr = rths_controller_numerical_dofs(c);
    rths_krylov_report rep;
    assert_int_equal(rths_controller_krylov_report(c, &rep), 1);
    assert_true(nr > 1 && nr <= RTHS_REALTIME_MAX_DOFS);
    assert_int_equal(nr, 1 + rep.basis);
    assert_int_equal(rep.check_points, RTHS_KRYLOV_CHECK_POINTS_DEFAULT);
    assert_true(rep.max_error <= RTHS_KRYLOV_MAX_ERROR_DEFAULT);
    assert_true(rep.at_hz >= 0.994 - 1e-12 && rep.at_hz <= 1.126 + 1e-12);
    char text[512];
    rths_controller_krylov_text(c, text, sizeof text);
    char want[96];
    snprintf(want, sizeof want, "sparse, 480 DoFs, reduced in real time to %d DoFs", nr);
    assert_non_null(strstr(text, want));
    assert_non_null(strstr(text, "over 31 check points of 0.994-1.126 Hz"));
    printf("%s\n", text);
    rths_controller_destroy(c);
    rths_setup_free(&s);

    /* a reduction worse than max_error in the band: refused, naming the key, error and band */
    const char *strict[] = {"model.solver=sparse", "controller.reduction.max_error=1e-16"};
    assert_int_equal(build(strict, 2, 1, &s, &c, &err), RTHS_EINPUT);
    assert_null(c);
    assert_non_null(strstr(err.msg, "controller.reduction.max_error"));
    assert_non_null(strstr(err.msg, "0.994-1.126 Hz"));
    /* no sweep, no band */
    assert_int_equal(build(sparse, 1, 0, &s, &c, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "continuation.start_hz"));
    /* the dense path: no Krylov reduction (Craig-Bampton, as before) */
    const char *dense[] = {"model.solver=dense"};
    if (build(dense, 1, 1, &s, &c, &err)) fail_msg("%s", err.msg);
    assert_int_equal(rths_controller_krylov_report(c, &rep), 0);
    rths_controller_krylov_text(c, text, sizeof text);
    assert_string_equal(text, "");
    rths_controller_destroy(c);
    rths_setup_free(&s);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sparse_realtime),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
