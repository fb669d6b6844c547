/* The controller's side of the I/O plug-in ABI (see io.h): load, check, open, call per sample. */
#include "io/io_internal.h"
#include "rths/io.h"

#include <dlfcn.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct rths_io {
    rths_io_plugin fn;
    void *device;
    void *library; /* dlopen handle, NULL for a table in memory */
    rths_io_device_info info;
    /* the full scales checked per sample (info's; 0: none), and whether any is set */
    double fs_displacement, fs_acceleration, fs_force, fs_demand;
    int check_sensors;
    unsigned read_flags, write_flags; /* the last sample's, RTHS_IO_SAMPLE_* */
};

static int check_table(const rths_io_plugin *t, const char *name, rths_error *err) {
    static const char *const symbols[6] = {RTHS_IO_SYM_ABI_VERSION, RTHS_IO_SYM_OPEN,
                                           RTHS_IO_SYM_CLOSE,       RTHS_IO_SYM_READ,
                                           RTHS_IO_SYM_WRITE,       RTHS_IO_SYM_SAFE_STATE};
    const int present[6] = {t->abi_version != NULL, t->open != NULL,  t->close != NULL,
                            t->read != NULL,        t->write != NULL, t->safe_state != NULL};
    for (int i = 0; i < 6; i++)
        if (!present[i])
            return rths_error_set(err, RTHS_EINPUT,
                                  "I/O plug-in %s: symbol '%s' is missing (docs/io-plugins.md "
                                  "lists the six a plug-in exports)",
                                  name, symbols[i]);
    uint32_t v = t->abi_version();
    if (v < RTHS_IO_ABI_VERSION_MIN || v > RTHS_IO_ABI_VERSION)
        return rths_error_set(err, RTHS_EINPUT,
                              "I/O plug-in %s: ABI version %u, this controller speaks versions %u "
                              "to %u (rebuild the plug-in against this rths's include/rths/io.h)",
                              name, (unsigned)v, (unsigned)RTHS_IO_ABI_VERSION_MIN,
                              (unsigned)RTHS_IO_ABI_VERSION);
    return RTHS_OK;
}

/* A full scale as checked: finite and positive, else none (0). */
static double full_scale(double v) {
    return isfinite(v) && v > 0 ? v : 0.0;
}

/* The per-sample checks from the device info; an older plug-in's fields beyond its version are
 * zero (the info starts zeroed), and its optional entry points are not used. */
static void seam_from_info(rths_io *io, uint32_t version) {
    if (version < 2) {
        io->fn.sample_flags = NULL;
        io->fn.watchdog_arm = NULL;
        io->fn.watchdog_kick = NULL;
        io->info.displacement_full_scale_m = io->info.acceleration_full_scale_m_s2 = 0;
        io->info.force_full_scale_n = io->info.demand_full_scale_v = 0;
    }
    io->fs_displacement = full_scale(io->info.displacement_full_scale_m);
    io->fs_acceleration = full_scale(io->info.acceleration_full_scale_m_s2);
    io->fs_force = full_scale(io->info.force_full_scale_n);
    io->fs_demand = full_scale(io->info.demand_full_scale_v);
    io->check_sensors = io->fs_displacement > 0 || io->fs_acceleration > 0 || io->fs_force > 0;
}

int rths_io_open_table(const rths_io_plugin *table, const char *name, const rths_io_open_args *args,
                       rths_io **out, rths_error *err) {
    *out = NULL;
    int rc = check_table(table, name, err);
    if (rc) return rc;
    rths_io *io = calloc(1, sizeof *io);
    if (!io) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    io->fn = *table;
    rths_error_clear(err);
    /* the plug-in is spoken to in its own version (check_table: within the range spoken) */
    rths_io_open_args spoken = *args;
    spoken.abi_version = table->abi_version();
    rc = io->fn.open(&spoken, &io->device, &io->info, err);
    if (rc) {
        if (!err->msg[0]) rths_error_set(err, rc, "I/O plug-in %s: open failed", name);
        free(io);
        return rc == RTHS_EINPUT ? RTHS_EINPUT : RTHS_EFAIL;
    }
    io->info.description[sizeof io->info.description - 1] = '\0';
    seam_from_info(io, spoken.abi_version);
    *out = io;
    return RTHS_OK;
}

