/* A minimal I/O plug-in for a DAQ card through Comedi (docs/io-plugins.md): one analog input per
 * physical DoF's displacement sensor, one for the accelerometer, one for the load cell, one analog
 * output for the actuator demand, read and written once per controller sample with single
 * conversions (comedi_data_read / comedi_data_write). Built only when libcomedi-dev is installed
 * (CMake option RTHS_IO_COMEDI); its settings are the io section of the test configuration:
 *
 *   io:
 *     plugin: build/rths_io_comedi.so
 *     device: /dev/comedi0
 *     input_subdevice: 0            # analog input subdevice
 *     output_subdevice: 1           # analog output subdevice
 *     range: 0                      # Comedi range index of every channel (e.g. +-10 V)
 *     displacement_channels: [0, 1, 2]        # physical DoFs in order, interface last
 *     displacement_m_per_v: [1e-3, 1e-3, 1e-3]
 *     acceleration_channel: 3
 *     acceleration_m_s2_per_v: 9.81
 *     force_channel: 4
 *     force_n_per_v: 100
 *     demand_channel: 0             # analog output driving the actuator amplifier
 *     displacement_noise_m: 2e-7    # measured noise of a displacement reading (host's SE floor)
 */
#include "rths/io.h"

#include <comedilib.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    unsigned subdevice, channel, range_index;
    comedi_range *range; /* owned by comedilib */
    lsampl_t maxdata;
    double scale; /* engineering unit per volt */
} channel;

typedef struct {
    comedi_t *card;
    int n;
    channel displacement[RTHS_MAX_SENSED_DOFS], acceleration, force, demand;
} comedi_device;

uint32_t rths_io_plugin_abi_version(void) {
    return RTHS_IO_ABI_VERSION;
}

static int channel_open(comedi_device *d, channel *c, long subdevice, long chan, long range,
                        double scale, rths_error *err) {
    c->subdevice = (unsigned)subdevice;
    c->channel = (unsigned)chan;
    c->scale = scale;
    c->range_index = (unsigned)range;
    c->range = comedi_get_range(d->card, c->subdevice, c->channel, c->range_index);
    c->maxdata = comedi_get_maxdata(d->card, c->subdevice, c->channel);
    if (!c->range || c->maxdata == 0)
        return rths_error_set(err, RTHS_EFAIL, "comedi: subdevice %ld channel %ld range %ld: %s",
                              subdevice, chan, range, comedi_strerror(comedi_errno()));
    return RTHS_OK;
}

/* io.* keys, read with the configuration's own getters (located errors, typos refused). */
static int open_channels(comedi_device *d, rths_config *cfg, rths_error *err) {
    long in_sub, out_sub, range, acc_ch, force_ch, demand_ch;
    double acc_scale, force_scale;
    int *chans = NULL, n_chans = 0, n_scales = 0;
    double *scales = NULL;
    int rc;
    if ((rc = rths_config_get_int(cfg, "io.input_subdevice", 1, 0, 0, 255, &in_sub, err)) ||
        (rc = rths_config_get_int(cfg, "io.output_subdevice", 1, 0, 0, 255, &out_sub, err)) ||
        (rc = rths_config_get_int(cfg, "io.range", 0, 0, 0, 255, &range, err)) ||
        (rc = rths_config_get_int(cfg, "io.acceleration_channel", 1, 0, 0, 4095, &acc_ch, err)) ||
        (rc = rths_config_get_int(cfg, "io.force_channel", 1, 0, 0, 4095, &force_ch, err)) ||
        (rc = rths_config_get_int(cfg, "io.demand_channel", 1, 0, 0, 4095, &demand_ch, err)) ||
        (rc = rths_config_get_double(cfg, "io.acceleration_m_s2_per_v", 1, 0, -1e9, 1e9, &acc_scale,
                                     err)) ||
        (rc =
             rths_config_get_double(cfg, "io.force_n_per_v", 1, 0, -1e9, 1e9, &force_scale, err)) ||
        (rc =
             rths_config_get_int_list(cfg, "io.displacement_channels", 1, &chans, &n_chans, err)) ||
        (rc = rths_config_get_double_list(cfg, "io.displacement_m_per_v", 1, &scales, &n_scales,
                                          err)))
        goto done;
    if (n_chans != d->n || n_scales != d->n) {
        rc = rths_config_error_at(cfg, "io.displacement_channels", err,
                                  "%d channels and %d scales for %d physical DoFs", n_chans,
                                  n_scales, d->n);
        goto done;
    }
    for (int i = 0; i < d->n && !rc; i++)
        rc = channel_open(d, &d->displacement[i], in_sub, chans[i], range, scales[i], err);
    if (!rc) rc = channel_open(d, &d->acceleration, in_sub, acc_ch, range, acc_scale, err);
    if (!rc) rc = channel_open(d, &d->force, in_sub, force_ch, range, force_scale, err);
    if (!rc) rc = channel_open(d, &d->demand, out_sub, demand_ch, range, 1.0, err);
done:
    free(chans);
    free(scales);
    return rc;
}

