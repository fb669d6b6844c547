/* The frequency form's nonlinear numerical substructure (harmonic_balance.h,
 * rths_hb_substructure) against independent truths:
 *  - the whole assembly's harmonic balance (rths_hb_solve, uncondensed, on all four DoFs of
 *    examples/four_storey_bilinear_numerical.yaml, the leg in contact over part of the period):
 *    the interface force it implies on the numerical side, fed to the substructure with all its
 *    harmonics, gives back the assembly's interface motion;
 *  - the displacement-driven direction inverts the force-driven one;
 *  - without elements the substructure is the linear receptance (rths_frf), and
 *    rths_frequency_convert through it is the linear conversion. */
#include "testlib.h"

#include "rths/harmonic_balance.h"
#include "rths/iterate.h"
#include "rths/reduce.h"
#include "rths/setup.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static void load_example(rths_config **cfg, rths_setup *s) {
    rths_error err;
    if (rths_config_load(rths_test_source_path("examples/four_storey_bilinear_numerical.yaml"),
                         NULL, 0, cfg, &err) ||
        rths_setup_read(*cfg, s, &err))
        fail_msg("%s", err.msg);
}

enum { H = 25, N = 512, NB = 2 * H + 1 };

static double basis(int j, double theta) {
    if (j == 0) return 1.0;
    int k = (j + 1) / 2;
    return j % 2 ? cos(k * theta) : sin(k * theta);
}

static void test_agrees_with_assembly(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load_example(&cfg, &s);
    const int n = s.assembly.n;
    const double f_hz = 14.97, w = 2 * M_PI * f_hz;
    rths_hb_options opt;
    rths_hb_defaults(&opt);
    opt.harmonics = H;
    opt.samples = N;
    double *coef = calloc((size_t)n * NB, sizeof(double));
    rths_error err;
    int it;
    if (rths_hb_solve(&s.assembly, s.n_nonlinear, s.nonlinear, s.static_force, s.force, w, &opt,
                      coef, &it, &err))
        fail_msg("%s", err.msg);
    /* the numerical side: interface (DoF 3) and storey 4; the leg 3-4 is the element */
    const rths_split *sp = &s.split;
    assert_int_equal(sp->nn, 2);
    int dof[2] = {sp->int_dofs[0], sp->num_dofs[0]};
    /* the leg's deformation must cross the kink at this frequency (else the test is linear) */
    const rths_nl_element *leg = &s.nonlinear[0];
    double dmin = 1e9, dmax = -1e9;
    double g_h[NB] = {0};
    for (int m = 0; m < N; m++) {
        double th = 2 * M_PI * m / N, d = 0;
        for (int j = 0; j < NB; j++)
            d += basis(j, th) *
                 (coef[leg->dof_i + n * j] - (leg->dof_j >= 0 ? coef[leg->dof_j + n * j] : 0.0));
        dmin = fmin(dmin, d), dmax = fmax(dmax, d);
        double g = rths_nl_force(leg, d, NULL);
        for (int j = 0; j < NB; j++)
            g_h[j] += (j == 0 ? 1.0 : 2.0) / N * basis(j, th) * g;
    }
    assert_true(dmin < -leg->clearance_m && dmax > -leg->clearance_m);
    /* the force on the numerical substructure's interface, per harmonic:
     * F = [D_num x]_int + (the element's force on the interface) - (forcing on the interface) */
    double fa[H + 1] = {0}, fb[H + 1] = {0};
    double sign_int = leg->dof_i == dof[0] ? 1.0 : (leg->dof_j == dof[0] ? -1.0 : 0.0);
    for (int k = 1; k <= H; k++) {
        double complex f = 0;
        for (int c = 0; c < 2; c++) {
            double kk = RTHS_AT(sp->stiffness_num, 2, 0, c), cc = RTHS_AT(sp->damping_num, 2, 0, c),
                   mm = RTHS_AT(sp->mass_num, 2, 0, c);
            double complex d = kk - k * k * w * w * mm + I * k * w * cc;
            f += d * (coef[dof[c] + n * (2 * k - 1)] - I * coef[dof[c] + n * (2 * k)]);
        }
        f += sign_int * (g_h[2 * k - 1] - I * g_h[2 * k]);
        if (k == 1 && s.forcing_dof == dof[0]) f -= s.forcing_amplitude_n;
        fa[k] = creal(f);
        fb[k] = -cimag(f);
    }
    rths_hb_substructure *hb;
    rths_hb_options sub_opt = opt;
    if (rths_hb_substructure_create(sp, s.n_nonlinear, s.nonlinear, s.static_force, s.forcing_dof,
                                    &sub_opt, &hb, &err))
        fail_msg("%s", err.msg);
    /* the assembly's interface motion, every harmonic prescribed: the force it needs is the
     * assembly's (the internal DoF's periodic response to a given base motion is unique here; the
     * force-driven direction has several solutions near the folds, so the check goes this way) */
    double xa[H + 1], xb[H + 1], ga_h[H + 1], gb_h[H + 1];
    for (int k = 0; k <= H; k++) {
        xa[k] = k == 0 ? coef[dof[0]] : coef[dof[0] + n * (2 * k - 1)];
        xb[k] = k == 0 ? 0.0 : coef[dof[0] + n * (2 * k)];
    }
    if (rths_hb_substructure_force(hb, w, s.forcing_amplitude_n, H, xa, xb, ga_h, gb_h, &err))
        fail_msg("%s", err.msg);
    double famp1 = hypot(fa[1], fb[1]);
    /* the same truncated system solved to 1e-10 of the loads on both sides */
    for (int k = 1; k <= H; k++) {
        assert_close(ga_h[k], fa[k], 1e-7 * famp1);
        assert_close(gb_h[k], fb[k], 1e-7 * famp1);
    }
    /* the other way round: the force the assembly's interface motion needs is fa, fb (the
     * interface harmonics 1..5 prescribed, above them free of force: not the assembly's, whose
     * interface force has every harmonic, so the round trip is checked on the substructure's own
     * solution instead) */
    double ya[RTHS_MAX_HARMONICS + 1], yb[RTHS_MAX_HARMONICS + 1];
    double ga[RTHS_MAX_HARMONICS + 1], gb[RTHS_MAX_HARMONICS + 1];
    if (rths_hb_substructure_solve(hb, w, s.forcing_amplitude_n, RTHS_MAX_HARMONICS, fa, fb,
                                   coef[dof[0]], ya, yb, NULL, &err) ||
        rths_hb_substructure_force(hb, w, s.forcing_amplitude_n, RTHS_MAX_HARMONICS, ya, yb, ga, gb,
                                   &err))
        fail_msg("%s", err.msg);
    double famp = famp1;
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++) {
        assert_close(ga[k], fa[k], 1e-7 * famp);
        assert_close(gb[k], fb[k], 1e-7 * famp);
    }
    char text[256];
    rths_hb_substructure_describe(hb, text, sizeof text);
    assert_non_null(strstr(text, "25 harmonics, 512 time samples"));
    rths_hb_substructure_destroy(hb);
    free(coef);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* No element: the force-driven solve is H F + X_forced amplitude per harmonic, and the frequency
 * problem's conversion through the object equals the linear one (rths_numerical_receptance). */