int rths_io_adopt(const rths_io_plugin *table, const char *name, void *device,
                  const rths_io_device_info *info, rths_io **out, rths_error *err) {
    *out = NULL;
    int rc = check_table(table, name, err);
    if (rc) return rc;
    rths_io *io = calloc(1, sizeof *io);
    if (!io) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    io->fn = *table;
    io->device = device;
    io->info = *info;
    seam_from_info(io, table->abi_version());
    *out = io;
    return RTHS_OK;
}

int rths_io_load(const char *path, const rths_io_open_args *args, rths_io **out, rths_error *err) {
    *out = NULL;
    /* dlopen searches the system's library path for a name without a slash: an unset variable
     * in a lab's script or a typo would load some library of the system, or nothing */
    if (!path || !path[0])
        return rths_error_set(err, RTHS_EINPUT,
                              "I/O plug-in: the path is empty; give the plug-in's shared object "
                              "by a path (e.g. ./lab_daq.so), or leave io.plugin and --io out "
                              "for the simulated plant");
    if (!strchr(path, '/'))
        return rths_error_set(err, RTHS_EINPUT,
                              "I/O plug-in '%s': not a path; name the shared object by a path "
                              "containing '/' (e.g. ./%s), it is never looked up in the system's "
                              "library path",
                              path, path);
    /* RTLD_LOCAL: two plug-ins (or a plug-in and rths) never bind each other's symbols */
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) return rths_error_set(err, RTHS_EINPUT, "I/O plug-in %s: %s", path, dlerror());
    rths_io_plugin t;
    /* object pointer -> function pointer through memcpy: ISO C has no conversion, POSIX
     * guarantees the representation */
    void *sym[9];
    static const char *const names[9] = {
        RTHS_IO_SYM_ABI_VERSION,  RTHS_IO_SYM_OPEN,         RTHS_IO_SYM_CLOSE,
        RTHS_IO_SYM_READ,         RTHS_IO_SYM_WRITE,        RTHS_IO_SYM_SAFE_STATE,
        RTHS_IO_SYM_SAMPLE_FLAGS, RTHS_IO_SYM_WATCHDOG_ARM, RTHS_IO_SYM_WATCHDOG_KICK};
    for (int i = 0; i < 9; i++)
        sym[i] = dlsym(lib, names[i]); /* the last three are optional: NULL is fine */
    memcpy(&t.abi_version, &sym[0], sizeof t.abi_version);
    memcpy(&t.open, &sym[1], sizeof t.open);
    memcpy(&t.close, &sym[2], sizeof t.close);
    memcpy(&t.read, &sym[3], sizeof t.read);
    memcpy(&t.write, &sym[4], sizeof t.write);
    memcpy(&t.safe_state, &sym[5], sizeof t.safe_state);
    memcpy(&t.sample_flags, &sym[6], sizeof t.sample_flags);
    memcpy(&t.watchdog_arm, &sym[7], sizeof t.watchdog_arm);
    memcpy(&t.watchdog_kick, &sym[8], sizeof t.watchdog_kick);
    int rc = rths_io_open_table(&t, path, args, out, err);
    if (rc) {
        dlclose(lib);
        return rc;
    }
    (*out)->library = lib;
    return RTHS_OK;
}

void rths_io_destroy(rths_io *io) {
    if (!io) return;
    io->fn.safe_state(io->device);
    io->fn.close(io->device);
    if (io->library) dlclose(io->library);
    free(io);
}

const rths_io_device_info *rths_io_info(const rths_io *io) {
    return &io->info;
}

/* 1 when any reading of the sample is at or beyond its converter's full scale (a NaN is not:
 * the step latches the non-finite fault for it). */
