/* A misbehaving I/O plug-in for tests/cli/controller.sh (compiled there with cc against
 * librths.so): the reference plug-in (the simulated plant) with two faults a lab's device can
 * have, chosen by its io section:
 *   io.sleep_us: N            every read takes N microseconds longer (a slow DAQ driver): the
 *                             loop overruns, and the period records must count the late samples
 *   io.block_after_samples: N the read after N samples never returns (a driver that hangs): the
 *                             controller's supervisor must drive the safe state
 * safe_state (which the supervisor may call from its own thread while read is blocked) reports
 * on stderr, once, how long after the blocked sample's deadline it came, in ms. Not a model of
 * good behaviour: a real plug-in must never block or print on the loop thread. */
#include "rths/io.h"

#include <stdatomic.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

typedef struct {
    void *inner; /* the reference plug-in's device */
    long sleep_ns;
    long block_after, reads;
    double period_s;
    _Atomic double blocked_at_s; /* monotonic time the blocking read started; 0 before */
    atomic_int safe_reported;
} misbehaving;

static misbehaving the_device; /* one device per process is all the tests open */

static double mono_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

uint32_t rths_io_plugin_abi_version(void) {
    return RTHS_IO_ABI_VERSION;
}

int rths_io_plugin_open(const rths_io_open_args *args, void **device, rths_io_device_info *info,
                        rths_error *err) {
    misbehaving *d = &the_device;
    memset(d, 0, sizeof *d);
    long sleep_us = 0;
    int rc = rths_config_get_int(args->config, "io.sleep_us", 0, 0, 0, 1000000, &sleep_us, err);
    if (!rc)
        rc = rths_config_get_int(args->config, "io.block_after_samples", 0, 0, 0, 1000000000L,
                                 &d->block_after, err);
    if (!rc) rc = rths_io_virtual_plugin.open(args, &d->inner, info, err);
    if (rc) return rc;
    d->sleep_ns = sleep_us * 1000;
    d->period_s = 1.0 / args->sample_rate_hz;
    snprintf(info->description, sizeof info->description,
             "misbehaving test plug-in (sleep %ld us per read, block after %ld samples)", sleep_us,
             d->block_after);
    *device = d;
    return RTHS_OK;
}

void rths_io_plugin_close(void *device) {
    misbehaving *d = device;
    rths_io_virtual_plugin.close(d->inner);
}

int rths_io_plugin_read(void *device, rths_sensor_sample *out) {
    misbehaving *d = device;
    if (d->block_after > 0 && ++d->reads > d->block_after) {
        atomic_store(&d->blocked_at_s, mono_s());
        for (;;) { /* a driver that hangs: never returns */
            struct timespec ts = {1, 0};
            nanosleep(&ts, NULL);
        }
    }
    if (d->sleep_ns > 0) {
        struct timespec ts = {0, d->sleep_ns};
        nanosleep(&ts, NULL);
    }
    return rths_io_virtual_plugin.read(d->inner, out);
}

void rths_io_plugin_write(void *device, const rths_io_demand *demand) {
    misbehaving *d = device;
    rths_io_virtual_plugin.write(d->inner, demand);
}

void rths_io_plugin_safe_state(void *device) {
    misbehaving *d = device;
    rths_io_virtual_plugin.safe_state(d->inner);
    double blocked = atomic_load(&d->blocked_at_s);
    if (blocked > 0 && !atomic_exchange(&d->safe_reported, 1)) {
        char line[160];
        int n = snprintf(line, sizeof line,
                         "misbehaving plug-in: safe state %.1f ms after the blocked sample's "
                         "deadline\n",
                         (mono_s() - (blocked + d->period_s)) * 1e3);
        ssize_t w = write(2, line, (size_t)n);
        (void)w;
    }
}

unsigned rths_io_plugin_sample_flags(void *device) {
    misbehaving *d = device;
    return rths_io_virtual_plugin.sample_flags(d->inner);
}
