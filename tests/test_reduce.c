/* The Craig-Bampton reduction (include/rths/reduce.h) against closed forms: the interface dynamic
 * stiffness of a two-mass system, the series stiffness of a grounded spring chain (static
 * condensation is exact), the error bound (exact when one mode is dropped, respected by a
 * 300-DoF rod at test frequencies), and the config keys. */
#include "testlib.h"

#include "rths/fidelity.h"
#include "rths/reduce.h"
#include "rths/setup.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* A spring-mass chain, DoF 0 the boundary: spring k[i] joins DoF i and i + 1; grounded adds a
 * spring k[n - 1] from the last DoF to the ground. Damping beta K (stiffness-proportional). */
static void chain(int n, const double *m, const double *k, int grounded, double beta, double *mm,
                  double *cc, double *kk) {
    memset(mm, 0, sizeof(double) * (size_t)(n * n));
    memset(kk, 0, sizeof(double) * (size_t)(n * n));
    for (int i = 0; i < n; i++)
        mm[i + i * n] = m[i];
    for (int i = 0; i + 1 < n; i++) {
        kk[i + i * n] += k[i];
        kk[(i + 1) + (i + 1) * n] += k[i];
        kk[i + (i + 1) * n] -= k[i];
        kk[(i + 1) + i * n] -= k[i];
    }
    if (grounded) kk[(n - 1) + (n - 1) * n] += k[n - 1];
    for (int i = 0; i < n * n; i++)
        cc[i] = beta * kk[i];
}

static void expect_ok(int rc, const rths_error *err) {
    if (rc) fail_msg("%s", err->msg);
}

/* Two masses: S = k - w^2 m0 - k^2 / (k - w^2 m1) (eliminate the free mass). Keeping the mode
 * reproduces it to rounding; dropping it leaves the rigid Guyan model -w^2 (m0 + m1), whose error
 * w^4 m1^2 / (k - w^2 m1) is exactly the bound (one dropped mode, m_j^2 = m1). */
static void test_two_masses(void **state) {
    (void)state;
    const double m[2] = {2.0, 3.0}, k[1] = {5000.0};
    double mm[4], cc[4], kk[4];
    chain(2, m, k, 0, 0.0, mm, cc, kk);
    rths_error err;
    rths_reduced full, none;
    expect_ok(rths_reduce_craig_bampton(2, 1, mm, cc, kk, 1e6, 8, 0, &full, &err), &err);
    expect_ok(rths_reduce_craig_bampton(2, 1, mm, cc, kk, 1.0, 8, 0, &none, &err), &err);
    assert_int_equal(full.nr, 2);
    assert_int_equal(none.nr, 1);
    assert_rel(none.mass[0], 5.0, 1e-14);
    assert_close(none.stiffness[0], 0.0, 1e-9);
    assert_rel(none.first_dropped_hz, sqrt(k[0] / m[1]) / (2 * M_PI), 1e-12);
    assert_rel(none.dropped_mass_kg, m[1], 1e-12);
    for (double w = 5; w < 40; w += 7) {
        double complex s_true = k[0] - w * w * m[0] - k[0] * k[0] / (k[0] - w * w * m[1]);
        double complex s, s_full, s_none;
        expect_ok(rths_interface_dynamic_stiffness(2, 1, mm, cc, kk, w, &s, &err), &err);
        expect_ok(rths_interface_dynamic_stiffness(2, 1, full.mass, full.damping, full.stiffness, w,
                                                   &s_full, &err),
                  &err);
        expect_ok(rths_interface_dynamic_stiffness(1, 1, none.mass, none.damping, none.stiffness, w,
                                                   &s_none, &err),
                  &err);
        assert_rel(creal(s), creal(s_true), 1e-12);
        assert_rel(creal(s_full), creal(s_true), 1e-10);
        assert_rel(cabs(s_none - s_true), rths_reduced_stiffness_error_bound(&none, w), 1e-9);
    }
    rths_reduced_free(&full);
    rths_reduced_free(&none);
}

/* A grounded chain of springs in series: the static interface stiffness is 1 / sum(1 / k_i),
 * and the reduction keeps it exactly whatever it drops (static condensation). */