int rths_io_plugin_open(const rths_io_open_args *args, void **device, rths_io_device_info *info,
                        rths_error *err) {
    *device = NULL;
    const char *path = NULL;
    double noise = 0;
    int rc = rths_config_get_string(args->config, "io.device", 0, "/dev/comedi0", &path, err);
    if (!rc)
        rc = rths_config_get_double(args->config, "io.displacement_noise_m", 0, 0, 0, 1, &noise,
                                    err);
    if (rc) return rc;
    if (args->physical_dofs < 1 || args->physical_dofs > RTHS_MAX_SENSED_DOFS)
        return rths_error_set(err, RTHS_EINPUT,
                              "comedi: %d physical DoFs; a sensor sample carries 1 to %d",
                              args->physical_dofs, RTHS_MAX_SENSED_DOFS);
    comedi_device *d = calloc(1, sizeof *d);
    if (!d) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    d->n = args->physical_dofs;
    d->card = comedi_open(path);
    if (!d->card) {
        free(d);
        return rths_error_set(err, RTHS_EFAIL, "comedi: %s: %s", path,
                              comedi_strerror(comedi_errno()));
    }
    /* a reading at the end of a range is not a measurement: NaN, so the controller trips */
    comedi_set_global_oor_behavior(COMEDI_OOR_NAN);
    rc = open_channels(d, args->config, err);
    if (rc) {
        comedi_close(d->card);
        free(d);
        return rc;
    }
    snprintf(info->description, sizeof info->description, "Comedi %s (%s), %d displacement inputs",
             path, comedi_get_board_name(d->card), d->n);
    info->displacement_noise_m = noise;
    info->applies_internal_forcing = 0; /* one actuator: a forcing must be on the numerical side */
    /* ABI 2: the output range, so the controller counts the demands comedi_from_phys clips (the
     * inputs need no full scale: a reading at a range's end is NaN, above) */
    info->demand_full_scale_v = d->demand.range->max;
    *device = d;
    rths_io_plugin_safe_state(d);
    return RTHS_OK;
}

void rths_io_plugin_close(void *device) {
    comedi_device *d = device;
    if (!d) return;
    comedi_close(d->card);
    free(d);
}

/* One single conversion, in the channel's engineering unit; NaN on failure or out of range. */
static double read_channel(comedi_device *d, const channel *c) {
    lsampl_t raw;
    if (comedi_data_read(d->card, c->subdevice, c->channel, c->range_index, AREF_GROUND, &raw) < 0)
        return NAN;
    return c->scale * comedi_to_phys(raw, c->range, c->maxdata);
}

int rths_io_plugin_read(void *device, rths_sensor_sample *out) {
    comedi_device *d = device;
    out->n = d->n;
    for (int i = 0; i < d->n; i++)
        out->displacement_m[i] = read_channel(d, &d->displacement[i]);
    out->interface_acceleration_m_s2 = read_channel(d, &d->acceleration);
    out->interface_force_n = read_channel(d, &d->force);
    int bad = !isfinite(out->interface_acceleration_m_s2) || !isfinite(out->interface_force_n);
    for (int i = 0; i < d->n; i++)
        bad |= !isfinite(out->displacement_m[i]);
    return bad ? -1 : 0;
}

void rths_io_plugin_write(void *device, const rths_io_demand *demand) {
    comedi_device *d = device;
    /* comedi_from_phys clips to the converter's range; the controller's demand limit trips first */
    lsampl_t raw = comedi_from_phys(demand->demand_v, d->demand.range, d->demand.maxdata);
    comedi_data_write(d->card, d->demand.subdevice, d->demand.channel, d->demand.range_index,
                      AREF_GROUND, raw);
}

void rths_io_plugin_safe_state(void *device) {
    rths_io_demand zero = {0};
    rths_io_plugin_write(device, &zero);
}
