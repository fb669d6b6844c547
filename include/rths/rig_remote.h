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
 * DoF. A controller of another protocol version is refused naming both versions.
 *
 * rths_rig_set_forcing sends SET_FORCING without waiting for its ACK, so the target set next
 * follows it on the wire with no round trip between them and both keep the change's periods
 * (docs/protocol.md, "Which periods follow a change"). A controller's refusal of that forcing
 * (e.g. beyond server.max_frequency_hz) is therefore returned by the next rths_rig_set_target,
 * rths_rig_run_periods or rths_rig_record_trace, naming SET_FORCING, and again by each of them
 * until the next set_forcing (rths_rig_reset_fault does not clear it); the forcing before it
 * stays in force. */
#ifndef RTHS_RIG_REMOTE_H
#define RTHS_RIG_REMOTE_H

#include "rths/rig.h"

typedef struct rths_remote_options {
    double connect_timeout_s; /* connect + HELLO; default 5 s */
    double reply_timeout_s;   /* one request's reply; default 5 s */
    double stall_timeout_s;   /* no period for this long (beyond one period) = link fault; 10 s */
    const char *client_name;  /* sent in HELLO; default "rths host" */
    /* Test hook (docs/protocol.md, "Injected link delay"): every frame to the controller is sent
     * this long after it is ready (one sent right behind another travels with it), and every
     * frame from it is read this long after it arrived,
     * as over a link of that one-way latency; 0 (default): none. When 0, the environment variable
     * RTHS_TEST_LINK_DELAY_S (seconds, 0..60) sets it; only tests use either. */
    double link_delay_s;
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

/* The fault a remote rig knows without asking (the controller pushes a STATUS whenever its fault
 * or armed state changes, taken in whenever the rig reads; a lost link latches at once): 1 with
 * *out filled for a remote rig, 0 for any other rig. rths_rig_get_fault asks the controller
 * (a round trip over the link) when none is known. */
int rths_remote_rig_known_fault(rths_rig *rig, rths_rig_fault *out);

/* ---- multi-site tests (docs/method.md, "Multi-site tests") ----
 *
 * One rig over several sites, each a rig of its own (a controller process: its own physical
 * substructure, actuators, sample rate and clock) driving a subset of the host's interface DoFs.
 * Targets are split by site, every operation goes to all sites at once (one thread per further
 * site), and the i-th period each site delivers after the last setting is joined into the
 * host's i-th record, every DoF from its site (samples and integrity counts summed); after a
 * forcing change a site that starts later in the glide than the others (its target came late)
 * has them drop their leading glide periods to line up (docs/protocol.md, "Which periods follow
 * a change"), and sites whose periods' frequencies still differ are an error. A fault or
 * lost link at any site disarms every other site (excitation and target ramped to zero) and is
 * the joined rig's fault. Its time is the longest any site ran since the join. */
typedef struct rths_site_info {
    char uri[300];
    char description[256];            /* the site's rig, as it describes itself */
    int interface_dofs;               /* DoFs the site drives */
    int map[RTHS_MAX_INTERFACE_DOFS]; /* host interface index (0-based) of its DoF j */
    double rig_time_s;                /* its controller's time since the join, s */
    rths_rig_fault fault;             /* its latched fault */
    rths_rig_integrity integrity;     /* its periods' integrity counts */
} rths_site_info;

/* Joins n_sites rigs (taken over: destroyed with the joined rig, or here on error); site k's DoF
 * j is the host's interface DoF maps[k][j] (0-based), every one of interface_dofs driven by
 * exactly one site; names[k] names the site in messages. RTHS_EINPUT naming the DoF otherwise. */
int rths_sites_rig_join(int n_sites, rths_rig **rigs, const char *const *names,
                        const int *const *maps, int interface_dofs, rths_rig **out,
                        rths_error *err);
/* Connects to every site's controller (rths_remote_rig_create with opt) and joins them. */
int rths_sites_rig_create(int n_sites, const char *const *uris, const int *const *maps,
                          int interface_dofs, const rths_remote_options *opt, rths_rig **out,
                          rths_error *err);
/* The sites of a joined rig (0 for any other rig) and what site k did (RTHS_EINPUT: no such). */
int rths_sites_rig_count(rths_rig *rig);
int rths_sites_rig_site(rths_rig *rig, int k, rths_site_info *out);

#endif
