/* The per-sample controller step: allocation-free and library-call-free by construction and by
 * measurement; Fourier sums exact for known sinusoids, phase-continuous across a frequency
 * change; limits latch and ramp the demand to zero. */
#include "testlib.h"

#include "rths/controller.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

static void seed_setup(rths_setup *s, rths_config **cfg) {
    rths_error err;
    if (rths_config_load(rths_test_source_path("examples/four_storey.yaml"), NULL, 0, cfg, &err) ||
        rths_setup_read(*cfg, s, &err))
        fail_msg("%s", err.msg);
}

static rths_controller *make(rths_setup *s, rths_config **cfg, rths_controller_options *o) {
    seed_setup(s, cfg);
    rths_controller_defaults(o);
    rths_controller *c;
    rths_error err;
    if (rths_controller_create(s, o, &c, &err)) fail_msg("%s", err.msg);
    return c;
}

/* 100000 steps with forcing, target and period publication allocate nothing. */
static void test_step_allocates_nothing(void **state) {
    (void)state;
#ifdef __SANITIZE_ADDRESS__
    skip();
#else
    rths_setup s;
    rths_config *cfg;
    rths_controller_options o;
    rths_controller *c = make(&s, &cfg, &o);
    double a[1] = {1e-5}, b[1] = {0};
    rths_controller_set_forcing(c, 13.0, 1.0);
    rths_controller_set_target(c, 1, a, b);
    rths_controller_arm(c, 1);
    rths_sensor_sample in = {.n = 3};
    rths_controller_output out;
    long before = allocations;
    for (int i = 0; i < 100000; i++) {
        in.displacement_m[2] = 1e-5 * sin(2 * M_PI * 13.0 * i * 1e-4);
        rths_controller_step(c, &in, &out);
    }
    long during = allocations - before;
    assert_int_equal(during, 0);
    rths_period p;
    int periods = 0;
    while (rths_controller_pop_period(c, &p))
        periods++;
    assert_true(periods >= 129); /* 10 s at 13 Hz, ring of 256 */
    rths_controller_destroy(c);
    rths_setup_free(&s);
    rths_config_free(cfg);
#endif
}

/* By construction: the step's source calls no allocator, lock, printing or LAPACK. */
static void test_step_source_is_clean(void **state) {
    (void)state;
    FILE *f = fopen(rths_test_source_path("src/controller/step.c"), "r");
    assert_non_null(f);
    char line[512];
    int in_step = 0, n = 0;
    while (fgets(line, sizeof line, f)) {
        n++;
        if (strstr(line, "double rths_controller_step(")) in_step = 1;
        if (in_step && line[0] == '}') in_step = 0;
        if (strstr(line, "lapack") || strstr(line, "LAPACK_") || strstr(line, "cblas"))
            fail_msg("step.c:%d mentions LAPACK/BLAS: %s", n, line);
        if (in_step && (strstr(line, "alloc(") || strstr(line, "printf") || strstr(line, "mutex") ||
                        strstr(line, "free(") || strstr(line, "puts")))
            fail_msg("step.c:%d: %s", n, line);
    }
    fclose(f);
}

/* Measured signals that are exact sinusoids give exact coefficients (trapezoid in theta with
 * exact period ends: error O((omega h)^2), here < 1e-5 relative). */
