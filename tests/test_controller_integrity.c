/* A period's integrity and a fault's words (issue 24 items 1 and 2, issue 23 items 4 and 8):
 *
 * - every published period counts its late samples (marked by the controller process's pacing),
 *   the samples in which an actuator demand was clipped and those in which a converter reading
 *   sat at its full scale, exactly: compared sample by sample with what a device in memory did;
 * - the reference plug-in declares the simulated converters' ranges, so the seam counts the
 *   simulated ADC's saturation and DAC's clipping (as it would a lab's plug-in's), and the
 *   simulated actuator's force clip through the optional sample_flags entry;
 * - without any of it (the virtual rig's defaults) every count is 0;
 * - every fault the step latches names the channel, the value and the limit. */
#include "testlib.h"

#include "rths/controller.h"
#include "rths/io.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static rths_config *seed_config(void) {
    rths_config *cfg = NULL;
    rths_error err;
    if (rths_config_load(rths_test_source_path("examples/four_storey.yaml"), NULL, 0, &cfg, &err))
        fail_msg("%s", err.msg);
    return cfg;
}

/* ---- the step's faults ---- */

static rths_controller *seed_controller(rths_setup *s, rths_config **cfg,
                                        rths_controller_options *o) {
    rths_error err;
    *cfg = seed_config();
    if (rths_setup_read(*cfg, s, &err)) fail_msg("%s", err.msg);
    rths_controller *c = NULL;
    if (rths_controller_create(s, o, &c, &err)) fail_msg("%s", err.msg);
    rths_controller_arm(c, 1);
    rths_controller_set_forcing(c, 13.0, 1.0);
    return c;
}

static void fault_text(rths_controller *c, char *out, size_t cap) {
    rths_fault_detail d;
    rths_controller_fault_detail(c, &d);
    rths_fault_detail_format(&d, out, cap);
}

/* Issue 23.8: "a demand-limit fault names no DoF, demand or limit". Each limit of the seed's step
 * (three lasers on storeys 1 to 3, the interface storey 3 on actuator 1): the text names the
 * sensor or actuator, the value that tripped (the reading, or the demand the step computed at
 * the latching sample) and the limit. */
