/* rths io: the per-sample I/O seam as a versioned C ABI, so a lab can drive its own hardware
 * (a DAQ card, a real-time I/O board) from `rths controller --io PATH.so` without editing rths
 * (docs/io-plugins.md).
 *
 * A plug-in is a shared object exporting six symbols (names below). The controller loads it with
 * dlopen, refuses it before anything is armed when the ABI version differs or a symbol is missing,
 * opens it once with the test configuration (the plug-in's own settings are the `io` section), and
 * then, on the loop thread, once per controller sample: read the sensors, step the controller,
 * write the actuator demand. safe_state is called when the loop stops (after the ramp to zero), on
 * a failed read, and before close; it must put the actuator in its safe state (zero volts, valve
 * closed) without blocking.
 *
 * The simulated plant (plant.h) is the reference plug-in: built as build/rths_io_virtual.so from
 * src/io/io_virtual.c and also linked into the library, so the in-process virtual rig and the
 * controller process run the same per-sample calls a lab's plug-in receives.
 *
 * Module order: controller -> io -> plant (docs/architecture.md): the controller's per-sample
 * loop calls a device through this header only; the reference plug-in here wraps the plant. */
#ifndef RTHS_IO_H
#define RTHS_IO_H

#include "rths/config.h"
#include "rths/plant.h"
#include "rths/setup.h"
#include "rths/signals.h"

#include <stdint.h>

/* Changes whenever a struct or a signature below changes. A plug-in reporting a version from
 * RTHS_IO_ABI_VERSION_MIN to RTHS_IO_ABI_VERSION loads (open receives the plug-in's own version
 * in abi_version, and the fields and entry points a version added are left out for an older
 * one); any other is refused. Version 2 added the converter full scales of rths_io_device_info
 * and the optional entry points (sample flags, hardware watchdog). */
#define RTHS_IO_ABI_VERSION 2u
#define RTHS_IO_ABI_VERSION_MIN 1u

/* What the controller tells the plug-in at open. */
typedef struct rths_io_open_args {
    uint32_t abi_version;  /* the version spoken: the plug-in's own (see above) */
    double sample_rate_hz; /* read and write each run once per sample at this rate */
    int physical_dofs;     /* displacements per sensor sample (physical DoFs, interface last) */
    rths_config *config;   /* the test configuration (read with rths_config_get_*; keys the
                              plug-in reads are marked known, others under `section` too) */
    const char *section;   /* "io": the plug-in's own settings, e.g. io.device */
} rths_io_open_args;

/* What the plug-in tells the controller at open. */
typedef struct rths_io_device_info {
    char description[160];        /* one line, shown in HELLO and logs */
    double displacement_noise_m;  /* standard deviation of a displacement reading, m (0: none) */
    int applies_internal_forcing; /* 1: write applies the forcing of rths_io_demand on an internal
                                     physical DoF; 0: a setup forcing one is refused at create */
    /* ABI 2 (zero from an older plug-in: not known). The converters' full scales in engineering
       units: a reading whose magnitude is at or beyond it sat at full scale (every laser, every
       accelerometer, every load cell); a demand whose magnitude is beyond the DAC's range was
       clipped by the device. The controller counts both per sample at the seam, for every
       plug-in, into the period records (signals.h, rths_period). 0: no converter, or unknown. */
    double displacement_full_scale_m;
    double acceleration_full_scale_m_s2;
    double force_full_scale_n;
    double demand_full_scale_v;
} rths_io_device_info;

/* The actuator demand for the next sample, and the forcing over it (for a plant that applies a
 * forcing on an internal physical DoF: amplitude_n cos(theta + omega tau), 0 <= tau <= h; a
 * device without such an exciter ignores it; the controller refuses that setup otherwise). */
