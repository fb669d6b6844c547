/* The reference I/O plug-in: the simulated plant (plant.h) behind the ABI of io.h. The same
 * functions are linked into the library (rths_io_virtual_plugin) and exported by
 * build/rths_io_virtual.so (src/io/plugin/virtual_export.c). */
#include "io/io_internal.h"
#include "rths/io.h"

#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct {
    rths_plant *plant; /* first: rths_io_virtual_plant reads it through the device pointer */
    /* safe state: the demand written is ignored, zero is applied. Atomic: the controller
     * process's supervisor may set it while the loop thread is inside write. */
    atomic_int safe;
    int force_clip;          /* the actuator clips its force command (rig.actuator.limits) */
    long force_clipped_seen; /* the plant's count of clipped samples at the last write */
    unsigned flags;          /* this sample's RTHS_IO_SAMPLE_* from the plant's own limits */
} virtual_device;

/* An ADC's full scale in engineering units, as plant.c's converter clips: +-range_v volts times
 * units_per_v; none without a converter (bits 0: the reading is continuous, never clipped). */
static double adc_full_scale(const rths_adc_spec *adc) {
    return adc->bits > 0 ? adc->range_v * adc->units_per_v : 0.0;
}

static uint32_t virtual_abi_version(void) {
    return RTHS_IO_ABI_VERSION;
}

static int device_create(const rths_setup *setup, const rths_plant_options *popt, double rate,
                         void **device, rths_io_device_info *info, rths_error *err) {
    virtual_device *d = calloc(1, sizeof *d);
    if (!d) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = rths_plant_create(setup, popt, rate, &d->plant, err);
    if (rc) {
        free(d);
        return rc;
    }
    snprintf(info->description, sizeof info->description,
             "virtual plant (reference I/O plug-in): %d physical DoFs, noise %s", setup->split.np,
             popt->noise ? "on" : "off");
    info->displacement_noise_m = rths_plant_noise_level_m(d->plant);
    info->applies_internal_forcing = 1; /* rths_plant_set_forcing, in continuous time */
    /* the converters' ranges, so the seam counts saturated readings and clipped demands */
    info->displacement_full_scale_m = adc_full_scale(&popt->laser_adc);
    info->acceleration_full_scale_m_s2 = adc_full_scale(&popt->accelerometer_adc);
    info->force_full_scale_n = adc_full_scale(&popt->load_cell_adc);
    info->demand_full_scale_v = popt->actuator.dac_bits > 0 ? popt->actuator.dac_range_v : 0.0;
    d->force_clip = popt->actuator.force_clip && popt->actuator.force_limit_n > 0;
    *device = d;
    return RTHS_OK;
}

/* From the configuration: the setup (structure, split, forcing) and the rig section. The
 * reference plant has no settings of its own in the io section. */
static int virtual_open(const rths_io_open_args *args, void **device, rths_io_device_info *info,
                        rths_error *err) {
    *device = NULL;
    if (args->abi_version != RTHS_IO_ABI_VERSION)
        return rths_error_set(err, RTHS_EINPUT, "virtual plant: controller ABI version %u, not %u",
                              (unsigned)args->abi_version, (unsigned)RTHS_IO_ABI_VERSION);
    rths_setup setup;
    rths_plant_options popt;
    rths_plant_defaults(&popt);
    int rc = rths_setup_read(args->config, &setup, err);
    if (rc) return rc;
    rc = rths_plant_config_read(args->config, &popt, err);
    if (!rc && setup.split.np != args->physical_dofs)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "virtual plant: %d physical DoFs, the controller expects %d",
                            setup.split.np, args->physical_dofs);
    if (!rc) rc = device_create(&setup, &popt, args->sample_rate_hz, device, info, err);
    rths_setup_free(&setup);
    return rc;
}

static void virtual_close(void *device) {
    virtual_device *d = device;
    if (!d) return;
    rths_plant_destroy(d->plant);
    free(d);
}

static int virtual_read(void *device, rths_sensor_sample *out) {
    rths_plant *p = ((virtual_device *)device)->plant;
    rths_plant_read(p, out);
    return (int)rths_plant_limit_fault(p); /* the actuator's limits with action fault */
}

static void virtual_write(void *device, const rths_io_demand *demand) {
    virtual_device *d = device;
    rths_plant_set_forcing(d->plant, demand->forcing_amplitude_n, demand->forcing_theta_rad,
                           demand->forcing_omega_rad_s);
    double safe[RTHS_MAX_INTERFACE_DOFS] = {0};
    const int is_safe = atomic_load_explicit(&d->safe, memory_order_relaxed);
    if (demand->n_demands > 1)
        rths_plant_advance_dofs(d->plant, is_safe ? safe : demand->demand_dof_v);
    else
        rths_plant_advance(d->plant, is_safe ? 0.0 : demand->demand_v);
    /* the actuator's force clip (rig.actuator.limits.force_action: clip) is a clamped command */
    d->flags = 0;
    if (d->force_clip) {
        rths_actuator_status st;
        rths_plant_actuator_status(d->plant, &st);
        if (st.force_clipped_samples != d->force_clipped_seen)
            d->flags |= RTHS_IO_SAMPLE_DEMAND_CLIPPED;
        d->force_clipped_seen = st.force_clipped_samples;
    }
}

static unsigned virtual_sample_flags(void *device) {
    return ((virtual_device *)device)->flags;
}

/* The simulated actuator's safe state: no demand from now on (what a lab's amplifier-off does);
 * the structure keeps moving freely. Cleared by nothing: a stopped loop does not restart. */
static void virtual_safe_state(void *device) {
    atomic_store_explicit(&((virtual_device *)device)->safe, 1, memory_order_relaxed);
}

const rths_io_plugin rths_io_virtual_plugin = {
    .abi_version = virtual_abi_version,
    .open = virtual_open,
    .close = virtual_close,
    .read = virtual_read,
    .write = virtual_write,
    .safe_state = virtual_safe_state,
    .sample_flags = virtual_sample_flags,
};

int rths_io_open_virtual(const rths_setup *setup, const rths_plant_options *popt,
                         double sample_rate_hz, rths_io **out, rths_error *err) {
    /* the table's open takes a configuration; here the options are parsed already, so the
     * device is made directly and handed to the same per-sample functions */
    *out = NULL;
    void *device = NULL;
    rths_io_device_info info = {0};
    int rc = device_create(setup, popt, sample_rate_hz, &device, &info, err);
    if (!rc) rc = rths_io_adopt(&rths_io_virtual_plugin, "virtual plant", device, &info, out, err);
    if (rc) virtual_close(device);
    return rc;
}
