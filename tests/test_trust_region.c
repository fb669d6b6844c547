/* The targets' trust region (docs/method.md, "Iteration and continuation") on a mock linear rig
 * with one interface DoF and one harmonic: the residual of target z = A* + i B* is
 * Phi = g (z - z_true), the physical response follows the target (x = z) and the numerical side
 * is x - Phi, so the root z_true and every target the corrector sends are known exactly.
 *
 * The hazard: a point near a resonance leaves a small carried gain (|g| = 0.005); at the next
 * point the rig's gain is 1 and a quarter turn away (a noisy secant update or a stale model can
 * leave a Jacobian as wrong as that). The Newton step from the carried gain is 60 times the
 * solution's size; the corrector's step limit (twice the numerical response) still sends a target
 * 3 times the last accepted point's size. With the trust region no target may exceed twice that
 * size (trust_growth 2), and the correction must still converge. Conversely a solution that does
 * lie far beyond the region (6 times the anchor, a correct Jacobian) must be reached by widening
 * the region, at a cost of a few evaluations. */
#include "testlib.h"

#include "rths/iterate.h"

#include <complex.h>
#include <math.h>
#include <string.h>

typedef struct mock_rig {
    double complex gain, root; /* Phi = gain (z - root), metres */
    double noise_m;            /* standard deviation of each residual entry */
    rths_rng rng;
    double largest_target_m; /* the largest |z| sent in the current correction */
    int evaluations;
} mock_rig;

static int mock_eval(void *ctx, const double *u, double omega_rad_s, rths_residual *out,
                     rths_error *err) {
    (void)omega_rad_s;
    (void)err;
    mock_rig *rig = ctx;
    double complex z = u[0] + I * u[1], phi = rig->gain * (z - rig->root);
    memset(out, 0, sizeof *out);
    out->n = 2;
    out->phi[0] = creal(phi) + rig->noise_m * rths_rng_normal(&rig->rng);
    out->phi[1] = cimag(phi) + rig->noise_m * rths_rng_normal(&rig->rng);
    out->response[0] = u[0];
    out->response[1] = u[1];
    for (int i = 0; i < 2; i++) {
        out->reference[i] = out->response[i] - out->phi[i];
        out->phi_se[i] = out->reference_se[i] = rig->noise_m;
    }
    out->samples = 1;
    rig->largest_target_m = fmax(rig->largest_target_m, cabs(z));
    rig->evaluations++;
    return RTHS_OK;
}

static const double root_size_m = 1e-3;
/* the residual's noise: 1e-3 of the root's size at unit gain, well below the step sizes that
 * decide the test, and it makes the finite differences and secants realistic */
static const double noise_m = 1e-9;

/* A corrector over the mock, with a Jacobian carried from a converged point of gain 0.005 at
 * root (1 + 0i) mm (the last accepted point: its size is the trust anchor). */
static rths_corrector *after_resonance_point(mock_rig *rig, double trust_growth) {
    memset(rig, 0, sizeof *rig);
    rths_rng_seed(&rig->rng, 7);
    rig->noise_m = noise_m;
    rig->gain = 0.005;
    rig->root = root_size_m;
    rths_zero_problem problem = {.n = 2, .harmonics = 1, .eval = mock_eval, .ctx = rig};
    rths_newton_options opt;
    rths_newton_defaults(&opt, 0);
    opt.report_matched = 0;
    opt.rel_tolerance = 1e-4;
    opt.abs_tolerance_m = 0;
    opt.trust_growth = trust_growth;
    rths_corrector *c;
    rths_error err;
    assert_int_equal(rths_corrector_create(&problem, &opt, &c, &err), RTHS_OK);
    rths_corrector_set_scales(c, root_size_m, 1.0);
    double u0[2] = {1.5 * root_size_m, 0};
    assert_int_equal(rths_corrector_solve(c, u0, 1.0, NULL, &err), RTHS_OK);
    return c;
}

/* Corrects the next point (gain, root) from the prediction u0 with the anchor at the last
 * point's size; returns the converged targets' distance from the root relative to what
 * convergence guarantees: the measured |Phi| is below rel_tolerance 1e-4 times the numerical
 * response (within 10 % of |root| once converged) or 3 noise standard errors (4.2 noise), the true
 * |Phi| at most 3 noise more, and |z - root| = |Phi| / |gain|. At most 1 when converged. */
