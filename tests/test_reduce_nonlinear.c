/* A Craig-Bampton reduction that keeps the DoFs a nonlinear element touches as boundary
 * coordinates (reduce.h, rths_reduce_craig_bampton_keeping) against the unreduced model: a
 * 12-DoF chain (1 kg, 1e4 N/m, grounded at its far end, Rayleigh damping) driven at DoF 1 by
 * 0.5 N at 5 Hz with a hardening cubic spring between DoFs 6 and 7 (k3 = 1e14 N/m^3, strong
 * enough that the third harmonic is 2 % of the fundamental). Both periodic responses
 * by the same harmonic balance (harmonic_balance.h): the reduced one, the element on its kept
 * coordinates, within 1e-3 of the full one at harmonics 1 and 3, as the dropped fixed-interface
 * modes' bound w^4 tr(M_dropped) / (w_c^2 - w^2) relative to the interface stiffness predicts
 * (well below it at 5 and 15 Hz against a first dropped mode near 30 Hz). */
#include "testlib.h"

#include "rths/harmonic_balance.h"
#include "rths/reduce.h"

#include <math.h>
#include <stdlib.h>

enum { N = 12, H = 7 };

static void test_keeping_agrees_with_full(void **state) {
    (void)state;
    double *m = rths_mat_new(N, N), *c = rths_mat_new(N, N), *k = rths_mat_new(N, N);
    for (int i = 0; i < N; i++) {
        RTHS_AT(m, N, i, i) = 1.0;
        if (i + 1 < N) {
            RTHS_AT(k, N, i, i) += 1e4, RTHS_AT(k, N, i + 1, i + 1) += 1e4;
            RTHS_AT(k, N, i, i + 1) -= 1e4, RTHS_AT(k, N, i + 1, i) -= 1e4;
        }
    }
    RTHS_AT(k, N, N - 1, N - 1) += 1e4; /* the far end to the ground */
    for (int i = 0; i < N * N; i++)
        c[i] = 1e-4 * k[i] + 0.5 * m[i];
    rths_nl_element el = {.type = RTHS_NL_CUBIC, .dof_i = 5, .dof_j = 6, .numerical = 1, .k = 1e14};
    double force[N] = {0.5}, zero[N] = {0};
    rths_hb_options opt;
    rths_hb_defaults(&opt);
    opt.harmonics = H;
    opt.samples = 64;
    const double w = 2 * M_PI * 5.0;
    rths_assembly full = {.n = N, .mass = m, .damping = c, .stiffness = k};
    double full_coef[N * (2 * H + 1)] = {0};
    rths_error err;
    int it;
    if (rths_hb_solve(&full, 1, &el, zero, force, w, &opt, full_coef, &it, &err))
        fail_msg("%s", err.msg);
    /* keep DoFs 6 and 7 (0-based 5, 6) besides the interface DoF 1 */
    rths_reduced red;
    int keep[2] = {5, 6};
    if (rths_reduce_craig_bampton_keeping(N, 1, m, c, k, 2, keep, 30.0, N, 1, &red, &err))
        fail_msg("%s", err.msg);
    assert_int_equal(red.n_boundary, 3);
    assert_true(red.n_modes < N - 3); /* some modes dropped: a real reduction */
    /* the kept DoFs are coordinates of their own: T's rows 6 and 7 are unit rows */
    for (int col = 0; col < red.nr; col++) {
        assert_close(red.transform[5 + (size_t)col * N], col == 1, 1e-12);
        assert_close(red.transform[6 + (size_t)col * N], col == 2, 1e-12);
    }
    rths_assembly reduced = {
        .n = red.nr, .mass = red.mass, .damping = red.damping, .stiffness = red.stiffness};
    rths_nl_element rel = el;
    rel.dof_i = 1, rel.dof_j = 2;
    double rforce[N] = {0.5}, rzero[N] = {0};
    double *red_coef = calloc((size_t)red.nr * (2 * H + 1), sizeof(double));
    if (rths_hb_solve(&reduced, 1, &rel, rzero, rforce, w, &opt, red_coef, &it, &err))
        fail_msg("%s", err.msg);
    double a1 = hypot(full_coef[N], full_coef[2 * N]);
    double a3 = hypot(full_coef[5 * N], full_coef[6 * N]);
    assert_true(a3 > 0.01 * a1); /* the element matters */
    double worst = 0;
    for (int j = 1; j <= 6; j++) {
        assert_close(red_coef[red.nr * j], full_coef[N * j], 1e-3 * a1);
        worst = fmax(worst, fabs(red_coef[red.nr * j] - full_coef[N * j]) / a1);
    }
    print_message("reduced (%d of %d DoFs) vs full: %.3g of the fundamental; a3 / a1 %.3g\n",
                  red.nr, N, worst, a3 / a1);
    /* without the reduction's kept DoFs the element could not be placed: its DoFs would be
     * interior and mixed into modes (rths_reduce_craig_bampton keeps only the interface) */
    rths_reduced plain;
    if (rths_reduce_craig_bampton(N, 1, m, c, k, 30.0, N, 1, &plain, &err)) fail_msg("%s", err.msg);
    assert_true(fabs(plain.transform[5 + (size_t)1 * N]) != 1.0 || plain.nr < 3);
    rths_reduced_free(&plain);
    free(red_coef);
    rths_reduced_free(&red);
    free(m), free(c), free(k);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_keeping_agrees_with_full),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
