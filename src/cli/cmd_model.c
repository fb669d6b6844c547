/* rths model CONFIG --out DIR: modes and analytic FRF of the true assembly, the ground truth every
 * hybrid result is judged against. */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/report.h"
#include "rths/setup.h"

#include <complex.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
    "Usage: rths model CONFIG --out DIR [--set key=value]... [--quiet]\n"
    "\n"
    "Modal analysis and analytic frequency response of the true assembly described by CONFIG\n"
    "(structure, split, forcing sections; see docs/config.md).\n"
    "\n"
    "Prints the modes and writes into DIR:\n"
    "  modes.csv      mode, frequency_hz, omega_rad_s, damping_ratio, phi<i> (mass-normalised)\n"
    "  true_frf.csv   frequency_hz, x<i>_amplitude_m, x<i>_phase_rad, response to the configured\n"
    "                 force; range model.frf.{start_hz,end_hz,points}, by default up to 1.25 x\n"
    "                 the highest mode with every peak resolved\n"
    "                 (DoFs i: all of them up to 64 DoFs; above, the physical substructure's\n"
    "                 and the forcing DoF, in both files)\n"
    "  true_frf.gp/.png/.svg   the FRF figure\n"
    "  summary.json, config.yaml (as resolved), run.log (with the time of each stage)\n"
    "\n"
    "Options:\n"
    "  --out DIR          output folder (created)\n"
    "  --set key=value    override a configuration key (repeatable), e.g. split.mass_ratio=0.33\n"
    "  --quiet            print nothing but errors\n"
    "  --help             this text\n"
    "\n"
    "Exit status: 0 success, 1 failure, 2 bad usage or configuration (nothing written).\n";

static int write_modes(rths_report *rep, const rths_modes *m, const int *dofs, int n_out,
                       rths_error *err) {
    int n = m->n, cols = 4 + n_out;
    const char **header = calloc((size_t)cols, sizeof *header);
    char(*names)[32] = calloc((size_t)n_out, sizeof *names);
    double *row = calloc((size_t)cols, sizeof *row);
    char *path = rths_report_path(rep, "modes.csv");
    rths_csv *csv = NULL;
    int rc = (header && names && row && path) ? RTHS_OK
                                              : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        header[0] = "mode";
        header[1] = "frequency_hz";
        header[2] = "omega_rad_s";
        header[3] = "damping_ratio";
        for (int i = 0; i < n_out; i++) {
            snprintf(names[i], sizeof names[i], "phi%d_per_sqrt_kg", dofs[i] + 1);
            header[4 + i] = names[i];
        }
        rc = rths_csv_open(path, cols, header, &csv, err);
    }
    for (int r = 0; r < n && !rc; r++) {
        row[0] = r + 1;
        row[1] = m->frequency_hz[r];
        row[2] = m->omega_rad_s[r];
        row[3] = m->damping_ratio[r];
        for (int i = 0; i < n_out; i++)
            row[4 + i] = RTHS_AT(m->shapes, n, dofs[i], r);
        rc = rths_csv_row(csv, row);
        if (rc) rths_error_set(err, RTHS_EFAIL, "writing modes.csv failed");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(header);
    free(names);
    free(row);
    free(path);
    return rc;
}

