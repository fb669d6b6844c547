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
    rule->pd_decay_fraction = 0.9;
    rule->delay_s = -1;
}

/* The setup's physical substructure on the rig: the interface block the rig's mass
 * (rig.interface_mass, setup.h), the actuators' armatures through the actuator transform. The
 * sensor transform cancels against the controller's inverse of it (tune.h). */
int rths_pd_loop_from_setup(const rths_setup *setup, const rths_controller_options *copt,
                            const rths_plant_options *popt, double delay_s, rths_pd_loop **out,
                            rths_error *err) {
    *out = NULL;
    const rths_split *s = &setup->split;
    const int ni = s->n_int, n = s->np;
    if (ni < 1 || ni > RTHS_MAX_INTERFACE_DOFS || ni > n)
        return rths_error_set(err, RTHS_EINPUT,
                              "the gain tuning models 1 to %d physical interface DoFs; this split "
                              "has %d (split.interface)",
                              RTHS_MAX_INTERFACE_DOFS, ni);
    if (ni > 1 && popt->actuator.model == RTHS_ACTUATOR_TRANSFER_FUNCTION)
        return rths_error_set(err, RTHS_EINPUT,
                              "rig.actuator.model: transfer_function drives one interface DoF "
                              "(the virtual plant's limit); this split has %d (split.interface)",
                              ni);
    double *m = malloc(sizeof(double) * (size_t)n * (size_t)n);
    if (!m) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    memcpy(m, s->mass_phys, sizeof(double) * (size_t)n * (size_t)n);
    for (int d = 0; d < ni; d++)
        for (int e = 0; e < ni; e++)
            RTHS_AT(m, n, n - ni + d, n - ni + e) = rths_setup_rig_interface_mass(setup, d, e);
    /* the virtual rig's delay line holds whole samples (plant_build.c: rounded) */
    rths_plant_options rig = *popt;
    rig.delay_s = delay_s >= 0
                      ? delay_s
                      : lround(popt->delay_s * copt->sample_rate_hz) / copt->sample_rate_hz;
    rths_pd_loop_spec spec = {.n = n,
                              .ni = ni,
                              .mass = m,
                              .damping = s->damping_phys,
                              .stiffness = s->stiffness_phys,
                              .sample_rate_hz = copt->sample_rate_hz,
                              .velocity_cutoff_hz = copt->velocity_cutoff_hz,
                              .rig = &rig,
                              .actuator_transform = setup->actuator_transform};
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

/* The coupled loop's gain margin: the largest factor c on every PD gain together with the loop
 * still stable, bisected in log c over [1e-3, 1e3] to 0.1 %, in dB; 60 dB when stable at 1e3,
 * -INFINITY when unstable at 1e-3. */
static double coupled_gain_margin_db(const rths_pd_loop *loop, const double *kp, const double *kd) {
    const int ni = rths_pd_loop_dofs(loop);
    double lo = 1e-3, hi = 1e3, kps[RTHS_MAX_INTERFACE_DOFS], kds[RTHS_MAX_INTERFACE_DOFS];
    for (int it = -2; it < 40 && hi / lo > 1.001; it++) {
        double c = it == -2 ? lo : it == -1 ? hi : sqrt(lo * hi);
        for (int d = 0; d < ni; d++)
            kps[d] = c * kp[d], kds[d] = c * kd[d];
        double r = rths_pd_loop_radius_dofs(loop, kps, kds);
        if (it == -2 && !(r < 1)) return -INFINITY;
        if (it == -1 && r < 1) return 60;
        if (it >= 0) {
            if (r < 1)
                lo = c;
            else
                hi = c;
        }
    }
    return 20 * log10(lo);
}

/* Several interface DoFs: loop at a time (docs/method.md, "Tuning the gains"). The start is the
 * configured gains, scaled down when needed until the coupled loop has the rule's gain margin
 * (with the other loops open, the physical substructure may be free and a loop alone has no
 * stable state to check); then passes in which each loop in turn takes the rule's pick with the
 * others closed at their current gains, the coupled loop's spectral radius checked, until a
 * pass changes nothing (at most 6). */
static int tune_pd_dofs(const rths_pd_loop *loop, const rths_tune_rule *rule, rths_tune_result *out,
                        rths_error *err) {
    const int ni = rths_pd_loop_dofs(loop);
    double *kp = out->kp, *kd = out->kd;
    double start_db = coupled_gain_margin_db(loop, out->current_kp, out->current_kd);
    if (!isfinite(start_db) || start_db < -59)
        return rths_error_set(err, RTHS_EFAIL,
                              "the gain tuning of %d interface DoFs starts from the configured PD "
                              "gains (controller.kp_per_dof, kd_per_dof), and those leave the "
                              "coupled physical loop unstable even at 1e-3 times them: give a "
                              "pair per DoF that is stable at some scale",
                              ni);
    double scale = start_db < rule->min_gain_margin_db
                       ? pow(10.0, (start_db - rule->min_gain_margin_db) / 20)
                       : 1.0;
    for (int d = 0; d < ni; d++)
        kp[d] = scale * out->current_kp[d], kd[d] = scale * out->current_kd[d];
    /* the coupled loop's stated margin: stable with every gain times this too */
    const double margin_factor = pow(10.0, rule->min_gain_margin_db / 20);
    int rc = RTHS_OK;
    out->sweeps = 0;
    for (int changed = 1; !rc && changed && out->sweeps < 6; out->sweeps++) {
        changed = 0;
        for (int d = 0; d < ni && !rc; d++) {
            double was_kp = kp[d], was_kd = kd[d];
            rc = rths_pd_loop_best_decay_dof(loop, d, kp, kd, margin_factor,
                                             rule->pd_decay_fraction, rule->min_gain_margin_db,
                                             rule->min_phase_margin_deg, &out->tuned_dof[d], err);
            changed |= kp[d] != was_kp || kd[d] != was_kd;
        }
    }
    for (int d = 0; d < ni && !rc; d++)
        rc = rths_pd_loop_margins_dof(loop, d, kp, kd, &out->tuned_dof[d], err);
    return rc;
}

int rths_tune(const rths_setup *setup, const rths_controller_options *copt,
              const rths_plant_options *popt, const rths_tune_rule *rule, rths_tune_result *out,
              rths_error *err) {
    memset(out, 0, sizeof *out);
    if (setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY)
        return rths_error_set(err, RTHS_EINPUT,
                              "split.numerical_solver: frequency has no grounding loop to tune; "
                              "the gain tuning needs the controller's own numerical substructure");
    if (copt->gain_matrix_rows > 0)
        return rths_error_set(err, RTHS_EINPUT,
                              "controller.kp_matrix and kd_matrix are set; the gain tuning gives "
                              "a PD per interface DoF (controller.kp_per_dof, kd_per_dof): remove "
                              "the matrices to tune");
    rths_pd_loop *loop = NULL;
    int rc = rths_pd_loop_from_setup(setup, copt, popt, rule->delay_s, &loop, err);
    if (rc) return rc;
    const int ni = out->n_int = setup->split.n_int;
    out->delay_samples = rths_pd_loop_delay_samples(loop);
    out->delay_fraction = rths_pd_loop_delay_fraction(loop);
    for (int d = 0; d < ni; d++) {
        double gkp, gkd;
        configured_gains(copt, d, &out->current_kp[d], &out->current_kd[d], &gkp, &gkd);
    }
    out->current_kp_v_per_m = out->current_kp[0];
    out->current_kd_v_s_per_m = out->current_kd[0];
    for (int d = 0; d < ni && !rc; d++)
        rc = rths_pd_loop_margins_dof(loop, d, out->current_kp, out->current_kd,
                                      &out->current_dof[d], err);
    if (!rc && ni == 1) {
        rc = rths_pd_loop_best(loop, rule->min_gain_margin_db, rule->min_phase_margin_deg,
                               &out->kp[0], &out->kd[0], &out->tuned_dof[0], err);
        out->sweeps = 1;
    } else if (!rc) {
        rc = tune_pd_dofs(loop, rule, out, err);
    }
    if (!rc) {
        out->current = out->current_dof[0];
        out->tuned = out->tuned_dof[0];
        out->kp_v_per_m = out->kp[0];
        out->kd_v_s_per_m = out->kd[0];
        out->coupled_gain_margin_db = coupled_gain_margin_db(loop, out->kp, out->kd);
        out->current_coupled_gain_margin_db =
            coupled_gain_margin_db(loop, out->current_kp, out->current_kd);
        double c = pow(10.0, rule->min_gain_margin_db / 20), kps[RTHS_MAX_INTERFACE_DOFS],
               kds[RTHS_MAX_INTERFACE_DOFS];
        for (int d = 0; d < ni; d++)
            kps[d] = c * out->kp[d], kds[d] = c * out->kd[d];
        out->coupled_radius_at_margin = rths_pd_loop_radius_dofs(loop, kps, kds);
        /* one DoF: the rule's frequency-domain gain margin is this one (tests/test_tune.c) */
        if (ni > 1 && !(out->coupled_gain_margin_db >= rule->min_gain_margin_db))
            rc = rths_error_set(err, RTHS_EFAIL,
                                "the tuned PD gains leave the coupled physical loop (every "
                                "interface DoF closed) a gain margin of %.2f dB, below %g dB",
                                out->coupled_gain_margin_db, rule->min_gain_margin_db);
    }
    rths_pd_loop_destroy(loop);
    if (rc) return rc;
    out->lowest_mode_hz = lowest_mode_hz(setup, err);
    if (out->lowest_mode_hz < 0) return RTHS_EFAIL;
    return tune_grounding(setup, copt, rule, out, err);
}
