/* The virtual rig against independent truths: at the target that matches the interface, the
 * measured response equals the frequency-domain fidelity model of the same scheme (docs/method.md,
 * "Numerical substructure integration") and, for the default scheme, the analytic FRF; runs repeat
 * exactly for a seed; the bilinear leg's static force-displacement has both slopes and the kink. */
#include "fixture_seed_rig.h"
#include "testlib.h"

#include "rths/fidelity.h"
#include "rths/iterate.h"
#include "rths/rig_virtual.h"
#include "rths/run.h"

#include <complex.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* ---- counting allocator (not under ASan, which owns malloc) ---- */
#ifndef __SANITIZE_ADDRESS__
extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void __libc_free(void *);
static long allocations;
void *malloc(size_t n) {
    allocations++;
    return __libc_malloc(n);
}
void *calloc(size_t a, size_t b) {
    allocations++;
    return __libc_calloc(a, b);
}
void *realloc(void *p, size_t n) {
    allocations++;
    return __libc_realloc(p, n);
}
void free(void *p) {
    if (p) allocations++;
    __libc_free(p);
}
#endif

/* Solves the interface match at f_hz to a tight tolerance; returns the physical amplitude. */
static double matched_amplitude(const rths_setup *s, rths_scheme scheme, int ideal, double f_hz) {
    rths_controller_options co;
    rths_plant_options po;
    rths_fixture_quiet_options(ideal, &co, &po);
    co.scheme = scheme;
    rths_rig *rig = rths_fixture_rig(s, &co, &po);
    rths_error err;
    rths_settle_options so;
    rths_newton_options no;
    rths_fixture_tight_match(&so, &no);
    rths_corrector_state st;
    memset(&st, 0, sizeof st);
    rths_solution sol;
    memset(&sol, 0, sizeof sol);
    sol.harmonics = 1;
    sol.omega_rad_s = 2 * M_PI * f_hz;
    if (rths_correct(rig, &so, &no, s->forcing_amplitude_n, NULL, &st, &sol, &err))
        fail_msg("%s", err.msg);
    double a = hypot(sol.eval.phys.a[1], sol.eval.phys.b[1]);
    /* both sides agree (that is what converged means): the corrector's floor is three standard
     * errors of the residual, which the last transient keeps near 1e-6 of the amplitude */
    assert_close(hypot(sol.eval.num.a[1], sol.eval.num.b[1]), a, 1e-5 * a);
    rths_rig_destroy(rig);
    return a;
}

/* Ideal shaker (continuous force), noise off: every scheme's time-domain steady state at the
 * matched target equals the frequency-domain fidelity model to 5e-5 (measured <= 8e-6: what
 * remains is the corrector's and the steady-state test's floors); the default scheme equals the
 * analytic FRF to 1e-4 at the second mode's peak (measured 5e-6), implicit Euler is about a
 * quarter low (docs/method.md, "Numerical substructure integration"). */
static void test_matched_equals_fidelity(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    rths_fidelity *fid;
    rths_error err;
    assert_int_equal(rths_fidelity_create(&s.split, s.force, 1e-4, &fid, &err), RTHS_OK);
    const double f = 13.47;
    double complex x[4];
    assert_int_equal(rths_fidelity_response(fid, RTHS_FIDELITY_TRUE, 2 * M_PI * f, x, &err), 0);
    double truth = cabs(x[2]);
    for (int sc = 0; sc < RTHS_SCHEME_COUNT; sc++) {
        assert_int_equal(rths_fidelity_response(fid, sc, 2 * M_PI * f, x, &err), RTHS_OK);
        double a = matched_amplitude(&s, (rths_scheme)sc, 1, f);
        print_message("%-15s time domain %.6e m, fidelity model %.6e m, truth %.6e m\n",
                      rths_scheme_name((rths_scheme)sc), a, cabs(x[2]), truth);
        assert_close(a, cabs(x[2]), 5e-5 * cabs(x[2]));
        if (sc == RTHS_SCHEME_EXACT_FOH) assert_close(a, truth, 1e-4 * truth);
        if (sc == RTHS_SCHEME_IMPLICIT_EULER) assert_true(a / truth > 0.70 && a / truth < 0.78);
    }
    rths_fidelity_free(fid);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* The default rig (250 us delay, 1 kHz lag, armature mass, amplifier reconstruction), noise off,
 * at its matched target: within 0.2 % of the analytic FRF at the second mode's peak (measured
 * -0.0008 %) and 0.1 % off it (measured -0.0015 % at 13 Hz); the delay and lag act only inside the
 * control loop, which the iteration removes. With a bare DAC step (rig.shaker.hold: step) the peak
 * is 0.55 % low: the numerical side sees the staircase force only at the samples. */