static void test_static_exact(void **state) {
    (void)state;
    enum { N = 40 };
    double m[N], k[N], mm[N * N], cc[N * N], kk[N * N], compliance = 0;
    for (int i = 0; i < N; i++) {
        m[i] = 1.0 + 0.1 * i;
        k[i] = 1e4 * (1.0 + 0.05 * i);
        compliance += 1.0 / k[i];
    }
    chain(N, m, k, 1, 1e-4, mm, cc, kk);
    rths_error err;
    rths_reduced r;
    expect_ok(rths_reduce_craig_bampton(N, 1, mm, cc, kk, 1e-3, 8, 0, &r, &err), &err);
    assert_int_equal(r.n_modes, 0);
    assert_rel(r.stiffness[0], 1.0 / compliance, 1e-12);
    double complex s0;
    expect_ok(rths_interface_dynamic_stiffness(N, 1, mm, cc, kk, 0.0, &s0, &err), &err);
    assert_rel(creal(s0), 1.0 / compliance, 1e-12);
    assert_true(rths_reduced_stiffness_error_bound(&r, 0.0) == 0.0);
    rths_reduced_free(&r);
}

/* A free rod of 300 elements with a storey on top (the numerical side of examples/rod_chain_1000
 * in miniature), undamped and with stiffness-proportional damping (which the fixed-interface
 * modes decouple): the reduced interface dynamic stiffness stays within the bound at every test
 * frequency up to half the cutoff, and the bound is not slack by orders of magnitude. */
static void test_rod_bound(void **state) {
    (void)state;
    enum { N = 300 };
    double *m = malloc(sizeof(double) * N), *k = malloc(sizeof(double) * N);
    double *mm = malloc(sizeof(double) * N * N), *cc = malloc(sizeof(double) * N * N),
           *kk = malloc(sizeof(double) * N * N);
    for (int i = 0; i < N; i++) {
        m[i] = 0.01;
        k[i] = 3e7;
    }
    m[N - 1] = 10.0; /* a storey on top */
    for (int damped = 0; damped < 2; damped++) {
        chain(N, m, k, 0, damped ? 2e-6 : 0.0, mm, cc, kk);
        rths_error err;
        rths_reduced r;
        expect_ok(rths_reduce_craig_bampton(N, 1, mm, cc, kk, 800.0, 30, 0, &r, &err), &err);
        assert_true(r.n_modes >= 1 && r.n_modes < 30);
        assert_true(r.first_dropped_hz > 800.0);
        double worst_ratio = 0;
        for (double hz = 2; hz < 400; hz *= 1.37) {
            double w = 2 * M_PI * hz;
            double complex s, sr;
            expect_ok(rths_interface_dynamic_stiffness(N, 1, mm, cc, kk, w, &s, &err), &err);
            expect_ok(rths_interface_dynamic_stiffness(r.nr, 1, r.mass, r.damping, r.stiffness, w,
                                                       &sr, &err),
                      &err);
            double bound = rths_reduced_stiffness_error_bound(&r, w);
            /* rounding of S itself: 1e-12 of its terms */
            assert_true(cabs(sr - s) <= bound * (1 + 1e-9) + 1e-12 * cabs(s) + 1e-9);
            worst_ratio = fmax(worst_ratio, cabs(sr - s) / bound);
        }
        assert_true(worst_ratio > 0.05);
        rths_reduced_free(&r);
    }
    free(m), free(k), free(mm), free(cc), free(kk);
}

/* Too many modes below an explicit cutoff are refused, naming the count; clip keeps the lowest. */
static void test_size_bound(void **state) {
    (void)state;
    enum { N = 60 };
    double m[N], k[N], mm[N * N], cc[N * N], kk[N * N];
    for (int i = 0; i < N; i++)
        m[i] = 1.0, k[i] = 1e4;
    chain(N, m, k, 0, 0.0, mm, cc, kk);
    rths_error err;
    rths_reduced r;
    assert_int_equal(rths_reduce_craig_bampton(N, 1, mm, cc, kk, 1e9, 10, 0, &r, &err),
                     RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "59 fixed-interface modes"));
    expect_ok(rths_reduce_craig_bampton(N, 1, mm, cc, kk, 1e9, 10, 1, &r, &err), &err);
    assert_int_equal(r.nr, 11);
    assert_true(r.cutoff_hz == r.mode_hz[9] && r.first_dropped_hz > r.cutoff_hz);
    rths_reduced_free(&r);
}

