/* rths_api_tune: PD and grounding gains from the model (docs/method.md, "Tuning the gains") as a
 * table, a summary and the YAML fragment to paste. The one implementation of `rths tune`'s
 * outputs: the command calls rths_api_tune_run (over rths_api_tune_compute) and writes its result
 * with rths_api_result_write, as rths_api_tune does. */
#include "api/api_internal.h"
#include "rths/controller.h"
#include "rths/tune.h"

#include <json-c/json.h>
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void margins_text(const rths_loop_margins *m, char *buf, size_t size) {
    char gm[48], pm[48];
    if (isinf(m->gain_margin_db))
        snprintf(gm, sizeof gm, "no phase crossover");
    else
        snprintf(gm, sizeof gm, "%.2f dB at %.1f Hz", m->gain_margin_db, m->gain_margin_hz);
    if (isinf(m->phase_margin_deg))
        snprintf(pm, sizeof pm, "no gain crossover");
    else
        snprintf(pm, sizeof pm, "%.1f deg at %.1f Hz", m->phase_margin_deg, m->crossover_hz);
    snprintf(buf, size,
             "%s, spectral radius %.6f, gain margin %s, phase margin %s, bandwidth %.1f Hz",
             m->stable ? "stable" : "UNSTABLE", m->spectral_radius, gm, pm, m->bandwidth_hz);
}

/* One interface DoF: what `rths tune` has always printed. */
static void fragment_one(FILE *f, const rths_tune_result *r, const rths_tune_rule *rule) {
    char cur[320], tuned[320];
    margins_text(&r->current, cur, sizeof cur);
    margins_text(&r->tuned, tuned, sizeof tuned);
    fprintf(
        f,
        "# rths tune (docs/method.md, \"Tuning the gains\"); physical loop with a delay of %.6g "
        "samples\n"
        "# configured kp %g V/m, kd %g V s/m: %s\n"
        "# tuned (gain margin >= %g dB, phase margin >= %g deg, widest bandwidth): %s\n"
        "# grounding: configured spectral radius %.9f per sample%s; tuned %.9f, at %g x the "
        "gains %.9f (a tie at %.3g Hz, damping ratio %g; slowest transient decays at %.3g /s, "
        "the fastest found %.3g /s; lowest mode %.3g Hz)\n"
        "controller:\n"
        "  kp_v_per_m: %.6g\n"
        "  kd_v_s_per_m: %.6g\n"
        "  grounding_kp_n_per_m: %.6g\n"
        "  grounding_kd_n_s_per_m: %.6g\n",
        r->delay_samples + r->delay_fraction, r->current_kp_v_per_m, r->current_kd_v_s_per_m, cur,
        rule->min_gain_margin_db, rule->min_phase_margin_deg, tuned, r->grounding_radius_current,
        r->grounding_radius_current < 1 ? "" : " (UNSTABLE)", r->grounding_radius,
        rule->grounding_gain_factor, r->grounding_radius_margin, r->grounding_frequency_hz,
        r->grounding_damping_ratio, r->grounding_decay_per_s, r->grounding_best_decay_per_s,
        r->lowest_mode_hz, r->kp_v_per_m, r->kd_v_s_per_m, r->grounding_kp[0], r->grounding_kd[0]);
}

static void list(FILE *f, const char *key, const double *v, int n) {
    fprintf(f, "  %s: [", key);
    for (int d = 0; d < n; d++)
        fprintf(f, "%s%.6g", d ? ", " : "", v[d]);
    fprintf(f, "]\n");
}

static void coupled_text(double gm_db, char *buf, size_t size) {
    if (!isfinite(gm_db))
        snprintf(buf, size, "unstable at 1e-3 times every PD gain");
    else if (gm_db >= 60)
        snprintf(buf, size, "stable up to 1000 times every PD gain (60 dB or more)");
    else
        snprintf(buf, size, "stable up to %.2f dB on every PD gain together", gm_db);
}

/* Several interface DoFs: a line per loop (broken at its effort demand, the others closed), the
 * coupled loop's margin, the lists the controller reads. */
