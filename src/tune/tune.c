/* rths_tune: the PD gains of the physical loop and the grounding gains of the numerical one
 * (docs/method.md, "Tuning the gains"). */
#include "rths/model.h"
#include "rths/reduce.h"
#include "rths/tune.h"

#include "tune/tune_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void rths_tune_rule_defaults(rths_tune_rule *rule) {
    rule->min_gain_margin_db = 6.0;
    rule->min_phase_margin_deg = 45.0;
    rule->grounding_gain_factor = 2.0;
    rule->grounding_max_radius = 1.0;
    rule->grounding_decay_fraction = 0.9;
    rule->delay_s = -1;
}

/* The setup's physical substructure on the rig: the interface element the rig's mass
 * (rig.interface_mass, setup.h). */
int rths_pd_loop_from_setup(const rths_setup *setup, const rths_controller_options *copt,
                            const rths_plant_options *popt, double delay_s, rths_pd_loop **out,
                            rths_error *err) {
    *out = NULL;
    const rths_split *s = &setup->split;
    if (s->n_int != 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "the gain tuning models one interface DoF; this split has %d "
                              "(split.interface)",
                              s->n_int);
    if (setup->actuator_transform || setup->sensor_transform)
        return rths_error_set(err, RTHS_EINPUT,
                              "the gain tuning does not model actuator or sensor transforms "
                              "(rig.actuators, rig.lasers); remove them to tune");
    int n = s->np;
    double *m = malloc(sizeof(double) * (size_t)n * (size_t)n);
    if (!m) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    memcpy(m, s->mass_phys, sizeof(double) * (size_t)n * (size_t)n);
    RTHS_AT(m, n, n - 1, n - 1) = rths_setup_rig_interface_mass(setup, 0, 0);
    /* the virtual rig's delay line holds whole samples (plant.c: rounded) */
    rths_plant_options rig = *popt;
    rig.delay_s = delay_s >= 0
                      ? delay_s
                      : lround(popt->delay_s * copt->sample_rate_hz) / copt->sample_rate_hz;
    rths_pd_loop_spec spec = {.n = n,
                              .mass = m,
                              .damping = s->damping_phys,
                              .stiffness = s->stiffness_phys,
                              .sample_rate_hz = copt->sample_rate_hz,
                              .velocity_cutoff_hz = copt->velocity_cutoff_hz,
                              .rig = &rig};
    int rc = rths_pd_loop_create(&spec, out, err);
    free(m);
    return rc;
}

/* The numerical substructure's discrete model as rths_controller_create builds it (step.c,
 * build_numerical: Craig-Bampton reduction when it applies, the configured scheme), inputs the
 * interface forces. */
static int numerical_model(const rths_setup *setup, const rths_controller_options *copt,
                           rths_discrete *d, rths_error *err) {
    const rths_split *s = &setup->split;
    const rths_reduction_options *ro = &copt->reduction;
    rths_reduced red = {0};
    int rc = RTHS_OK, reduce = rths_reduction_applies(ro, s->nn), ni = s->n_int;
    if (reduce)
        rc = rths_reduce_craig_bampton(s->nn, ni, s->mass_num, s->damping_num, s->stiffness_num,
                                       rths_reduction_cutoff_hz(ro, copt->sample_rate_hz),
                                       RTHS_REALTIME_MAX_DOFS - ni, ro->cutoff_hz <= 0, &red, err);
    int n = reduce ? red.nr : s->nn;
    double *input = rc ? NULL : rths_mat_new(s->nn, ni), *reduced = NULL, *a = NULL, *b = NULL;
    if (!rc && !input) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int k = 0; !rc && k < ni; k++)
        input[k + (size_t)k * s->nn] = 1.0;
    if (!rc && reduce) {
        reduced = rths_mat_new(n, ni);
        if (!reduced)
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        else
            rths_mat_mul(n, ni, s->nn, 1.0, red.transform, 1, input, 0, 0.0, reduced);
    }
    if (!rc)
        rc = rths_state_space(
            n, reduce ? red.mass : s->mass_num, reduce ? red.damping : s->damping_num,
            reduce ? red.stiffness : s->stiffness_num, ni, reduce ? reduced : input, &a, &b, err);
    if (!rc)
        rc = rths_discretise(2 * n, ni, a, b, 1.0 / copt->sample_rate_hz, copt->scheme, d, err);
    free(a), free(b), free(input), free(reduced);
    rths_reduced_free(&red);
    return rc;
}