static void test_fault_names_channel_value_limit(void **state) {
    (void)state;
    rths_setup s;
    rths_config *cfg;
    rths_controller_options o;
    rths_controller_defaults(&o);
    rths_controller *c = seed_controller(&s, &cfg, &o);
    char text[256];
    rths_sensor_sample in = {.n = 3};
    in.displacement_m[1] = 0.0123; /* storey 2's laser, beyond the 0.01 m limit */
    rths_controller_step(c, &in, NULL);
    assert_int_equal(rths_controller_fault(c), RTHS_RIG_FAULT_DISPLACEMENT);
    fault_text(c, text, sizeof text);
    assert_string_equal(text, "displacement limit: the laser on DoF 2 reads 0.0123 m, beyond "
                              "+-0.01 m");
    rths_controller_reset_fault(c);
    fault_text(c, text, sizeof text);
    assert_string_equal(text, "no fault");

    in.displacement_m[1] = 0;
    in.interface_force_n = -612.5;
    rths_controller_step(c, &in, NULL);
    fault_text(c, text, sizeof text);
    assert_string_equal(text, "force limit: the load cell of actuator 1 reads -612.5 N, beyond "
                              "+-500 N");
    rths_controller_reset_fault(c);

    in.interface_force_n = 0;
    in.displacement_m[0] = NAN;
    rths_controller_step(c, &in, NULL);
    fault_text(c, text, sizeof text);
    assert_string_equal(text, "non-finite signal: the laser on DoF 1 reads nan");
    rths_controller_reset_fault(c);
    rths_controller_destroy(c);

    /* the demand: a 1 V limit, the target clamped to the 0.01 m stroke against a measured
     * -0.009 m, so the PD asks about 100 V/m x 0.019 m as the target ramps up; the text carries
     * the very demand the PD asked at the latching sample: the truth from a twin with no limit
     * (the same state until then; the tripped one scales its output by the ramp to zero) */
    rths_error err;
    rths_controller *twin = NULL;
    o.demand_limit_v = 1e6;
    if (rths_controller_create(&s, &o, &twin, &err)) fail_msg("%s", err.msg);
    o.demand_limit_v = 1.0;
    if (rths_controller_create(&s, &o, &c, &err)) fail_msg("%s", err.msg);
    double a[1] = {1.0}, b[1] = {0};
    rths_controller *both[2] = {c, twin};
    for (int i = 0; i < 2; i++) {
        rths_controller_arm(both[i], 1);
        rths_controller_set_forcing(both[i], 13.0, 1.0);
        rths_controller_set_target(both[i], 1, a, b);
    }
    in.displacement_m[0] = 0;
    in.displacement_m[2] = -0.009;
    rths_controller_output out;
    double latched_demand = NAN;
    for (int k = 0; k < 2000 && !rths_controller_fault(c); k++) {
        rths_controller_step(c, &in, NULL);
        rths_controller_step(twin, &in, &out);
        latched_demand = out.demand_v;
    }
    rths_controller_destroy(twin);
    assert_true(fabs(latched_demand) > 1.0);
    assert_int_equal(rths_controller_fault(c), RTHS_RIG_FAULT_DEMAND);
    rths_fault_detail d;
    rths_controller_fault_detail(c, &d);
    assert_true(d.value == latched_demand);
    assert_int_equal(d.channel, 1);
    char want[256];
    snprintf(want, sizeof want, "demand limit: actuator 1 demand %.4g V, beyond +-1 V",
             latched_demand);
    fault_text(c, text, sizeof text);
    assert_string_equal(text, want);
    print_message("%s\n", text);
    /* an external trip with a detail (the controller process's watchdog) keeps its words */
    rths_controller_reset_fault(c);
    rths_fault_detail why = {.fault = RTHS_RIG_FAULT_WATCHDOG,
                             .cause = RTHS_FAULT_CAUSE_HOST_SILENT,
                             .value = 2.5,
                             .limit = 2.0};
    rths_controller_trip_detail(c, &why);
    fault_text(c, text, sizeof text);
    assert_string_equal(text,
                        "watchdog: the host was silent for 2.5 s, beyond server.watchdog_s = 2 s");
    rths_controller_destroy(c);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* ---- late samples ---- */

/* The process's pacing marks late samples; each published period counts exactly the marked
 * samples it holds (a sample belongs to the period its step continues or closes). Unmarked (the
 * in-process virtual rig, on a simulated clock), every period counts 0. */
static void test_late_samples_counted_per_period(void **state) {
    (void)state;
    rths_config *cfg = seed_config();
    rths_setup s;
    rths_error err;
    rths_controller_options co;
    rths_plant_options po;
    rths_controller_defaults(&co);
    rths_plant_defaults(&po);
    if (rths_setup_read(cfg, &s, &err) || rths_sample_loop_config_read(cfg, &co, &po, &err))
        fail_msg("%s", err.msg);
    for (int marking = 0; marking < 2; marking++) {
        rths_sample_loop *l = NULL;
        if (rths_sample_loop_create(&s, &co, &po, &l, &err)) fail_msg("%s", err.msg);
        rths_controller *c = rths_sample_loop_controller(l);
        rths_sample_loop_arm(l);
        rths_controller_set_forcing(c, 13.0, 1.0);
        int pending = 0, periods = 0, late_total = 0;
        for (int k = 0; k < 20000; k++) {
            int late = marking && (k % 3 == 0 || (k / 1000) % 2 == 1);
            if (late) rths_sample_loop_mark_late(l);
            pending += late;
            rths_sample_loop_run(l, NULL);
            rths_period p;
            if (rths_controller_pop_period(c, &p)) {
                assert_int_equal(p.late_samples, pending);
                assert_true(p.late_samples <= p.samples);
                assert_int_equal(p.clipped_demand_samples, 0);
                assert_int_equal(p.saturated_sensor_samples, 0);
                late_total += p.late_samples;
                pending = 0;
                periods++;
            }
        }
        assert_true(periods >= 25); /* 2 s at 13 Hz */
        if (marking)
            assert_true(late_total > 0);
        else
            assert_int_equal(late_total, 0);
        rths_sample_loop_destroy(l);
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* ---- the seam: a device in memory with declared full scales ---- */

static struct {
    int reads, writes, physical;
    double last_demand_v;
} fake;

static uint32_t fake_version(void) {
    return RTHS_IO_ABI_VERSION;
}
static int fake_open(const rths_io_open_args *a, void **device, rths_io_device_info *info,
                     rths_error *err) {
    (void)err;
    memset(&fake, 0, sizeof fake);
    fake.physical = a->physical_dofs;
    snprintf(info->description, sizeof info->description, "fake with converters");
    info->displacement_full_scale_m = 1e-3;
    info->acceleration_full_scale_m_s2 = 50.0;
    info->force_full_scale_n = 100.0;
    info->demand_full_scale_v = 0.02;
    *device = &fake;
    return 0;
}
static void fake_close(void *device) {
    (void)device;
}
/* Which of the device's own rules a sample breaks: by its read index, so the test can predict
 * them: a laser at full scale (k % 7 == 0), the accelerometer beyond it (k % 11 == 0), the load
 * cell at exactly its full scale (k % 13 == 0); the device's own clip flag (k % 5 == 0). */
static int fake_saturates(int k) {
    return k % 7 == 0 || k % 11 == 0 || k % 13 == 0;
}
static int fake_read(void *device, rths_sensor_sample *out) {
    (void)device;
    int k = fake.reads++;
    memset(out, 0, sizeof *out);
    out->n = fake.physical;
    if (k % 7 == 0) out->displacement_m[0] = -1e-3; /* an internal storey's laser */
    out->displacement_m[fake.physical - 1] = 5e-4 * sin(0.01 * k);
    out->interface_acceleration_m_s2 = k % 11 == 0 ? 51.0 : 1.0;
    out->interface_force_n = k % 13 == 0 ? 100.0 : -20.0;
    return 0;
}
static void fake_write(void *device, const rths_io_demand *d) {
    (void)device;
    fake.last_demand_v = d->demand_v;
    fake.writes++;
}
static void fake_safe(void *device) {
    (void)device;
}
static unsigned fake_flags(void *device) {
    (void)device;
    return (fake.writes - 1) % 5 == 0 ? RTHS_IO_SAMPLE_DEMAND_CLIPPED : 0u;
}

/* Every count of every period equals the count of what the device did in that period's samples:
 * saturated readings counted in the period they were read in, clipped demands (beyond the
 * declared DAC range, or flagged by the device) in the period the demand acts over. */
static void test_seam_counts_exactly(void **state) {
    (void)state;
    const rths_io_plugin table = {.abi_version = fake_version,
                                  .open = fake_open,
                                  .close = fake_close,
                                  .read = fake_read,
                                  .write = fake_write,
                                  .safe_state = fake_safe,
                                  .sample_flags = fake_flags};
    rths_config *cfg = seed_config();
    rths_setup s;
    rths_error err;
    if (rths_setup_read(cfg, &s, &err)) fail_msg("%s", err.msg);
    rths_io_open_args args = {RTHS_IO_ABI_VERSION, 10000.0, s.split.np, cfg, "io"};
    rths_io *io = NULL;
    if (rths_io_open_table(&table, "fake", &args, &io, &err)) fail_msg("%s", err.msg);
    rths_controller_options co;
    rths_controller_defaults(&co);
    co.force_limit_n = 1e3; /* the load cell's full scale is below the limit: no fault */
    rths_sample_loop *l = NULL;
    if (rths_sample_loop_create_io(&s, &co, io, &l, &err)) fail_msg("%s", err.msg);
    rths_controller *c = rths_sample_loop_controller(l);
    rths_controller_set_forcing(c, 13.0, 0.0);
    double a[1] = {4e-4}, b[1] = {0};
    rths_controller_set_target(c, 1, a, b);
    assert_int_equal(rths_sample_loop_arm(l), RTHS_OK);
    int sat_pending = 0, clip_pending = 0, periods = 0, sat_total = 0, clip_total = 0;
    for (int k = 0; k < 20000; k++) {
        sat_pending += fake_saturates(k);
        rths_sample_loop_run(l, NULL);
        const int clipped = fabs(fake.last_demand_v) > 0.02 || k % 5 == 0;
        rths_period p;
        if (rths_controller_pop_period(c, &p)) {
            assert_int_equal(p.saturated_sensor_samples, sat_pending);
            assert_int_equal(p.clipped_demand_samples, clip_pending);
            assert_int_equal(p.late_samples, 0);
            sat_total += p.saturated_sensor_samples;
            clip_total += p.clipped_demand_samples;
            sat_pending = 0;
            clip_pending = 0;
            periods++;
        }
        clip_pending += clipped; /* counted after the step: in the period now open */
    }
    assert_int_equal(rths_controller_fault(c), RTHS_RIG_OK);
    assert_true(periods >= 25);
    print_message("%d periods: %d saturated, %d clipped samples\n", periods, sat_total, clip_total);
    assert_true(sat_total > 0 && clip_total > 0);
    rths_sample_loop_destroy(l);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* ---- the reference plug-in's converters ---- */

typedef struct {
    int periods;
    long samples, saturated, clipped;
    long interface_at_full_scale; /* samples whose interface laser reading was at full scale */
    long demand_beyond_dac;       /* samples whose demand was beyond the DAC range */
} run_counts;

static run_counts run_virtual(const rths_setup *s, const rths_plant_options *po, double fs_m,
                              double dac_v) {
    rths_controller_options co;
    rths_controller_defaults(&co);
    rths_error err;
    rths_sample_loop *l = NULL;
    if (rths_sample_loop_create(s, &co, po, &l, &err)) fail_msg("%s", err.msg);
    rths_controller *c = rths_sample_loop_controller(l);
    rths_sample_loop_arm(l);
    rths_controller_set_forcing(c, 13.0, 1.0);
    double a[1] = {1e-4}, b[1] = {0}; /* the interface driven to 1e-4 m */
    rths_controller_set_target(c, 1, a, b);
    run_counts r = {0};
    /* the truths, attributed as the seam does: a reading to the period its step continues or
     * closes, a demand (counted after its step) to the period open after it */
    long sat_pending = 0, clip_pending = 0;
    for (int k = 0; k < 30000; k++) {
        rths_controller_output out;
        rths_sample_loop_run(l, &out);
        sat_pending += fs_m > 0 && fabs(out.x_phys_m) >= fs_m;
        const int beyond = dac_v > 0 && fabs(out.demand_v) > dac_v;
        rths_period p;
        if (rths_controller_pop_period(c, &p)) {
            r.periods++;
            r.samples += p.samples;
            r.saturated += p.saturated_sensor_samples;
            r.clipped += p.clipped_demand_samples;
            r.interface_at_full_scale += sat_pending;
            r.demand_beyond_dac += clip_pending;
            sat_pending = clip_pending = 0;
        }
        clip_pending += beyond;
    }
    rths_sample_loop_destroy(l);
    return r;
}

/* Issue 23.4: "clipping is counted nowhere". The simulated plant's converters clip as a lab's
 * do; the reference plug-in declares their ranges (rig.sensors.*.adc_*, rig.actuator.dac.*), so
 * the seam counts them. The seed forced at 13 Hz with its interface driven to 1e-4 m: a laser ADC
 * whose full scale is 3e-5 m sits at it for much of each period; a DAC of +-0.002 V clips the PD's
 * demands. The interface laser alone gives a lower bound of the saturated samples (the other
 * lasers and sensors can add), the demand the exact count of the clipped ones. */
static void test_virtual_plant_converters_counted(void **state) {
    (void)state;
    rths_config *cfg = seed_config();
    rths_setup s;
    rths_error err;
    if (rths_setup_read(cfg, &s, &err)) fail_msg("%s", err.msg);
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.noise = 0;
    run_counts clean = run_virtual(&s, &po, 0, 0);
    assert_true(clean.periods >= 30);
    assert_int_equal(clean.saturated, 0); /* the defaults: no converter, nothing counted */
    assert_int_equal(clean.clipped, 0);

    rths_plant_options adc = po;
    adc.laser_adc = (rths_adc_spec){.bits = 16, .range_v = 3.0, .units_per_v = 1e-5};
    run_counts sat = run_virtual(&s, &adc, 3e-5, 0);
    print_message("laser ADC at +-3e-5 m: %ld of %ld samples saturated (interface laser at full "
                  "scale in %ld)\n",
                  sat.saturated, sat.samples, sat.interface_at_full_scale);
    assert_true(sat.interface_at_full_scale > 0);
    assert_true(sat.saturated >= sat.interface_at_full_scale);
    assert_true(sat.saturated <= sat.samples);
    assert_int_equal(sat.clipped, 0);

    rths_plant_options dac = po;
    dac.actuator.dac_bits = 16;
    dac.actuator.dac_range_v = 0.002;
    run_counts clip = run_virtual(&s, &dac, 0, 0.002);
    print_message("DAC at +-0.002 V: %ld of %ld samples clipped (demand beyond it in %ld)\n",
                  clip.clipped, clip.samples, clip.demand_beyond_dac);
    assert_true(clip.demand_beyond_dac > 0);
    assert_int_equal(clip.clipped, clip.demand_beyond_dac);
    assert_int_equal(clip.saturated, 0);

    /* the simulated actuator's force clip (rig.actuator.limits.force_action: clip), reported by
     * the reference plug-in's sample_flags */
    rths_plant_options fc = po;
    fc.actuator.force_clip = 1;
    fc.actuator.force_limit_n = 0.05;
    run_counts force = run_virtual(&s, &fc, 0, 0);
    print_message("force clip at 0.05 N: %ld of %ld samples clipped\n", force.clipped,
                  force.samples);
    assert_true(force.clipped > 0 && force.clipped <= force.samples);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fault_names_channel_value_limit),
        cmocka_unit_test(test_late_samples_counted_per_period),
        cmocka_unit_test(test_seam_counts_exactly),
        cmocka_unit_test(test_virtual_plant_converters_counted),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
