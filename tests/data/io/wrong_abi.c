/* A deliberately broken I/O plug-in (tests/test_io.c): every symbol present, but built for an ABI
 * version the controller does not speak. Opening it would be an error: the controller must refuse
 * it before calling open. */
#include "rths/io.h"

#include <stdlib.h>

uint32_t rths_io_plugin_abi_version(void) {
    return RTHS_IO_ABI_VERSION + 41;
}
int rths_io_plugin_open(const rths_io_open_args *args, void **device, rths_io_device_info *info,
                        rths_error *err) {
    (void)args, (void)info, (void)err;
    abort(); /* never reached: the version check comes first */
    *device = NULL;
    return 0;
}
void rths_io_plugin_close(void *device) {
    (void)device;
}
int rths_io_plugin_read(void *device, rths_sensor_sample *out) {
    (void)device, (void)out;
    return 1;
}
void rths_io_plugin_write(void *device, const rths_io_demand *demand) {
    (void)device, (void)demand;
}
void rths_io_plugin_safe_state(void *device) {
    (void)device;
}