static void fragment_dofs(FILE *f, const rths_setup *setup, const rths_tune_result *r,
                          const rths_tune_rule *rule) {
    const int ni = r->n_int;
    fprintf(f,
            "# rths tune (docs/method.md, \"Tuning the gains\"); physical loop with a delay of "
            "%.6g samples; %d interface DoFs, each loop's margins with the loop broken at its "
            "effort demand and the others closed\n",
            r->delay_samples + r->delay_fraction, ni);
    for (int pass = 0; pass < 2; pass++) {
        const double *kp = pass ? r->kp : r->current_kp, *kd = pass ? r->kd : r->current_kd;
        const rths_loop_margins *m = pass ? r->tuned_dof : r->current_dof;
        for (int d = 0; d < ni; d++) {
            int rot = rths_setup_dof_is_rotation(setup, setup->split.int_dofs[d]);
            char text[320];
            margins_text(&m[d], text, sizeof text);
            fprintf(f, "# %s DoF %d (assembly DoF %d, %s): kp %g %s, kd %g %s: %s\n",
                    pass ? "tuned" : "configured", d + 1, setup->split.int_dofs[d] + 1,
                    rot ? "rotation" : "displacement", kp[d], rot ? "V m/rad" : "V/m", kd[d],
                    rot ? "V s m/rad" : "V s/m", text);
        }
        char coupled[96];
        coupled_text(pass ? r->coupled_gain_margin_db : r->current_coupled_gain_margin_db, coupled,
                     sizeof coupled);
        if (pass)
            fprintf(f,
                    "# tuned, coupled (every DoF closed): spectral radius %.6f, %s; at %g dB "
                    "(each loop: gain margin >= %g dB, phase margin >= %g deg, widest bandwidth, "
                    "%d passes) %.6f\n",
                    r->tuned.spectral_radius, coupled, rule->min_gain_margin_db,
                    rule->min_gain_margin_db, rule->min_phase_margin_deg, r->sweeps,
                    r->coupled_radius_at_margin);
        else
            fprintf(f, "# configured, coupled (every DoF closed): spectral radius %.6f%s, %s\n",
                    r->current.spectral_radius, r->current.stable ? "" : " (UNSTABLE)", coupled);
    }
    fprintf(f,
            "# grounding (N/m, N s/m; N m/rad, N m s/rad on rotations): configured spectral "
            "radius %.9f per sample%s; tuned %.9f, at %g x the gains %.9f (a tie at %.3g Hz on "
            "each DoF's numerical interface mass, damping ratio %g; slowest transient decays at "
            "%.3g /s, the fastest found %.3g /s; lowest mode %.3g Hz)\n",
            r->grounding_radius_current, r->grounding_radius_current < 1 ? "" : " (UNSTABLE)",
            r->grounding_radius, rule->grounding_gain_factor, r->grounding_radius_margin,
            r->grounding_frequency_hz, r->grounding_damping_ratio, r->grounding_decay_per_s,
            r->grounding_best_decay_per_s, r->lowest_mode_hz);
    fprintf(f, "controller:\n");
    list(f, "kp_per_dof", r->kp, ni);
    list(f, "kd_per_dof", r->kd, ni);
    list(f, "grounding_kp_per_dof", r->grounding_kp, ni);
    list(f, "grounding_kd_per_dof", r->grounding_kd, ni);
}

static char *fragment(const rths_setup *setup, const rths_tune_result *r,
                      const rths_tune_rule *rule) {
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    if (!f) return NULL;
    if (r->n_int == 1)
        fragment_one(f, r, rule);
    else
        fragment_dofs(f, setup, r, rule);
    fclose(f);
    return text;
}

static json_object *number_or_null(double v) {
    /* JSON has no infinity: null where there is no crossover */
    return isfinite(v) ? json_object_new_double(v) : NULL;
}

static json_object *margins_json(const rths_loop_margins *m) {
    json_object *o = json_object_new_object();
    json_object_object_add(o, "stable", json_object_new_boolean(m->stable));
    json_object_object_add(o, "spectral_radius", json_object_new_double(m->spectral_radius));
    json_object_object_add(o, "gain_margin_db", number_or_null(m->gain_margin_db));
    json_object_object_add(o, "gain_margin_hz", number_or_null(m->gain_margin_hz));
    json_object_object_add(o, "phase_margin_deg", number_or_null(m->phase_margin_deg));
    json_object_object_add(o, "crossover_hz", number_or_null(m->crossover_hz));
    json_object_object_add(o, "bandwidth_hz", json_object_new_double(m->bandwidth_hz));
    return o;
}

