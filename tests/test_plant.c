/* The virtual plant alone against independent truths: its forced response equals the analytic
 * FRF of the physical substructure with the FULL interface mass (plus armature) through the
 * shaker's hold, delay and lag; the exact integrator (the default) equals RK4 at fine steps, with
 * and without the bilinear leg, and a free bilinear oscillator's period, peak ratio and energy
 * through 80 kink crossings; rig.plant_integrator selects RK4; the load cell reads the shaker force
 * minus the armature's inertia; sensors apply gain error, offset, quantisation and noise of the
 * configured size, all off with rig.noise false; a seed repeats; the bilinear leg's static slopes,
 * kink and preloaded static point; actuator and sensor transforms: a plant whose actuators push
 * through T and whose lasers read through S moves exactly as a plant with one actuator per DoF
 * driven by T u, and its lasers read S q. */
#include "testlib.h"

#include "rths/plant.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define H 1e-4

static void load(const char *const *ov, int n, rths_config **cfg, rths_setup *s) {
    rths_error err;
    if (rths_config_load(rths_test_source_path("examples/four_storey.yaml"), ov, n, cfg, &err) ||
        rths_setup_read(*cfg, s, &err))
        fail_msg("%s", err.msg);
}

static rths_plant *make(const rths_setup *s, const rths_plant_options *po) {
    rths_plant *p;
    rths_error err;
    if (rths_plant_create(s, po, 1.0 / H, &p, &err)) fail_msg("%s", err.msg);
    return p;
}

/* Analytic interface response of the rig's physical substructure (full interface mass plus the
 * armature) to a unit force on the interface at omega. */
static double complex rig_frf(const rths_setup *s, double armature_kg, double omega) {
    const rths_split *sp = &s->split;
    int n = sp->np;
    double m[RTHS_MAX_SENSED_DOFS * RTHS_MAX_SENSED_DOFS], f[RTHS_MAX_SENSED_DOFS] = {0};
    memcpy(m, sp->mass_phys, sizeof(double) * (size_t)(n * n));
    int iface = sp->int_dofs[0];
    RTHS_AT(m, n, n - 1, n - 1) =
        RTHS_AT(s->assembly.mass, s->assembly.n, iface, iface) + armature_kg;
    f[n - 1] = 1.0;
    double complex x[RTHS_MAX_SENSED_DOFS];
    rths_error err;
    if (rths_frf(n, m, sp->damping_phys, sp->stiffness_phys, f, omega, x, &err))
        fail_msg("%s", err.msg);
    return x[n - 1];
}

/* Drives the plant with demand (f0 / gain) cos(omega t_k), lets the transient die for settle_s,
 * then takes the fundamental of the sampled true interface displacement and of the load-cell
 * reading over whole periods (f chosen so a period is a whole number of samples: the sampled
 * DFT is then exact for the fundamental, up to aliasing of the hold's images near 10 kHz, which
 * is far below 1e-7 relative here). */
static void forced(rths_plant *p, const rths_plant_options *po, double f_hz, double f0,
                   double settle_s, double complex *x_out, double complex *force_out) {
    const double w = 2 * M_PI * f_hz;
    long per = lround(1.0 / (f_hz * H)), settle = lround(settle_s / H);
    assert_true(fabs(per * f_hz * H - 1) < 1e-12);
    long periods = 4, total = settle + periods * per;
    double complex x = 0, force = 0;
    for (long k = 0; k < total; k++) {
        double t = k * H;
        if (k >= settle) {
            rths_sensor_sample in;
            rths_plant_read(p, &in);
            double complex e = cexp(-I * w * t);
            x += rths_plant_interface_displacement_m(p) * e;
            force += in.interface_force_n * e;
        }
        rths_plant_advance(p, f0 / po->gain_n_per_v * cos(w * t));
    }
    *x_out = x * 2.0 / (double)(periods * per);
    *force_out = force * 2.0 / (double)(periods * per);
}

/* Ideal shaker: the force is the linear interpolant of the demand samples, reaching each sample's
 * value one sample later (the amplifier's reconstruction): a factor sinc^2(w h / 2) e^{-i w h}
 * on the force. The response must then equal the analytic FRF to 1e-7 (measured 1e-10): the
 * plant's own integration error is negligible. Heavy leg damping (by --set) lets the transient
 * die within the run: slowest decay time below 0.1 s, settle 3 s. */
