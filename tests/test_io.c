/* The I/O plug-in ABI (include/rths/io.h): the reference plug-in loaded from its shared object
 * (build/rths_io_virtual.so) reads and writes exactly what the simulated plant does when called
 * directly, sample for sample, noise included; the per-sample loop over it equals the loop over
 * the in-process reference device; a plug-in built for another ABI version, or missing a symbol,
 * is refused with a message naming it, before it is opened and before anything can be armed (also
 * through the controller process's create); a device whose read fails latches the non-finite
 * fault and is put into its safe state; safe_state and close run once at destroy. */
#include "fixture_seed_rig.h"
#include "testlib.h"

#include "rths/controller.h"
#include "rths/io.h"
#include "rths/server.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define WRONG_ABI_SO RTHS_TEST_BUILD_DIR "/tests/io/wrong_abi.so"
#define MISSING_SYMBOL_SO RTHS_TEST_BUILD_DIR "/tests/io/missing_symbol.so"

static rths_io_open_args args_for(rths_config *cfg, const rths_setup *s) {
    return (rths_io_open_args){RTHS_IO_ABI_VERSION, 10000.0, s->split.np, cfg, "io"};
}

/* The shared object and the plant called directly, driven by the same demand and forcing with
 * sensor noise on (seed 1): every reading identical to the last bit, so the plug-in path adds
 * nothing (no copy, conversion or reordering) between the plant and the controller. */