static json_object *array_json(const double *v, int n) {
    json_object *a = json_object_new_array();
    for (int d = 0; d < n; d++)
        json_object_array_add(a, json_object_new_double(v[d]));
    return a;
}

/* Several DoFs: per loop (each with its gains), the lists and the coupled loop's margin. */
static void dofs_json(json_object *o, const rths_loop_margins *m, const double *kp,
                      const double *kd, double coupled_db, int ni) {
    json_object *loops = json_object_new_array();
    for (int d = 0; d < ni; d++) {
        json_object *l = margins_json(&m[d]);
        json_object_object_add(l, "kp", json_object_new_double(kp[d]));
        json_object_object_add(l, "kd", json_object_new_double(kd[d]));
        json_object_array_add(loops, l);
    }
    json_object_object_add(o, "loops", loops);
    json_object_object_add(o, "kp_per_dof", array_json(kp, ni));
    json_object_object_add(o, "kd_per_dof", array_json(kd, ni));
    /* null: unstable at 1e-3 times the gains; 60: stable at 1e3 times them (the search's cap) */
    json_object_object_add(o, "coupled_gain_margin_db", number_or_null(coupled_db));
}

static void tune_summary_add(json_object *root, const rths_setup *setup, const rths_tune_result *r,
                             const rths_tune_rule *rule, const char *text) {
    const int ni = r->n_int;
    json_object *rl = json_object_new_object();
    json_object_object_add(rl, "min_gain_margin_db",
                           json_object_new_double(rule->min_gain_margin_db));
    json_object_object_add(rl, "min_phase_margin_deg",
                           json_object_new_double(rule->min_phase_margin_deg));
    json_object_object_add(rl, "grounding_gain_factor",
                           json_object_new_double(rule->grounding_gain_factor));
    json_object_object_add(rl, "grounding_decay_fraction",
                           json_object_new_double(rule->grounding_decay_fraction));
    json_object_object_add(root, "rule", rl);
    json_object_object_add(root, "delay_samples",
                           json_object_new_double(r->delay_samples + r->delay_fraction));
    json_object *cur = margins_json(&r->current), *tun = margins_json(&r->tuned);
    json_object_object_add(cur, "kp_v_per_m", json_object_new_double(r->current_kp_v_per_m));
    json_object_object_add(cur, "kd_v_s_per_m", json_object_new_double(r->current_kd_v_s_per_m));
    json_object_object_add(cur, "grounding_spectral_radius",
                           json_object_new_double(r->grounding_radius_current));
    json_object_object_add(tun, "kp_v_per_m", json_object_new_double(r->kp_v_per_m));
    json_object_object_add(tun, "kd_v_s_per_m", json_object_new_double(r->kd_v_s_per_m));
    json_object_object_add(tun, "grounding_kp_n_per_m", json_object_new_double(r->grounding_kp[0]));
    json_object_object_add(tun, "grounding_kd_n_s_per_m",
                           json_object_new_double(r->grounding_kd[0]));
    json_object_object_add(tun, "grounding_spectral_radius",
                           json_object_new_double(r->grounding_radius));
    json_object_object_add(tun, "grounding_spectral_radius_at_factor",
                           json_object_new_double(r->grounding_radius_margin));
    json_object_object_add(tun, "grounding_frequency_hz",
                           json_object_new_double(r->grounding_frequency_hz));
    json_object_object_add(tun, "grounding_damping_ratio",
                           json_object_new_double(r->grounding_damping_ratio));
    json_object_object_add(tun, "grounding_decay_per_s",
                           json_object_new_double(r->grounding_decay_per_s));
    if (ni > 1) {
        json_object *dofs = json_object_new_array();
        for (int d = 0; d < ni; d++)
            json_object_array_add(dofs, json_object_new_int(setup->split.int_dofs[d] + 1));
        json_object_object_add(root, "interface_dofs", dofs);
        dofs_json(cur, r->current_dof, r->current_kp, r->current_kd,
                  r->current_coupled_gain_margin_db, ni);
        dofs_json(tun, r->tuned_dof, r->kp, r->kd, r->coupled_gain_margin_db, ni);
        json_object_object_add(tun, "coupled_spectral_radius_at_min_gain_margin",
                               json_object_new_double(r->coupled_radius_at_margin));
        json_object_object_add(tun, "passes", json_object_new_int(r->sweeps));
        json_object_object_add(tun, "grounding_kp_per_dof", array_json(r->grounding_kp, ni));
        json_object_object_add(tun, "grounding_kd_per_dof", array_json(r->grounding_kd, ni));
    }
    json_object_object_add(root, "current", cur);
    json_object_object_add(root, "tuned", tun);
    json_object_object_add(root, "lowest_mode_hz", json_object_new_double(r->lowest_mode_hz));
    json_object_object_add(root, "tuned_yaml", json_object_new_string(text));
}

