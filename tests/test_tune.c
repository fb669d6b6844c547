/* rths tune (docs/method.md, "Tuning the gains"): the sampled PD loop's stability against closed
 * forms and independent simulations, its margins against its own spectral radius, the grounding
 * check against the controller's, and the tuned seed's gains. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>

#include <cmocka.h>

#include "testlib.h"

#include "rths/controller.h"
#include "rths/tune.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A free mass m on an ideal actuator (force g u, no lag, no armature) with a step hold (ZOH) and
 * the raw backward difference, no delay. Its pulse transfer X/F = (h^2 / 2m)(z + 1)/(z - 1)^2 with
 * u = -(kp x_k + kd (x_k - x_{k-1}) / h) gives the characteristic cubic
 *   z^3 + (b c1 - 2) z^2 + (1 + b (c1 - c0)) z - b c0,  b = g h^2 / 2m, c1 = kp + kd / h,
 *   c0 = kd / h,
 * stable by Jury's test iff P(1) > 0, -P(-1) > 0, |a0| < 1 and |a0^2 - 1| > |a0 a2 - a1|. */
static int jury_stable(double m, double g, double h, double kp, double kd) {
    double b = g * h * h / (2 * m), c1 = kp + kd / h, c0 = kd / h;
    double a2 = b * c1 - 2, a1 = 1 + b * (c1 - c0), a0 = -b * c0;
    double p1 = 1 + a2 + a1 + a0, pm1 = -1 + a2 - a1 + a0;
    return p1 > 0 && -pm1 > 0 && fabs(a0) < 1 && fabs(a0 * a0 - 1) > fabs(a0 * a2 - a1);
}

static rths_pd_loop *free_mass_loop(double m, double g, double rate, double cutoff, double delay_s,
                                    int linear_hold) {
    rths_plant_options rig;
    rths_plant_defaults(&rig);
    rig.gain_n_per_v = g;
    rig.delay_s = delay_s;
    rig.lag_cutoff_hz = 0;
    rig.armature_mass_kg = 0;
    rig.linear_hold = linear_hold;
    double mass = m, zero = 0;
    rths_pd_loop_spec spec = {.n = 1,
                              .mass = &mass,
                              .damping = &zero,
                              .stiffness = &zero,
                              .sample_rate_hz = rate,
                              .velocity_cutoff_hz = cutoff,
                              .rig = &rig};
    rths_pd_loop *loop;
    rths_error err;
    if (rths_pd_loop_create(&spec, &loop, &err)) fail_msg("%s", err.msg);
    return loop;
}

/* The spectral radius agrees with Jury's closed form on a grid of (kp, kd) around the boundary,
 * and the boundary in kp at fixed kd (bisection of the closed form) is where the radius crosses
 * 1, to 1e-6. */
static void test_free_mass_matches_jury(void **state) {
    (void)state;
    const double m = 2.0, g = 40.0, rate = 1000.0, h = 1.0 / rate;
    rths_pd_loop *loop = free_mass_loop(m, g, rate, 0, 0, 0);
    assert_int_equal(rths_pd_loop_delay_samples(loop), 0);
    int stable_count = 0, checked = 0;
    for (int i = 0; i <= 20; i++)
        for (int j = 0; j <= 20; j++) {
            double kd = 2 * m / (g * h) * pow(10.0, -3 + 0.16 * i); /* up to 1.6x |a0| = 1 */
            double kp = 2 * m / (g * h * h) * pow(10.0, -5 + 0.3 * j);
            int truth = jury_stable(m, g, h, kp, kd);
            double r = rths_pd_loop_radius(loop, kp, kd);
            assert_true(r >= 0);
            if (fabs(r - 1) < 1e-9) continue; /* on the boundary itself */
            checked++;
            stable_count += truth;
            if (truth != (r < 1))
                fail_msg("kp %g kd %g: Jury says %s, spectral radius %.12f", kp, kd,
                         truth ? "stable" : "unstable", r);
        }
    assert_true(stable_count > 30 && stable_count < checked - 30); /* both sides sampled */
    /* boundary in kp at kd = 0.4 of the a0 limit */
    double kd = 0.4 * 2 * m / (g * h), lo = 1e-3, hi = 1e9;
    assert_true(jury_stable(m, g, h, lo, kd) && !jury_stable(m, g, h, hi, kd));
    for (int it = 0; it < 200; it++) {
        double mid = sqrt(lo * hi);
        if (jury_stable(m, g, h, mid, kd))
            lo = mid;
        else
            hi = mid;
    }
    print_message("free mass, ZOH, no delay: kp boundary %.6g V/m at kd %.6g V s/m\n", lo, kd);
    assert_true(rths_pd_loop_radius(loop, lo * (1 - 1e-6), kd) < 1);
    assert_true(rths_pd_loop_radius(loop, lo * (1 + 1e-6), kd) > 1);
    rths_pd_loop_destroy(loop);
}

