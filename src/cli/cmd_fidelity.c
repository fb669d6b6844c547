/* rths fidelity: the hybrid test's steady-state FRF at a perfect interface match for every
 * integration scheme of the numerical substructure, against the true assembly (docs/method.md,
 * "Numerical substructure integration"). */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/controller.h"
#include "rths/fidelity.h"

#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
    "Usage: rths fidelity CONFIG --out DIR [--set KEY=VALUE]... [--quiet]\n"
    "\n"
    "What the numerical substructure's integration scheme does to the result "
    "of a hybrid test\n"
    "(docs/method.md, \"Numerical substructure integration\"). For each scheme (implicit_euler, "
    "trapezoidal, exact_zoh, "
    "exact_foh) the converged\n"
    "hybrid test is computed in the frequency domain: the physical "
    "substructure in continuous "
    "time,\n"
    "the numerical substructure discretised at the controller's sample step "
    "and driven by the\n"
    "sampled interface force, the interface displacements matched. Its "
    "interface amplitude is\n"
    "compared with the true assembly's analytic FRF.\n"
    "\n"
    "Configuration keys (docs/config/fidelity.md): fidelity.start_hz, "
    "fidelity.end_hz (default\n"
    "+-10 % around the second natural frequency), fidelity.points (default "
    "1001);\n"
    "controller.sample_rate_hz (default 10000).\n"
    "\n"
    "Writes DIR/fidelity.csv (frequency_hz, true_amplitude_m, "
    "<scheme>_amplitude_m), "
    "summary.json,\n"
    "config.yaml, fidelity.gp/.png/.svg, run.log. Prints each scheme's peak "
    "and its error.\n"
    "\n"
    "Options:\n"
    "  --out DIR          output folder (created)\n"
    "  --set KEY=VALUE    override a configuration key (repeatable)\n"
    "  --quiet            print nothing on success\n"
    "  --help             this text\n"
    "\n"
    "Exit status: 0 success, 1 failure, 2 bad usage or input (nothing "
    "written).\n";

#define N_CURVES (RTHS_SCHEME_COUNT + 1)

typedef struct {
    rths_fidelity_options sweep;
    double sample_rate_hz;
    int dof; /* 0-based: the (first) interface DoF */
    rths_reduction_options reduction;
} fidelity_options;

static int read_options(rths_config *cfg, const rths_setup *setup, fidelity_options *o,
                        rths_error *err) {
    int rc = rths_fidelity_config_read(cfg, &setup->assembly, &o->sweep, err);
    if (rc) return rc;
    /* the controller's own reader: one default and range for the sample rate, and the rest of
     * the controller section is checked too */
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    if ((rc = rths_controller_config_read(cfg, &copt, err))) return rc;
    o->sample_rate_hz = copt.sample_rate_hz;
    o->dof = setup->split.int_dofs[0];
    o->reduction = copt.reduction;
    return rths_reduction_config_read(cfg, &o->reduction, err);
}

static const char *curve_name(int c) {
    return c == RTHS_FIDELITY_TRUE ? "true" : rths_scheme_name((rths_scheme)c);
}

static int write_csv(rths_report *rep, const rths_fidelity *f, const fidelity_options *o,
                     const double *freqs, int count, rths_error *err) {
    const char *header[N_CURVES + 1] = {"frequency_hz", "true_amplitude_m"};
    char names[RTHS_SCHEME_COUNT][64];
    for (int s = 0; s < RTHS_SCHEME_COUNT; s++) {
        snprintf(names[s], sizeof names[s], "%s_amplitude_m", rths_scheme_name((rths_scheme)s));
        header[2 + s] = names[s];
    }
    char *path = rths_report_path(rep, "fidelity.csv");
    double complex *x = malloc((size_t)rths_fidelity_dofs(f) * sizeof *x);
    rths_csv *csv = NULL;
    int rc = (path && x) ? rths_csv_open(path, N_CURVES + 1, header, &csv, err)
                         : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < count && !rc; i++) {
        double row[N_CURVES + 1] = {freqs[i]};
        for (int c = RTHS_FIDELITY_TRUE; c < RTHS_SCHEME_COUNT && !rc; c++) {
            rc = rths_fidelity_response(f, c, 2 * M_PI * freqs[i], x, err);
            row[2 + c] = cabs(x[o->dof]);
        }
        if (!rc && rths_csv_row(csv, row))
            rc = rths_error_set(err, RTHS_EFAIL, "writing %s failed", path);
    }
    rc = rths_csv_finish(csv, rc, err);
    free(path);
    free(x);
    return rc;
}

