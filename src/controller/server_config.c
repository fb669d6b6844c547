/* `server` section of the test configuration (docs/config/server.md). Kept apart from server.c
 * so the server links without the configuration reader (tests, bench). */
#include "rths/server.h"

int rths_server_config_read(rths_config *cfg, rths_server_options *opt, rths_error *err) {
    int rc;
    long v;
    if ((rc = rths_config_get_double(cfg, "server.watchdog_s", 0, opt->watchdog_s, 0.01, 3600.0,
                                     &opt->watchdog_s, err)) ||
        (rc =
             rths_config_get_bool(cfg, "server.realtime", 0, opt->realtime, &opt->realtime, err)) ||
        (rc = rths_config_get_double(cfg, "server.max_frequency_hz", 0, opt->max_frequency_hz, 1e-3,
                                     1e4, &opt->max_frequency_hz, err)) ||
        (rc = rths_config_get_double(cfg, "server.max_amplitude_n", 0, opt->max_amplitude_n, 0.0,
                                     1e5, &opt->max_amplitude_n, err)) ||
        (rc = rths_config_get_double(cfg, "server.stall_margin_s", 0, opt->stall_margin_s, 1e-3,
                                     10.0, &opt->stall_margin_s, err)) ||
        (rc = rths_config_get_double(cfg, "server.hardware_watchdog_s", 0, opt->hardware_watchdog_s,
                                     1e-3, 60.0, &opt->hardware_watchdog_s, err)))
        return rc;
    if ((rc = rths_config_get_int(cfg, "server.priority", 0, opt->priority, 1, 99, &v, err)))
        return rc;
    opt->priority = (int)v;
    if ((rc = rths_config_get_int(cfg, "server.cpu", 0, opt->cpu, -1, 1023, &v, err))) return rc;
    opt->cpu = (int)v;
    return RTHS_OK;
}