/* The grounding loop's radius (model.h): the same matrix the controller checks at create. */
static double grounding_radius_of(const rths_discrete *dm, int ni, double h, const double *gkp,
                                  const double *gkd) {
    return rths_grounding_loop_radius(dm->nx, dm->nu, dm->ad, dm->b_prev, dm->b_curr, h, ni, gkp,
                                      gkd);
}

double rths_grounding_radius(const rths_setup *setup, const rths_controller_options *copt,
                             const double *gkp, const double *gkd, rths_error *err) {
    rths_discrete dm = {0};
    if (numerical_model(setup, copt, &dm, err)) return -1;
    double r = grounding_radius_of(&dm, setup->split.n_int, 1.0 / copt->sample_rate_hz, gkp, gkd);
    rths_discrete_free(&dm);
    if (r < 0)
        rths_error_set(err, RTHS_EFAIL,
                       "the eigenvalues of the grounding loop could not be computed");
    return r;
}

/* The configured gains of interface DoF d, as rths_controller_create resolves them. */
static void configured_gains(const rths_controller_options *c, int d, double *kp, double *kd,
                             double *gkp, double *gkd) {
    *kp = c->kp_dof_v_per_m[d] > 0 ? c->kp_dof_v_per_m[d] : c->kp_v_per_m;
    *kd = c->kd_dof_v_s_per_m[d] > 0 ? c->kd_dof_v_s_per_m[d] : c->kd_v_s_per_m;
    *gkp = c->grounding_kp_dof[d] > 0 ? c->grounding_kp_dof[d] : c->grounding_kp_n_per_m;
    *gkd = c->grounding_kd_dof[d] > 0 ? c->grounding_kd_dof[d] : c->grounding_kd_n_s_per_m;
}

static double lowest_mode_hz(const rths_setup *setup, rths_error *err) {
    rths_modes modes = {0};
    if (rths_modal_analysis(&setup->assembly, &modes, err)) return -1;
    double f = modes.n > 0 ? modes.frequency_hz[0] : -1;
    rths_modes_free(&modes);
    if (!(f > 0)) rths_error_set(err, RTHS_EFAIL, "the assembly's lowest natural frequency is 0");
    return f > 0 ? f : -1;
}

/* Grounding (docs/method.md, "Tuning the gains"): a spring kp^ = m w_g^2 and a damper
 * kd^ = 2 zeta m w_g on the numerical interface mass m, over w_g from 1/100 of the lowest natural
 * frequency up to a tenth of the sample rate (10 per decade) and zeta in {0.5, 0.7, 1, 1.5, 2}.
 * Each pair's figure is the decay rate of the grounded numerical substructure's slowest transient,
 * -ln(spectral radius) / h (what sets the settling after each new target); a pair counts only
 * when the loop is also stable at grounding_gain_factor times its gains. The pick: the softest tie
 * (smallest kp^, then kd^) that reaches decay_fraction of the best decay rate found. */
