/* A deliberately broken I/O plug-in (tests/test_io.c): the right ABI version, but no
 * rths_io_plugin_safe_state. The controller must refuse it, naming the symbol. */
#include "rths/io.h"

uint32_t rths_io_plugin_abi_version(void) {
    return RTHS_IO_ABI_VERSION;
}
int rths_io_plugin_open(const rths_io_open_args *args, void **device, rths_io_device_info *info,
                        rths_error *err) {
    (void)args, (void)info, (void)err;
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