static double next_point(rths_corrector *c, mock_rig *rig, double complex gain, double complex root,
                         const double *u0) {
    rig->gain = gain;
    rig->root = root;
    rig->largest_target_m = 0;
    rig->evaluations = 0;
    rths_corrector_set_trust_anchor(c, root_size_m);
    rths_error err;
    int rc = rths_corrector_solve(c, u0, 1.0, NULL, &err);
    if (rc) fail_msg("the correction failed: %s", err.msg);
    double u[2];
    rths_corrector_unknowns(c, u);
    double guaranteed = (1e-4 * 1.1 * cabs(root) + 7.3 * noise_m) / cabs(gain);
    return cabs(u[0] + I * u[1] - root) / guaranteed;
}

/* A carried gain 200 times too small and a quarter turn off, prediction 30 % long. */
static void test_stale_jacobian_stays_inside(void **state) {
    (void)state;
    double u0[2] = {1.3 * root_size_m, 0};
    mock_rig rig;
    /* control: without the trust region the step limit alone (twice the numerical response,
     * |1.3 - 0.3 i| mm) sends |1.3 - 2.67 i| = 2.97 times the anchor, so the scenario is the
     * hazard it is meant to be */
    rths_corrector *c = after_resonance_point(&rig, 0);
    next_point(c, &rig, I, root_size_m, u0);
    assert_true(rig.largest_target_m > 2.5 * root_size_m);
    rths_corrector_destroy(c);

    c = after_resonance_point(&rig, 2.0);
    double miss = next_point(c, &rig, I, root_size_m, u0);
    /* every target within the radius, 2 x 1 mm (rounding of the quadratic's root aside) */
    assert_true(rig.largest_target_m <= 2.0 * root_size_m * (1 + 1e-12));
    assert_true(miss <= 1.0);
    assert_true(rths_corrector_trust_actions(c) >= 1);
    rths_corrector_destroy(c);
}

/* The solution lies 6 times the anchor away along a correct Jacobian (the gain carried is the
 * rig's): the region widens after each step that reduced the residual as promised (2, 4, 8 mm),
 * so the root is reached in three steps instead of one. */
static void test_region_widens_for_a_real_jump(void **state) {
    (void)state;
    mock_rig rig;
    rths_corrector *c = after_resonance_point(&rig, 2.0);
    double u0[2] = {root_size_m, 0};
    double miss = next_point(c, &rig, 0.005, 6 * root_size_m, u0);
    assert_true(miss <= 1.0);
    /* the targets never exceeded the widest radius, 8 mm */
    assert_true(rig.largest_target_m <= 8.0 * root_size_m * (1 + 1e-12));
    /* one evaluation at the prediction and one per step (2, 4, 6 mm); a line search or a fresh
     * Jacobian would add more, so at most 6 */
    assert_true(rig.evaluations <= 6);
    assert_true(rths_corrector_trust_actions(c) >= 2);
    rths_corrector_destroy(c);
}

/* A prediction outside the region is shrunk onto it before it is sent, and a prediction inside
 * it is sent as it is. */
static void test_prediction_shrunk_onto_region(void **state) {
    (void)state;
    mock_rig rig;
    rths_corrector *c = after_resonance_point(&rig, 2.0);
    double far[2] = {0, 5 * root_size_m}, near[2] = {0, 1.9 * root_size_m};
    rths_corrector_set_trust_anchor(c, root_size_m);
    assert_false(rths_corrector_trust_allows(c, far));
    assert_true(rths_corrector_trust_allows(c, near));
    rths_corrector_set_trust_anchor(c, 0);
    assert_true(rths_corrector_trust_allows(c, far));
    double miss = next_point(c, &rig, 0.005, I * 1.5 * root_size_m, far);
    assert_true(miss <= 1.0);
    assert_true(rig.largest_target_m <= 2.0 * root_size_m * (1 + 1e-12));
    rths_corrector_destroy(c);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stale_jacobian_stays_inside),
        cmocka_unit_test(test_region_widens_for_a_real_jump),
        cmocka_unit_test(test_prediction_shrunk_onto_region),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
