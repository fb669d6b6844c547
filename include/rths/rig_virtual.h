/* rths virtual rig: the in-process rig backend, the controller step driving the virtual plant
 * on a simulated clock, as fast as the CPU allows or paced at a factor of real time (rig.pace).
 * Implements rig.h. */
#ifndef RTHS_RIG_VIRTUAL_H
#define RTHS_RIG_VIRTUAL_H

#include "rths/controller.h"
#include "rths/plant.h"
#include "rths/rig.h"

/* From the configuration: controller and rig sections (rths_controller_config_read,
 * rths_plant_config_read). seed_override: when has_seed, replaces rig.seed. */
int rths_virtual_rig_create(rths_config *cfg, const rths_setup *setup, int has_seed,
                            uint64_t seed_override, rths_rig **out, rths_error *err);
/* From parsed options (tests, benches). The rig starts armed, at rest, without forcing. */
int rths_virtual_rig_create_with(const rths_setup *setup, const rths_controller_options *copt,
                                 const rths_plant_options *popt, rths_rig **out, rths_error *err);
/* Paces the rig at factor x real time (1: a rig second takes a wall second; 20: a twentieth),
 * so a demo looks like a lab run and a live view can be seen moving; 0: unpaced (the default).
 * Pacing only sleeps, per delivered period, to an absolute monotonic deadline: results are
 * bit-identical to an unpaced run. Also from the configuration as rig.pace. RTHS_EINPUT for a
 * negative or non-finite factor or a rig that is not virtual. */
int rths_virtual_rig_set_pace(rths_rig *rig, double factor, rths_error *err);
/* The controller inside a virtual rig (feedback mode, direct inspection); NULL for other rigs. */
rths_controller *rths_virtual_rig_controller(rths_rig *rig);
rths_plant *rths_virtual_rig_plant(rths_rig *rig);
/* The integrity counts (rths_period) of every period the rig's controller closed since the rig
 * was created, delivered by run_periods or not (a trace's, a perturbed record's, those dropped
 * after a new setting): what feedback mode, which records traces only, judges clipping by.
 * RTHS_EINPUT (zeros) for a rig that is not virtual. */
int rths_virtual_rig_integrity(rths_rig *rig, rths_rig_integrity *out);

/* The per-sample loop's demand perturbation (defined in src/controller/sample_loop.c beside the
 * loop, declared here for its one user): rms_v 0 turns it off. Band-limited white noise, see
 * rths_perturbation in rig.h. RTHS_EINPUT for a negative or non-finite level. The loop then adds
 * it to the first actuator's demand every sample, allocation- and library-free. */
int rths_sample_loop_set_perturbation(rths_sample_loop *loop, double rms_v, double cutoff_hz,
                                      double sample_rate_hz, uint64_t seed);
/* The perturbation added at the last sample, V. */
double rths_sample_loop_perturbation_v(const rths_sample_loop *loop);

#endif