static void test_default_rig_close_to_truth(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    const double freqs[2] = {13.0, 13.47};
    const double tol[2] = {1e-3, 2e-3};
    for (int i = 0; i < 2; i++) {
        double complex x[4];
        rths_error err;
        assert_int_equal(rths_frf(4, s.assembly.mass, s.assembly.damping, s.assembly.stiffness,
                                  s.force, 2 * M_PI * freqs[i], x, &err),
                         RTHS_OK);
        double a = matched_amplitude(&s, RTHS_SCHEME_DEFAULT, 0, freqs[i]);
        print_message("default rig at %.2f Hz: %.6e m, analytic %.6e m (%+.4f %%)\n", freqs[i], a,
                      cabs(x[2]), 100 * (a / cabs(x[2]) - 1));
        assert_close(a, cabs(x[2]), tol[i] * cabs(x[2]));
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Forcing on a physical storey (storey 2): the virtual rig's plant applies it in continuous
 * time, the controller keeps only its phase. At the matched target (ideal shaker, exact FOH)
 * the interface amplitude equals the analytic FRF of the assembly forced at storey 2 to 1e-4
 * (the same bound as for forcing on the numerical side; measured 3e-6), off and at the second
 * mode. A
 * controller created without plant_applies_forcing refuses such a split. */
static void test_forcing_on_physical_dof(void **state) {
    (void)state;
    const char *ov[] = {"forcing.dof=2"};
    rths_config *cfg;
    rths_setup s;
    rths_fixture_seed_setup(ov, 1, &cfg, &s);
    const double freqs[2] = {9.0, 13.47};
    for (int i = 0; i < 2; i++) {
        double complex x[4];
        rths_error err;
        assert_int_equal(rths_frf(4, s.assembly.mass, s.assembly.damping, s.assembly.stiffness,
                                  s.force, 2 * M_PI * freqs[i], x, &err),
                         RTHS_OK);
        double a = matched_amplitude(&s, RTHS_SCHEME_EXACT_FOH, 1, freqs[i]);
        print_message("forcing on storey 2, %.2f Hz: %.6e m, analytic %.6e m\n", freqs[i], a,
                      cabs(x[2]));
        assert_close(a, cabs(x[2]), 1e-4 * cabs(x[2]));
    }
    rths_controller_options co;
    rths_controller_defaults(&co);
    rths_controller *c;
    rths_error err;
    assert_int_equal(rths_controller_create(&s, &co, &c, &err), RTHS_EINPUT);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static void run_stream(const rths_setup *s, uint64_t seed, rths_period *out, int count) {
    rths_controller_options co;
    rths_plant_options po;
    rths_controller_defaults(&co);
    rths_plant_defaults(&po);
    po.seed = seed;
    rths_rig *rig = rths_fixture_rig(s, &co, &po);
    rths_error err;
    double a[1] = {1e-5}, b[1] = {-2e-5};
    assert_int_equal(rths_rig_set_forcing(rig, 13.2, 1.0, &err), RTHS_OK);
    assert_int_equal(rths_rig_set_target(rig, 1, a, b, &err), RTHS_OK);
    assert_int_equal(rths_rig_run_periods(rig, count, out, &err), RTHS_OK);
    assert_true(rths_rig_noise_level_m(rig) > 0);
    rths_rig_destroy(rig);
}

static void test_deterministic_for_a_seed(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    rths_period p1[5], p2[5], p3[5];
    run_stream(&s, 42, p1, 5);
    run_stream(&s, 42, p2, 5);
    run_stream(&s, 43, p3, 5);
    assert_memory_equal(p1, p2, sizeof p1);
    assert_true(memcmp(&p1[4].phys, &p3[4].phys, sizeof p1[4].phys) != 0);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Static force on storey 3 through the shaker: the bilinear leg below it carries the whole
 * force (storey 3 is the physical substructure's top), so its extension is
 * (F - preload) / k for a pulling net force and (F - preload) / (2 k) for a pushing one.
 * Heavy damping (by --set) lets the plant settle in a fraction of a second. */
static void test_bilinear_static_slopes(void **state) {
    (void)state;
    const char *ov[] = {"structure.bilinear.enabled=true",
                        "structure.storeys.damping_n_s_per_m=[800, 800, 800, 3.7421]"};
    rths_config *cfg;
    rths_setup s;
    rths_fixture_seed_setup(ov, 2, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    rths_plant_ideal(&po);
    const double k = 45052, preload = 26.68;
    for (double force = -40; force <= 80; force += 10) {
        rths_plant *p;
        rths_error err;
        if (rths_plant_create(&s, &po, 10000, &p, &err)) fail_msg("%s", err.msg);
        for (int i = 0; i < 20000; i++)
            rths_plant_advance(p, force / po.gain_n_per_v);
        rths_sensor_sample in;
        rths_plant_read(p, &in);
        double delta = in.displacement_m[2] - in.displacement_m[1];
        double net = force - preload;
        double expect = net >= 0 ? net / k : net / (2 * k);
        assert_close(delta, expect, 1e-9 + 1e-6 * fabs(expect));
        assert_close(rths_plant_leg_force_n(p, delta), net, 1e-6 * fabs(net) + 1e-9);
        rths_plant_destroy(p);
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Issue 18: out-of-range commands are refused with the key that bounds them, before they reach
 * the step: a frequency below controller.min_frequency_hz (1e-300 Hz overflowed the sample
 * budget of run_periods), a target whose peak is beyond the displacement limit; and a shaker
 * delay the plant cannot hold is a located configuration error naming rig.shaker.delay_s. */
static void test_refuses_out_of_range_commands(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    rths_rig *rig;
    rths_error err;
    if (rths_virtual_rig_create(cfg, &s, 0, 0, &rig, &err)) fail_msg("%s", err.msg);
    const double tiny[] = {1e-300, 0.05, -1, NAN};
    for (int i = 0; i < 4; i++) {
        assert_int_equal(rths_rig_set_forcing(rig, tiny[i], 1.0, &err), RTHS_EINPUT);
        assert_non_null(strstr(err.msg, "controller.min_frequency_hz"));
    }
    assert_int_equal(rths_rig_set_forcing(rig, 0.1, 1.0, &err), RTHS_OK);
    const double a_far[1] = {0.3}, b_far[1] = {0.4}; /* peak 0.5 m; the limit is 0.01 m */
    assert_int_equal(rths_rig_set_target(rig, 1, a_far, b_far, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "0.5 m"));
    assert_non_null(strstr(err.msg, "controller.limits.displacement_m"));
    const double a_ok[1] = {6e-3}, b_ok[1] = {8e-3}; /* peak exactly the limit: accepted */
    assert_int_equal(rths_rig_set_target(rig, 1, a_ok, b_ok, &err), RTHS_OK);
    rths_rig_destroy(rig);
    rths_setup_free(&s);
    rths_config_free(cfg);

    const char *ov[] = {"controller.sample_rate_hz=1000000", "rig.shaker.delay_s=0.05"};
    rths_fixture_seed_setup(ov, 2, &cfg, &s);
    assert_int_equal(rths_virtual_rig_create(cfg, &s, 0, 0, &rig, &err), RTHS_EINPUT);
    print_message("%s\n", err.msg);
    assert_non_null(strstr(err.msg, "key 'rig.shaker.delay_s'"));
    assert_non_null(strstr(err.msg, "50000 samples"));
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* One short session of the config's rig (5 periods at 13.2 Hz, then a 0.1 s trace): fills
 * periods and trace, returns the rig time it ran (s) and, in wall_s, the wall time it took. */
static double paced_session(rths_config *cfg, const rths_setup *s, rths_period *periods,
                            rths_trace_sample *trace, int *n_trace, double *wall_s) {
    rths_rig *rig;
    rths_error err;
    if (rths_virtual_rig_create(cfg, s, 0, 0, &rig, &err)) fail_msg("%s", err.msg);
    double a[1] = {1e-5}, b[1] = {-2e-5};
    assert_int_equal(rths_rig_set_forcing(rig, 13.2, 1.0, &err), RTHS_OK);
    assert_int_equal(rths_rig_set_target(rig, 1, a, b, &err), RTHS_OK);
    struct timespec t0, t1;
    double rig0 = rths_rig_time_s(rig);
    clock_gettime(CLOCK_MONOTONIC, &t0);
    assert_int_equal(rths_rig_run_periods(rig, 5, periods, &err), RTHS_OK);
    assert_int_equal(rths_rig_record_trace(rig, 0.1, 50, trace, n_trace, &err), RTHS_OK);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double rig_s = rths_rig_time_s(rig) - rig0;
    *wall_s = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    rths_rig_destroy(rig);
    return rig_s;
}

/* rig.pace = 4: the session takes at least its rig time / 4 of wall time (a lower bound only:
 * sleeping never makes a run faster, so this cannot flake on a loaded machine), and every period
 * coefficient and trace sample is bit-identical to the unpaced run's (pacing only sleeps).
 * Factors that are not a pace are refused, naming the key. */
static void test_pace_sleeps_without_changing_results(void **state) {
    (void)state;
    const double pace = 4;
    const char *paced_ov[] = {"rig.pace=4"};
    rths_config *cfg_fast, *cfg_paced;
    rths_setup s_fast, s_paced;
    rths_fixture_seed_setup(NULL, 0, &cfg_fast, &s_fast);
    rths_fixture_seed_setup(paced_ov, 1, &cfg_paced, &s_paced);
    rths_period p_fast[5], p_paced[5];
    rths_trace_sample t_fast[50], t_paced[50];
    int n_fast = 0, n_paced = 0;
    double wall_fast, wall_paced;
    double rig_fast = paced_session(cfg_fast, &s_fast, p_fast, t_fast, &n_fast, &wall_fast);
    double rig_paced = paced_session(cfg_paced, &s_paced, p_paced, t_paced, &n_paced, &wall_paced);
    print_message("rig %.4f s: unpaced %.4f s wall, paced x%g %.4f s wall (bound %.4f s)\n",
                  rig_paced, wall_fast, pace, wall_paced, rig_paced / pace);
    assert_true(rig_paced > 0.45); /* 5 periods of 1/13.2 s and 0.1 s: a bound worth testing */
    assert_true(wall_paced >= rig_paced / pace);
    assert_memory_equal(&rig_fast, &rig_paced, sizeof rig_fast);
    assert_memory_equal(p_fast, p_paced, sizeof p_fast);
    assert_int_equal(n_fast, n_paced);
    assert_memory_equal(t_fast, t_paced, sizeof t_fast[0] * (size_t)n_fast);
    rths_rig *rig;
    rths_error err;
    if (rths_virtual_rig_create(cfg_fast, &s_fast, 0, 0, &rig, &err)) fail_msg("%s", err.msg);
    const double bad[] = {-1, NAN, INFINITY, 2e6};
    for (int i = 0; i < 4; i++)
        assert_int_equal(rths_virtual_rig_set_pace(rig, bad[i], &err), RTHS_EINPUT);
    assert_int_equal(rths_virtual_rig_set_pace(rig, 0.5, &err), RTHS_OK);
    rths_rig_destroy(rig);
    rths_setup_free(&s_fast);
    rths_setup_free(&s_paced);
    rths_config_free(cfg_fast);
    rths_config_free(cfg_paced);
    const char *neg[] = {"rig.pace=-1"};
    rths_fixture_seed_setup(neg, 1, &cfg_fast, &s_fast);
    assert_int_equal(rths_virtual_rig_create(cfg_fast, &s_fast, 0, 0, &rig, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "rig.pace"));
    rths_setup_free(&s_fast);
    rths_config_free(cfg_fast);
}

/* ---- the experimental Floquet estimate on the virtual rig ---- */

/* Converges the interface match at f_hz on rig (default tolerances, tight enough for a held
 * orbit) and leaves the rig there. */
static void hold_matched(rths_rig *rig, const rths_setup *s, double f_hz) {
    rths_settle_options so;
    rths_newton_options no;
    rths_settle_defaults(&so, 0);
    rths_newton_defaults(&no, 0);
    no.rel_tolerance = 1e-5;
    rths_corrector_state st;
    memset(&st, 0, sizeof st);
    rths_solution sol;
    memset(&sol, 0, sizeof sol);
    sol.harmonics = 1;
    sol.omega_rad_s = 2 * M_PI * f_hz;
    rths_error err;
    if (rths_correct(rig, &so, &no, s->forcing_amplitude_n, NULL, &st, &sol, &err))
        fail_msg("%s", err.msg);
    assert_true(sol.converged);
}

/* Largest |exp(lambda T)| over the eigenvalues of the assembly's first-order form. */
static double assembly_max_multiplier(const rths_assembly *a, double period_s) {
    const int n = a->n, nx = 2 * n;
    double *minv_k = malloc(sizeof(double) * n * n), *minv_c = malloc(sizeof(double) * n * n);
    double *m = malloc(sizeof(double) * n * n), *big = calloc((size_t)(nx * nx), sizeof(double));
    double *wr = malloc(sizeof(double) * nx), *wi = malloc(sizeof(double) * nx), vl, vr;
    lapack_int *ipiv = malloc(sizeof(lapack_int) * n);
    memcpy(minv_k, a->stiffness, sizeof(double) * n * n);
    memcpy(minv_c, a->damping, sizeof(double) * n * n);
    memcpy(m, a->mass, sizeof(double) * n * n);
    if (LAPACKE_dgesv(LAPACK_COL_MAJOR, n, n, m, n, ipiv, minv_k, n)) fail_msg("dgesv");
    memcpy(m, a->mass, sizeof(double) * n * n);
    if (LAPACKE_dgesv(LAPACK_COL_MAJOR, n, n, m, n, ipiv, minv_c, n)) fail_msg("dgesv");
    for (int i = 0; i < n; i++) {
        big[i + (n + i) * nx] = 1;
        for (int j = 0; j < n; j++) {
            big[(n + i) + j * nx] = -minv_k[i + j * n];
            big[(n + i) + (n + j) * nx] = -minv_c[i + j * n];
        }
    }
    if (LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', nx, big, nx, wr, wi, &vl, 1, &vr, 1))
        fail_msg("dgeev");
    double mx = 0;
    for (int i = 0; i < nx; i++)
        mx = fmax(mx, exp(wr[i] * period_s));
    free(minv_k), free(minv_c), free(m), free(big), free(wr), free(wi), free(ipiv);
    return mx;
}

/* The perturbed per-sample loop allocates nothing (the loop's own test covers it unperturbed),
 * and the perturbation has the requested RMS: at a 200 Hz band limit its correlation time is
 * about 1.6 ms, so 3 s hold about 1900 independent stretches and the RMS is known to 1.6 %; 8 %
 * is five of those. */
static void test_perturbed_loop_allocates_nothing(void **state) {
    (void)state;
#ifdef __SANITIZE_ADDRESS__
    skip();
#else
    rths_config *cfg;
    rths_setup s;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    rths_controller_options co;
    rths_plant_options po;
    rths_controller_defaults(&co);
    rths_plant_defaults(&po);
    rths_sample_loop *loop;
    rths_error err;
    if (rths_sample_loop_create(&s, &co, &po, &loop, &err)) fail_msg("%s", err.msg);
    rths_controller *c = rths_sample_loop_controller(loop);
    assert_int_equal(rths_sample_loop_arm(loop), RTHS_OK);
    const double a[1] = {1e-5}, b[1] = {0};
    rths_controller_set_target(c, 1, a, b);
    rths_controller_set_forcing(c, 13.0, s.forcing_amplitude_n);
    assert_int_equal(rths_sample_loop_set_perturbation(loop, 0.05, 200, co.sample_rate_hz, 3), 0);
    double sum2 = 0;
    const int n = 30000;
    long before = allocations;
    for (int k = 0; k < n; k++) {
        rths_sample_loop_run(loop, NULL);
        double v = rths_sample_loop_perturbation_v(loop);
        sum2 += v * v;
    }
    assert_int_equal(allocations - before, 0);
    assert_int_equal(rths_controller_fault(c), RTHS_RIG_OK);
    assert_rel(sqrt(sum2 / n), 0.05, 0.08);
    assert_int_equal(rths_sample_loop_set_perturbation(loop, -1, 0, co.sample_rate_hz, 0),
                     RTHS_EINPUT);
    rths_sample_loop_destroy(loop);
    rths_setup_free(&s);
    rths_config_free(cfg);
#endif
}

/* A perturbed record repeats for a seed, differs for another, and leaves the rig unperturbed;
 * a rig without the operation is refused by name. */
static void test_perturbed_record_repeats_for_a_seed(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    enum { MAX = 20000 };
    rths_perturbed_sample *rec[3];
    int n[3];
    for (int r = 0; r < 3; r++) {
        rths_rig *rig;
        rths_error err;
        if (rths_virtual_rig_create(cfg, &s, 0, 0, &rig, &err)) fail_msg("%s", err.msg);
        assert_int_equal(rths_rig_set_forcing(rig, 13.0, s.forcing_amplitude_n, &err), 0);
        rths_perturbation p = {.rms_v = 0.02, .cutoff_hz = 5, .seed = r < 2 ? 9 : 10};
        rec[r] = malloc(MAX * sizeof *rec[r]);
        if (rths_rig_record_perturbed(rig, &p, 3, MAX, rec[r], &n[r], &err))
            fail_msg("%s", err.msg);
        /* 3 whole periods lie inside: at least 3, at most 5 periods of samples at 13 Hz */
        assert_true(n[r] >= 3 * 10000 / 13 && n[r] <= 5 * 10000 / 13 + 1);
        assert_true(rths_rig_can_record_perturbed(rig));
        rths_rig_destroy(rig);
    }
    assert_int_equal(n[0], n[1]);
    assert_memory_equal(rec[0], rec[1], (size_t)n[0] * sizeof *rec[0]);
    assert_true(rec[0][n[0] - 1].perturbation_v != rec[2][n[2] - 1].perturbation_v);
    for (int r = 0; r < 3; r++)
        free(rec[r]);
    rths_rig_ops none = {0};
    rths_rig *bare = rths_rig_create(&none, NULL, "bare");
    rths_perturbed_sample one;
    int got;
    rths_error err;
    rths_perturbation p = {.rms_v = 0.02};
    assert_int_equal(rths_rig_record_perturbed(bare, &p, 3, 1, &one, &got, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "bare"));
    rths_rig_destroy(bare);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* On the linear example (default noise, seed 1) the measured largest multiplier modulus lies
 * within 3e-3 of the assembly's, max |exp(lambda T)| (the first mode's, 0.9974..0.9978 over
 * 12..14 Hz), below and at the second mode's resonance and above it. Measured: 9.5e-4, 2.2e-3
 * (low: at the resonance the record is dominated by the second mode and sees the first one
 * least) and 1.2e-4; 3e-3 fails a closure that misses the first mode's damping
 * (1 - 0.9976 = 2.4e-3) by more than its own size, and an estimate that sees no damping at all. */
static void test_floquet_linear_rig(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    rths_fixture_setup("examples/four_storey_linear.yaml", NULL, 0, &cfg, &s);
    const double freqs_hz[3] = {12.0, 13.47, 14.0};
    for (int i = 0; i < 3; i++) {
        rths_rig *rig;
        if (rths_virtual_rig_create(cfg, &s, 0, 0, &rig, &err)) fail_msg("%s", err.msg);
        hold_matched(rig, &s, freqs_hz[i]);
        rths_floquet_measure_options o;
        rths_floquet_measure_defaults(&o);
        rths_floquet_estimate e;
        double rig_s;
        if (rths_floquet_measure(rig, freqs_hz[i], &o, 5, &e, &rig_s, &err))
            fail_msg("%s", err.msg);
        double truth = assembly_max_multiplier(&s.assembly, 1 / freqs_hz[i]);
        printf("%.2f Hz: largest |mu| %.5f, truth %.5f (order %d, residual %.3g, condition %.3g, "
               "halves %.5f %.5f, %.1f s of rig time)\n",
               freqs_hz[i], e.max_abs, truth, e.order, e.relative_residual, e.condition,
               e.max_abs_half[0], e.max_abs_half[1], rig_s);
        assert_close(e.max_abs, truth, 3e-3);
        assert_true(e.stable);
        /* 120 periods of rig time, plus at most one period of alignment */
        assert_true(rig_s > 120 / freqs_hz[i] && rig_s < 122.5 / freqs_hz[i]);
        rths_rig_destroy(rig);
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_matched_equals_fidelity),
        cmocka_unit_test(test_default_rig_close_to_truth),
        cmocka_unit_test(test_deterministic_for_a_seed),
        cmocka_unit_test(test_bilinear_static_slopes),
        cmocka_unit_test(test_forcing_on_physical_dof),
        cmocka_unit_test(test_refuses_out_of_range_commands),
        cmocka_unit_test(test_pace_sleeps_without_changing_results),
        cmocka_unit_test(test_perturbed_loop_allocates_nothing),
        cmocka_unit_test(test_perturbed_record_repeats_for_a_seed),
        cmocka_unit_test(test_floquet_linear_rig),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
