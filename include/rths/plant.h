/* rths plant: the virtual laboratory (docs/method.md, "The virtual
 * rig") behind the per-sample I/O seam (rths_sensor_sample).
 *
 * The physical substructure with the interface mass the rig carries (rig.interface_mass, setup.h:
 * the storey's FULL mass, the mass ratio emulated by the controller's inertial compensation, or
 * only the physical share (1 - p) M_II of a light specimen), optionally the bilinear leg with
 * its static preload; an electrodynamic shaker in current mode (force = gain x demand through a
 * pure transport delay and a first-order lag, armature mass moving with the interface storey),
 * or an actuator given as a transfer function with the specimen's velocity fed back (a
 * servo-hydraulic actuator; rths_actuator_options), with force, stroke and velocity limits and a
 * DAC; a load cell between actuator and storey; lasers on every physical DoF and an accelerometer
 * on the interface, each with gain error, offset, white noise and quantisation from a seeded RNG,
 * and optionally an ADC (resolution over a voltage range, noise in volts; rths_adc_spec).
 * The demand is held over a sample (linear reconstruction by default, or a DAC's step; see
 * linear_hold) and the plant is advanced by its exact discretisation (matrix exponential of the
 * held demand, static force and forcing, precomputed at create; a sample that crosses the
 * bilinear kink is split at the crossing, each part integrated by RK4); classical RK4 at
 * substeps_per_sample substeps remains as rig.plant_integrator: rk4 (tests/test_plant.c: the two
 * agree to 1.2e-13 of the response, 8e-11 through the kink). The preload is a static external force
 * on the interface storey that the load cell does not see (the seed's shaker offset). Forcing on an
 * internal physical DoF, when the setup has it there, is applied here (rths_plant_set_forcing);
 * so is base excitation's inertial load -M 1 a_g on the internal physical DoFs.
 *
 * The plant reaches the controller as the reference I/O plug-in (io.h); a lab's DAQ plug-in
 * replaces it at the same seam: read the sensors, apply the demand, once per sample. */
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

/* An analog-to-digital converter in front of a sensor: the reading in engineering units, divided
 * by units_per_v, plus white noise of noise_v volts, clipped to +-range_v and rounded to the
 * converter's step 2 range_v / 2^bits, times units_per_v again. bits 0: no converter (the reading
 * is continuous); noise_v acts whenever rig.noise is on. */
typedef struct rths_adc_spec {
    int bits;           /* 0: none */
    double range_v;     /* symmetric input range, +-V */
    double units_per_v; /* sensor scaling: m, m/s^2 or N per volt */
    double noise_v;     /* white noise at the converter input, V rms */
} rths_adc_spec;

typedef enum {
    RTHS_ACTUATOR_SHAKER = 0,            /* electrodynamic shaker: gain, delay, lag, armature */
    RTHS_ACTUATOR_TRANSFER_FUNCTION = 1, /* rational N(s)/D(s) from demand to force */
} rths_actuator_model;

#define RTHS_ACTUATOR_MAX_ORDER 8

/* The actuator between the demand (V) and the interface storey. transfer_function: the force
 * F(s) = (N(s) U(s) - velocity_feedback V(s)) / D(s), V the interface storey's velocity (the
 * feedback a constant or a polynomial in s, velocity_feedback_poly): with
 * D(s) = s + a and velocity_feedback = 2 beta A^2 / V_oil this is the servo-hydraulic actuator
 * whose oil column feeds the specimen's velocity back into its force (control-structure
 * interaction; docs/config/rig.md). Coefficients in descending powers of s, deg N <= deg D <=
 * RTHS_ACTUATOR_MAX_ORDER; realised in observer canonical form and discretised exactly with the
 * structure (one matrix exponential of the coupled state, at create). Limits apply to both
 * models; 0 means none. */