static void test_config(void **state) {
    (void)state;
    char dir[] = "/tmp/rths_reduce_XXXXXX", path[256];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/c.yaml", dir);
    const char *docs[] = {"controller:\n  reduction:\n    method: craig_bampton\n    cutoff_hz: "
                          "auto\n",
                          "controller:\n  reduction:\n    cutoff_hz: 250\n",
                          "controller:\n  reduction:\n    method: guyan\n",
                          "controller:\n  reduction:\n    cutoff_hz: -3\n"};
    const int expect_rc[] = {RTHS_OK, RTHS_OK, RTHS_EINPUT, RTHS_EINPUT};
    for (int d = 0; d < 4; d++) {
        FILE *f = fopen(path, "w");
        fputs(docs[d], f);
        fclose(f);
        rths_config *cfg;
        rths_error err;
        expect_ok(rths_config_load(path, NULL, 0, &cfg, &err), &err);
        rths_reduction_options opt;
        rths_reduction_defaults(&opt);
        assert_int_equal(rths_reduction_config_read(cfg, &opt, &err), expect_rc[d]);
        if (d == 0) {
            assert_int_equal(opt.method, RTHS_REDUCTION_CRAIG_BAMPTON);
            assert_close(rths_reduction_cutoff_hz(&opt, 10000), 500.0, 0);
        }
        if (d == 1) {
            assert_int_equal(opt.method, RTHS_REDUCTION_AUTO);
            assert_close(rths_reduction_cutoff_hz(&opt, 10000), 250.0, 0);
            assert_false(rths_reduction_applies(&opt, RTHS_REDUCE_FULL_UP_TO));
            assert_true(rths_reduction_applies(&opt, RTHS_REDUCE_FULL_UP_TO + 1));
        }
        if (expect_rc[d]) assert_non_null(strstr(err.msg, "controller.reduction."));
        rths_config_free(cfg);
    }
    remove(path);
    rmdir(dir);
}

/* The fidelity model with a reduced numerical substructure: keeping every mode is a change of
 * coordinates, so each scheme's curve and every DoF equal the unreduced model's (1e-9: the
 * discretisation of the transformed matrices rounds differently); the continuous reduced curve
 * equals the true assembly's. Dropping the seed's one interior mode (storey 4 on its leg) leaves
 * the rigid Guyan model, visibly wrong at the second mode (> 10 %). */
static void test_fidelity_reduced(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    expect_ok(rths_config_load(rths_test_source_path("examples/four_storey_linear.yaml"), NULL, 0,
                               &cfg, &err),
              &err);
    expect_ok(rths_setup_read(cfg, &s, &err), &err);
    const rths_split *sp = &s.split;
    rths_reduced all, rigid;
    expect_ok(rths_reduce_craig_bampton(sp->nn, 1, sp->mass_num, sp->damping_num, sp->stiffness_num,
                                        1e4, 8, 0, &all, &err),
              &err);
    expect_ok(rths_reduce_craig_bampton(sp->nn, 1, sp->mass_num, sp->damping_num, sp->stiffness_num,
                                        1.0, 8, 0, &rigid, &err),
              &err);
    rths_fidelity *plain, *red, *guyan;
    expect_ok(rths_fidelity_create(sp, s.force, 1e-4, &plain, &err), &err);
    expect_ok(rths_fidelity_create_reduced(sp, s.force, 1e-4, &all, &red, &err), &err);
    expect_ok(rths_fidelity_create_reduced(sp, s.force, 1e-4, &rigid, &guyan, &err), &err);
    double complex x[4], y[4];
    for (double hz = 9.0; hz < 15.0; hz += 1.1) {
        double w = 2 * M_PI * hz;
        for (int c = 0; c < RTHS_SCHEME_COUNT; c++) {
            expect_ok(rths_fidelity_response(plain, c, w, x, &err), &err);
            expect_ok(rths_fidelity_response(red, c, w, y, &err), &err);
            for (int i = 0; i < 4; i++)
                assert_true(cabs(y[i] - x[i]) <= 1e-9 * cabs(x[i]));
        }
        expect_ok(rths_fidelity_response(plain, RTHS_FIDELITY_TRUE, w, x, &err), &err);
        expect_ok(rths_fidelity_response(red, RTHS_FIDELITY_REDUCED, w, y, &err), &err);
        for (int i = 0; i < 4; i++)
            assert_true(cabs(y[i] - x[i]) <= 1e-10 * cabs(x[i]));
    }
    expect_ok(rths_fidelity_response(plain, RTHS_FIDELITY_TRUE, 2 * M_PI * 13.47, x, &err), &err);
    expect_ok(rths_fidelity_response(guyan, RTHS_FIDELITY_REDUCED, 2 * M_PI * 13.47, y, &err),
              &err);
    assert_true(cabs(y[2] - x[2]) > 0.1 * cabs(x[2]));
    rths_fidelity_free(plain), rths_fidelity_free(red), rths_fidelity_free(guyan);
    rths_reduced_free(&all), rths_reduced_free(&rigid);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_two_masses), cmocka_unit_test(test_static_exact),
        cmocka_unit_test(test_rod_bound),  cmocka_unit_test(test_size_bound),
        cmocka_unit_test(test_config),     cmocka_unit_test(test_fidelity_reduced),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
