/* Private to src/io: wrapping a device already opened by its maker. */
#ifndef RTHS_IO_INTERNAL_H
#define RTHS_IO_INTERNAL_H

#include "rths/io.h"

/* Checks the table like rths_io_open_table and takes over device (closed by rths_io_destroy);
 * on failure the caller still owns device. */
int rths_io_adopt(const rths_io_plugin *table, const char *name, void *device,
                  const rths_io_device_info *info, rths_io **out, rths_error *err);

#endif
