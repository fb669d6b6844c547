/* rths tune: PD and grounding gains from the model, checked stable with a stated margin against
 * the sampled loop, the actuator and the delay (docs/method.md, "Tuning the gains"). */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/controller.h"
#include "rths/tune.h"

#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
    "Usage: rths tune CONFIG [--out DIR] [--delay S] [--set KEY=VALUE]... [--quiet]\n"
    "\n"
    "Gains for the controller from the model (docs/method.md, \"Tuning the gains\"):\n"
    "  - the physical PD (controller.kp_v_per_m, kd_v_s_per_m): the physical substructure on the\n"
    "    configured rig (interface mass, actuator, lag, delay, hold), sampled exactly at the\n"
    "    controller's rate and closed by its discrete PD; the pair with the widest bandwidth "
    "whose\n"
    "    closed loop is stable (spectral radius < 1) with a gain margin >= 6 dB and a phase\n"
    "    margin >= 45 deg;\n"
    "  - the grounding (controller.grounding_kp_n_per_m, grounding_kd_n_s_per_m): a critically\n"
    "    damped tie on the numerical interface mass: the softest whose slowest transient decays "
    "at\n"
    "    90 per cent of the fastest rate found, stable at twice the gains (acting one sample late, "
    "as\n"
    "    the controller does).\n"
    "The configured gains' margins are reported too. One interface DoF, no actuator or sensor\n"
    "transforms.\n"
    "\n"
    "Prints the keys to paste as a YAML fragment on stdout (comments say the margins). With\n"
    "--out DIR also writes DIR/tuned.yaml (the fragment), summary.json, loop.csv (the configured\n"
    "and the tuned loop's gain, phase and sensitivity over frequency) and its figure loop.png,\n"
    ".svg, .gp, config.yaml, run.log.\n"
    "\n"
    "Options:\n"
    "  --out DIR          output folder (created)\n"
    "  --delay S          the physical loop's transport delay, s, in [0, 0.1], a fraction of a\n"
    "                     sample included (a lab's measured delay); default: the configured\n"
    "                     delay as the virtual rig holds it, rounded to whole samples\n"
    "  --set KEY=VALUE    override a configuration key (repeatable)\n"
    "  --quiet            print nothing on success\n"
    "  --help             this text\n"
    "\n"
    "Exit status: 0 gains found (even when the configured ones are unstable: that is reported),\n"
    "1 no gains meet the rule, 2 bad usage or input (nothing written).\n";

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

static char *fragment(const rths_tune_result *r, const rths_tune_rule *rule) {
    char cur[320], tuned[320];
    margins_text(&r->current, cur, sizeof cur);
    margins_text(&r->tuned, tuned, sizeof tuned);
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    if (!f) return NULL;
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
    fclose(f);
    return text;
}

static json_object *margins_json(const rths_loop_margins *m) {
    json_object *o = json_object_new_object();
    json_object_object_add(o, "stable", json_object_new_boolean(m->stable));
    json_object_object_add(o, "spectral_radius", json_object_new_double(m->spectral_radius));
    /* JSON has no infinity: null where there is no crossover */
    json_object_object_add(o, "gain_margin_db",
                           isfinite(m->gain_margin_db) ? json_object_new_double(m->gain_margin_db)
                                                       : NULL);
    json_object_object_add(o, "gain_margin_hz",
                           isfinite(m->gain_margin_hz) ? json_object_new_double(m->gain_margin_hz)
                                                       : NULL);
    json_object_object_add(
        o, "phase_margin_deg",
        isfinite(m->phase_margin_deg) ? json_object_new_double(m->phase_margin_deg) : NULL);
    json_object_object_add(o, "crossover_hz",
                           isfinite(m->crossover_hz) ? json_object_new_double(m->crossover_hz)
                                                     : NULL);
    json_object_object_add(o, "bandwidth_hz", json_object_new_double(m->bandwidth_hz));
    return o;
}

/* loop.csv: the configured and the tuned loop L = K P and sensitivity S = 1 / (1 + L) over the
 * margins' frequencies; loop.png/.svg: their Bode plots. */
