/* The sparse solves of the frequency form and of the truth are kept per frequency (issue 26;
 * docs/architecture.md, "Sparse algebra"): an evaluation at a frequency already solved costs no
 * factorisation. Every period of every evaluation converts the numerical side at its
 * RTHS_MAX_HARMONICS harmonics (iterate/frequency_problem.c), so without the cache a 60 000-DoF
 * model refactorised 5 times per period, 16-25 s each. On the 482-DoF frame of
 * tools/gen_frame3d.py, for rths_sparse_model_receptance_eval and rths_sparse_frf_direct:
 *  - asked again at each of the 5 harmonics of a forcing frequency, after other frequencies, the
 *    results are bitwise the first ones and the seconds spent in factorisations and solves
 *    (rths_sparse_model_receptance_s, rths_sparse_frf_direct_s, which grow with every solve) do
 *    not grow;
 *  - a new frequency is still solved (the seconds grow) and its result is not a cached one's. */
#include "testlib.h"

#include "rths/config.h"
#include "rths/model.h"
#include "rths/setup.h"
#include "rths/signals.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void test_sparse_cache(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_test_sparse_cache_XXXXXX", cmd[512], path[96];
    assert_non_null(mkdtemp(dir));
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 %s --nx 4 --ny 4 --nz 5 --seed 1 --specimen 2 2e3 %s >/dev/null",
             rths_test_source_path("tools/gen_frame3d.py"), dir);
    assert_int_equal(system(cmd), 0);
    snprintf(path, sizeof path, "%s/frame.yaml", dir);
    const char *sets[] = {"model.solver=sparse", "split.numerical_solver=frequency"};
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (rths_config_load(path, sets, 2, &cfg, &err)) fail_msg("%s", err.msg);
    if (rths_setup_read(cfg, &s, &err)) fail_msg("%s", err.msg);
    rths_config_free(cfg);

    rths_sparse_model_receptance *r;
    if (rths_sparse_model_receptance_create(s.sparse, &r, &err)) fail_msg("%s", err.msg);
    int out_dofs[2] = {s.split.int_dofs[0], s.forcing_dof};
    rths_sparse_frf *frf;
    if (rths_sparse_frf_create(s.sparse, NULL, 2, out_dofs, &frf, &err)) fail_msg("%s", err.msg);
    const double w = 2 * M_PI * 1.07;
    double complex h[RTHS_MAX_HARMONICS], f[RTHS_MAX_HARMONICS], x[RTHS_MAX_HARMONICS][2];
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
        if (rths_sparse_model_receptance_eval(r, k * w, &h[k - 1], &f[k - 1], &err) ||
            rths_sparse_frf_direct(frf, k * w, x[k - 1], &err))
            fail_msg("%s", err.msg);
    }
    /* another frequency in between: solved */
    double complex h2, f2, x2[2];
    double rs = rths_sparse_model_receptance_s(r, NULL), ds = rths_sparse_frf_direct_s(frf);
    if (rths_sparse_model_receptance_eval(r, 1.5 * w, &h2, &f2, &err) ||
        rths_sparse_frf_direct(frf, 1.5 * w, x2, &err))
        fail_msg("%s", err.msg);
    assert_true(rths_sparse_model_receptance_s(r, NULL) > rs);
    assert_true(rths_sparse_frf_direct_s(frf) > ds);
    assert_true(h2 != h[0] && x2[0] != x[0][0]);
    /* the harmonics again: from the cache, bitwise, no solve */
    rs = rths_sparse_model_receptance_s(r, NULL), ds = rths_sparse_frf_direct_s(frf);
    for (int k = RTHS_MAX_HARMONICS; k >= 1; k--) {
        double complex hk, fk, xk[2];
        if (rths_sparse_model_receptance_eval(r, k * w, &hk, &fk, &err) ||
            rths_sparse_frf_direct(frf, k * w, xk, &err))
            fail_msg("%s", err.msg);
        assert_true(hk == h[k - 1] && fk == f[k - 1]);
        assert_true(xk[0] == x[k - 1][0] && xk[1] == x[k - 1][1]);
    }
    assert_true(rths_sparse_model_receptance_s(r, NULL) == rs);
    assert_true(rths_sparse_frf_direct_s(frf) == ds);
    int analyses = 0;
    rths_sparse_model_receptance_s(r, &analyses);
    assert_int_equal(analyses, 1);
    rths_sparse_model_receptance_destroy(r);
    rths_sparse_frf_destroy(frf);
    rths_setup_free(&s);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sparse_cache),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