static int saturated(const rths_io *io, const rths_sensor_sample *s) {
    int hit = 0;
    if (io->fs_displacement > 0)
        for (int i = 0; i < s->n && i < RTHS_MAX_SENSED_DOFS; i++)
            hit |= fabs(s->displacement_m[i]) >= io->fs_displacement;
    /* the scalars are the first interface DoF's; the arrays, when filled, every DoF's */
    const int ni =
        s->n_interface < RTHS_MAX_INTERFACE_DOFS ? s->n_interface : RTHS_MAX_INTERFACE_DOFS;
    if (io->fs_acceleration > 0) {
        hit |= fabs(s->interface_acceleration_m_s2) >= io->fs_acceleration;
        for (int d = 0; d < ni; d++)
            hit |= fabs(s->interface_acceleration_dof_m_s2[d]) >= io->fs_acceleration;
    }
    if (io->fs_force > 0) {
        hit |= fabs(s->interface_force_n) >= io->fs_force;
        for (int d = 0; d < ni; d++)
            hit |= fabs(s->interface_force_dof_n[d]) >= io->fs_force;
    }
    return hit;
}

int rths_io_read(rths_io *io, rths_sensor_sample *out) {
    int rc = io->fn.read(io->device, out);
    io->read_flags = 0;
    if (rc >= 0 && io->check_sensors && saturated(io, out))
        io->read_flags = RTHS_IO_SAMPLE_SENSOR_SATURATED;
    if (rc < 0) {
        /* a reading that failed must not look like a reading: the step trips on the NaN */
        for (int i = 0; i < RTHS_MAX_SENSED_DOFS; i++)
            out->displacement_m[i] = NAN;
        out->interface_acceleration_m_s2 = NAN;
        out->interface_force_n = NAN;
        io->fn.safe_state(io->device);
    }
    return rc;
}

void rths_io_write(rths_io *io, const rths_io_demand *demand) {
    io->fn.write(io->device, demand);
    unsigned flags = io->fn.sample_flags ? io->fn.sample_flags(io->device) : 0u;
    if (io->fs_demand > 0) {
        /* a one-actuator device reads demand_v; a several-actuator one every demand_dof_v */
        int clipped = fabs(demand->demand_v) > io->fs_demand;
        for (int a = 1; a < demand->n_demands && a < RTHS_MAX_INTERFACE_DOFS; a++)
            clipped |= fabs(demand->demand_dof_v[a]) > io->fs_demand;
        if (clipped) flags |= RTHS_IO_SAMPLE_DEMAND_CLIPPED;
    }
    io->write_flags = flags;
}

unsigned rths_io_read_flags(const rths_io *io) {
    return io->read_flags;
}

unsigned rths_io_write_flags(const rths_io *io) {
    return io->write_flags;
}

void rths_io_safe_state(rths_io *io) {
    io->fn.safe_state(io->device);
}

int rths_io_watchdog_arm(rths_io *io, double timeout_s, rths_error *err) {
    if (!io->fn.watchdog_arm || !io->fn.watchdog_kick)
        return rths_error_set(err, RTHS_EFAIL,
                              "the I/O plug-in has no hardware watchdog (rths_io_plugin_"
                              "watchdog_arm and _kick, docs/io-plugins.md)");
    int rc = io->fn.watchdog_arm(io->device, timeout_s);
    if (rc < 0)
        return rths_error_set(err, RTHS_EFAIL,
                              "the I/O plug-in could not arm its hardware watchdog (%d)", rc);
    return RTHS_OK;
}

void rths_io_watchdog_kick(rths_io *io) {
    if (io->fn.watchdog_kick) io->fn.watchdog_kick(io->device);
}

rths_plant *rths_io_virtual_plant(rths_io *io) {
    if (!io || io->fn.open != rths_io_virtual_plugin.open) return NULL;
    return *(rths_plant **)io->device; /* the reference device starts with its plant */
}