typedef struct rths_actuator_options {
    rths_actuator_model model;
    int numerator_count, denominator_count;
    double numerator[RTHS_ACTUATOR_MAX_ORDER + 1];   /* N/V, descending powers of s */
    double denominator[RTHS_ACTUATOR_MAX_ORDER + 1]; /* descending powers of s */
    double velocity_feedback; /* N/(m/s) times the unit of D(s): N/m for a first-order D */
    /* V(s) as a polynomial, descending powers of s, when velocity_feedback_count > 0 (it then
     * replaces the constant velocity_feedback): F = (N U - V(s) x') / D, deg V < deg D. The
     * servo-hydraulic model with a second-order valve, F = a1 b0 / ((s^2 + b1 s + b2)(s + a3)) u
     * - a2 s / (s + a3) x, is V = a2 (s^2 + b1 s + b2) over D = (s^2 + b1 s + b2)(s + a3). */
    int velocity_feedback_count;
    double velocity_feedback_poly[RTHS_ACTUATOR_MAX_ORDER];
    int displacement_output;             /* 0: N(s)/D(s) gives the force (N/V); 1: the piston's
                                            displacement y (m/V), which pushes the interface storey through
                                            the connection spring: F = k_c (y - x_interface) */
    double connection_stiffness_n_per_m; /* k_c (displacement output): rod, load cell, clevis */
    double force_limit_n;  /* |actuator force| beyond: fault, or clip of the force command */
    double stroke_limit_m; /* |interface displacement| beyond: fault, or flagged */
    double velocity_limit_m_per_s; /* |interface velocity| beyond: fault, or flagged */
    int force_clip;     /* 1: the force command (static gain x demand) saturates at the limit, the
                           samples are counted; 0: the output force beyond the limit trips */
    int stroke_flag;    /* 1: samples beyond are counted and reported; 0: trip */
    int velocity_flag;  /* 1: samples beyond are counted and reported; 0: trip */
    int dac_bits;       /* demand DAC: 0 none; else the demand is clipped to +-dac_range_v and */
    double dac_range_v; /* rounded to 2 dac_range_v / 2^dac_bits before the actuator */
} rths_actuator_options;

/* What the actuator's limits saw (rths_plant_actuator_status). */
typedef struct rths_actuator_status {
    long force_clipped_samples, stroke_flagged_samples, velocity_flagged_samples;
    rths_rig_fault beyond;        /* the limit the last sample was beyond with action fault */
    double peak_force_n;          /* largest |actuator force| so far */
    double peak_stroke_m;         /* largest |interface displacement| so far */
    double peak_velocity_m_per_s; /* largest |interface velocity| so far */
} rths_actuator_status;

const char *rths_actuator_model_name(rths_actuator_model model);

/* The longest shaker transport delay the plant holds, in samples (delay_s x sample rate, rounded;
 * the delay line of plant.c). */
#define RTHS_PLANT_MAX_DELAY_SAMPLES 4095

typedef struct rths_plant_options {
    double gain_n_per_v;     /* shaker force per demand volt */
    double delay_s;          /* pure transport delay (rounded to whole samples) */
    double lag_cutoff_hz;    /* first-order lag; 0: none */
    double armature_mass_kg; /* moves with the interface storey */
    int noise;     /* 0: every sensor exact (gain error, offset, noise, quantum off); 1: default
                    * noise; 2: rig.noise: lab (ten times the sensor noise, plant_config.c;
                    * a process force, plant.c) */
    uint64_t seed; /* noise generator seed */
    int substeps_per_sample; /* 0: exact discretisation (default); n >= 1: RK4, n substeps */
    int linear_hold;         /* 1: the demand ramps linearly from the last sample's value over
                                the sample (a reconstruction filter) instead of a DAC's step */
    rths_sensor_spec laser, accelerometer, load_cell;
    rths_adc_spec laser_adc, accelerometer_adc, load_cell_adc;
    rths_actuator_options actuator;
} rths_plant_options;

void rths_plant_defaults(rths_plant_options *opt);
/* An ideal shaker and exact sensors: no delay, no lag, no armature mass, no noise, and a
 * continuous force (linear hold of the demand): the only discrete thing left is the controller. */
void rths_plant_ideal(rths_plant_options *opt);
/* Reads the `rig` section (rig.noise, rig.seed, rig.shaker.*, rig.actuator.*, rig.sensors.*) over
 * the defaults. */
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
/* The same with one demand per actuator (one per interface DoF, the split's interface order);
 * rths_plant_advance is its one-actuator case. */
void rths_plant_advance_dofs(rths_plant *p, const double *demand_v);
/* RTHS_RIG_OK, or the fault of a limit with action fault that the state is beyond now
 * (stroke: RTHS_RIG_FAULT_DISPLACEMENT, velocity: RTHS_RIG_FAULT_DISPLACEMENT, force:
 * RTHS_RIG_FAULT_FORCE). */
rths_rig_fault rths_plant_limit_fault(const rths_plant *p);
void rths_plant_actuator_status(const rths_plant *p, rths_actuator_status *out);
double rths_plant_time_s(const rths_plant *p);
/* True interface displacement (no sensor effects) of the first interface DoF, m: for tests. */
double rths_plant_interface_displacement_m(const rths_plant *p);
/* Displacement noise standard deviation of the lasers, m (0 with noise off). */
double rths_plant_noise_level_m(const rths_plant *p);
/* Restoring force of the bilinear leg (N, positive pulling the storeys together in extension)
 * for a leg extension delta (m): k delta for delta >= 0, ratio k delta below. */
double rths_plant_leg_force_n(const rths_plant *p, double delta_m);

#endif
