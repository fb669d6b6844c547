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
    if (v != RTHS_IO_ABI_VERSION)
        return rths_error_set(err, RTHS_EINPUT,
                              "I/O plug-in %s: ABI version %u, this controller speaks version %u "
                              "(rebuild the plug-in against this rths's include/rths/io.h)",
                              name, (unsigned)v, (unsigned)RTHS_IO_ABI_VERSION);
    return RTHS_OK;
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
    rc = io->fn.open(args, &io->device, &io->info, err);
    if (rc) {
        if (!err->msg[0]) rths_error_set(err, rc, "I/O plug-in %s: open failed", name);
        free(io);
        return rc == RTHS_EINPUT ? RTHS_EINPUT : RTHS_EFAIL;
    }
    io->info.description[sizeof io->info.description - 1] = '\0';
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
    *out = io;
    return RTHS_OK;
}

int rths_io_load(const char *path, const rths_io_open_args *args, rths_io **out, rths_error *err) {
    *out = NULL;
    /* RTLD_LOCAL: two plug-ins (or a plug-in and rths) never bind each other's symbols */
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) return rths_error_set(err, RTHS_EINPUT, "I/O plug-in %s: %s", path, dlerror());
    rths_io_plugin t;
    /* object pointer -> function pointer through memcpy: ISO C has no conversion, POSIX
     * guarantees the representation */
    void *sym[6];
    static const char *const names[6] = {RTHS_IO_SYM_ABI_VERSION, RTHS_IO_SYM_OPEN,
                                         RTHS_IO_SYM_CLOSE,       RTHS_IO_SYM_READ,
                                         RTHS_IO_SYM_WRITE,       RTHS_IO_SYM_SAFE_STATE};
    for (int i = 0; i < 6; i++)
        sym[i] = dlsym(lib, names[i]);
    memcpy(&t.abi_version, &sym[0], sizeof t.abi_version);
    memcpy(&t.open, &sym[1], sizeof t.open);
    memcpy(&t.close, &sym[2], sizeof t.close);
    memcpy(&t.read, &sym[3], sizeof t.read);
    memcpy(&t.write, &sym[4], sizeof t.write);
    memcpy(&t.safe_state, &sym[5], sizeof t.safe_state);
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

int rths_io_read(rths_io *io, rths_sensor_sample *out) {
    int rc = io->fn.read(io->device, out);
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
}

void rths_io_safe_state(rths_io *io) {
    io->fn.safe_state(io->device);
}

rths_plant *rths_io_virtual_plant(rths_io *io) {
    if (!io || io->fn.open != rths_io_virtual_plugin.open) return NULL;
    return *(rths_plant **)io->device; /* the reference device starts with its plant */
}