static int tune_grounding(const rths_setup *setup, const rths_controller_options *copt,
                          const rths_tune_rule *rule, rths_tune_result *out, rths_error *err) {
    const rths_split *s = &setup->split;
    const int ni = s->n_int;
    rths_discrete dm = {0};
    int rc = numerical_model(setup, copt, &dm, err);
    if (rc) return rc;
    double h = 1.0 / copt->sample_rate_hz, cur_kp[RTHS_MAX_INTERFACE_DOFS],
           cur_kd[RTHS_MAX_INTERFACE_DOFS];
    for (int d = 0; d < ni; d++) {
        double kp, kd;
        configured_gains(copt, d, &kp, &kd, &cur_kp[d], &cur_kd[d]);
    }
    out->grounding_radius_current = grounding_radius_of(&dm, ni, h, cur_kp, cur_kd);
    enum { ZETAS = 5, MAX_STEPS = 200 };
    static const double zetas[ZETAS] = {0.5, 0.7, 1.0, 1.5, 2.0};
    double w_lo = 2 * M_PI * out->lowest_mode_hz / 100, w_hi = 2 * M_PI * copt->sample_rate_hz / 10;
    int steps = (int)ceil(10 * log10(w_hi / w_lo));
    if (steps > MAX_STEPS) steps = MAX_STEPS;
    if (steps < 1) steps = 1;
    double(*radius)[ZETAS] = malloc(sizeof *radius * (MAX_STEPS + 1));
    if (!radius) {
        rths_discrete_free(&dm);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    double best_decay = 0;
    for (int k = 0; k <= steps && !rc; k++)
        for (int z = 0; z < ZETAS && !rc; z++) {
            double wg = w_lo * pow(10.0, 0.1 * k), kp[RTHS_MAX_INTERFACE_DOFS],
                   kd[RTHS_MAX_INTERFACE_DOFS], kp2[RTHS_MAX_INTERFACE_DOFS],
                   kd2[RTHS_MAX_INTERFACE_DOFS];
            for (int d = 0; d < ni; d++) {
                double m = RTHS_AT(s->mass_num, s->nn, d, d);
                kp[d] = m * wg * wg;
                kd[d] = 2 * zetas[z] * m * wg;
                kp2[d] = rule->grounding_gain_factor * kp[d];
                kd2[d] = rule->grounding_gain_factor * kd[d];
            }
            double r = grounding_radius_of(&dm, ni, h, kp, kd),
                   r2 = grounding_radius_of(&dm, ni, h, kp2, kd2);
            if (r < 0 || r2 < 0) rc = RTHS_EFAIL;
            radius[k][z] = r < 1 && r2 < rule->grounding_max_radius ? r : INFINITY;
            if (radius[k][z] < 1 && -log(radius[k][z]) / h > best_decay)
                best_decay = -log(radius[k][z]) / h;
        }
    int found = 0;
    /* the softest: w_g ascending, then zeta ascending (kd^ grows with both) */
    for (int k = 0; k <= steps && !rc && !found; k++)
        for (int z = 0; z < ZETAS && !found; z++) {
            if (!(radius[k][z] < 1 &&
                  -log(radius[k][z]) / h >= rule->grounding_decay_fraction * best_decay))
                continue;
            double wg = w_lo * pow(10.0, 0.1 * k);
            for (int d = 0; d < ni; d++) {
                double m = RTHS_AT(s->mass_num, s->nn, d, d);
                out->grounding_kp[d] = m * wg * wg;
                out->grounding_kd[d] = 2 * zetas[z] * m * wg;
            }
            out->grounding_radius = radius[k][z];
            out->grounding_frequency_hz = wg / (2 * M_PI);
            out->grounding_damping_ratio = zetas[z];
            out->grounding_decay_per_s = -log(radius[k][z]) / h;
            out->grounding_best_decay_per_s = best_decay;
            double kp2[RTHS_MAX_INTERFACE_DOFS], kd2[RTHS_MAX_INTERFACE_DOFS];
            for (int d = 0; d < ni; d++) {
                kp2[d] = rule->grounding_gain_factor * out->grounding_kp[d];
                kd2[d] = rule->grounding_gain_factor * out->grounding_kd[d];
            }
            out->grounding_radius_margin = grounding_radius_of(&dm, ni, h, kp2, kd2);
            found = 1;
        }
    rths_discrete_free(&dm);
    free(radius);
    if (rc)
        return rths_error_set(err, RTHS_EFAIL,
                              "the eigenvalues of the grounding loop could not be computed");
    if (!found)
        return rths_error_set(err, RTHS_EFAIL,
                              "no grounding gains keep the numerical substructure stable at %g "
                              "times them",
                              rule->grounding_gain_factor);
    return RTHS_OK;
}

int rths_tune(const rths_setup *setup, const rths_controller_options *copt,
              const rths_plant_options *popt, const rths_tune_rule *rule, rths_tune_result *out,
              rths_error *err) {
    memset(out, 0, sizeof *out);
    if (setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY)
        return rths_error_set(err, RTHS_EINPUT,
                              "split.numerical_solver: frequency has no grounding loop to tune; "
                              "the gain tuning needs the controller's own numerical substructure");
    rths_pd_loop *loop = NULL;
    int rc = rths_pd_loop_from_setup(setup, copt, popt, rule->delay_s, &loop, err);
    if (rc) return rc;
    out->n_int = setup->split.n_int;
    out->delay_samples = rths_pd_loop_delay_samples(loop);
    out->delay_fraction = rths_pd_loop_delay_fraction(loop);
    double gkp, gkd;
    configured_gains(copt, 0, &out->current_kp_v_per_m, &out->current_kd_v_s_per_m, &gkp, &gkd);
    rc = rths_pd_loop_margins(loop, out->current_kp_v_per_m, out->current_kd_v_s_per_m,
                              &out->current, err);
    if (!rc)
        rc = rths_pd_loop_best(loop, rule->min_gain_margin_db, rule->min_phase_margin_deg,
                               &out->kp_v_per_m, &out->kd_v_s_per_m, &out->tuned, err);
    rths_pd_loop_destroy(loop);
    if (rc) return rc;
    out->lowest_mode_hz = lowest_mode_hz(setup, err);
    if (out->lowest_mode_hz < 0) return RTHS_EFAIL;
    return tune_grounding(setup, copt, rule, out, err);
}