static void test_linear_limit(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load_example(&cfg, &s);
    rths_error err;
    rths_hb_substructure *hb;
    rths_numerical_receptance *rec;
    if (rths_hb_substructure_create(&s.split, 0, NULL, s.static_force, s.forcing_dof, NULL, &hb,
                                    &err) ||
        rths_numerical_receptance_create(&s.split, s.forcing_dof, &rec, &err))
        fail_msg("%s", err.msg);
    rths_fourier f = {{0, 3.0, -0.5, 0.2, 0.1, 0.05}, {0, -1.0, 0.4, 0.0, -0.1, 0.02}};
    rths_fourier phys = {{1e-4, 0, 0, 0, 0, 0}, {0}};
    rths_fourier a = f, b = f;
    const double f_hz = 14.7;
    if (rths_frequency_convert(&a, NULL, &phys, NULL, f_hz, s.forcing_amplitude_n,
                               rths_hb_substructure_eval, hb, &err) ||
        rths_frequency_convert(&b, NULL, &phys, NULL, f_hz, s.forcing_amplitude_n,
                               rths_numerical_receptance_eval, rec, &err))
        fail_msg("%s", err.msg);
    double amp = hypot(b.a[1], b.b[1]);
    assert_true(amp > 0);
    for (int k = 0; k <= RTHS_MAX_HARMONICS; k++) {
        assert_close(a.a[k], b.a[k], 1e-10 * amp);
        assert_close(a.b[k], b.b[k], 1e-10 * amp);
    }
    rths_hb_substructure_destroy(hb);
    rths_numerical_receptance_destroy(rec);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_agrees_with_assembly),
        cmocka_unit_test(test_linear_limit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