/* Growth of the same discrete loop simulated step by step from its definition (not through the
 * module's matrices): the free mass integrated exactly under a force that is piecewise linear in
 * time. The demand u_j becomes the command w_j = g u_j; before the fractional delay, sample j's
 * command ramps from w_{j-D-1} to w_{j-D} (linear hold) or holds w_{j-D} (step); the fraction
 * f h shifts that signal, so sample k sees the last f h of sample k - 1's segment, then the first
 * (1 - f) h of its own. The velocity by the filtered backward difference. Returns the log growth
 * per sample of the peak |x| between the middle and the end. */
static double segment(const double *w, int j, int delay, int linear, double t_over_h) {
    double end = j - delay >= 0 ? w[j - delay] : 0,
           start = j - delay - 1 >= 0 ? w[j - delay - 1] : 0;
    return linear ? start + (end - start) * t_over_h : end;
}

static void mass_advance(double m, double length, double f0, double f1, double *x, double *v) {
    *x += *v * length + length * length * (f0 / 2 + (f1 - f0) / 6) / m;
    *v += length * (f0 + f1) / 2 / m;
}

static double simulated_growth(double m, double g, double h, double alpha, int delay,
                               double fraction, int linear, double kp, double kd, int steps) {
    double *w = calloc((size_t)steps, sizeof(double));
    assert_non_null(w);
    double x = 1e-3, v = 0, x_prev = x, v_est = 0, peak_mid = 0, peak_end = 0;
    for (int k = 0; k < steps; k++) {
        v_est = alpha * v_est + (1 - alpha) * (x - x_prev) / h;
        x_prev = x;
        w[k] = g * (-kp * x - kd * v_est);
        if (fraction > 0)
            mass_advance(m, fraction * h, segment(w, k - 1, delay, linear, 1 - fraction),
                         segment(w, k - 1, delay, linear, 1), &x, &v);
        mass_advance(m, (1 - fraction) * h, segment(w, k, delay, linear, 0),
                     segment(w, k, delay, linear, 1 - fraction), &x, &v);
        if (k >= steps / 2 && k < steps / 2 + 200) peak_mid = fmax(peak_mid, fabs(x));
        if (k >= steps - 200) peak_end = fmax(peak_end, fabs(x));
    }
    free(w);
    return log(peak_end / peak_mid) / (steps / 2.0);
}

/* With a transport delay of whole samples and a fraction, a linear or step hold and the filtered
 * differentiator, the boundary (both gains scaled together) found from the spectral radius
 * separates decaying from growing simulations: 3 % inside decays, 3 % outside grows. */