static int write_loop(rths_report *rep, const rths_setup *setup,
                      const rths_controller_options *copt, const rths_plant_options *popt,
                      const rths_tune_rule *rule, const rths_tune_result *r, rths_error *err) {
    rths_pd_loop *loop = NULL;
    int rc = rths_pd_loop_from_setup(setup, copt, popt, rule->delay_s, &loop, err);
    if (rc) return rc;
    int n = rths_pd_loop_points();
    double *f = malloc(sizeof *f * (size_t)n);
    double complex *lc = malloc(sizeof *lc * (size_t)n), *lt = malloc(sizeof *lt * (size_t)n);
    if (!f || !lc || !lt) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    static const char *const header[] = {"frequency_hz",
                                         "configured_loop_gain_db",
                                         "configured_loop_phase_deg",
                                         "configured_sensitivity_db",
                                         "tuned_loop_gain_db",
                                         "tuned_loop_phase_deg",
                                         "tuned_sensitivity_db"};
    char path[4096];
    rths_csv *csv = NULL;
    if (!rc) {
        rths_pd_loop_response(loop, r->current_kp_v_per_m, r->current_kd_v_s_per_m, f, lc);
        rths_pd_loop_response(loop, r->kp_v_per_m, r->kd_v_s_per_m, f, lt);
        snprintf(path, sizeof path, "%s/loop.csv", rths_report_dir(rep));
        rc = rths_csv_open(path, 7, header, &csv, err);
    }
    for (int g = 0; !rc && g < n; g++) {
        double row[7] = {f[g],
                         20 * log10(cabs(lc[g])),
                         carg(lc[g]) * 180 / M_PI,
                         -20 * log10(cabs(1 + lc[g])),
                         20 * log10(cabs(lt[g])),
                         carg(lt[g]) * 180 / M_PI,
                         -20 * log10(cabs(1 + lt[g]))};
        rc = rths_csv_row(csv, row);
        if (rc) rths_error_set(err, RTHS_EFAIL, "%s: write failed", path);
    }
    if (csv) rc = rths_csv_finish(csv, rc, err);
    free(f), free(lc), free(lt);
    rths_pd_loop_destroy(loop);
    if (rc) return rc;
    char body[2048];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set multiplot layout 2,1 title 'PD loop L = K P broken at the demand: configured "
             "(kp %g, kd %g) and tuned (kp %g, kd %g)'\n"
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
             r->current_kp_v_per_m, r->current_kd_v_s_per_m, r->kp_v_per_m, r->kd_v_s_per_m);
    return rths_plot(rep, rths_report_dir(rep), "loop", 1200, 900, body, err);
}

static int write_outputs(const rths_cli *cli, rths_report *rep, const rths_tune_result *r,
                         const rths_tune_rule *rule, const char *text, rths_error *err) {
    char path[4096];
    snprintf(path, sizeof path, "%s/tuned.yaml", rths_report_dir(rep));
    int rc = rths_write_file_atomic(path, text, strlen(text), err);
    if (rc) return rc;
    json_object *root = rths_cli_summary_new(cli);
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
    json_object_object_add(root, "current", cur);
    json_object_object_add(root, "tuned", tun);
    json_object_object_add(root, "lowest_mode_hz", json_object_new_double(r->lowest_mode_hz));
    rc = rths_cli_write_summary(rep, "summary.json", root, err);
    json_object_put(root);
    return rc;
}

int rths_cmd_tune(int argc, char **argv) {
    rths_cli_opt opts[] = {{"--out", "DIR", NULL}, {"--delay", "S", NULL}};
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG, usage, opts, 2);
    if (rc || cli.help) return rc;
    cli.out_dir = opts[0].value;
    rths_error err = {0};
    rths_tune_rule rule;
    rths_tune_rule_defaults(&rule);
    if (opts[1].value &&
        (rc = rths_cli_double("--delay", opts[1].value, 0, 0.1, &rule.delay_s, &err)))
        return rths_cli_fail(&cli, rc, &err);
    rths_config *cfg = NULL;
    rths_setup setup = {0};
    rths_report *rep = NULL;
    char *text = NULL;
    rc = rths_cli_load(&cli, &cfg, &setup, &err);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    rths_controller_options copt;
    rths_plant_options popt;
    rths_controller_defaults(&copt);
    rths_plant_defaults(&popt);
    rths_tune_result result;
    rc = rths_sample_loop_config_read(cfg, &copt, &popt, &err);
    if (!rc) rc = rths_cli_check_config(cfg, &err);
    if (!rc) rc = rths_tune(&setup, &copt, &popt, &rule, &result, &err);
    if (!rc && !(text = fragment(&result, &rule)))
        rc = rths_error_set(&err, RTHS_EFAIL, "out of memory");
    if (!rc && cli.out_dir) rc = rths_cli_open_report(&cli, cfg, argc, argv, &rep, &err);
    if (!rc) rths_cli_print(&cli, "%s", text);
    if (!rc && rep) rc = write_outputs(&cli, rep, &result, &rule, text, &err);
    if (!rc && rep) rc = write_loop(rep, &setup, &copt, &popt, &rule, &result, &err);
    if (rep)
        rths_report_log(rep, "finished with status %d%s%s", rc, rc ? ": " : "", rc ? err.msg : "");
    if (rc) rths_cli_fail(&cli, rc, &err);
    free(text);
    rths_cli_unload(cfg, &setup);
    rths_report_close(rep);
    return rc;
}