/* Table "loop": the configured and the tuned loop L = K P and sensitivity S = 1 / (1 + L) over
 * the margins' frequencies; with several DoFs each loop's (broken, the others closed), columns
 * prefixed dof<d>_. */
static int loop_table(rths_result *res, const rths_pd_loop *loop, const rths_tune_result *r,
                      rths_error *err) {
    static const char *const kinds[6] = {"configured_loop_gain_db",   "configured_loop_phase_deg",
                                         "configured_sensitivity_db", "tuned_loop_gain_db",
                                         "tuned_loop_phase_deg",      "tuned_sensitivity_db"};
    const int n = rths_pd_loop_points(), ni = r->n_int, cols = 1 + 6 * ni;
    double *data = malloc(sizeof *data * (size_t)n * (size_t)cols);
    double complex *l = malloc(sizeof *l * (size_t)n);
    char(*names)[64] = calloc((size_t)cols, sizeof *names);
    const char **name_ptr = calloc((size_t)cols, sizeof *name_ptr);
    const double **col_ptr = calloc((size_t)cols, sizeof *col_ptr);
    int rc = data && l && names && name_ptr && col_ptr
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int c = 0; !rc && c < cols; c++) {
        if (c == 0)
            snprintf(names[c], sizeof names[c], "frequency_hz");
        else if (ni == 1)
            snprintf(names[c], sizeof names[c], "%s", kinds[c - 1]);
        else
            snprintf(names[c], sizeof names[c], "dof%d_%s", (c - 1) / 6 + 1, kinds[(c - 1) % 6]);
        name_ptr[c] = names[c];
        col_ptr[c] = data + (size_t)c * n;
    }
    for (int d = 0; !rc && d < ni; d++)
        for (int pass = 0; !rc && pass < 2; pass++) {
            const double *kp = pass ? r->kp : r->current_kp, *kd = pass ? r->kd : r->current_kd;
            if (ni == 1)
                rths_pd_loop_response(loop, kp[0], kd[0], data, l);
            else if (rths_pd_loop_response_dof(loop, d, kp, kd, data, l))
                rc = rths_error_set(err, RTHS_EFAIL,
                                    "the loop of interface DoF %d could not be formed", d + 1);
            double *gain = data + (size_t)(1 + 6 * d + 3 * pass) * n, *phase = gain + n,
                   *sens = phase + n;
            for (int g = 0; !rc && g < n; g++) {
                gain[g] = 20 * log10(cabs(l[g]));
                phase[g] = carg(l[g]) * 180 / M_PI;
                sens[g] = -20 * log10(cabs(1 + l[g]));
            }
        }
    if (!rc) rc = rths_result_add_columns(res, "loop", n, cols, name_ptr, col_ptr, err);
    free(data), free(l), free(names), free(name_ptr), free(col_ptr);
    return rc;
}

/* loop.png/.svg: the Bode plots of loop.csv (DoF 1's loop with several). */
static int plot_loop(rths_result *res, const rths_tune_result *r, rths_error *err) {
    char body[2048], title[256];
    if (r->n_int > 1)
        snprintf(title, sizeof title,
                 "PD loop of interface DoF 1 broken at its demand, the other %d closed: "
                 "configured (kp %g, kd %g) and tuned (kp %g, kd %g)",
                 r->n_int - 1, r->current_kp[0], r->current_kd[0], r->kp[0], r->kd[0]);
    else
        snprintf(title, sizeof title,
                 "PD loop L = K P broken at the demand: configured (kp %g, kd %g) and tuned (kp "
                 "%g, kd %g)",
                 r->current_kp_v_per_m, r->current_kd_v_s_per_m, r->kp_v_per_m, r->kd_v_s_per_m);
    /* columns by number: 1 + (the kind's place) in both layouts */
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set multiplot layout 2,1 title '%s'\n"
             "set grid\n"
             "set logscale x\n"
             "set xlabel 'frequency (Hz)'\n"
             "set ylabel 'gain (dB)'\n"
             "set key bottom left\n"
             "plot 'loop.csv' skip 1 using 1:2 with lines lw 2 title '|L| configured', \\\n"
             "  '' skip 1 using 1:5 with lines lw 2 title '|L| tuned', \\\n"
             "  '' skip 1 using 1:7 with lines dt 2 title '|S| tuned', 0 with lines lc rgb "
             "'gray50' notitle\n"
             "set ylabel 'phase (deg)'\n"
             "set yrange [-180:180]\n"
             "plot 'loop.csv' skip 1 using 1:3 with lines lw 2 title 'configured', \\\n"
             "  '' skip 1 using 1:6 with lines lw 2 title 'tuned'\n"
             "unset multiplot\n",
             title);
    return rths_result_add_figure(res, "loop", 1200, 900, body, err);
}