static int plot(rths_report *rep, const fidelity_options *o, double mass_ratio, double true_peak_hz,
                double true_peak_m, double half_width_hz, rths_error *err) {
    /* Left: a linear zoom on the peak, where the schemes differ and a log axis would hide it.
     * Right: each scheme's amplitude error against the true FRF over the whole sweep. */
    double lo = fmax(o->sweep.start_hz, true_peak_hz - half_width_hz);
    double hi = fmin(o->sweep.end_hz, true_peak_hz + half_width_hz);
    char body[4096];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set multiplot layout 1,2 title 'Integration fidelity of the "
             "numerical substructure: "
             "hybrid test at a perfect interface match, h = %g s, p = %g, "
             "interface DoF %d'\n"
             "set grid\n"
             "set xlabel 'forcing frequency (Hz)'\n"
             "set title 'interface amplitude near the peak'\n"
             "set ylabel 'interface amplitude (m)'\n"
             "set format y '%%.1e'\n"
             "set key top right\n"
             "set xrange [%.17g:%.17g]\n"
             "set yrange [0:%.17g]\n"
             "plot 'fidelity.csv' skip 1 using 1:2 with lines lw 4 lc rgb "
             "'#000000' title 'true "
             "(analytic)', \\\n"
             "  '' skip 1 using 1:3 with lines lw 2 lc rgb '#d62728' title "
             "'implicit Euler', \\\n"
             "  '' skip 1 using 1:4 with lines lw 2 dt 2 lc rgb '#2ca02c' title "
             "'trapezoidal', \\\n"
             "  '' skip 1 using 1:5 with lines lw 2 lc rgb '#1f77b4' title "
             "'exact ZOH', \\\n"
             "  '' skip 1 using 1:6 with lines lw 2 dt 3 lc rgb '#ff7f0e' title "
             "'exact FOH'\n"
             "set title 'amplitude error against the true FRF'\n"
             "set ylabel 'amplitude error (%%)'\n"
             "set format y '%%g'\n"
             "set key bottom right\n"
             "set xrange [%.17g:%.17g]\n"
             "set yrange [*:*]\n"
             "plot 'fidelity.csv' skip 1 using 1:(100*($3/$2-1)) with lines lw 2 "
             "lc rgb '#d62728' "
             "title 'implicit Euler', \\\n"
             "  '' skip 1 using 1:(100*($4/$2-1)) with lines lw 2 dt 2 lc rgb "
             "'#2ca02c' "
             "title 'trapezoidal', \\\n"
             "  '' skip 1 using 1:(100*($5/$2-1)) with lines lw 2 lc rgb "
             "'#1f77b4' title 'exact ZOH', "
             "\\\n"
             "  '' skip 1 using 1:(100*($6/$2-1)) with lines lw 2 dt 3 lc rgb "
             "'#ff7f0e' "
             "title 'exact FOH'\n"
             "unset multiplot\n",
             1.0 / o->sample_rate_hz, mass_ratio, o->dof + 1, lo, hi, 1.08 * true_peak_m,
             o->sweep.start_hz, o->sweep.end_hz);
    return rths_plot(rep, rths_report_dir(rep), "fidelity", 1400, 600, body, err);
}

/* The numerical substructure as the controller integrates it: reduced (Craig-Bampton, the same
 * cutoff rule as the controller's build) when the reduction applies, else NULL. */
static int build_reduction(const rths_setup *setup, const fidelity_options *o, rths_reduced *red,
                           int *applies, rths_error *err) {
    const rths_split *s = &setup->split;
    *applies = rths_reduction_applies(&o->reduction, s->nn);
    if (!*applies) return RTHS_OK;
    return rths_reduce_craig_bampton(s->nn, s->n_int, s->mass_num, s->damping_num, s->stiffness_num,
                                     rths_reduction_cutoff_hz(&o->reduction, o->sample_rate_hz),
                                     RTHS_REALTIME_MAX_DOFS - s->n_int, o->reduction.cutoff_hz <= 0,
                                     red, err);
}

/* The reduction's own error (continuous time, no scheme): its peak against the true one and the
 * largest relative interface FRF error over the grid; printed and added to the summary. */