static void test_delayed_loop_matches_simulation(void **state) {
    (void)state;
    const double m = 5.0, g = 20.0, rate = 4096.0, h = 1.0 / rate, cutoff = 600.0;
    const double alpha = exp(-2 * M_PI * cutoff * h);
    const double delays[5] = {0, 0.3, 2, 2.5, 7.8};
    for (int c = 0; c < 5; c++)
        for (int linear = 0; linear <= 1; linear++) {
            rths_pd_loop *loop = free_mass_loop(m, g, rate, cutoff, delays[c] * h, linear);
            int whole = (int)floor(delays[c]);
            double fraction = delays[c] - whole;
            assert_int_equal(rths_pd_loop_delay_samples(loop), whole);
            assert_close(rths_pd_loop_delay_fraction(loop), fraction, 1e-9);
            /* kd / kp = 0.05 s: a PD that stabilises the mass at low gain */
            double lo = 1e-3, hi = 1e9;
            assert_true(rths_pd_loop_radius(loop, lo, 0.05 * lo) < 1);
            assert_true(rths_pd_loop_radius(loop, hi, 0.05 * hi) > 1);
            for (int it = 0; it < 100; it++) {
                double mid = sqrt(lo * hi);
                if (rths_pd_loop_radius(loop, mid, 0.05 * mid) < 1)
                    lo = mid;
                else
                    hi = mid;
            }
            double in = simulated_growth(m, g, h, alpha, whole, fraction, linear, 0.97 * lo,
                                         0.05 * 0.97 * lo, 60000);
            double out = simulated_growth(m, g, h, alpha, whole, fraction, linear, 1.03 * lo,
                                          0.05 * 1.03 * lo, 60000);
            print_message("delay %.1f samples, %s hold: boundary kp %.6g V/m; growth per sample "
                          "%.3g inside, %.3g outside\n",
                          delays[c], linear ? "linear" : "step", lo, in, out);
            assert_true(in < 0);
            assert_true(out > 0);
            rths_pd_loop_destroy(loop);
        }
}

static void test_lag_equals_transfer_function(void **state) {
    (void)state;
    double mass[4] = {3, 0, 0, 1.5}, damp[4] = {12, -4, -4, 4}, stiff[4] = {3e4, -1e4, -1e4, 1e4};
    rths_plant_options shaker, tf;
    rths_plant_defaults(&shaker);
    shaker.gain_n_per_v = 25;
    shaker.lag_cutoff_hz = 300;
    shaker.armature_mass_kg = 0;
    shaker.delay_s = 5e-4;
    tf = shaker;
    tf.actuator.model = RTHS_ACTUATOR_TRANSFER_FUNCTION;
    tf.actuator.numerator_count = 1;
    tf.actuator.numerator[0] = 25;
    tf.actuator.denominator_count = 2;
    tf.actuator.denominator[0] = 1 / (2 * M_PI * 300);
    tf.actuator.denominator[1] = 1;
    tf.actuator.velocity_feedback = 0;
    tf.actuator.velocity_feedback_count = 0;
    rths_pd_loop_spec spec = {.n = 2,
                              .mass = mass,
                              .damping = damp,
                              .stiffness = stiff,
                              .sample_rate_hz = 10000,
                              .velocity_cutoff_hz = 1000,
                              .rig = &shaker};
    rths_pd_loop *a, *b;
    rths_error err;
    if (rths_pd_loop_create(&spec, &a, &err)) fail_msg("%s", err.msg);
    spec.rig = &tf;
    if (rths_pd_loop_create(&spec, &b, &err)) fail_msg("%s", err.msg);
    for (int i = 0; i < 8; i++) {
        double kp = 100 * pow(4.0, i), kd = 0.02 * kp;
        rths_loop_margins ma, mb;
        assert_int_equal(rths_pd_loop_margins(a, kp, kd, &ma, &err), RTHS_OK);
        assert_int_equal(rths_pd_loop_margins(b, kp, kd, &mb, &err), RTHS_OK);
        assert_close(ma.spectral_radius, mb.spectral_radius, 1e-9);
        if (isfinite(ma.gain_margin_db)) assert_close(ma.gain_margin_db, mb.gain_margin_db, 1e-6);
    }
    rths_pd_loop_destroy(a);
    rths_pd_loop_destroy(b);
}

static void seed(const char *const *sets, int n_sets, rths_config **cfg, rths_setup *s,
                 rths_controller_options *copt, rths_plant_options *popt) {
    rths_error err;
    if (rths_config_load(rths_test_source_path("examples/four_storey.yaml"), sets, n_sets, cfg,
                         &err) ||
        rths_setup_read(*cfg, s, &err))
        fail_msg("%s", err.msg);
    rths_controller_defaults(copt);
    rths_plant_defaults(popt);
    if (rths_sample_loop_config_read(*cfg, copt, popt, &err)) fail_msg("%s", err.msg);
}