/* The result from the options read (copt, popt) */
static int tune_result(const rths_setup *setup, const rths_controller_options *copt,
                       const rths_plant_options *popt, double delay_s, const char *config_path,
                       const char *const *overrides, int n_overrides, rths_result **out,
                       rths_error *err) {
    *out = NULL;
    if (!(delay_s < 0) && !(delay_s <= 0.1))
        return rths_error_set(err, RTHS_EINPUT,
                              "delay %g s: must be in [0, 0.1] (or < 0: the "
                              "configured delay)",
                              delay_s);
    rths_tune_rule rule;
    rths_tune_rule_defaults(&rule);
    rule.delay_s = delay_s < 0 ? -1 : delay_s;
    rths_tune_result *r = calloc(1, sizeof *r);
    if (!r) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    rths_result *res = NULL;
    rths_pd_loop *loop = NULL;
    char *text = NULL;
    int rc = rths_tune(setup, copt, popt, &rule, r, err);
    if (!rc && !(text = fragment(setup, r, &rule)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_result_new(&res, err);
    if (!rc) rc = rths_pd_loop_from_setup(setup, copt, popt, rule.delay_s, &loop, err);
    if (!rc) rc = loop_table(res, loop, r, err);
    if (!rc) {
        json_object *summary = rths_api_summary_new("tune", config_path, overrides, n_overrides);
        if (summary) tune_summary_add(summary, setup, r, &rule, text);
        rc = rths_result_set_summary(res, summary, err);
    }
    rths_pd_loop_destroy(loop);
    if (!rc) rths_result_printf(res, "%s", text);
    if (!rc) rc = rths_result_add_file(res, "tuned.yaml", text, err);
    if (!rc) rc = plot_loop(res, r, err);
    free(r);
    free(text);
    if (rc) {
        rths_result_free(res);
        return rc;
    }
    *out = res;
    return RTHS_OK;
}

int rths_api_tune_compute(rths_config *c, const rths_setup *setup, double delay_s,
                          const char *config_path, const char *const *overrides, int n_overrides,
                          rths_result **out, rths_error *err) {
    *out = NULL;
    if (rths_setup_require_dense(setup, "rths tune", err)) return RTHS_EINPUT;
    rths_controller_options copt;
    rths_plant_options popt;
    rths_controller_defaults(&copt);
    rths_plant_defaults(&popt);
    /* the gains are designed from the loop's model; where the sites' controllers run plays no
     * part in it (a multi-site config tunes as one rig) */
    rths_config_mark_known(c, "rig.sites");
    int rc = rths_sample_loop_config_read(c, &copt, &popt, err);
    if (!rc) rc = rths_api_check_config(c, NULL, err);
    if (!rc)
        rc = tune_result(setup, &copt, &popt, delay_s, config_path, overrides, n_overrides, out,
                         err);
    return rc;
}

int rths_api_tune(const rths_api_config *cfg, double delay_s, const char *out_dir,
                  rths_result **out, rths_error *err) {
    *out = NULL;
    if (!cfg) return rths_error_set(err, RTHS_EINPUT, "no configuration given");
    rths_config *c;
    rths_setup setup;
    rths_result *r = NULL;
    int rc = rths_api_load(cfg, &c, &setup, err);
    if (rc) return rc;
    rc = rths_api_tune_compute(c, &setup, delay_s, cfg->path, (const char *const *)cfg->overrides,
                               cfg->n_overrides, &r, err);
    rc = rths_api_finish(r, rc, c, out_dir, "tune", out, err);
    rths_api_unload(c, &setup);
    return rc;
}