typedef struct rths_io_demand {
    double demand_v; /* the first actuator's (demand_dof_v[0]) */
    double forcing_amplitude_n, forcing_theta_rad, forcing_omega_rad_s;
    int n_demands; /* actuators: one per interface DoF (a one-actuator device reads demand_v) */
    double demand_dof_v[RTHS_MAX_INTERFACE_DOFS];
} rths_io_demand;

/* The six symbols of a plug-in. open returns RTHS_OK or fills err (RTHS_EINPUT: the io section
 * is wrong; RTHS_EFAIL: the device cannot be opened). read returns 0; a positive rths_rig_fault
 * code when the device's own limit is beyond (the sample is valid; the controller latches that
 * fault and ramps the demand to zero); a negative number when the device could not be read (the
 * sample becomes NaN, the controller latches the non-finite fault and calls safe_state). read,
 * write and safe_state run on the loop thread: they must not allocate, block or print. */
typedef uint32_t (*rths_io_abi_version_fn)(void);
typedef int (*rths_io_open_fn)(const rths_io_open_args *args, void **device,
                               rths_io_device_info *info, rths_error *err);
typedef void (*rths_io_close_fn)(void *device);
typedef int (*rths_io_read_fn)(void *device, rths_sensor_sample *out);
typedef void (*rths_io_write_fn)(void *device, const rths_io_demand *demand);
typedef void (*rths_io_safe_state_fn)(void *device);

#define RTHS_IO_SYM_ABI_VERSION "rths_io_plugin_abi_version"
#define RTHS_IO_SYM_OPEN "rths_io_plugin_open"
#define RTHS_IO_SYM_CLOSE "rths_io_plugin_close"
#define RTHS_IO_SYM_READ "rths_io_plugin_read"
#define RTHS_IO_SYM_WRITE "rths_io_plugin_write"
#define RTHS_IO_SYM_SAFE_STATE "rths_io_plugin_safe_state"

/* Optional entry points (ABI 2; a plug-in without them loads, and the controller does without).
 *
 * sample_flags: once per sample after write, on the loop thread: what the device itself saw in
 * this sample beyond the full scales of rths_io_device_info (a DAQ's over-range bit, an
 * amplifier's current limit, the simulated actuator's force clip): RTHS_IO_SAMPLE_* bits.
 *
 * watchdog_arm, watchdog_kick: a hardware watchdog (docs/io-plugins.md, "Stalls and crashes").
 * The controller process calls watchdog_arm once before its loop starts, with the time after
 * which the hardware must put the actuator in its safe state by itself when no kick arrives;
 * it returns 0 when armed, else a negative number (the controller says so and runs without).
 * watchdog_kick runs on the loop thread once per sample after write: the proof that the loop
 * lives. A process that crashes or hangs stops kicking, and the hardware acts without it. */
#define RTHS_IO_SAMPLE_DEMAND_CLIPPED 0x1u   /* an actuator demand or command was clamped */
#define RTHS_IO_SAMPLE_SENSOR_SATURATED 0x2u /* a converter reading sat at its full scale */
typedef unsigned (*rths_io_sample_flags_fn)(void *device);
typedef int (*rths_io_watchdog_arm_fn)(void *device, double timeout_s);
typedef void (*rths_io_watchdog_kick_fn)(void *device);

#define RTHS_IO_SYM_SAMPLE_FLAGS "rths_io_plugin_sample_flags"
#define RTHS_IO_SYM_WATCHDOG_ARM "rths_io_plugin_watchdog_arm"
#define RTHS_IO_SYM_WATCHDOG_KICK "rths_io_plugin_watchdog_kick"

/* A plug-in defines these (with C linkage, exported from its shared object). */
uint32_t rths_io_plugin_abi_version(void);
int rths_io_plugin_open(const rths_io_open_args *args, void **device, rths_io_device_info *info,
                        rths_error *err);
void rths_io_plugin_close(void *device);
int rths_io_plugin_read(void *device, rths_sensor_sample *out);
void rths_io_plugin_write(void *device, const rths_io_demand *demand);
void rths_io_plugin_safe_state(void *device);
/* Optional (see above). */
unsigned rths_io_plugin_sample_flags(void *device);
int rths_io_plugin_watchdog_arm(void *device, double timeout_s);
void rths_io_plugin_watchdog_kick(void *device);

