/* The controller process's view of the per-sample machinery (controller step + plant seam).
 * server.c does pacing, threads and the network; server_engine.c adapts the step and plant.
 * Private to src/controller. Functions marked "loop" run only on the loop thread and must not
 * allocate, block or print; "network" ones only on the network thread. */
#ifndef RTHS_SERVER_ENGINE_H
#define RTHS_SERVER_ENGINE_H

#include "rths/config.h"
#include "rths/controller.h"
#include "rths/protocol.h"

typedef struct rths_engine rths_engine;

typedef struct rths_engine_info {
    double sample_period_s;
    double noise_level_m; /* displacement noise std of the plant's sensors, m */
    int max_harmonics;
    int interface_dofs;          /* interface DoFs the loop drives, one actuator each */
    double ramp_time_s;          /* disarm/fault ramp of demand, forcing and target to zero, s */
    double min_frequency_hz;     /* controller.min_frequency_hz: SET_FORCING below is refused */
    double displacement_limit_m; /* controller.limits.displacement_m: targets beyond are refused */
    char description[RTHS_PROTO_MAX_TEXT + 1];
} rths_engine_info;

/* Builds step and plant from the configuration (setup, rig/plant and controller sections). */
int rths_engine_create(rths_config *cfg, rths_engine **out, rths_engine_info *info,
                       rths_error *err);
void rths_engine_destroy(rths_engine *e);

/* loop: one controller sample (sensors in, step, demand out, plant advances one sample);
 * fills the signals of this sample for traces. */
void rths_engine_step(rths_engine *e, rths_proto_trace_sample *sig);
/* loop: 0 when armed, RTHS_PROTO_ESTATE when a latched fault forbids it. */
int rths_engine_arm(rths_engine *e);
void rths_engine_disarm(rths_engine *e); /* loop: ramp excitation and target to zero */
/* loop: latch the watchdog fault + disarm; silence_s and watchdog_s name it */
void rths_engine_trip_watchdog(rths_engine *e, double silence_s, double watchdog_s);
/* loop: latch the fault the supervisor found (a stalled loop) + disarm */
void rths_engine_trip(rths_engine *e, const rths_fault_detail *detail);
/* loop: what latched the fault (cause NONE without one) */
void rths_engine_fault_detail(const rths_engine *e, rths_fault_detail *out);
/* loop: the next step's sample started after its deadline (counted late in its period) */
void rths_engine_mark_late(rths_engine *e);
/* any thread: drives the device's safe state (the supervisor, while the loop may be stuck) */
void rths_engine_safe_state(rths_engine *e);
/* before the loop starts: arms the device's hardware watchdog (io.h); RTHS_EFAIL when it has
 * none or refused, err says which */
int rths_engine_watchdog_arm(rths_engine *e, double timeout_s, rths_error *err);
void rths_engine_set_forcing(rths_engine *e, double frequency_hz, double amplitude_n); /* loop */
/* the time from which the host keeps periods after that change
 * (rths_controller_forcing_valid_from_s) */
double rths_engine_forcing_valid_from_s(const rths_engine *e);
/* loop: targets of every interface DoF, DoF d's coefficients at a[d * harmonics + k - 1] */
void rths_engine_set_target(rths_engine *e, int dofs, int harmonics, const double *a,
                            const double *b);
/* the time from which the host keeps periods after that target
 * (rths_controller_target_valid_from_s) */
double rths_engine_target_valid_from_s(const rths_engine *e);
/* loop: every actuator's demand after the last sample, V (info.interface_dofs of them) */
void rths_engine_demands(const rths_engine *e, double *demand_v);
void rths_engine_reset_fault(rths_engine *e);           /* loop */
int rths_engine_armed(const rths_engine *e);            /* loop */
int rths_engine_fault(const rths_engine *e);            /* loop; rths_rig_fault numbering */
double rths_engine_time_s(const rths_engine *e);        /* loop: controller (rig) time, s */
long rths_engine_dropped_periods(const rths_engine *e); /* loop */

/* network: next whole period from the step's ring; 1 when one was popped. */
int rths_engine_pop_period(rths_engine *e, rths_proto_period *out);

#endif
