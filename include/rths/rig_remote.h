/* rths remote rig: the host-side client of the controller process (`rths controller`).
 *
 * Implements the rig interface (rig.h) over the binary protocol of docs/protocol.md, so iterate/,
 * continuation/ and the commands run unchanged against a controller on another machine. Rig time
 * is the controller's time as it reports it (samples run x sample period). Link errors (lost
 * connection, protocol error, reply timeout) latch RTHS_RIG_FAULT_LINK; rths_rig_reset_fault then
 * reconnects and restores the last forcing and target (the controller is left disarmed until the
 * next run). Faults the controller latches (limits, watchdog) are reported as they are.
 *
 * Protocol version 2 carries every interface DoF: the rig drives the interface DoFs the
 * controller announces in HELLO_REPLY (rths_rig_interface_dofs), sends every DoF's target
 * (rths_rig_set_target_dofs; rths_rig_set_target is its one-DoF case) and returns periods
 * carrying every DoF (rths_period.interface_dofs, phys_dof...). Traces carry the first interface
 * DoF. A controller of another protocol version is refused naming both versions. */
#ifndef RTHS_RIG_REMOTE_H
#define RTHS_RIG_REMOTE_H

#include "rths/rig.h"

typedef struct rths_remote_options {
    double connect_timeout_s; /* connect + HELLO; default 5 s */
    double reply_timeout_s;   /* one request's reply; default 5 s */
    double stall_timeout_s;   /* no period for this long (beyond one period) = link fault; 10 s */
    const char *client_name;  /* sent in HELLO; default "rths host" */
} rths_remote_options;

void rths_remote_options_defaults(rths_remote_options *opt);

/* 1 when uri names a remote rig ("tcp://..."). */
int rths_rig_uri_is_remote(const char *uri);

/* Parses "tcp://HOST:PORT" (HOST may be a name, an IPv4 address or [IPv6]). RTHS_EINPUT when
 * malformed. host must hold host_cap bytes. */
int rths_remote_parse_uri(const char *uri, char *host, size_t host_cap, int *port, rths_error *err);

/* Connects to the controller at uri and says HELLO; opt may be NULL for the defaults.
 * RTHS_EINPUT for a malformed uri, RTHS_EFAIL when the controller cannot be reached or refuses
 * (e.g. busy with another armed client), with the reason in err. */
int rths_remote_rig_create(const char *uri, const rths_remote_options *opt, rths_rig **out,
                           rths_error *err);

#endif