/* The plug-in's entry points, as the controller holds them (the optional ones may be NULL). */
typedef struct rths_io_plugin {
    rths_io_abi_version_fn abi_version;
    rths_io_open_fn open;
    rths_io_close_fn close;
    rths_io_read_fn read;
    rths_io_write_fn write;
    rths_io_safe_state_fn safe_state;
    rths_io_sample_flags_fn sample_flags;   /* optional */
    rths_io_watchdog_arm_fn watchdog_arm;   /* optional */
    rths_io_watchdog_kick_fn watchdog_kick; /* optional */
} rths_io_plugin;

/* ---- the controller's side ---- */

/* An opened device: a plug-in's entry points, its device handle, and the shared object. */
typedef struct rths_io rths_io;

/* Loads PATH with dlopen, checks the ABI version and every symbol, then opens the device. A
 * wrong version or a missing symbol fails with RTHS_EINPUT naming PATH and what is wrong. PATH
 * must contain a '/' (e.g. ./lab.so): a bare name would be searched in the system's library
 * path, and an empty one names nothing; both are refused, naming the rule. */
int rths_io_load(const char *path, const rths_io_open_args *args, rths_io **out, rths_error *err);
/* Opens a device through an entry-point table already in memory (the built-in reference plug-in,
 * tests), with the same checks. */
int rths_io_open_table(const rths_io_plugin *table, const char *name, const rths_io_open_args *args,
                       rths_io **out, rths_error *err);
/* Calls safe_state, close, and unloads. NULL is fine. */
void rths_io_destroy(rths_io *io);
const rths_io_device_info *rths_io_info(const rths_io *io);

/* Loop thread, once per sample. read's result is the plug-in's (see above); after a failure
 * (negative) the sample is NaN and safe_state has been called. */
int rths_io_read(rths_io *io, rths_sensor_sample *out);
void rths_io_write(rths_io *io, const rths_io_demand *demand);
/* After rths_io_read: RTHS_IO_SAMPLE_SENSOR_SATURATED when any reading of that sample sat at a
 * full scale of the device info. After rths_io_write: RTHS_IO_SAMPLE_DEMAND_CLIPPED when any
 * demand was beyond the DAC range, together with the device's own sample_flags bits. Loop thread.
 */
unsigned rths_io_read_flags(const rths_io *io);
unsigned rths_io_write_flags(const rths_io *io);
/* Drives the plug-in's safe state. Also called from the controller process's supervisor thread
 * while the loop thread may be blocked inside read or write (docs/io-plugins.md): a plug-in's
 * safe_state must be safe to call then. */
void rths_io_safe_state(rths_io *io);
/* The hardware watchdog, when the plug-in has one: arms it (0; RTHS_EFAIL when the plug-in has
 * none or refused, err says which) and kicks it (loop thread, once per sample; nothing without). */
int rths_io_watchdog_arm(rths_io *io, double timeout_s, rths_error *err);
void rths_io_watchdog_kick(rths_io *io);

/* ---- the reference plug-in: the simulated plant ---- */

/* Its entry points (the same functions build/rths_io_virtual.so exports). Its open reads the
 * setup (structure, split, forcing) and the rig section from args->config. */
extern const rths_io_plugin rths_io_virtual_plugin;
/* The reference plug-in over parsed options (the in-process virtual rig, tests). */
int rths_io_open_virtual(const rths_setup *setup, const rths_plant_options *popt,
                         double sample_rate_hz, rths_io **out, rths_error *err);
/* The plant behind a reference-plug-in device in this process; NULL for any other device (or the
 * reference plug-in loaded from its shared object, whose plant lives in another copy). */
rths_plant *rths_io_virtual_plant(rths_io *io);

#endif
