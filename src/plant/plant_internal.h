/* Private to src/plant (and src/tune/pd_loop.c, which models the same physical loop): the plant's
 * state, its exact discretisation of a sample, and the functions one of its files calls in
 * another. plant.c is the per-sample path, plant_build.c builds a plant from its options and
 * plant_config.c reads those options from the configuration. */
#ifndef RTHS_PLANT_INTERNAL_H
#define RTHS_PLANT_INTERNAL_H

#include "rths/plant.h"

/* Runge-Kutta substeps per segment of a sample whose kink crossing the exact path splits off */
#define CROSSING_SUBSTEPS 8

/* The exact discretisation of one side of the leg (or the linear plant): over a sample,
 * z_{k+1} = phi z_k + g_target_start T0 + g_target_slope (T1 - T0) + g_static
 *         + sum_k g_forcing[k] f^(k)(0)
 * for the force target ramping from T0 to T1 (equal for a DAC step) and the forcing
 * f(tau) = amplitude cos(theta + omega tau) on the physical DoFs, through its Taylor polynomial
 * of degree 3 over the sample (derivatives exact; truncation (omega h)^4 / 24, 2e-10 at 13 Hz and
 * 10 kHz). The g_forcing are the responses to the unit powers tau^k / k!: computed once at
 * create for every frequency, so a frequency change costs the per-sample loop nothing (no
 * matrix exponential, no allocation, no LAPACK). */
typedef struct {
    double *phi; /* nz rows of nz_padded, row-major; the padding columns are zero */
    double *g_target_start, *g_target_slope, *g_static;
    double *g_forcing[4];
    /* actuators 1..ni-1 (several interface DoFs): their force targets' start and slope columns,
       nz each, actuator d's pair at 2 (d - 1) nz; NULL with one actuator */
    double *g_more;
} exact_side;

/* A sensor's options as one reading uses them, the noise switch applied and the reciprocals of
 * its step and scale formed once (a division per reading sat on the read's critical path; the
 * product differs from the quotient by an ulp at most, which moves a rounding to the step only
 * within an ulp of a half step). */
typedef struct {
    int noisy;                      /* rig.noise on: gain error, offset, noise, step apply */
    double gain, offset, noise_std; /* 1 + gain_error, offset, noise, in the sensor's unit */
    double quantum, per_quantum;    /* the step and its reciprocal (0: none) */
    int converter;                  /* an ADC's resolution or its volts noise applies */
    int adc_bits;
    double adc_range_v, units_per_v, per_unit_v, adc_noise_v; /* adc_noise_v 0 without noise */
} sensor_channel;
enum { SENSOR_LASER, SENSOR_ACCELEROMETER, SENSOR_LOAD_CELL, SENSOR_KINDS };

enum { NORMAL_POOL = 64 };

struct rths_plant {
    rths_plant_options opt;
    sensor_channel sensor[SENSOR_KINDS];
    int n;  /* physical DoFs, the interface DoFs last */
    int ni; /* interface DoFs, one actuator each: actuator d acts on physical DoF n - ni + d */
    double h;
    double *minv, *c, *k; /* n x n */
    /* the interface DoFs' accelerations as rows of M^-1 applied to the forces, per DoF d at
     * d * accel_row_len: 2n state coefficients (-M^-1 K, -M^-1 C), ni actuator forces, then the
     * static force's, the forcing's and the leg's compression force's (see accel_rows_init) */
    double *accel_rows;
    int accel_row_len;
    double *static_force;     /* n */
    int leg_lower, leg_upper; /* physical indices (-1: ground), leg_upper < 0: no bilinear leg */
    double leg_extra_k;       /* (ratio - 1) k added in compression */
    double leg_k, leg_ratio;
    double *z;         /* state: q (n), v (n), then the shaker force when it lags */
    double *q, *v, fs; /* q = z, v = z + n; shaker force */
    double *z_next;    /* nz */
    double *rk;        /* scratch: Runge-Kutta stages 10 n, forces n */
    int nz;            /* 2n + na */
    int nz_padded;     /* nz rounded up to a multiple of 4: phi's rows and z, padded with zeros,
                          are summed four terms per loop pass */
    int na;            /* actuator states: 1 for the shaker's lag, the order of a transfer
                          function (observer canonical form, after q and v in z) */
    int tf;            /* transfer-function actuator: the input is the demand itself */
    double *act_a, *act_bu, *act_bv; /* na x na (column-major), na, na */
    double act_d;                    /* feedthrough of the demand to the output */
    double act_out;       /* force per unit output: 1 (force output) or the connection stiffness */
    double act_spring;    /* displacement output: the connection's stiffness k_c, N/m; 0: force */
    double command_limit; /* force clip: |input| at most this (0: no clip) */
    rths_actuator_status status;
    exact_side side[2]; /* 0: extension (or no leg), 1: compression */
    double time_s;
    double *delay_line;
    int delay_samples, delay_pos;
    double lag_rate;          /* 2 pi f_c, 0: no lag */
    double last_force_target; /* gain x demand of the previous sample (linear hold) */
    double armature_kg;
    /* actuators 1..ni-1 (index 0 unused: actuator 0 is fs, last_force_target, delay_line) */
    double fs_more[RTHS_MAX_INTERFACE_DOFS], last_force_target_more[RTHS_MAX_INTERFACE_DOFS];
    /* actuator and sensor transforms (setup.h), ni x ni column-major; NULL: the identity */
    double *act_t, *sens_t;
    int forcing_index;     /* internal physical forcing DoF, -1: none */
    double *forcing_shape; /* n: base excitation's -M 1 on the internal physical DoFs; NULL:
                              the forcing acts on forcing_index alone */
    double forcing_amplitude, forcing_theta, forcing_omega, forcing_now;
    rths_rng rng;
    /* normal draws of rng, taken in order: refilled a block at a time, where a call per draw
     * cost as much as the draw (the sequence is the same as drawing one by one) */
    double normal_pool[NORMAL_POOL];
    int normal_next; /* next unused entry; NORMAL_POOL: empty */
};

/* rig.noise: lab, the follow-up's laboratory (opt->noise = 2): sensors ten times noisier than the
 * default rig's, and a random force on the physical interface, held per sample (amplifier noise
 * and the disturbances no sensor sees), so that a new point's first residual is only a few times
 * the tolerance. The sensors' own keys still override these levels. */
enum { PLANT_NOISE_LAB = 2 };

/* A transfer-function actuator F = (N U - V(s) x') / D in observer canonical form (plant_build.c,
 * plant_tf_form_of): order states, A (order x order, column-major), the demand's column b_u, the
 * interface velocity's column b_v, the feedthrough d, and the static gain N(0) / D(0) (infinite
 * when D(0) = 0). The plant and src/tune/pd_loop.c realise an actuator through this one copy. */
typedef struct {
    int order;
    double d, static_gain;
    double a[RTHS_ACTUATOR_MAX_ORDER * RTHS_ACTUATOR_MAX_ORDER];
    double bu[RTHS_ACTUATOR_MAX_ORDER], bv[RTHS_ACTUATOR_MAX_ORDER];
} plant_tf_form;
void plant_tf_form_of(const rths_actuator_options *a, plant_tf_form *f);

#endif