/* Writes true_frf.csv; returns the interface DoF's peak (amplitude, frequency) for the summary. */
static int write_frf(rths_report *rep, const rths_setup *s, rths_frf_sweep *sweep, const int *dofs,
                     int n_out, const double *freqs, int count, double *peak_amp, double *peak_hz,
                     rths_error *err) {
    int cols = 1 + 2 * n_out;
    const char **header = calloc((size_t)cols, sizeof *header);
    char(*names)[40] = calloc((size_t)(2 * n_out), sizeof *names);
    double *row = calloc((size_t)cols, sizeof *row);
    double complex *x = calloc((size_t)n_out, sizeof *x);
    char *path = rths_report_path(rep, "true_frf.csv");
    rths_csv *csv = NULL;
    int rc = (header && names && row && x && path)
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    int iface = 0;
    if (!rc) {
        header[0] = "frequency_hz";
        for (int i = 0; i < n_out; i++) {
            snprintf(names[2 * i], sizeof names[0], "x%d_amplitude_m", dofs[i] + 1);
            snprintf(names[2 * i + 1], sizeof names[0], "x%d_phase_rad", dofs[i] + 1);
            header[1 + 2 * i] = names[2 * i];
            header[2 + 2 * i] = names[2 * i + 1];
            if (dofs[i] == s->split.int_dofs[0]) iface = i;
        }
        rc = rths_csv_open(path, cols, header, &csv, err);
    }
    *peak_amp = 0;
    *peak_hz = 0;
    for (int j = 0; j < count && !rc; j++) {
        rc = rths_frf_sweep_eval(sweep, 2 * M_PI * freqs[j], x, err);
        if (rc) break;
        row[0] = freqs[j];
        for (int i = 0; i < n_out; i++) {
            row[1 + 2 * i] = cabs(x[i]);
            row[2 + 2 * i] = carg(x[i]);
        }
        if (cabs(x[iface]) > *peak_amp) {
            *peak_amp = cabs(x[iface]);
            *peak_hz = freqs[j];
        }
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing true_frf.csv");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(header);
    free(names);
    free(row);
    free(x);
    free(path);
    return rc;
}

/* At most this many modes are marked in the figure (and printed): the rest are in modes.csv. */
#define MODES_SHOWN 40

static int plot_frf(rths_report *rep, const rths_setup *s, const rths_modes *m, const int *dofs,
                    int n_out, double f_lo, double f_hi, rths_error *err) {
    size_t cap = 4096 + (size_t)(n_out + MODES_SHOWN) * 256;
    char *body = malloc(cap);
    if (!body) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    char forcing[96];
    rths_setup_forcing_text(s, forcing, sizeof forcing);
    size_t len = (size_t)snprintf(body, cap,
                                  "set datafile separator ','\n"
                                  "set title 'True assembly: response to %s (analytic)'\n"
                                  "set xlabel 'Forcing frequency (Hz)'\n"
                                  "set ylabel 'Displacement amplitude (m)'\n"
                                  "set logscale y\n"
                                  "set format y '10^{%%L}'\n"
                                  "set grid\n"
                                  "set key top right\n",
                                  forcing);
    for (int r = 0, shown = 0; r < m->n && shown < MODES_SHOWN && len < cap; r++) {
        if (m->frequency_hz[r] < f_lo || m->frequency_hz[r] > f_hi) continue;
        shown++;
        len += (size_t)snprintf(body + len, cap - len,
                                "set arrow from %.6g, graph 0 to %.6g, graph 1 nohead dt 3 lc "
                                "rgb 'gray50'\n",
                                m->frequency_hz[r], m->frequency_hz[r]);
    }
    if (len < cap) len += (size_t)snprintf(body + len, cap - len, "plot ");
    for (int k = 0; k < n_out && len < cap; k++) {
        int i = dofs[k];
        const char *role = s->roles[i] == RTHS_DOF_INTERFACE  ? "interface"
                           : s->roles[i] == RTHS_DOF_PHYSICAL ? "physical"
                                                              : "numerical";
        len += (size_t)snprintf(body + len, cap - len,
                                "%s'true_frf.csv' using 1:%d skip 1 with lines lw %d title "
                                "'x_%d (%s)'",
                                k ? ", \\\n     " : "", 2 + 2 * k,
                                s->roles[i] == RTHS_DOF_INTERFACE ? 3 : 1, i + 1, role);
    }
    if (len < cap) snprintf(body + len, cap - len, "\n");
    int rc = rths_plot(rep, rths_report_dir(rep), "true_frf", 1200, 800, body, err);
    free(body);
    return rc;
}

static int write_summary(const rths_cli *cli, rths_report *rep, const rths_setup *s,
                         const rths_modes *m, double peak_amp, double peak_hz, int points,
                         rths_error *err) {
    json_object *root = rths_cli_summary_new(cli);
    rths_model_summary_add(root, s, m, points, peak_amp, peak_hz);
    int rc = rths_cli_write_summary(rep, "summary.json", root, err);
    json_object_put(root);
    return rc;
}

static void print_modes(const rths_cli *cli, const rths_setup *setup, const rths_modes *modes) {
    char forcing[96];
    rths_setup_forcing_text(setup, forcing, sizeof forcing);
    rths_cli_print(cli, "True assembly: %d DoFs, interface DoF %d, p = %g, %s\n", setup->assembly.n,
                   setup->split.int_dofs[0] + 1, setup->split.mass_ratio, forcing);
    rths_cli_print(cli, "%6s %14s %14s %14s\n", "mode", "frequency_hz", "omega_rad_s", "damping_%");
    for (int r = 0; r < modes->n && r < MODES_SHOWN; r++)
        rths_cli_print(cli, "%6d %14.4f %14.3f %14.4f\n", r + 1, modes->frequency_hz[r],
                       modes->omega_rad_s[r], 100 * modes->damping_ratio[r]);
    if (modes->n > MODES_SHOWN)
        rths_cli_print(cli, "%6s (%d more modes in modes.csv)\n", "...", modes->n - MODES_SHOWN);
}

int rths_cmd_model(int argc, char **argv) {
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT, usage, NULL, 0);
    if (rc || cli.help) return rc;
    rths_error err = {0};
    rths_config *cfg = NULL;
    rths_setup setup = {0};
    rths_modes modes = {0};
    rths_report *rep = NULL;
    rths_frf_sweep *sweep = NULL;
    double *freqs = NULL;
    int count = 0, n_out = 0, *dofs = NULL;
    double t0 = rths_monotonic_s();
    rc = rths_cli_load(&cli, &cfg, &setup, &err);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    double t_read = rths_monotonic_s();
    static const char *const own[] = {"structure", "split", "forcing", "model", NULL};
    rc = rths_cli_check_config_own(cfg, own, &err);
    if (!rc) rc = rths_modal_analysis(&setup.assembly, &modes, &err);
    double t_modes = rths_monotonic_s();
    if (!rc)
        rc = rths_frf_grid(&modes, setup.frf_start_hz, setup.frf_end_hz, setup.frf_points, &freqs,
                           &count, &err);
    if (!rc && !(dofs = rths_setup_output_dofs(&setup, &n_out)))
        rc = rths_error_set(&err, RTHS_EFAIL, "out of memory");
    if (!rc)
        rc = rths_frf_sweep_create(&setup.assembly, &modes, setup.force, n_out, dofs, &sweep, &err);
    double t_prepare = rths_monotonic_s();
    if (!rc) rc = rths_cli_open_report(&cli, cfg, argc, argv, &rep, &err);
    if (!rc) print_modes(&cli, &setup, &modes);
    double peak_amp = 0, peak_hz = 0, t_frf = t_prepare;
    if (!rc) rc = write_modes(rep, &modes, dofs, n_out, &err);
    if (!rc) {
        double t = rths_monotonic_s();
        rc = write_frf(rep, &setup, sweep, dofs, n_out, freqs, count, &peak_amp, &peak_hz, &err);
        t_frf = rths_monotonic_s() - t;
    }
    if (!rc) rc = write_summary(&cli, rep, &setup, &modes, peak_amp, peak_hz, count, &err);
    if (!rc) rc = plot_frf(rep, &setup, &modes, dofs, n_out, freqs[0], freqs[count - 1], &err);
    if (!rc) {
        rths_cli_print(&cli,
                       "Interface (DoF %d) peak: %.4g m at %.4f Hz; %d frequencies in "
                       "%s/true_frf.csv\n",
                       setup.split.int_dofs[0] + 1, peak_amp, peak_hz, count, rths_report_dir(rep));
        rths_report_log(rep,
                        "timing: %d DoFs; reading the configuration %.3f s, modes (%s) %.3f s, "
                        "FRF preparation (%s) %.3f s, FRF at %d frequencies with %d DoFs written "
                        "%.3f s; total %.3f s",
                        setup.assembly.n, t_read - t0,
                        rths_assembly_half_bandwidth(&setup.assembly) <= setup.assembly.n / 8
                            ? "banded, dsbgvd"
                            : "dense, dsygvd",
                        t_modes - t_read, rths_frf_method_name(rths_frf_sweep_method(sweep)),
                        t_prepare - t_modes, count, n_out, t_frf, rths_monotonic_s() - t0);
    }
    /* results.mat is part of the outputs: one that cannot be written fails the command (exit 1,
     * one line; the other files stay), rather than a warning at close */
    if (!rc) rc = rths_report_write_mat(rep, &err);
    if (rep)
        rths_report_log(rep, "finished with status %d%s%s", rc, rc ? ": " : "", rc ? err.msg : "");
    if (rc) rths_cli_fail(&cli, rc, &err);
    free(freqs);
    free(dofs);
    rths_frf_sweep_destroy(sweep);
    rths_modes_free(&modes);
    rths_cli_unload(cfg, &setup);
    rths_report_close(rep);
    return rc;
}