static void test_forced_response_ideal(void **state) {
    (void)state;
    const char *ov[] = {"structure.storeys.damping_n_s_per_m=[400, 400, 400, 3.7421]"};
    rths_config *cfg;
    rths_setup s;
    load(ov, 1, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    rths_plant_ideal(&po);
    const double freqs[3] = {5.0, 12.5, 25.0};
    for (int i = 0; i < 3; i++) {
        double w = 2 * M_PI * freqs[i];
        rths_plant *p = make(&s, &po);
        double complex x, force;
        forced(p, &po, freqs[i], 2.0, 3.0, &x, &force);
        double sinc = sin(w * H / 2) / (w * H / 2);
        double complex expect = 2.0 * rig_frf(&s, 0, w) * sinc * sinc * cexp(-I * w * H);
        print_message("%5.1f Hz: plant %.9e%+.9ei, analytic %.9e%+.9ei, rel err %.2e\n", freqs[i],
                      creal(x), cimag(x), creal(expect), cimag(expect),
                      cabs(x - expect) / cabs(expect));
        assert_true(cabs(x - expect) <= 1e-7 * cabs(expect));
        /* no armature: the load cell reads the shaker force itself, sampled: 2 e^{-i w h} */
        assert_true(cabs(force - 2.0 * cexp(-I * w * H)) <= 1e-6 * 2.0);
        rths_plant_destroy(p);
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Real shaker: transport delay of d whole samples, first-order lag 1 / (1 + i w / w_c) and an
 * armature moving with the interface storey (its mass adds to the storey's); the load cell
 * between armature and storey reads the shaker force minus m_a times the acceleration. */
static void test_forced_response_shaker(void **state) {
    (void)state;
    const char *ov[] = {"structure.storeys.damping_n_s_per_m=[400, 400, 400, 3.7421]"};
    rths_config *cfg;
    rths_setup s;
    load(ov, 1, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.noise = 0;
    po.delay_s = 3e-4;
    po.lag_cutoff_hz = 800;
    po.armature_mass_kg = 0.4;
    const double f = 12.5, w = 2 * M_PI * f;
    rths_plant *p = make(&s, &po);
    double complex x, force;
    forced(p, &po, f, 2.0, 3.0, &x, &force);
    double sinc = sin(w * H / 2) / (w * H / 2);
    double complex shaker =
        2.0 * sinc * sinc * cexp(-I * w * H * 4) / (1 + I * w / (2 * M_PI * po.lag_cutoff_hz));
    double complex expect = shaker * rig_frf(&s, po.armature_mass_kg, w);
    print_message("shaker: plant %.9e%+.9ei, analytic %.9e%+.9ei\n", creal(x), cimag(x),
                  creal(expect), cimag(expect));
    assert_true(cabs(x - expect) <= 1e-5 * cabs(expect));
    /* the sampled force's fundamental is the continuous one's up to the hold's images near
     * 10 kHz, which the lag attenuates to below 1e-6 */
    double complex lc = shaker + po.armature_mass_kg * w * w * expect;
    assert_true(cabs(force - lc) <= 1e-5 * cabs(lc));
    /* and the armature term is really there: it is far above that tolerance */
    assert_true(cabs(po.armature_mass_kg * w * w * expect) > 1e-3 * cabs(lc));
    rths_plant_destroy(p);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Transfer-function actuator with velocity feedback, the servo-hydraulic model of
 * control-structure interaction: F = (N U - k_v V) / D, D = s + a, so that
 * X = H F  =>  X = H N U_held / (D + k_v i w H), with H the rig's analytic FRF and U_held the
 * demand through a DAC step (zero-order hold: sinc(w h / 2) e^{-i w h / 2}). The plant's exact
 * discretisation of the coupled state must give this to 1e-6 (the hold's images near 10 kHz
 * alias back below 1e-7 relative); the velocity feedback must matter (it changes the response by
 * far more than the tolerance), and a first-order transfer function equals the shaker's lag. */
static void test_transfer_function_actuator(void **state) {
    (void)state;
    const char *ov[] = {"structure.storeys.damping_n_s_per_m=[400, 400, 400, 3.7421]"};
    rths_config *cfg;
    rths_setup s;
    load(ov, 1, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.noise = 0;
    po.delay_s = 0;
    po.linear_hold = 0;
    po.actuator.model = RTHS_ACTUATOR_TRANSFER_FUNCTION;
    const double a = 30.0, gain = 50.0, kv = 6000.0; /* hydraulic damping k_v / a = 200 N s/m */
    po.actuator.numerator[0] = gain * a;
    po.actuator.numerator_count = 1;
    po.actuator.denominator[0] = 1.0;
    po.actuator.denominator[1] = a;
    po.actuator.denominator_count = 2;
    po.actuator.velocity_feedback = kv;
    const double f = 12.5, w = 2 * M_PI * f, u = 2.0 / po.gain_n_per_v;
    double complex held = sin(w * H / 2) / (w * H / 2) * cexp(-I * w * H / 2), x, force;
    double complex hs = rig_frf(&s, 0, w), d = I * w + a;
    double complex expect = hs * gain * a * u * held / (d + kv * I * w * hs);
    double complex open_loop = hs * gain * a * u * held / d;
    rths_plant *p = make(&s, &po);
    forced(p, &po, f, 2.0, 3.0, &x, &force);
    print_message("servo-hydraulic: plant %.9e%+.9ei, analytic %.9e%+.9ei, rel err %.2e; "
                  "without the velocity feedback %.9e%+.9ei\n",
                  creal(x), cimag(x), creal(expect), cimag(expect), cabs(x - expect) / cabs(expect),
                  creal(open_loop), cimag(open_loop));
    assert_true(cabs(x - expect) <= 1e-6 * cabs(expect));
    assert_true(cabs(open_loop - expect) > 1e-2 * cabs(expect));
    rths_plant_destroy(p);

    /* the shaker's first-order lag, gain w_c / (s + w_c), as a transfer function: the same
     * coupled system, realised by other code (observer form vs the lag state) */
    rths_plant_options lag;
    rths_plant_defaults(&lag);
    lag.noise = 0;
    lag.delay_s = 0;
    lag.armature_mass_kg = 0;
    lag.lag_cutoff_hz = 800;
    rths_plant_options tf = lag;
    double wc = 2 * M_PI * lag.lag_cutoff_hz;
    tf.actuator = (rths_actuator_options){.model = RTHS_ACTUATOR_TRANSFER_FUNCTION,
                                          .numerator = {lag.gain_n_per_v * wc},
                                          .numerator_count = 1,
                                          .denominator = {1.0, wc},
                                          .denominator_count = 2};
    rths_plant *pl = make(&s, &lag), *pt = make(&s, &tf);
    double worst = 0, peak = 0;
    for (int k = 0; k < 20000; k++) {
        double dv = 0.05 * sin(2 * M_PI * 13.0 * k * H);
        rths_plant_advance(pl, dv);
        rths_plant_advance(pt, dv);
        rths_sensor_sample rl, rt;
        rths_plant_read(pl, &rl);
        rths_plant_read(pt, &rt);
        worst = fmax(worst, fabs(rl.displacement_m[2] - rt.displacement_m[2]));
        worst = fmax(worst, 1e-5 * fabs(rl.interface_force_n - rt.interface_force_n));
        peak = fmax(peak, fabs(rl.displacement_m[2]));
    }
    print_message("lag as a transfer function: largest difference %.2e m of %.2e m\n", worst, peak);
    assert_true(worst <= 1e-12 * peak);
    rths_plant_destroy(pl);
    rths_plant_destroy(pt);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* rig.interface_mass: physical_share (issue 23.1): the rig carries (1 - p) of the interface
 * storey's 5.37 kg plus the armature, no more. The forced response through the ideal shaker's
 * linear hold equals the analytic FRF of the physical substructure with that interface mass to
 * 1e-7 (as for the full mass), and differs from the full-mass plant's by far more. */
static void test_physical_share_mass(void **state) {
    (void)state;
    const char *ov[] = {"structure.storeys.damping_n_s_per_m=[400, 400, 400, 3.7421]",
                        "rig.interface_mass=physical_share", "split.mass_ratio=0.7"};
    rths_config *cfg;
    rths_setup s;
    load(ov, 3, &cfg, &s);
    assert_int_equal(s.interface_mass, RTHS_INTERFACE_MASS_PHYSICAL_SHARE);
    rths_plant_options po;
    rths_plant_defaults(&po);
    rths_plant_ideal(&po);
    po.armature_mass_kg = 0.4;
    const double f = 12.5, w = 2 * M_PI * f, sinc = sin(w * H / 2) / (w * H / 2);
    /* the full-mass FRF with the mass difference taken off: (1 - p) 5.37 + 0.4 on the rig */
    double full_kg = 5.37, rig_kg = (1 - 0.7) * full_kg + po.armature_mass_kg;
    double complex expect = 2.0 * rig_frf(&s, rig_kg - full_kg, w) * sinc * sinc * cexp(-I * w * H);
    double complex full =
        2.0 * rig_frf(&s, po.armature_mass_kg, w) * sinc * sinc * cexp(-I * w * H);
    rths_plant *p = make(&s, &po);
    double complex x, force;
    forced(p, &po, f, 2.0, 3.0, &x, &force);
    print_message("physical share: plant %.9e%+.9ei, analytic %.9e%+.9ei, rel err %.2e; full mass "
                  "%.9e%+.9ei\n",
                  creal(x), cimag(x), creal(expect), cimag(expect), cabs(x - expect) / cabs(expect),
                  creal(full), cimag(full));
    assert_true(cabs(x - expect) <= 1e-7 * cabs(expect));
    assert_true(cabs(full - expect) > 1e-2 * cabs(expect));
    rths_plant_destroy(p);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* The servo-hydraulic actuator with a second-order servo-valve and control-structure interaction
 * (issue 23.2): F = a1 b0 / ((s^2 + b1 s + b2)(s + a3)) u - a2 s / (s + a3) x, written as one
 * denominator D = (s^2 + b1 s + b2)(s + a3) with the velocity path a polynomial, V(s) =
 * a2 (s^2 + b1 s + b2), F = (N U - V x') / D. The truth from the transfer functions: X = H F
 * => X = H N U_held / (D + V i w H) (H the rig's analytic FRF, U_held the DAC step's sinc and
 * half-sample delay), at 1e-6 as for the first-order actuator; the load cell reads F itself (no
 * armature) = N U_held / D - V i w X / D; the CSI term must matter (the open loop differs by far
 * more than the tolerance). */
static void test_servo_valve_velocity_polynomial(void **state) {
    (void)state;
    const char *ov[] = {"structure.storeys.damping_n_s_per_m=[400, 400, 400, 3.7421]"};
    rths_config *cfg;
    rths_setup s;
    load(ov, 1, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.noise = 0;
    po.delay_s = 0;
    po.linear_hold = 0;
    po.armature_mass_kg = 0;
    /* valve 50 Hz-ish (b2 = 1e5 rad^2/s^2, b1 = 425 rad/s), a3 = 30 rad/s, a2 = 4e4 N/m, static
     * gain a1 b0 / (b2 a3) = 50 N/V */
    const double b1 = 425, b2 = 1e5, a3 = 30, a2 = 4e4, a1b0 = 50.0 * b2 * a3;
    po.actuator = (rths_actuator_options){.model = RTHS_ACTUATOR_TRANSFER_FUNCTION,
                                          .numerator = {a1b0},
                                          .numerator_count = 1,
                                          .denominator = {1.0, b1 + a3, b2 + b1 * a3, b2 * a3},
                                          .denominator_count = 4,
                                          .velocity_feedback_poly = {a2, a2 * b1, a2 * b2},
                                          .velocity_feedback_count = 3};
    const double f = 12.5, w = 2 * M_PI * f, u = 2.0 / po.gain_n_per_v;
    double complex iw = I * w, held = sin(w * H / 2) / (w * H / 2) * cexp(-iw * H / 2), x, force;
    double complex d = (iw * iw + b1 * iw + b2) * (iw + a3), v = a2 * (iw * iw + b1 * iw + b2);
    double complex hs = rig_frf(&s, 0, w);
    double complex expect = hs * a1b0 * u * held / (d + v * iw * hs);
    double complex expect_force = a1b0 * u * held / d - v * iw * expect / d;
    double complex open_loop = hs * a1b0 * u * held / d;
    rths_plant *p = make(&s, &po);
    forced(p, &po, f, 2.0, 3.0, &x, &force);
    print_message("servo-valve CSI: plant %.9e%+.9ei, analytic %.9e%+.9ei, rel err %.2e; force "
                  "rel err %.2e; without the CSI %.9e%+.9ei\n",
                  creal(x), cimag(x), creal(expect), cimag(expect), cabs(x - expect) / cabs(expect),
                  cabs(force - expect_force) / cabs(expect_force), creal(open_loop),
                  cimag(open_loop));
    assert_true(cabs(x - expect) <= 1e-6 * cabs(expect));
    assert_true(cabs(force - expect_force) <= 1e-5 * cabs(expect_force));
    assert_true(cabs(open_loop - expect) > 1e-2 * cabs(expect));
    rths_plant_destroy(p);
    /* V of D's degree would feed the velocity through: refused by name */
    po.actuator.velocity_feedback_poly[3] = 1.0;
    po.actuator.velocity_feedback_count = 4;
    rths_error err;
    assert_int_equal(rths_plant_create(&s, &po, 1.0 / H, &p, &err), RTHS_EINPUT);
    if (!strstr(err.msg, "velocity feedback V(s) has degree 3")) fail_msg("%s", err.msg);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Transfer-function actuator with displacement output: the piston follows y = G(s) U with
 * G = g w_a / (s + w_a) (a displacement-controlled actuator of 50 Hz bandwidth) and pushes the
 * interface storey through a connection of stiffness k_c, F = k_c (y - x). The truth: the rig's
 * structure with k_c added at the interface, loaded by k_c G U_held (linear hold: sinc^2
 * e^{-i w h}), by a complex solve; the load cell reads k_c (y - x), a small difference of two
 * close displacements. Both to 1e-6 (measured 1.7e-13 and 4.5e-9; with a bare DAC step the
 * staircase's images, which the stiff connection passes into the sampled force, leave 9e-4 there
 * while the displacement still agrees to 1e-9). */
static void test_displacement_output_actuator(void **state) {
    (void)state;
    const char *ov[] = {"structure.storeys.damping_n_s_per_m=[400, 400, 400, 3.7421]"};
    rths_config *cfg;
    rths_setup s;
    load(ov, 1, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.noise = 0;
    po.delay_s = 0;
    po.linear_hold = 1;
    const double g = 1e-3, wa = 2 * M_PI * 50.0, kc = 2e6;
    po.actuator = (rths_actuator_options){.model = RTHS_ACTUATOR_TRANSFER_FUNCTION,
                                          .numerator = {g * wa},
                                          .numerator_count = 1,
                                          .denominator = {1.0, wa},
                                          .denominator_count = 2,
                                          .displacement_output = 1,
                                          .connection_stiffness_n_per_m = kc};
    const rths_split *sp = &s.split;
    int n = sp->np, iface = sp->int_dofs[0];
    double m[RTHS_MAX_SENSED_DOFS * RTHS_MAX_SENSED_DOFS],
        k[RTHS_MAX_SENSED_DOFS * RTHS_MAX_SENSED_DOFS], f[RTHS_MAX_SENSED_DOFS] = {0};
    memcpy(m, sp->mass_phys, sizeof(double) * (size_t)(n * n));
    memcpy(k, sp->stiffness_phys, sizeof(double) * (size_t)(n * n));
    RTHS_AT(m, n, n - 1, n - 1) = RTHS_AT(s.assembly.mass, s.assembly.n, iface, iface);
    RTHS_AT(k, n, n - 1, n - 1) += kc;
    f[n - 1] = 1.0;
    const double fhz = 12.5, w = 2 * M_PI * fhz, u = 2.0 / po.gain_n_per_v;
    double complex held = pow(sin(w * H / 2) / (w * H / 2), 2) * cexp(-I * w * H),
                   xs[RTHS_MAX_SENSED_DOFS];
    rths_error err;
    if (rths_frf(n, m, sp->damping_phys, k, f, w, xs, &err)) fail_msg("%s", err.msg);
    double complex y = g * wa / (I * w + wa) * u * held, expect = xs[n - 1] * kc * y;
    double complex force_expect = kc * (y - expect);
    rths_plant *p = make(&s, &po);
    double complex x, force;
    forced(p, &po, fhz, 2.0, 3.0, &x, &force);
    print_message("displacement output: plant %.9e%+.9ei, analytic %.9e%+.9ei (rel %.2e); load "
                  "cell rel %.2e\n",
                  creal(x), cimag(x), creal(expect), cimag(expect), cabs(x - expect) / cabs(expect),
                  cabs(force - force_expect) / cabs(force_expect));
    assert_true(cabs(x - expect) <= 1e-6 * cabs(expect));
    assert_true(cabs(force - force_expect) <= 1e-6 * cabs(force_expect));
    rths_plant_destroy(p);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Largest difference of the interface displacement between two integrators (substeps 0: exact)
 * over 2 s of a 13.4 Hz demand of the given amplitude from rest, relative to the response's
 * size; the leg extension's range on the second one. */
static double integrator_difference(const char *const *ov, int n_ov, double demand_v, int sub_a,
                                    int sub_b, double *dmin, double *dmax) {
    rths_config *cfg;
    rths_setup s;
    load(ov, n_ov, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.noise = 0;
    po.substeps_per_sample = sub_a;
    rths_plant *a = make(&s, &po);
    po.substeps_per_sample = sub_b;
    rths_plant *b = make(&s, &po);
    const double w = 2 * M_PI * 13.4;
    double diff = 0, size = 0;
    *dmin = 1, *dmax = -1;
    for (long k = 0; k < 20000; k++) {
        double d = demand_v * cos(w * k * H);
        rths_plant_advance(a, d);
        rths_plant_advance(b, d);
        double xa = rths_plant_interface_displacement_m(a);
        double xb = rths_plant_interface_displacement_m(b);
        diff = fmax(diff, fabs(xa - xb));
        size = fmax(size, fabs(xb));
        rths_sensor_sample in;
        rths_plant_read(b, &in);
        double delta = in.displacement_m[2] - in.displacement_m[1];
        *dmin = fmin(*dmin, delta);
        *dmax = fmax(*dmax, delta);
    }
    assert_true(size > 1e-5);
    rths_plant_destroy(a);
    rths_plant_destroy(b);
    rths_setup_free(&s);
    rths_config_free(cfg);
    return diff / size;
}

/* The seed's light damping, a forced run through the second mode from rest: the exact plant
 * (the default) and RK4 at 64 substeps per sample (local error ~ (w_max h / 64)^5, w_max the
 * shaker lag's 6283 rad/s: 1e-14) agree to 1e-11 of the response (measured 1e-13), and RK4 at
 * 8 substeps (the former default) to 1e-9: the plant's own error is negligible next to
 * anything the hybrid test measures (>= 1e-4). */
static void test_exact_against_rk4(void **state) {
    (void)state;
    double dmin, dmax;
    double fine = integrator_difference(NULL, 0, 0.05, 0, 64, &dmin, &dmax);
    double coarse = integrator_difference(NULL, 0, 0.05, 0, 8, &dmin, &dmax);
    print_message("exact vs RK4 x 64: %.3e, vs RK4 x 8: %.3e of the response\n", fine, coarse);
    assert_true(fine <= 1e-11);
    assert_true(coarse <= 1e-9);
}

/* The same with the bilinear leg and an oscillation that crosses the kink at every cycle: RK4
 * loses an order at each crossing (the stiffness jumps; RK4 x 64's own error ~ 1e-10 of the
 * response), the exact plant locates each crossing inside its sample; the two agree to 1e-9
 * (measured 8e-11), RK4 x 8 to 1e-6 (measured 7e-9), far below the nonlinear effects studied
 * (the fold shifts are percent). */
static void test_exact_against_rk4_bilinear(void **state) {
    (void)state;
    const char *ov[] = {"structure.bilinear.enabled=true"};
    double dmin, dmax;
    double fine = integrator_difference(ov, 1, 1.0, 0, 64, &dmin, &dmax);
    double coarse = integrator_difference(ov, 1, 1.0, 0, 8, &dmin, &dmax);
    print_message("bilinear, exact vs RK4 x 64: %.3e, vs RK4 x 8: %.3e of the response; leg "
                  "extension %.3e .. %.3e m\n",
                  fine, coarse, dmin, dmax);
    assert_true(dmin < 0 && dmax > 0); /* the kink is crossed */
    assert_true(fine <= 1e-9);
    assert_true(coarse <= 1e-6);
}

/* Gain error and offset exactly as specified (noise std 0, no quantum); rig.noise false turns
 * everything off; quantisation gives whole multiples of the quantum; the noise has the
 * configured standard deviation (20000 readings: the sample std's own standard error is 0.5 %,
 * the tolerance 4 %). */
static void test_sensors(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load(NULL, 0, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.noise = 1;
    po.laser = (rths_sensor_spec){0.02, 3e-6, 0, 0};
    po.accelerometer = (rths_sensor_spec){-0.01, 0.05, 0, 0};
    po.load_cell = (rths_sensor_spec){0.03, -0.2, 0, 0};
    po.armature_mass_kg = 0;
    rths_plant *p = make(&s, &po);
    rths_plant_options exact = po;
    exact.noise = 0;
    rths_plant *q = make(&s, &exact);
    for (int k = 0; k < 3000; k++) {
        double d = 0.1 * sin(2 * M_PI * 9.0 * k * H);
        rths_plant_advance(p, d);
        rths_plant_advance(q, d);
    }
    rths_sensor_sample a, b;
    rths_plant_read(p, &a);
    rths_plant_read(q, &b);
    assert_int_equal(a.n, 3);
    assert_true(fabs(b.displacement_m[2]) > 1e-6); /* moving, so the gain error shows */
    assert_true(b.displacement_m[2] == rths_plant_interface_displacement_m(q));
    for (int i = 0; i < 3; i++)
        assert_close(a.displacement_m[i], 1.02 * b.displacement_m[i] + 3e-6, 1e-18);
    assert_close(a.interface_acceleration_m_s2, 0.99 * b.interface_acceleration_m_s2 + 0.05, 1e-12);
    assert_close(a.interface_force_n, 1.03 * b.interface_force_n - 0.2, 1e-12);
    assert_true(rths_plant_noise_level_m(q) == 0);
    rths_plant_destroy(p);
    rths_plant_destroy(q);

    /* noise and quantisation at rest (no preload without the bilinear leg: q = 0) */
    rths_plant_defaults(&po);
    po.laser = (rths_sensor_spec){0, 0, 2e-7, 0};
    po.load_cell = (rths_sensor_spec){0, 0, 1e-2, 1e-3};
    p = make(&s, &po);
    assert_close(rths_plant_noise_level_m(p), 2e-7, 0);
    double sum = 0, sum2 = 0;
    int count = 0;
    for (int k = 0; k < 20000; k++) {
        rths_plant_read(p, &a);
        double x = a.displacement_m[k % 3];
        sum += x;
        sum2 += x * x;
        count++;
        double r = a.interface_force_n / 1e-3;
        assert_close(r, nearbyint(r), 1e-9);
        rths_plant_advance(p, 0);
    }
    double mean = sum / count, sd = sqrt(sum2 / count - mean * mean);
    print_message("laser noise: sample std %.4e m (configured 2e-7), mean %.2e m\n", sd, mean);
    assert_close(sd, 2e-7, 0.04 * 2e-7);
    rths_plant_destroy(p);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static void readings(const rths_setup *s, uint64_t seed, double *out, int n) {
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.seed = seed;
    rths_plant *p = make(s, &po);
    for (int k = 0; k < n; k++) {
        rths_sensor_sample in;
        rths_plant_read(p, &in);
        out[k] = in.displacement_m[2] + in.interface_force_n + in.interface_acceleration_m_s2;
        rths_plant_advance(p, 0.01);
    }
    rths_plant_destroy(p);
}

static void test_seeded(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load(NULL, 0, &cfg, &s);
    double a[500], b[500], c[500];
    readings(&s, 7, a, 500);
    readings(&s, 7, b, 500);
    readings(&s, 8, c, 500);
    assert_memory_equal(a, b, sizeof a);
    int differ = 0;
    for (int k = 0; k < 500; k++)
        differ += a[k] != c[k];
    assert_true(differ > 450);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Bilinear leg below storey 3 (the physical top storey, so the leg carries the whole static force
 * on storey 3): the slope of force against extension is k = 45052 N/m on the extension side and
 * 2 k on the compression side, the kink sits at zero extension where the applied force equals the
 * preload, and with no demand the plant starts (and stays) at the preloaded static point on the
 * stiff side, delta = -preload / (2 k). Heavy damping (by --set) settles each point in 2 s to
 * well below the 1e-10 m asserted. */
static double static_delta(const rths_setup *s, const rths_plant_options *po, double force) {
    rths_plant *p = make(s, po);
    for (int i = 0; i < 20000; i++)
        rths_plant_advance(p, force / po->gain_n_per_v);
    rths_sensor_sample in;
    rths_plant_read(p, &in);
    rths_plant_destroy(p);
    return in.displacement_m[2] - in.displacement_m[1];
}

static void test_bilinear_leg(void **state) {
    (void)state;
    const char *ov[] = {"structure.bilinear.enabled=true",
                        "structure.storeys.damping_n_s_per_m=[800, 800, 800, 3.7421]"};
    rths_config *cfg;
    rths_setup s;
    load(ov, 2, &cfg, &s);
    assert_true(s.has_bilinear);
    rths_plant_options po;
    rths_plant_defaults(&po);
    rths_plant_ideal(&po);
    const double k = 45052, preload = s.preload_n;
    assert_close(preload, 26.68, 0);
    /* at rest: the preloaded static point, exactly */
    rths_plant *p = make(&s, &po);
    rths_sensor_sample in;
    rths_plant_read(p, &in);
    assert_close(in.displacement_m[2] - in.displacement_m[1], -preload / (2 * k), 1e-15);
    for (int i = 0; i < 1000; i++)
        rths_plant_advance(p, 0);
    rths_plant_read(p, &in);
    assert_close(in.displacement_m[2] - in.displacement_m[1], -preload / (2 * k), 1e-13);
    rths_plant_destroy(p);
    /* slopes from pairs of static points on each side */
    double e1 = static_delta(&s, &po, preload + 10), e2 = static_delta(&s, &po, preload + 30);
    double c1 = static_delta(&s, &po, preload - 10), c2 = static_delta(&s, &po, preload - 30);
    print_message("extension slope %.2f N/m, compression slope %.2f N/m\n", 20 / (e2 - e1),
                  20 / (c1 - c2));
    assert_true(e1 > 0 && c1 < 0);
    assert_close(20 / (e2 - e1), k, 1e-6 * k);
    assert_close(20 / (c1 - c2), 2 * k, 1e-6 * 2 * k);
    /* both lines pass through the kink at (delta 0, force = preload) */
    assert_close(e1 - 10 / k, 0, 1e-10);
    assert_close(c1 + 10 / (2 * k), 0, 1e-10);
    assert_close(static_delta(&s, &po, preload), 0, 1e-12);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* A 1-DoF bilinear oscillator through the plant (storey 1 of a 2-storey chain is the interface,
 * its leg to the ground bilinear, k = 53048 N/m in extension, 2 k in compression, no damping,
 * no preload), set swinging by a one-sample demand pulse. Free motion is then a half sine on
 * each side: period pi sqrt(m / k) + pi sqrt(m / 2k), compression peaks 1/sqrt(2) of the
 * extension peaks, energy conserved through every kink crossing. The exact integrator meets all
 * three to 1e-9 over 40 periods (80 crossings; measured 5e-11 .. 1.2e-10, while RK4 x 8 drifts
 * 3e-8 in energy); zero crossings are linearly interpolated between
 * samples (time error ~ h (w h)^2 / 6 = 1.6e-9 s), peaks by a parabola through three samples
 * (relative error ~ (w h)^4 / 8 = 1e-9). RK4 x 8, which straddles the kink, is printed beside. */
typedef struct {
    double period_s, peak_ratio, energy_drift;
} swing;

static swing bilinear_swing(int substeps) {
    const char *ov[] = {"structure.storeys.mass_kg=[5.37, 1]",
                        "structure.storeys.damping_n_s_per_m=[0, 0]",
                        "structure.storeys.stiffness_n_per_m=[53048, 1000]",
                        "split.interface=[1]",
                        "forcing.dof=2",
                        "structure.bilinear.enabled=true",
                        "structure.bilinear.storey=1",
                        "structure.bilinear.preload_n=0"};
    rths_config *cfg;
    rths_setup s;
    load(ov, 8, &cfg, &s);
    rths_plant_options po;
    rths_plant_defaults(&po);
    rths_plant_ideal(&po);
    po.substeps_per_sample = substeps;
    rths_plant *p = make(&s, &po);
    rths_plant_advance(p, 2.0); /* 100 N for one sample */
    double prev = rths_plant_interface_displacement_m(p), x1 = prev, x0 = prev;
    double first_up = -1, last_up = -1, first_ext = 0, last_ext = 0, first_comp = 0;
    int ups = 0;
    for (long k = 1; k < 23000; k++) {
        rths_plant_advance(p, 0);
        double x = rths_plant_interface_displacement_m(p);
        if (prev < 0 && x >= 0) {
            double t = (k - 1 + prev / (prev - x)) * H;
            if (first_up < 0) first_up = t;
            last_up = t, ups++;
        }
        if (x1 > x0 && x1 >= x) { /* a sampled maximum at k - 1: the parabola's vertex value */
            double a = 0.5 * (x0 + x) - x1, b = 0.5 * (x - x0);
            double peak = x1 - b * b / (4 * a);
            if (first_ext == 0) first_ext = peak;
            last_ext = peak;
        }
        if (x1 < x0 && x1 <= x && first_comp == 0) {
            double a = 0.5 * (x0 + x) - x1, b = 0.5 * (x - x0);
            first_comp = x1 - b * b / (4 * a);
        }
        x0 = x1, x1 = x, prev = x;
    }
    rths_plant_destroy(p);
    rths_setup_free(&s);
    rths_config_free(cfg);
    print_message("%d upward crossings\n", ups);
    assert_true(ups >= 40 && first_ext > 0 && first_comp < 0);
    return (swing){(last_up - first_up) / (ups - 1), -first_comp / first_ext,
                   last_ext / first_ext - 1};
}

static void test_kink_crossing(void **state) {
    (void)state;
    const double m = 5.37, k = 53048;
    const double period = M_PI * sqrt(m / k) + M_PI * sqrt(m / (2 * k));
    swing exact = bilinear_swing(0), rk4 = bilinear_swing(8);
    print_message("period: exact %.3e, RK4 x 8 %.3e relative error; compression/extension peak: "
                  "exact %.3e, RK4 %.3e from 1/sqrt 2; energy drift over 40 periods: exact %.3e, "
                  "RK4 %.3e\n",
                  exact.period_s / period - 1, rk4.period_s / period - 1,
                  exact.peak_ratio * sqrt(2) - 1, rk4.peak_ratio * sqrt(2) - 1, exact.energy_drift,
                  rk4.energy_drift);
    assert_rel(exact.period_s, period, 1e-9);
    assert_rel(exact.peak_ratio, 1 / sqrt(2), 1e-9);
    assert_close(exact.energy_drift, 0, 1e-9);
}

/* rig.plant_integrator picks the integrator; substeps belong to rk4 only. */
static void test_integrator_config(void **state) {
    (void)state;
    const char *rk4[] = {"rig.plant_integrator=rk4"},
               *rk4_16[] = {"rig.plant_integrator=rk4", "rig.substeps_per_sample=16"};
    const char *bad[] = {"rig.substeps_per_sample=16"};
    const char *const *ovs[4] = {NULL, rk4, rk4_16, bad};
    const int counts[4] = {0, 1, 2, 1}, expect[4] = {0, 8, 16, -1};
    for (int i = 0; i < 4; i++) {
        rths_config *cfg;
        rths_setup s;
        load(ovs[i], counts[i], &cfg, &s);
        rths_plant_options po;
        rths_plant_defaults(&po);
        rths_error err;
        int rc = rths_plant_config_read(cfg, &po, &err);
        if (expect[i] < 0) {
            assert_int_equal(rc, RTHS_EINPUT);
            assert_non_null(strstr(err.msg, "applies to rig.plant_integrator: rk4 only"));
        } else {
            assert_int_equal(rc, RTHS_OK);
            assert_int_equal(po.substeps_per_sample, expect[i]);
        }
        rths_setup_free(&s);
        rths_config_free(cfg);
    }
}

/* Two interface storeys (2, 3) of the seed, actuator 2 pushing both storeys (T = [1 1; 0 1]),
 * laser 2 reading storey 3 relative to storey 2 (S = [1 0; -1 1]), armatures 0 (the transform
 * places them, the reference plant cannot): 3000 samples of demands u with the shaker's delay and
 * lag give the same motion as the plain plant driven by T u, to rounding; the lasers read S q,
 * the load cells each actuator's own force. */
static void test_transforms(void **state) {
    (void)state;
    const char *plain_ov[] = {"split.interface=[2, 3]"};
    const char *ov[] = {"split.interface=[2, 3]", "rig.actuators.transform=[[1, 1], [0, 1]]",
                        "rig.lasers.transform=[[1, 0], [-1, 1]]"};
    rths_config *cfg_a, *cfg_b;
    rths_setup a, b;
    load(ov, 3, &cfg_a, &a);
    load(plain_ov, 1, &cfg_b, &b);
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.noise = 0;
    po.armature_mass_kg = 0;
    rths_plant *pa = make(&a, &po), *pb = make(&b, &po);
    double worst = 0, scale = 0;
    rths_sensor_sample ra, rb;
    for (int k = 0; k < 3000; k++) {
        double u[2] = {0.3 * sin(2 * M_PI * 13.0 * k * H), 0.2 * cos(2 * M_PI * 7.0 * k * H)};
        double tu[2] = {u[0] + u[1], u[1]};
        rths_plant_advance_dofs(pa, u);
        rths_plant_advance_dofs(pb, tu);
        rths_plant_read(pa, &ra);
        rths_plant_read(pb, &rb);
        int n = ra.n;
        double q2 = rb.displacement_m[n - 2], q3 = rb.displacement_m[n - 1];
        worst = fmax(worst, fabs(ra.displacement_m[n - 2] - q2));
        worst = fmax(worst, fabs(ra.displacement_m[n - 1] - (q3 - q2)));
        worst = fmax(worst, fabs(ra.displacement_m[0] - rb.displacement_m[0]));
        scale = fmax(scale, fabs(q3));
    }
    print_message("transformed plant against the plain one driven by T u: %.3g m of %.3g m\n",
                  worst, scale);
    assert_true(scale > 1e-4);
    assert_true(worst < 1e-12 * scale);
    /* efforts: T times the load cells equals the plain plant's per-DoF load cells */
    double f0 = ra.interface_force_dof_n[0] + ra.interface_force_dof_n[1];
    assert_close(f0, rb.interface_force_dof_n[0], 1e-12 * fabs(f0) + 1e-15);
    assert_close(ra.interface_force_dof_n[1], rb.interface_force_dof_n[1],
                 1e-12 + 1e-12 * fabs(f0));
    rths_plant_destroy(pa), rths_plant_destroy(pb);
    rths_setup_free(&a), rths_setup_free(&b);
    rths_config_free(cfg_a), rths_config_free(cfg_b);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_forced_response_ideal),
        cmocka_unit_test(test_forced_response_shaker),
        cmocka_unit_test(test_exact_against_rk4),
        cmocka_unit_test(test_exact_against_rk4_bilinear),
        cmocka_unit_test(test_sensors),
        cmocka_unit_test(test_seeded),
        cmocka_unit_test(test_bilinear_leg),
        cmocka_unit_test(test_kink_crossing),
        cmocka_unit_test(test_integrator_config),
        cmocka_unit_test(test_transforms),
        cmocka_unit_test(test_transfer_function_actuator),
        cmocka_unit_test(test_servo_valve_velocity_polynomial),
        cmocka_unit_test(test_physical_share_mass),
        cmocka_unit_test(test_displacement_output_actuator),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
