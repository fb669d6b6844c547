/* The frequency form's nonlinear numerical substructure with the real-time form's grounding
 * (rths_hb_substructure_set_grounding / _solve_dofs, harmonic_balance.h; docs/method.md,
 * "Nonlinear elements in the frequency form"), on examples/four_storey_bilinear_numerical.yaml:
 *  - without elements (every DoF but the interface condensed) it is the grounded linear
 *    substructure per harmonic,
 *    (D(k w) + k_g + i k w c_g e e^T) xi = e (F + (k_g + i k w c_g) x) + f_forcing, solved
 *    independently by rths_frf on the grounded matrices;
 *  - with the leg (the kink crossed at 14.97 Hz) and the base motion equal to the force-driven
 *    solution's own interface motion, the grounding carries nothing and the grounded solution
 *    is the force-driven one (5 harmonics kept, so the base carries every harmonic there is). */
#include "testlib.h"

#include "rths/harmonic_balance.h"
#include "rths/setup.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static void load_file(const char *rel, rths_config **cfg, rths_setup *s) {
    rths_error err;
    if (rths_config_load(rths_test_source_path(rel), NULL, 0, cfg, &err) ||
        rths_setup_read(*cfg, s, &err))
        fail_msg("%s", err.msg);
}

static void load_example(rths_config **cfg, rths_setup *s) {
    load_file("examples/four_storey_bilinear_numerical.yaml", cfg, s);
}

static void linear_grounded(const char *rel) {
    rths_config *cfg;
    rths_setup s;
    load_file(rel, &cfg, &s);
    const rths_split *sp = &s.split;
    const int nn = sp->nn;
    rths_error err;
    rths_hb_substructure *hb;
    if (rths_hb_substructure_create(sp, 0, NULL, s.static_force, s.forcing_dof, NULL, &hb, &err))
        fail_msg("%s", err.msg);
    const double kp = 1e4, kd = 200, w = 2 * M_PI * 14.97, amp = s.forcing_amplitude_n;
    if (rths_hb_substructure_set_grounding(hb, &kp, &kd, &err)) fail_msg("%s", err.msg);
    rths_fourier force = {0}, base = {0}, xi;
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
        force.a[k] = 3.0 / k, force.b[k] = -1.5 / (k * k);
        base.a[k] = 2e-5 / k, base.b[k] = 1e-5 * k;
    }
    base.a[0] = 1e-3;
    if (rths_hb_substructure_solve_dofs(hb, w, amp, &force, &base, &xi, &err))
        fail_msg("%s", err.msg);
    assert_float_equal(xi.a[0], base.a[0], 0);
    double *kg = rths_mat_dup(sp->stiffness_num, nn, nn),
           *cg = rths_mat_dup(sp->damping_num, nn, nn);
    double *f = calloc((size_t)nn, sizeof(double));
    double complex *x = malloc(sizeof(double complex) * (size_t)nn);
    assert_non_null(kg);
    kg[0] += kp, cg[0] += kd;
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
        double complex load = force.a[k] - I * force.b[k] +
                              (kp + I * k * w * kd) * (base.a[k] - I * base.b[k]),
                       xk = 0;
        /* by superposition: the interface load, then (k = 1) the forcing */
        memset(f, 0, sizeof(double) * (size_t)nn);
        f[0] = 1;
        if (rths_frf(nn, sp->mass_num, cg, kg, f, k * w, x, &err)) fail_msg("%s", err.msg);
        xk = x[0] * load;
        if (k == 1) {
            memset(f, 0, sizeof(double) * (size_t)nn);
            for (int i = 0; i < sp->n_num; i++)
                if (sp->num_dofs[i] == s.forcing_dof) f[sp->n_int + i] = 1;
            if (rths_frf(nn, sp->mass_num, cg, kg, f, k * w, x, &err)) fail_msg("%s", err.msg);
            xk += x[0] * amp;
        }
        double scale = cabs(xk);
        assert_close(xi.a[k], creal(xk), 1e-9 * scale);
        assert_close(xi.b[k], -cimag(xk), 1e-9 * scale);
    }
    free(kg), free(cg), free(f), free(x);
    rths_hb_substructure_destroy(hb);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* the seed's numerical side (interface and storey 4, nothing condensed without elements but
 * storey 4), and the five-storey building's (storeys 4 and 5 condensed, the forcing on 4) */
static void test_linear_grounded(void **state) {
    (void)state;
    linear_grounded("examples/four_storey_bilinear_numerical.yaml");
    linear_grounded("examples/five_storey.yaml");
}

static void test_grounding_carries_nothing_at_a_match(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load_example(&cfg, &s);
    rths_error err;
    rths_hb_options opt;
    rths_hb_defaults(&opt);
    opt.harmonics = RTHS_MAX_HARMONICS;
    opt.samples = 256;
    rths_hb_substructure *free_sub, *grounded;
    if (rths_hb_substructure_create(&s.split, s.n_nonlinear, s.nonlinear, s.static_force,
                                    s.forcing_dof, &opt, &free_sub, &err) ||
        rths_hb_substructure_create(&s.split, s.n_nonlinear, s.nonlinear, s.static_force,
                                    s.forcing_dof, &opt, &grounded, &err))
        fail_msg("%s", err.msg);
    const double kp = 1e4, kd = 200, w = 2 * M_PI * 14.97, amp = s.forcing_amplitude_n;
    if (rths_hb_substructure_set_grounding(grounded, &kp, &kd, &err)) fail_msg("%s", err.msg);
    /* an interface force near the hybrid's there: the leg's kink is crossed */
    rths_fourier force = {0}, x0 = {0}, x1;
    force.a[1] = 11.0, force.b[1] = -4.0, force.a[2] = 1.5, force.b[2] = 0.8;
    double mean = 0;
    if (rths_hb_substructure_solve(free_sub, w, amp, RTHS_MAX_HARMONICS, force.a, force.b, mean,
                                   x0.a, x0.b, NULL, &err))
        fail_msg("%s", err.msg);
    /* with the base at the solution's own motion the grounding pulls nowhere */
    if (rths_hb_substructure_solve_dofs(grounded, w, amp, &force, &x0, &x1, &err))
        fail_msg("%s", err.msg);
    double scale = hypot(x0.a[1], x0.b[1]);
    print_message("free interface: h1 %.3e m, h2 %.3e m\n", scale, hypot(x0.a[2], x0.b[2]));
    assert_true(hypot(x0.a[2], x0.b[2]) > 1e-3 * scale); /* nonlinear: the kink is crossed */
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
        assert_close(x1.a[k], x0.a[k], 1e-8 * scale);
        assert_close(x1.b[k], x0.b[k], 1e-8 * scale);
    }
    /* and a base away from it pulls the interface toward it */
    rths_fourier shifted = x0, x2;
    shifted.a[1] += 0.1 * scale;
    if (rths_hb_substructure_solve_dofs(grounded, w, amp, &force, &shifted, &x2, &err))
        fail_msg("%s", err.msg);
    assert_true(fabs(x2.a[1] - x0.a[1]) > 1e-4 * scale);
    rths_hb_substructure_destroy(free_sub);
    rths_hb_substructure_destroy(grounded);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_linear_grounded),
        cmocka_unit_test(test_grounding_carries_nothing_at_a_match),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