static void test_reference_plugin_equals_plant(void **state) {
    (void)state;
    const char *sets[] = {"forcing.dof=2"}; /* forcing on an internal physical DoF */
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    rths_fixture_seed_setup(sets, 1, &cfg, &s);
    rths_io_open_args args = args_for(cfg, &s);
    rths_io *io = NULL;
    if (rths_io_load(RTHS_IO_VIRTUAL_SO, &args, &io, &err)) fail_msg("%s", err.msg);
    assert_null(rths_io_virtual_plant(io)); /* its plant lives in the shared object's copy */
    assert_true(rths_io_info(io)->applies_internal_forcing);
    rths_plant_options po;
    rths_plant_defaults(&po);
    assert_close(rths_io_info(io)->displacement_noise_m, po.laser.noise_std, 0);
    assert_non_null(strstr(rths_io_info(io)->description, "virtual plant"));
    rths_plant *p = NULL;
    if (rths_plant_create(&s, &po, 10000.0, &p, &err)) fail_msg("%s", err.msg);
    double worst = 0, peak = 0;
    for (int k = 0; k < 20000; k++) {
        rths_sensor_sample a, b;
        assert_int_equal(rths_io_read(io, &a), 0);
        rths_plant_read(p, &b);
        assert_int_equal(a.n, b.n);
        for (int i = 0; i < a.n; i++)
            worst = fmax(worst, fabs(a.displacement_m[i] - b.displacement_m[i]));
        worst = fmax(worst, fabs(a.interface_force_n - b.interface_force_n));
        worst = fmax(worst, fabs(a.interface_acceleration_m_s2 - b.interface_acceleration_m_s2));
        peak = fmax(peak, fabs(b.displacement_m[b.n - 1]));
        double t = k * 1e-4, w = 2 * M_PI * 13.0;
        rths_io_demand d = {.demand_v = 0.02 * sin(w * t),
                            .forcing_amplitude_n = 1.0,
                            .forcing_theta_rad = w * t,
                            .forcing_omega_rad_s = w};
        rths_io_write(io, &d);
        rths_plant_set_forcing(p, d.forcing_amplitude_n, d.forcing_theta_rad,
                               d.forcing_omega_rad_s);
        rths_plant_advance(p, d.demand_v);
    }
    /* the plant moved (7.6e-5 m, far above the 1e-7 m sensor noise): not a comparison of
     * zeros */
    if (!(peak > 1e-5)) fail_msg("peak %g m", peak);
    assert_true(worst == 0);
    rths_plant_destroy(p);
    rths_io_destroy(io);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* The whole loop: configured with io.plugin = the shared object, and in process over parsed
 * options, with noise: the same demands to the last bit for a second of forced, armed running. */
static void test_loop_over_plugin_equals_in_process(void **state) {
    (void)state;
    const char *sets[] = {"io.plugin=" RTHS_IO_VIRTUAL_SO};
    rths_config *cfg = rths_fixture_seed_config(sets, 1);
    rths_setup s;
    rths_error err;
    rths_controller_options co;
    rths_plant_options po;
    rths_controller_defaults(&co);
    rths_plant_defaults(&po);
    if (rths_setup_read(cfg, &s, &err) || rths_sample_loop_config_read(cfg, &co, &po, &err))
        fail_msg("%s", err.msg);
    rths_sample_loop *a = NULL, *b = NULL;
    if (rths_sample_loop_create_configured(cfg, &s, &co, &a, &err) ||
        rths_sample_loop_create(&s, &co, &po, &b, &err))
        fail_msg("%s", err.msg);
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_OK);
    assert_null(rths_sample_loop_plant(a));
    assert_non_null(rths_sample_loop_plant(b));
    rths_sample_loop *loops[2] = {a, b};
    for (int i = 0; i < 2; i++) {
        assert_int_equal(rths_sample_loop_arm(loops[i]), RTHS_OK);
        rths_controller_set_forcing(rths_sample_loop_controller(loops[i]), 13.0, 1.0);
    }
    double worst = 0, peak = 0;
    for (int k = 0; k < 10000; k++) {
        double da = rths_sample_loop_run(a, NULL), db = rths_sample_loop_run(b, NULL);
        worst = fmax(worst, fabs(da - db));
        peak = fmax(peak, fabs(db));
    }
    assert_true(peak > 1e-3);
    assert_true(worst == 0);
    rths_sample_loop_destroy(a);
    rths_sample_loop_destroy(b);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static void expect_refused(const char *path, const char *needle) {
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    rths_io_open_args args = args_for(cfg, &s);
    rths_io *io = NULL;
    assert_int_equal(rths_io_load(path, &args, &io, &err), RTHS_EINPUT);
    assert_null(io);
    if (!strstr(err.msg, needle) || !strstr(err.msg, path)) fail_msg("message: %s", err.msg);
    rths_setup_free(&s);
    rths_config_free(cfg);

    /* the controller process refuses it at create: no thread runs, nothing can be armed */
    char set[512];
    snprintf(set, sizeof set, "io.plugin=%s", path);
    const char *sets[] = {set};
    cfg = rths_fixture_seed_config(sets, 1);
    rths_server_options so;
    rths_server_options_defaults(&so);
    so.quiet = 1;
    so.realtime = 0;
    rths_server *srv = NULL;
    assert_int_equal(rths_server_create(cfg, &so, &srv, &err), RTHS_EINPUT);
    assert_null(srv);
    if (!strstr(err.msg, needle)) fail_msg("message: %s", err.msg);
    rths_config_free(cfg);
}

static void test_wrong_abi_version_refused(void **state) {
    (void)state;
    /* wrong_abi.so aborts if its open is ever called: the check comes first */
    char needle[64];
    snprintf(needle, sizeof needle, "ABI version %u", RTHS_IO_ABI_VERSION + 41);
    expect_refused(WRONG_ABI_SO, needle);
}

static void test_missing_symbol_refused(void **state) {
    (void)state;
    expect_refused(MISSING_SYMBOL_SO, "'rths_io_plugin_safe_state' is missing");
}

static void test_missing_file_refused(void **state) {
    (void)state;
    expect_refused(RTHS_TEST_BUILD_DIR "/tests/io/no_such_plugin.so", "no_such_plugin.so");
}

/* A device in memory that counts its calls and fails its reads from sample 100 on. */
static struct { int reads, writes, safe, closes; } calls;
static uint32_t fake_version(void) {
    return RTHS_IO_ABI_VERSION;
}
static int fake_open(const rths_io_open_args *a, void **device, rths_io_device_info *info,
                     rths_error *err) {
    (void)err;
    memset(&calls, 0, sizeof calls);
    snprintf(info->description, sizeof info->description, "fake, %d DoFs", a->physical_dofs);
    *device = &calls;
    return 0;
}
static void fake_close(void *device) {
    assert_ptr_equal(device, &calls);
    calls.closes++;
}
static int fake_read(void *device, rths_sensor_sample *out) {
    (void)device;
    memset(out, 0, sizeof *out);
    out->n = 2;
    return ++calls.reads > 100 ? -1 : 0;
}
static void fake_write(void *device, const rths_io_demand *d) {
    (void)device, (void)d;
    calls.writes++;
}
static void fake_safe(void *device) {
    (void)device;
    calls.safe++;
}

static void test_failed_read_trips_and_safes(void **state) {
    (void)state;
    const rths_io_plugin table = {.abi_version = fake_version,
                                  .open = fake_open,
                                  .close = fake_close,
                                  .read = fake_read,
                                  .write = fake_write,
                                  .safe_state = fake_safe};
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    rths_io_open_args args = args_for(cfg, &s);
    rths_io *io = NULL;
    if (rths_io_open_table(&table, "fake", &args, &io, &err)) fail_msg("%s", err.msg);
    assert_string_equal(rths_io_info(io)->description, "fake, 3 DoFs"); /* storeys 1-3 */
    rths_controller_options co;
    rths_controller_defaults(&co);
    rths_sample_loop *loop = NULL;
    if (rths_sample_loop_create_io(&s, &co, io, &loop, &err)) fail_msg("%s", err.msg);
    assert_int_equal(rths_sample_loop_arm(loop), RTHS_OK);
    for (int k = 0; k < 100; k++)
        rths_sample_loop_run(loop, NULL);
    assert_int_equal(rths_controller_fault(rths_sample_loop_controller(loop)), RTHS_RIG_OK);
    assert_int_equal(calls.safe, 0);
    rths_sample_loop_run(loop, NULL); /* read 101 fails */
    assert_int_equal(rths_controller_fault(rths_sample_loop_controller(loop)),
                     RTHS_RIG_FAULT_NONFINITE);
    assert_int_equal(calls.safe, 1);
    assert_int_equal(rths_sample_loop_arm(loop), RTHS_EFAIL);
    assert_int_equal(calls.writes, 101);
    rths_sample_loop_destroy(loop);
    assert_int_equal(calls.safe, 2);
    assert_int_equal(calls.closes, 1);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* A device that cannot apply a forcing on an internal physical DoF refuses such a setup. */
static void test_internal_forcing_needs_a_device_that_applies_it(void **state) {
    (void)state;
    const rths_io_plugin table = {.abi_version = fake_version,
                                  .open = fake_open,
                                  .close = fake_close,
                                  .read = fake_read,
                                  .write = fake_write,
                                  .safe_state = fake_safe};
    const char *sets[] = {"forcing.dof=2"};
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    rths_fixture_seed_setup(sets, 1, &cfg, &s);
    rths_io_open_args args = args_for(cfg, &s);
    rths_io *io = NULL;
    if (rths_io_open_table(&table, "fake", &args, &io, &err)) fail_msg("%s", err.msg);
    rths_controller_options co;
    rths_controller_defaults(&co);
    rths_sample_loop *loop = NULL;
    assert_int_equal(rths_sample_loop_create_io(&s, &co, io, &loop, &err), RTHS_EINPUT);
    assert_null(loop);
    assert_int_equal(calls.closes, 1); /* taken over and closed on failure */
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* ABI 2's optional hardware watchdog: armed once with the timeout, kicked once per sample by the
 * loop (the proof that it lives), never without an arm; a plug-in without the entries says so. A
 * version-1 plug-in still loads: open is told version 1, and what version 2 added (full scales,
 * optional entries) is left out, so nothing it did not declare is counted. */
static struct {
    int kicks, arms, opened_version;
    double timeout_s;
} hw;
static uint32_t v1_version(void) {
    return 1;
}
static int hw_open(const rths_io_open_args *a, void **device, rths_io_device_info *info,
                   rths_error *err) {
    hw.opened_version = (int)a->abi_version;
    info->displacement_full_scale_m = 1e-12; /* beyond version 1: must be ignored for it */
    return fake_open(a, device, info, err);
}
static int hw_arm(void *device, double timeout_s) {
    (void)device;
    hw.arms++;
    hw.timeout_s = timeout_s;
    return 0;
}
static void hw_kick(void *device) {
    (void)device;
    hw.kicks++;
}
static int hw_read(void *device, rths_sensor_sample *out) {
    (void)device;
    memset(out, 0, sizeof *out);
    out->n = 3;
    out->displacement_m[2] = 1e-9; /* beyond the declared 1e-12 m full scale */
    return 0;
}
static unsigned hw_flags(void *device) {
    (void)device;
    return RTHS_IO_SAMPLE_DEMAND_CLIPPED;
}

static void test_hardware_watchdog_and_version_one(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    rths_fixture_seed_setup(NULL, 0, &cfg, &s);
    rths_io_open_args args = args_for(cfg, &s);
    rths_controller_options co;
    rths_controller_defaults(&co);
    for (int version = 1; version <= 2; version++) {
        memset(&hw, 0, sizeof hw);
        const rths_io_plugin table = {.abi_version = version == 1 ? v1_version : fake_version,
                                      .open = hw_open,
                                      .close = fake_close,
                                      .read = hw_read,
                                      .write = fake_write,
                                      .safe_state = fake_safe,
                                      .sample_flags = hw_flags,
                                      .watchdog_arm = hw_arm,
                                      .watchdog_kick = hw_kick};
        rths_io *io = NULL;
        if (rths_io_open_table(&table, "hw", &args, &io, &err)) fail_msg("%s", err.msg);
        assert_int_equal(hw.opened_version, version);
        rths_sample_loop *loop = NULL;
        if (rths_sample_loop_create_io(&s, &co, io, &loop, &err)) fail_msg("%s", err.msg);
        rths_controller *c = rths_sample_loop_controller(loop);
        rths_controller_set_forcing(c, 13.0, 0.0);
        for (int k = 0; k < 10; k++) /* not armed yet: no kick */
            rths_sample_loop_run(loop, NULL);
        assert_int_equal(hw.kicks, 0);
        int rc = rths_sample_loop_watchdog_arm(loop, 0.1, &err);
        long saturated = 0, clipped = 0;
        for (int k = 0; k < 2090; k++) { /* closes two periods at 13 Hz */
            rths_sample_loop_run(loop, NULL);
            rths_period p;
            while (rths_controller_pop_period(c, &p)) {
                saturated += p.saturated_sensor_samples;
                clipped += p.clipped_demand_samples;
            }
        }
        if (version == 1) {
            assert_int_equal(rc, RTHS_EFAIL);
            assert_non_null(strstr(err.msg, "no hardware watchdog"));
            assert_int_equal(hw.arms + hw.kicks, 0);
            assert_int_equal(saturated + clipped, 0);
        } else {
            assert_int_equal(rc, RTHS_OK);
            assert_int_equal(hw.arms, 1);
            assert_true(hw.timeout_s == 0.1);
            assert_int_equal(hw.kicks, 2090);
            assert_true(saturated > 0 && clipped > 0); /* what version 2 declared is counted */
        }
        rths_sample_loop_destroy(loop);
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_reference_plugin_equals_plant),
        cmocka_unit_test(test_loop_over_plugin_equals_in_process),
        cmocka_unit_test(test_wrong_abi_version_refused),
        cmocka_unit_test(test_missing_symbol_refused),
        cmocka_unit_test(test_missing_file_refused),
        cmocka_unit_test(test_failed_read_trips_and_safes),
        cmocka_unit_test(test_internal_forcing_needs_a_device_that_applies_it),
        cmocka_unit_test(test_hardware_watchdog_and_version_one),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
