/* build/rths_io_virtual.so: the reference I/O plug-in (the simulated plant, src/io/io_virtual.c)
 * under the exported names of the ABI (include/rths/io.h), for `rths controller --io`. */
#include "rths/io.h"

uint32_t rths_io_plugin_abi_version(void) {
    return rths_io_virtual_plugin.abi_version();
}
int rths_io_plugin_open(const rths_io_open_args *args, void **device, rths_io_device_info *info,
                        rths_error *err) {
    return rths_io_virtual_plugin.open(args, device, info, err);
}
void rths_io_plugin_close(void *device) {
    rths_io_virtual_plugin.close(device);
}
int rths_io_plugin_read(void *device, rths_sensor_sample *out) {
    return rths_io_virtual_plugin.read(device, out);
}
void rths_io_plugin_write(void *device, const rths_io_demand *demand) {
    rths_io_virtual_plugin.write(device, demand);
}
void rths_io_plugin_safe_state(void *device) {
    rths_io_virtual_plugin.safe_state(device);
}
unsigned rths_io_plugin_sample_flags(void *device) {
    return rths_io_virtual_plugin.sample_flags(device);
}
