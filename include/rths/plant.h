/* rths plant: the virtual laboratory (docs/method.md, "The virtual
 * rig") behind the per-sample I/O seam (rths_sensor_sample).
 *
 * The physical substructure with the interface storey's FULL mass (the rig's storey; the mass
 * ratio is emulated by the controller's inertial compensation), optionally the bilinear leg with
 * its static preload; an electrodynamic shaker in current mode (force = gain x demand through a
 * pure transport delay and a first-order lag, armature mass moving with the interface storey);
 * a load cell between shaker and storey; lasers on every physical DoF and an accelerometer on
 * the interface, each with gain error, offset, white noise and quantisation from a seeded RNG.
 * The demand is held over a sample (linear reconstruction by default, or a DAC's step; see
 * linear_hold) and the plant is advanced by its exact discretisation (matrix exponential of the
 * held demand, static force and forcing, precomputed at create; a sample that crosses the
 * bilinear kink is split at the crossing, each part integrated by RK4); classical RK4 at
 * substeps_per_sample substeps remains as rig.plant_integrator: rk4 (tests/test_plant.c: the two
 * agree to 1.2e-13 of the response, 8e-11 through the kink). The preload is a static external force
 * on the interface storey that the load cell does not see (the seed's shaker offset). Forcing on an
 * internal physical DoF, when the setup has it there, is applied here (rths_plant_set_forcing).
 *
 * A lab's DAQ backend replaces this module at the same seam: read the sensors, apply the
 * demand, once per sample. */
#ifndef RTHS_PLANT_H
#define RTHS_PLANT_H

#include "rths/setup.h"
#include "rths/signals.h"

typedef struct rths_sensor_spec {
    double gain_error; /* relative: reading = (1 + gain_error) x true + offset + noise */
    double offset;     /* in the sensor's unit (m, m/s^2, N) */
    double noise_std;  /* white noise standard deviation, sensor's unit */
    double quantum;    /* quantisation step (0: none) */
} rths_sensor_spec;

/* The longest shaker transport delay the plant holds, in samples (delay_s x sample rate, rounded;
 * the delay line of plant.c). */
#define RTHS_PLANT_MAX_DELAY_SAMPLES 4095

typedef struct rths_plant_options {
    double gain_n_per_v;     /* shaker force per demand volt */
    double delay_s;          /* pure transport delay (rounded to whole samples) */
    double lag_cutoff_hz;    /* first-order lag; 0: none */
    double armature_mass_kg; /* moves with the interface storey */
    int noise;               /* 0: every sensor exact (gain error, offset, noise, quantum off) */
    uint64_t seed;           /* noise generator seed */
    int substeps_per_sample; /* 0: exact discretisation (default); n >= 1: RK4, n substeps */
    int linear_hold;         /* 1: the demand ramps linearly from the last sample's value over
                                the sample (a reconstruction filter) instead of a DAC's step */
    rths_sensor_spec laser, accelerometer, load_cell;
} rths_plant_options;

void rths_plant_defaults(rths_plant_options *opt);
/* An ideal shaker and exact sensors: no delay, no lag, no armature mass, no noise, and a
 * continuous force (linear hold of the demand): the only discrete thing left is the controller. */
void rths_plant_ideal(rths_plant_options *opt);
/* Reads the `rig` section (rig.noise, rig.seed, rig.shaker.*, rig.sensors.*) over the defaults. */
int rths_plant_config_read(rths_config *cfg, rths_plant_options *opt, rths_error *err);

typedef struct rths_plant rths_plant;

int rths_plant_create(const rths_setup *setup, const rths_plant_options *opt, double sample_rate_hz,
                      rths_plant **out, rths_error *err);
void rths_plant_destroy(rths_plant *p);
/* Sensor readings at the current time (noise drawn here). */
void rths_plant_read(rths_plant *p, rths_sensor_sample *out);
/* Forcing on an internal physical DoF (the setup's forcing DoF, when it is one; ignored
 * otherwise) over the next sample: amplitude_n cos(theta + omega tau), 0 <= tau <= h, continuous
 * in time (rths_controller_forcing gives the arguments). */
void rths_plant_set_forcing(rths_plant *p, double amplitude_n, double theta, double omega_rad_s);
/* Advances one sample with the demand held. */
void rths_plant_advance(rths_plant *p, double demand_v);
double rths_plant_time_s(const rths_plant *p);
/* True interface displacement (no sensor effects), m: for tests. */
double rths_plant_interface_displacement_m(const rths_plant *p);
/* Displacement noise standard deviation of the lasers, m (0 with noise off). */
double rths_plant_noise_level_m(const rths_plant *p);
/* Restoring force of the bilinear leg (N, positive pulling the storeys together in extension)
 * for a leg extension delta (m): k delta for delta >= 0, ratio k delta below. */
double rths_plant_leg_force_n(const rths_plant *p, double delta_m);

#endif
