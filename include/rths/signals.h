/* rths signals: the data that crosses the seams between the real-time side and the host.
 *
 * The per-sample I/O seam (sensor sample in, actuator demand out) between the controller step and
 * the rig's hardware or virtual plant; the per-period record the step publishes at every whole
 * forcing period; the latched fault codes; the decimated trace sample. Both sides include this
 * header and nothing else of each other's: the host (iterate/, continuation/, rig/) never compiles
 * against the plant, the model or the setup (docs/architecture.md, the module order). */
#ifndef RTHS_SIGNALS_H
#define RTHS_SIGNALS_H

#define RTHS_MAX_HARMONICS 5
#define RTHS_MAX_SENSED_DOFS 16
/* Interface DoFs the real-time side drives (one actuator each): PD control, Fourier sums,
 * inertial compensation and grounding control per DoF, in fixed per-sample buffers. */
#define RTHS_MAX_INTERFACE_DOFS 4
/* Assembly DoFs reported beside the interface (output.dofs): one more Fourier sum each per
 * sample, in a fixed per-period buffer. */
#define RTHS_MAX_OUTPUT_DOFS 16

/* Fourier coefficients of one signal over one whole period, x(t) ~ a[0] + sum_k a[k] cos(k w t) +
 * b[k] sin(k w t), k = 1..RTHS_MAX_HARMONICS (b[0] unused, 0). t is measured from the start of the
 * forcing phase (phase-continuous across frequency changes), so coefficients of the physical and
 * numerical sides, target and forcing are all referred to the same phase. */
typedef struct rths_fourier {
    double a[RTHS_MAX_HARMONICS + 1];
    double b[RTHS_MAX_HARMONICS + 1];
} rths_fourier;

typedef struct rths_period {
    double frequency_hz; /* forcing frequency during this period */
    double end_time_s;   /* rig time at the end of the period */
    int samples;         /* controller samples in this period (sets the coefficients' noise) */
    rths_fourier phys;   /* physical interface displacement, m (the first interface DoF) */
    rths_fourier num;    /* numerical interface displacement, m (the first interface DoF) */
    rths_fourier force;  /* measured interface force (load cell), N (the first interface DoF) */
    /* every interface DoF d < interface_dofs, in the split's interface order (d = 0 repeats
     * phys, num and force); 0 in a record from a producer that carries one DoF only */
    int interface_dofs;
    rths_fourier phys_dof[RTHS_MAX_INTERFACE_DOFS];
    rths_fourier num_dof[RTHS_MAX_INTERFACE_DOFS];
    rths_fourier force_dof[RTHS_MAX_INTERFACE_DOFS];
    /* Integrity of the period: samples whose deadline was missed (the controller process; the
     * virtual rig runs on a simulated clock and never misses one), samples in which any
     * actuator demand was clamped (demand limit or DAC range), samples in which any converter
     * reading sat at its full scale. The coupling the result depends on holds only for samples
     * counted in none of them. */
    int late_samples;
    int clipped_demand_samples;
    int saturated_sensor_samples;
    /* output.dofs (docs/method.md, "Outputs"): the displacement (m, or rad for a rotation) of
     * every listed assembly DoF, in the list's order, summed like the interface's: a numerical
     * DoF from the controller's own state, a physical DoF below the interface from its sensor
     * (rths_sensor_sample.displacement_m), an interface DoF from its physical signal (phys_dof).
     * 0 without output.dofs, or from a producer that carries none. */
    int output_dofs;
    rths_fourier output_dof[RTHS_MAX_OUTPUT_DOFS];
} rths_period;

typedef enum {
    RTHS_RIG_OK = 0,
    RTHS_RIG_FAULT_DISPLACEMENT = 1, /* a displacement limit tripped */
    RTHS_RIG_FAULT_FORCE = 2,        /* the interface force limit tripped */
    RTHS_RIG_FAULT_DEMAND = 3,       /* the actuator demand limit tripped */
    RTHS_RIG_FAULT_NONFINITE = 4,    /* a NaN/inf reached the controller */
    RTHS_RIG_FAULT_LINK = 5,         /* remote rig: link lost or protocol error */
    RTHS_RIG_FAULT_WATCHDOG = 6,     /* remote rig: host went silent, excitation ramped to zero */
} rths_rig_fault;

/* "displacement limit", "watchdog", ... ("none" for RTHS_RIG_OK). */
const char *rths_rig_fault_name(rths_rig_fault f);

/* One sample of sensor readings: the per-sample I/O seam between controller and rig (the virtual
 * plant, or a DAQ card). Displacements in the physical substructure's DoF order (internal
 * physical DoFs, then the interface DoFs), m; acceleration of the interface storey, m/s^2; load
 * cell between actuator and interface storey, N (force on the storey, positive along x). The
 * scalar fields are the first interface DoF's; the arrays carry every interface DoF's (one
 * accelerometer and one load cell per actuator); n_interface 0 means the device fills the
 * scalars only (one interface DoF). */
typedef struct rths_sensor_sample {
    int n;
    double displacement_m[RTHS_MAX_SENSED_DOFS];
    double interface_acceleration_m_s2;
    double interface_force_n;
    int n_interface;
    double interface_acceleration_dof_m_s2[RTHS_MAX_INTERFACE_DOFS];
    double interface_force_dof_n[RTHS_MAX_INTERFACE_DOFS];
} rths_sensor_sample;

/* One decimated time trace sample. */
typedef struct rths_trace_sample {
    double time_s;
    double x_phys_m; /* physical interface displacement (laser) */
    double x_num_m;  /* numerical interface displacement */
    double target_m; /* control target x*(t) */
    double force_n;  /* load cell */
    double demand;   /* actuator demand (V) */
    /* with several interface DoFs (dofs > 1; 0 from a one-DoF producer): every DoF's signals,
     * DoF 0 repeating the fields above; m or rad as the DoF */
    int dofs;
    double x_phys_dof_m[RTHS_MAX_INTERFACE_DOFS], x_num_dof_m[RTHS_MAX_INTERFACE_DOFS];
    double target_dof_m[RTHS_MAX_INTERFACE_DOFS], force_dof_n[RTHS_MAX_INTERFACE_DOFS];
    double demand_dof_v[RTHS_MAX_INTERFACE_DOFS];
} rths_trace_sample;

#endif