static int report_reduction(const rths_cli *cli, rths_report *rep, const rths_fidelity *f,
                            const rths_reduced *red, const fidelity_options *o, const double *freqs,
                            int count, const double *true_peak, json_object *summary,
                            rths_error *err) {
    double peak_hz, peak_m, worst = 0, worst_hz = 0;
    int rc = rths_fidelity_peak(f, RTHS_FIDELITY_REDUCED, o->dof, o->sweep.start_hz,
                                o->sweep.end_hz, o->sweep.points, &peak_hz, &peak_m, err);
    double complex *x = malloc(sizeof *x * (size_t)rths_fidelity_dofs(f));
    double complex *t = malloc(sizeof *t * (size_t)rths_fidelity_dofs(f));
    if (!rc && (!x || !t)) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < count && !rc; i++) {
        rc = rths_fidelity_response(f, RTHS_FIDELITY_REDUCED, 2 * M_PI * freqs[i], x, err);
        if (!rc) rc = rths_fidelity_response(f, RTHS_FIDELITY_TRUE, 2 * M_PI * freqs[i], t, err);
        double e = rc ? 0 : cabs(x[o->dof] - t[o->dof]) / cabs(t[o->dof]);
        if (e > worst) worst = e, worst_hz = freqs[i];
    }
    free(x), free(t);
    if (rc) return rc;
    double peak_error = 100.0 * (peak_m - true_peak[0]) / true_peak[0];
    json_object *r = json_object_new_object();
    json_object_object_add(r, "method", json_object_new_string("craig_bampton"));
    json_object_object_add(r, "dofs", json_object_new_int(red->nr));
    json_object_object_add(r, "modes", json_object_new_int(red->n_modes));
    json_object_object_add(r, "cutoff_hz", json_object_new_double(red->cutoff_hz));
    json_object_object_add(r, "peak_hz", json_object_new_double(peak_hz));
    json_object_object_add(r, "peak_error_percent", json_object_new_double(peak_error));
    json_object_object_add(r, "max_interface_frf_error_relative", json_object_new_double(worst));
    json_object_object_add(summary, "reduction", r);
    rths_cli_print(cli,
                   "%-16s %14.6f %18.6e %+16.3f   (Craig-Bampton, %d DoFs, modes <= %g Hz; "
                   "interface FRF error <= %.2e, at %g Hz)\n",
                   "reduction", peak_hz, peak_m, peak_error, red->nr, red->cutoff_hz, worst,
                   worst_hz);
    rths_report_log(rep,
                    "reduction: %d DoFs (%d modes up to %g Hz), peak %+.4f %%, interface FRF "
                    "error up to %.3e at %g Hz",
                    red->nr, red->n_modes, red->cutoff_hz, peak_error, worst, worst_hz);
    return RTHS_OK;
}