static void test_fourier_sums_exact(void **state) {
    (void)state;
    rths_setup s;
    rths_config *cfg;
    rths_controller_options o;
    rths_controller *c = make(&s, &cfg, &o);
    const double f = 13.3, h = 1e-4, w = 2 * M_PI * f;
    rths_controller_set_forcing(c, f, 0.0);
    rths_sensor_sample in = {.n = 3};
    rths_period p;
    int got = 0;
    for (int i = 1; got < 5; i++) {
        double t = i * h;
        in.displacement_m[2] = 2e-6 + 3e-5 * cos(w * t) - 4e-5 * sin(w * t) + 5e-6 * sin(3 * w * t);
        in.interface_force_n = 0.7 * cos(2 * w * t);
        rths_controller_step(c, &in, NULL);
        if (rths_controller_pop_period(c, &p)) {
            got++;
            /* end of period k at k / f */
            assert_close(p.end_time_s, got / f, 1e-12);
            if (got == 1) continue; /* the first period starts without a previous sample */
            assert_close(p.frequency_hz, f, 0);
            assert_close(p.phys.a[0], 2e-6, 1e-10);
            assert_close(p.phys.a[1], 3e-5, 3e-10);
            assert_close(p.phys.b[1], -4e-5, 3e-10);
            assert_close(p.phys.b[3], 5e-6, 3e-10);
            assert_close(p.phys.a[2], 0, 3e-10);
            assert_close(p.force.a[2], 0.7, 1e-5);
            assert_true(abs(p.samples - (int)(1 / (f * h))) <= 1);
        }
    }
    /* frequency change: takes effect at the next period boundary and the phase stays
     * continuous, so a signal generated with the phase accumulated the same way keeps exact
     * coefficients in every later period */
    double phase = 0;
    {
        /* the phase the first loop ran at: w t at its last sample */
        long samples = lround(rths_controller_time_s(c) / h);
        phase = fmod(w * h * (double)samples, 2 * M_PI);
    }
    rths_controller_set_forcing(c, 12.1, 0.0);
    double w_now = w;
    got = 0;
    for (int i = 0; got < 4; i++) {
        phase += w_now * h;
        in.displacement_m[2] = 1e-5 * cos(phase);
        in.interface_force_n = 0;
        rths_controller_step(c, &in, NULL);
        if (rths_controller_pop_period(c, &p)) {
            got++;
            if (got == 1) {
                w_now = 2 * M_PI * 12.1; /* the period that just closed ran at 13.3 Hz */
                assert_close(p.frequency_hz, f, 1e-12);
                continue;
            }
            assert_close(p.frequency_hz, 12.1, 1e-12);
            assert_close(p.phys.a[1], 1e-5, 1e-10);
            assert_close(p.phys.b[1], 0, 1e-10);
        }
    }
    rths_controller_destroy(c);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* A forcing change (frequency and amplitude) waits for the period boundary; a second change
 * before then replaces the first. */
static void test_forcing_changes_at_boundary(void **state) {
    (void)state;
    rths_setup s;
    rths_config *cfg;
    rths_controller_options o;
    seed_setup(&s, &cfg);
    rths_controller_defaults(&o);
    o.ramp_time_s = 0; /* full amplitude at once */
    rths_controller *c;
    rths_error err;
    if (rths_controller_create(&s, &o, &c, &err)) fail_msg("%s", err.msg);
    rths_controller_arm(c, 1);
    rths_controller_set_forcing(c, 10.0, 1.0); /* at rest: starts now */
    rths_sensor_sample in = {.n = 3};
    double amp, theta, omega;
    for (int i = 0; i < 300; i++) /* 0.03 s: inside the first 0.1 s period */
        rths_controller_step(c, &in, NULL);
    rths_controller_forcing(c, &amp, &theta, &omega);
    assert_close(amp, 1.0, 0);
    assert_close(omega, 2 * M_PI * 10.0, 1e-12);
    assert_close(theta, 2 * M_PI * 10.0 * 0.03, 1e-9);
    rths_controller_set_forcing(c, 20.0, 5.0);
    rths_controller_set_forcing(c, 12.5, 2.0); /* replaces the pending 20 Hz, 5 N */
    rths_period p;
    int boundary = 0;
    for (int i = 0; i < 800; i++) {
        rths_controller_step(c, &in, NULL);
        rths_controller_forcing(c, &amp, &theta, &omega);
        if (rths_controller_pop_period(c, &p)) {
            boundary = 1;
            assert_close(p.frequency_hz, 10.0, 1e-12);
        }
        /* before the boundary the old forcing, from the boundary on the last requested one */
        assert_close(amp, boundary ? 2.0 : 1.0, 0);
        assert_close(omega, 2 * M_PI * (boundary ? 12.5 : 10.0), 1e-12);
    }
    assert_true(boundary);
    while (!rths_controller_pop_period(c, &p))
        rths_controller_step(c, &in, NULL);
    assert_close(p.frequency_hz, 12.5, 1e-12);
    assert_int_equal(p.samples, 800);
    rths_controller_destroy(c);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static void run_until_fault(rths_controller *c, rths_sensor_sample *in, rths_rig_fault expect,
                            double ramp_time) {
    rths_controller_output out;
    for (int i = 0; i < 100; i++)
        rths_controller_step(c, in, &out);
    assert_int_equal(rths_controller_fault(c), expect);
    /* after the ramp time the demand is exactly zero and stays there */
    for (int i = 0; i < (int)(ramp_time / 1e-4) + 2; i++)
        rths_controller_step(c, in, &out);
    assert_true(out.demand_v == 0.0);
}

static void test_limits_latch(void **state) {
    (void)state;
    rths_setup s;
    rths_config *cfg;
    rths_controller_options o;
    rths_controller *c = make(&s, &cfg, &o);
    rths_controller_arm(c, 1);
    rths_controller_set_forcing(c, 13.0, 1.0);
    rths_sensor_sample in = {.n = 3};
    in.displacement_m[2] = 2 * o.displacement_limit_m;
    run_until_fault(c, &in, RTHS_RIG_FAULT_DISPLACEMENT, o.ramp_time_s);
    /* latched: a healthy signal does not clear it, only a reset does */
    in.displacement_m[2] = 0;
    run_until_fault(c, &in, RTHS_RIG_FAULT_DISPLACEMENT, o.ramp_time_s);
    rths_controller_reset_fault(c);
    in.interface_force_n = 2 * o.force_limit_n;
    run_until_fault(c, &in, RTHS_RIG_FAULT_FORCE, o.ramp_time_s);
    rths_controller_reset_fault(c);
    in.interface_force_n = 0;
    in.displacement_m[2] = NAN;
    run_until_fault(c, &in, RTHS_RIG_FAULT_NONFINITE, o.ramp_time_s);
    rths_controller_reset_fault(c);
    /* a target far away asks for a demand beyond the limit */
    in.displacement_m[2] = 0;
    double a[1] = {1.0}, b[1] = {0};
    rths_controller_set_target(c, 1, a, b);
    run_until_fault(c, &in, RTHS_RIG_FAULT_DEMAND, o.ramp_time_s);
    rths_controller_destroy(c);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_step_allocates_nothing),
        cmocka_unit_test(test_step_source_is_clean),
        cmocka_unit_test(test_fourier_sums_exact),
        cmocka_unit_test(test_forcing_changes_at_boundary),
        cmocka_unit_test(test_limits_latch),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