/* The gain margin from the frequency response is the factor on both gains at which the spectral
 * radius reaches 1 (to the grid's 1 %); the seed's and a tuned pair's. */
static void test_gain_margin_is_the_radius_boundary(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_controller_options copt;
    rths_plant_options popt;
    seed(NULL, 0, &cfg, &s, &copt, &popt);
    rths_pd_loop *loop;
    rths_error err;
    if (rths_pd_loop_from_setup(&s, &copt, &popt, -1, &loop, &err)) fail_msg("%s", err.msg);
    assert_int_equal(rths_pd_loop_delay_samples(loop), 3); /* 2.5e-4 s at 10 kHz, rounded */
    const double pairs[3][2] = {{100, 10}, {891.251, 100}, {2000, 30}};
    for (int i = 0; i < 3; i++) {
        rths_loop_margins mg;
        assert_int_equal(rths_pd_loop_margins(loop, pairs[i][0], pairs[i][1], &mg, &err), 0);
        assert_true(mg.stable);
        assert_true(isfinite(mg.gain_margin_db));
        double c = pow(10.0, mg.gain_margin_db / 20);
        print_message("kp %g kd %g: gain margin %.3f dB (x%.4f) at %.1f Hz, phase margin %.1f "
                      "deg, radius at x0.99 %.8f, x1.01 %.8f\n",
                      pairs[i][0], pairs[i][1], mg.gain_margin_db, c, mg.gain_margin_hz,
                      mg.phase_margin_deg,
                      rths_pd_loop_radius(loop, 0.99 * c * pairs[i][0], 0.99 * c * pairs[i][1]),
                      rths_pd_loop_radius(loop, 1.01 * c * pairs[i][0], 1.01 * c * pairs[i][1]));
        assert_true(rths_pd_loop_radius(loop, 0.99 * c * pairs[i][0], 0.99 * c * pairs[i][1]) < 1);
        assert_true(rths_pd_loop_radius(loop, 1.01 * c * pairs[i][0], 1.01 * c * pairs[i][1]) > 1);
    }
    rths_pd_loop_destroy(loop);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* The virtual rig (plant.c and step.c) with the gains in o, rig noise on, the target at rest and
 * the limits wide but for 1 mm of displacement: whether a limit trips within 30000 samples
 * (asserted as expected: outside the loop's boundary it must, inside it must not). */
static void rig_trips_as_expected(const rths_setup *s, const rths_controller_options *gains,
                                  const rths_plant_options *popt, int outside, double factor,
                                  const char *boundary) {
    rths_controller_options o = *gains;
    o.demand_limit_v = 1e6;
    o.force_limit_n = 1e9;
    o.displacement_limit_m = 1e-3;
    o.ramp_time_s = 0;
    rths_plant_options p = *popt;
    p.noise = 1;
    rths_sample_loop *sl;
    rths_error err;
    if (rths_sample_loop_create(s, &o, &p, &sl, &err)) fail_msg("%s", err.msg);
    assert_int_equal(rths_sample_loop_arm(sl), RTHS_OK);
    long tripped_at = -1;
    for (long k = 0; k < 30000 && tripped_at < 0; k++) {
        rths_sample_loop_run(sl, NULL);
        if (rths_controller_fault(rths_sample_loop_controller(sl)) != RTHS_RIG_OK) tripped_at = k;
    }
    print_message("  %s %s (x%.3f): %s\n", outside ? "outside" : "inside", boundary, factor,
                  tripped_at >= 0 ? "tripped" : "quiet for 30000 samples");
    if (outside)
        assert_true(tripped_at >= 0);
    else
        assert_true(tripped_at < 0);
    rths_sample_loop_destroy(sl);
}

/* End to end on the virtual rig itself (plant.c and step.c, not this module's model): with rig
 * noise on and the target at rest, the configured PD gains scaled together to 5 % beyond the
 * loop's boundary grow until a limit trips, 5 % inside stay quiet for 30000 samples. The seed's
 * shaker (3-sample delay, lag, armature, linear hold) and the servo-hydraulic light specimen
 * (transfer function with the polynomial velocity path, physical_share, step hold, 4096 Hz; its
 * DAC off, so that the loop is linear). */
static void rig_agrees(const char *example, const char *const *sets, int n_sets) {
    rths_config *cfg;
    rths_setup s;
    rths_controller_options copt;
    rths_plant_options popt;
    rths_error err;
    if (rths_config_load(rths_test_source_path(example), sets, n_sets, &cfg, &err) ||
        rths_setup_read(cfg, &s, &err))
        fail_msg("%s", err.msg);
    rths_controller_defaults(&copt);
    rths_plant_defaults(&popt);
    if (rths_sample_loop_config_read(cfg, &copt, &popt, &err)) fail_msg("%s", err.msg);
    popt.actuator.dac_bits = 0;
    rths_pd_loop *loop;
    if (rths_pd_loop_from_setup(&s, &copt, &popt, -1, &loop, &err)) fail_msg("%s", err.msg);
    const double kp0 = copt.kp_v_per_m, kd0 = copt.kd_v_s_per_m;
    double lo = 1e-3, hi = 1e4;
    assert_true(rths_pd_loop_radius(loop, lo * kp0, lo * kd0) < 1);
    assert_true(rths_pd_loop_radius(loop, hi * kp0, hi * kd0) > 1);
    for (int it = 0; it < 80; it++) {
        double mid = sqrt(lo * hi);
        if (rths_pd_loop_radius(loop, mid * kp0, mid * kd0) < 1)
            lo = mid;
        else
            hi = mid;
    }
    rths_pd_loop_destroy(loop);
    print_message("%s: boundary at %.4f x (kp %.6g, kd %.6g)\n", example, lo, lo * kp0, lo * kd0);
    for (int outside = 0; outside <= 1; outside++) {
        double f = (outside ? 1.05 : 0.95) * lo;
        rths_controller_options o = copt;
        o.kp_v_per_m = f * kp0;
        o.kd_v_s_per_m = f * kd0;
        rig_trips_as_expected(&s, &o, &popt, outside, f, "the boundary");
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static void test_virtual_rig_agrees(void **state) {
    (void)state;
    const char *seed_sets[] = {"controller.kp_v_per_m=891.251", "controller.kd_v_s_per_m=100"};
    rig_agrees("examples/four_storey.yaml", seed_sets, 2);
    rig_agrees("examples/frame_servo_hydraulic.yaml", NULL, 0);
}

/* The grounding check repeats step.c's: rths_controller_create accepts exactly the gains whose
 * radius is at most 1 (+1e-9, its tolerance), over gains from the seed's to far beyond. */
static void test_grounding_matches_controller(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_controller_options copt;
    rths_plant_options popt;
    seed(NULL, 0, &cfg, &s, &copt, &popt);
    int accepted = 0, refused = 0;
    for (int i = 0; i < 12; i++)
        for (int j = 0; j < 6; j++) {
            rths_controller_options o = copt;
            o.grounding_kp_n_per_m = 5e4 * pow(10.0, 0.5 * i);
            o.grounding_kd_n_s_per_m = 1e3 * pow(10.0, 0.6 * j);
            rths_error err;
            double r = rths_grounding_radius(&s, &o, &o.grounding_kp_n_per_m,
                                             &o.grounding_kd_n_s_per_m, &err);
            assert_true(r >= 0);
            rths_controller *c = NULL;
            int rc = rths_controller_create(&s, &o, &c, &err);
            rths_controller_destroy(c);
            if (fabs(r - 1) < 1e-6) continue;
            assert_int_equal(rc == RTHS_OK, r <= 1 + 1e-9);
            accepted += rc == RTHS_OK;
            refused += rc != RTHS_OK;
        }
    assert_true(accepted > 5 && refused > 5);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* The seed's tuned gains meet the rule by the module's own independent checks: stable, margins
 * at least 6 dB and 45 deg, stable at 1.9x both gains; the grounding stable at 2x; and a
 * deliberately bad configured pair (kp 1e5 V/m) is reported unstable. */
static void test_tune_seed(void **state) {
    (void)state;
    const char *sets[] = {"controller.kp_v_per_m=1e5"};
    rths_config *cfg;
    rths_setup s;
    rths_controller_options copt;
    rths_plant_options popt;
    seed(sets, 1, &cfg, &s, &copt, &popt);
    rths_tune_rule rule;
    rths_tune_rule_defaults(&rule);
    rths_tune_result r;
    rths_error err;
    if (rths_tune(&s, &copt, &popt, &rule, &r, &err)) fail_msg("%s", err.msg);
    print_message("seed tuned: kp %g kd %g (GM %.2f dB, PM %.1f deg, bandwidth %.1f Hz); "
                  "grounding %g, %g (radius %.9f, at 2x %.9f); configured kp 1e5: radius %.4f\n",
                  r.kp_v_per_m, r.kd_v_s_per_m, r.tuned.gain_margin_db, r.tuned.phase_margin_deg,
                  r.tuned.bandwidth_hz, r.grounding_kp[0], r.grounding_kd[0], r.grounding_radius,
                  r.grounding_radius_margin, r.current.spectral_radius);
    assert_false(r.current.stable);
    assert_true(r.current.spectral_radius > 1);
    assert_true(r.tuned.stable && r.tuned.spectral_radius < 1);
    assert_true(r.tuned.gain_margin_db >= 6 && r.tuned.phase_margin_deg >= 45);
    rths_pd_loop *loop;
    if (rths_pd_loop_from_setup(&s, &copt, &popt, -1, &loop, &err)) fail_msg("%s", err.msg);
    assert_true(rths_pd_loop_radius(loop, 1.9 * r.kp_v_per_m, 1.9 * r.kd_v_s_per_m) < 1);
    rths_pd_loop_destroy(loop);
    double kp2 = 2 * r.grounding_kp[0], kd2 = 2 * r.grounding_kd[0];
    assert_true(rths_grounding_radius(&s, &copt, &kp2, &kd2, &err) < 1);
    assert_true(r.grounding_radius < 1);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Several interface DoFs (docs/method.md, "Tuning the gains"): the two-interface building (two
 * shakers on two storeys) and the cantilever with two shakers (a translation and a rotation at
 * the cut, actuator and sensor transforms, the armatures at the actuators' points). The tuned
 * gains meet the rule loop by loop (others closed) and the coupled loop is stable with every gain
 * doubled; each loop's gain margin is where the coupled spectral radius reaches 1 when that
 * loop's gains alone are scaled (1 %), which checks the broken-loop formula against the
 * eigenvalues; and the virtual rig itself (plant.c with the transforms and armatures, step.c's
 * PD through the inverse transforms), noise on and the target at rest, stays quiet for 30000
 * samples with every tuned gain at 0.95 times the coupled boundary and trips a limit at 1.05
 * times it, the boundary at least 2 (6 dB) times the tuned gains. */
static void tune_dofs_check(const char *example) {
    rths_config *cfg;
    rths_setup s;
    rths_controller_options copt;
    rths_plant_options popt;
    rths_error err;
    if (rths_config_load(rths_test_source_path(example), NULL, 0, &cfg, &err) ||
        rths_setup_read(cfg, &s, &err))
        fail_msg("%s", err.msg);
    rths_controller_defaults(&copt);
    rths_plant_defaults(&popt);
    if (rths_sample_loop_config_read(cfg, &copt, &popt, &err)) fail_msg("%s", err.msg);
    popt.actuator.dac_bits = 0;
    rths_tune_rule rule;
    rths_tune_rule_defaults(&rule);
    rths_tune_result r;
    if (rths_tune(&s, &copt, &popt, &rule, &r, &err)) fail_msg("%s", err.msg);
    const int ni = r.n_int;
    assert_int_equal(ni, 2);
    print_message("%s: tuned kp [%g, %g], kd [%g, %g], coupled radius %.6f, coupled margin "
                  "%.2f dB; grounding [%g, %g], [%g, %g]\n",
                  example, r.kp[0], r.kp[1], r.kd[0], r.kd[1], r.tuned.spectral_radius,
                  r.coupled_gain_margin_db, r.grounding_kp[0], r.grounding_kp[1], r.grounding_kd[0],
                  r.grounding_kd[1]);
    assert_true(r.tuned.stable && r.tuned.spectral_radius < 1);
    assert_true(r.coupled_gain_margin_db >= 6);
    assert_true(r.coupled_radius_at_margin < 1);
    assert_true(r.grounding_radius < 1 && r.grounding_radius_margin < 1);
    rths_pd_loop *loop;
    if (rths_pd_loop_from_setup(&s, &copt, &popt, -1, &loop, &err)) fail_msg("%s", err.msg);
    for (int d = 0; d < ni; d++) {
        const rths_loop_margins *m = &r.tuned_dof[d];
        print_message("  loop %d: GM %.2f dB at %.1f Hz, PM %.1f deg at %.1f Hz, bandwidth "
                      "%.1f Hz\n",
                      d + 1, m->gain_margin_db, m->gain_margin_hz, m->phase_margin_deg,
                      m->crossover_hz, m->bandwidth_hz);
        assert_true(r.kp[d] > 0);
        assert_true(m->gain_margin_db >= 6 && m->phase_margin_deg >= 45);
        double c = pow(10.0, m->gain_margin_db / 20), kp[2] = {r.kp[0], r.kp[1]},
               kd[2] = {r.kd[0], r.kd[1]};
        kp[d] = 0.99 * c * r.kp[d], kd[d] = 0.99 * c * r.kd[d];
        double inside = rths_pd_loop_radius_dofs(loop, kp, kd);
        kp[d] = 1.01 * c * r.kp[d], kd[d] = 1.01 * c * r.kd[d];
        double outside = rths_pd_loop_radius_dofs(loop, kp, kd);
        print_message("  loop %d's gains alone at 0.99 / 1.01 x its margin: radius %.6f / %.6f\n",
                      d + 1, inside, outside);
        assert_true(inside < 1);
        assert_true(outside > 1);
    }
    /* the coupled boundary: every gain scaled together */
    double lo = 1, hi = 1e3, kp[2], kd[2];
    for (int it = 0; it < 60; it++) {
        double mid = sqrt(lo * hi);
        for (int d = 0; d < ni; d++)
            kp[d] = mid * r.kp[d], kd[d] = mid * r.kd[d];
        if (rths_pd_loop_radius_dofs(loop, kp, kd) < 1)
            lo = mid;
        else
            hi = mid;
    }
    rths_pd_loop_destroy(loop);
    print_message("  coupled boundary at %.4f x the tuned gains (%.2f dB)\n", lo, 20 * log10(lo));
    assert_true(lo >= 2);
    assert_close(20 * log10(lo), r.coupled_gain_margin_db, 0.02);
    for (int outside = 0; outside <= 1; outside++) {
        double f = (outside ? 1.05 : 0.95) * lo;
        rths_controller_options o = copt;
        for (int d = 0; d < ni; d++) {
            o.kp_dof_v_per_m[d] = f * r.kp[d];
            o.kd_dof_v_s_per_m[d] = f * r.kd[d];
            o.grounding_kp_dof[d] = r.grounding_kp[d];
            o.grounding_kd_dof[d] = r.grounding_kd[d];
        }
        rig_trips_as_expected(&s, &o, &popt, outside, f, "the coupled boundary");
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static void test_tune_two_interface_storeys(void **state) {
    (void)state;
    tune_dofs_check("examples/two_interface_storeys.yaml");
}

static void test_tune_cantilever_two_shakers(void **state) {
    (void)state;
    tune_dofs_check("examples/cantilever_two_shakers.yaml");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_free_mass_matches_jury),
        cmocka_unit_test(test_delayed_loop_matches_simulation),
        cmocka_unit_test(test_lag_equals_transfer_function),
        cmocka_unit_test(test_gain_margin_is_the_radius_boundary),
        cmocka_unit_test(test_virtual_rig_agrees),
        cmocka_unit_test(test_grounding_matches_controller),
        cmocka_unit_test(test_tune_seed),
        cmocka_unit_test(test_tune_two_interface_storeys),
        cmocka_unit_test(test_tune_cantilever_two_shakers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