int rths_cmd_fidelity(int argc, char **argv) {
    static const char *const own_sections[] = {"fidelity", "controller", NULL};
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT, usage, NULL, 0);
    if (rc || cli.help) return rc;
    rths_error err;
    rths_error_clear(&err);
    rths_config *cfg = NULL;
    rths_setup setup;
    rths_report *rep = NULL;
    rths_fidelity *f = NULL;
    rths_reduced red = {0};
    int reduced = 0;
    double *freqs = NULL;
    json_object *summary = NULL;
    fidelity_options o;
    if ((rc = rths_cli_load(&cli, &cfg, &setup, &err))) return rths_cli_fail(&cli, rc, &err);
    if ((rc = read_options(cfg, &setup, &o, &err)) ||
        (rc = rths_cli_check_config_own(cfg, own_sections, &err)))
        goto done;
    double h = 1.0 / o.sample_rate_hz;
    if ((rc = build_reduction(&setup, &o, &red, &reduced, &err)) ||
        (rc = rths_fidelity_create_reduced(&setup.split, setup.force, h, reduced ? &red : NULL, &f,
                                           &err)))
        goto done;

    /* every curve's peak, refined beyond the grid, so the reported errors are the model's and the
     * CSV contains each exact peak */
    double peak_hz[N_CURVES], peak_m[N_CURVES];
    for (int c = RTHS_FIDELITY_TRUE; c < RTHS_SCHEME_COUNT && !rc; c++)
        rc = rths_fidelity_peak(f, c, o.dof, o.sweep.start_hz, o.sweep.end_hz, o.sweep.points,
                                &peak_hz[c + 1], &peak_m[c + 1], &err);
    if (rc) goto done;
    int unique;
    if ((rc = rths_fidelity_frequencies(&o.sweep, peak_hz, N_CURVES, &freqs, &unique, &err)))
        goto done;

    if ((rc = rths_cli_open_report(&cli, cfg, argc, argv, &rep, &err))) goto done;
    if ((rc = write_csv(rep, f, &o, freqs, unique, &err))) goto done;

    summary = rths_cli_summary_new(&cli);
    json_object *curves = json_object_new_object();
    json_object_object_add(summary, "sample_rate_hz", json_object_new_double(o.sample_rate_hz));
    json_object_object_add(summary, "time_step_s", json_object_new_double(h));
    json_object_object_add(summary, "mass_ratio", json_object_new_double(setup.split.mass_ratio));
    json_object_object_add(summary, "interface_dof", json_object_new_int(o.dof + 1));
    json_object_object_add(summary, "start_hz", json_object_new_double(o.sweep.start_hz));
    json_object_object_add(summary, "end_hz", json_object_new_double(o.sweep.end_hz));
    json_object_object_add(summary, "points", json_object_new_int(unique));
    json_object_object_add(summary, "default_scheme",
                           json_object_new_string(rths_scheme_name(RTHS_SCHEME_DEFAULT)));
    rths_cli_print(&cli,
                   "Integration fidelity: interface DoF %d, p = %g, h = %g s (%g Hz), "
                   "%g..%g Hz\n",
                   o.dof + 1, setup.split.mass_ratio, h, o.sample_rate_hz, o.sweep.start_hz,
                   o.sweep.end_hz);
    rths_cli_print(&cli, "%-16s %14s %18s %16s\n", "scheme", "peak_hz", "peak_amplitude_m",
                   "peak_error_%");
    double widest = 0;
    for (int c = RTHS_FIDELITY_TRUE; c < RTHS_SCHEME_COUNT; c++) {
        double e = 100.0 * (peak_m[c + 1] - peak_m[0]) / peak_m[0];
        json_object *o_c = json_object_new_object();
        json_object_object_add(o_c, "peak_hz", json_object_new_double(peak_hz[c + 1]));
        json_object_object_add(o_c, "peak_amplitude_m", json_object_new_double(peak_m[c + 1]));
        json_object_object_add(o_c, "peak_error_percent", json_object_new_double(e));
        json_object_object_add(o_c, "peak_shift_hz",
                               json_object_new_double(peak_hz[c + 1] - peak_hz[0]));
        json_object_object_add(curves, curve_name(c), o_c);
        rths_cli_print(&cli, "%-16s %14.6f %18.6e %+16.3f\n", curve_name(c), peak_hz[c + 1],
                       peak_m[c + 1], e);
        widest = fmax(widest, fabs(peak_hz[c + 1] - peak_hz[0]));
        rths_report_log(rep, "%s: peak %.9g m at %.9g Hz (%+.4f %%)", curve_name(c), peak_m[c + 1],
                        peak_hz[c + 1], e);
    }
    json_object_object_add(summary, "curves", curves);
    if (reduced &&
        (rc = report_reduction(&cli, rep, f, &red, &o, freqs, unique, peak_m, summary, &err)))
        goto done;
    if (setup.has_bilinear) {
        /* the frequency-domain model is linear: the leg's extension stiffness is what it sees */
        static const char leg_note[] = "the bilinear leg is not modelled: the structure is taken "
                                       "as linear with the leg's extension stiffness";
        static const char elements_note[] = "the nonlinear elements are not modelled: the "
                                            "structure is taken as linear (K and C without their "
                                            "forces)";
        /* structure.bilinear alone keeps its note; structure.nonlinear's elements get theirs */
        int leg_only = setup.n_nonlinear == 1 && setup.nonlinear[0].type == RTHS_NL_BILINEAR &&
                       setup.leg.upper_dof == setup.nonlinear[0].dof_i &&
                       setup.leg.stiffness_n_per_m > 0;
        const char *note = leg_only ? leg_note : elements_note;
        json_object_object_add(summary, "note", json_object_new_string(note));
        rths_cli_print(&cli, "note: %s\n", note);
    }
    if ((rc = rths_cli_write_summary(rep, "summary.json", summary, &err))) goto done;
    /* zoom: a few half-power bandwidths of the true peak (found on the analytic curve), wide enough
     * for every scheme's shifted peak */
    double half_power_hz = rths_fidelity_half_power_hz(
        f, RTHS_FIDELITY_TRUE, o.dof, peak_hz[0], peak_m[0], o.sweep.end_hz,
        0.1 * ((o.sweep.end_hz - o.sweep.start_hz) / (o.sweep.points - 1)));
    double half_width = fmax(6 * half_power_hz, 3 * widest);
    if (!(half_width > 0)) half_width = 0.5 * (o.sweep.end_hz - o.sweep.start_hz);
    rc = plot(rep, &o, setup.split.mass_ratio, peak_hz[0], peak_m[0], half_width, &err);
    /* results.mat is part of the outputs: one that cannot be written fails the command (exit 1,
     * one line; the other files stay), rather than a warning at close */
    if (!rc) rc = rths_report_write_mat(rep, &err);
done:
    if (summary) json_object_put(summary);
    free(freqs);
    rths_fidelity_free(f);
    rths_reduced_free(&red);
    if (rep) rths_report_close(rep);
    rths_cli_unload(cfg, &setup);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    return RTHS_OK;
}
