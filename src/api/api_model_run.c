/* `rths model`'s whole job behind the C API (rths_api_model_run): the solver path chosen from the
 * configuration (dense / banded / sparse: rths_model_choose_solver), the tables and summary of
 * rths_api_model_compute (or its sparse twin), the printed report, run.log's lines and the FRF
 * figure, all in one result the command writes with rths_api_result_write. */
#include "api/api_internal.h"
#include "api/api_model_sparse.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* At most this many modes are marked in the figure (and printed): the rest are in modes.csv. */
#define MODES_SHOWN 40

/* At most this many curves in the figure (a beam's 74 output DoFs drew 74 curves nobody could
 * tell apart): the interface, the forcing DoF and the physical side first, then DoFs spread
 * evenly over the rest; every DoF stays in true_frf.csv. */
#define FIGURE_CURVES 8

/* Which of the n_out output DoFs the figure draws (drawn[k] = 1). */
static void choose_curves(const rths_dof_role *roles, int forcing_dof, const int *dofs, int n_out,
                          char *drawn) {
    int chosen = 0;
    for (int k = 0; k < n_out; k++)
        drawn[k] = n_out <= FIGURE_CURVES;
    if (n_out <= FIGURE_CURVES) return;
    for (int pass = 0; pass < 3; pass++)
        for (int k = 0; k < n_out && chosen < FIGURE_CURVES; k++) {
            int i = dofs[k];
            int want = pass == 0   ? roles[i] == RTHS_DOF_INTERFACE
                       : pass == 1 ? i == forcing_dof
                                   : roles[i] == RTHS_DOF_PHYSICAL;
            if (want && !drawn[k]) drawn[k] = 1, chosen++;
        }
    int left = FIGURE_CURVES - chosen;
    for (int j = 0; j < left; j++) {
        /* spread evenly; a DoF drawn already passes the turn to the next one not drawn (n_out >
         * FIGURE_CURVES: there always is one) */
        int k = (int)(((long)j * 2 + 1) * n_out / (2L * left));
        for (int t = 0; t < n_out && drawn[k]; t++)
            k = (k + 1) % n_out;
        drawn[k] = 1;
    }
}

/* roles: every DoF's side (the dense setup's or the sparse model's); forcing: in words;
 * forcing_dof: 0-based, -1 for a base excitation; rotation: per output DoF, 1 for a rotation (rad,
 * drawn on a right-hand axis of its own), or NULL (every DoF a translation). The figures'
 * convention (report.h): the legend right of the plot, never over data; the modes' lines
 * labelled. */
static int plot_frf(rths_result *res, const rths_dof_role *roles, const char *forcing,
                    int forcing_dof, const double *mode_hz, int n_modes, const int *dofs, int n_out,
                    const char *rotation, double f_lo, double f_hi, rths_error *err) {
    char *drawn = malloc((size_t)n_out + 1);
    if (!drawn) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    choose_curves(roles, forcing_dof, dofs, n_out, drawn);
    int any_rotation = 0;
    for (int k = 0; k < n_out && rotation; k++)
        any_rotation |= drawn[k] && rotation[k];
    size_t cap = 4096 + (size_t)(n_out + 2 * MODES_SHOWN) * 256;
    char *body = malloc(cap);
    if (!body) {
        free(drawn);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    size_t len = (size_t)snprintf(body, cap,
                                  "set datafile separator ','\n"
                                  "set title 'True assembly: response to %s (analytic)'\n"
                                  "set xlabel 'Forcing frequency (Hz)'\n"
                                  "set ylabel 'Displacement amplitude (m)'\n"
                                  "set logscale y\n"
                                  "set format y '10^{%%L}'\n"
                                  "set grid\n"
                                  "set lmargin at screen 0.08\n"
                                  "set rmargin at screen %.2f\n"
                                  "set key at screen %.2f, graph 1 left top Left reverse "
                                  "samplen 2\n",
                                  forcing, any_rotation ? 0.70 : 0.76, any_rotation ? 0.78 : 0.77);
    if (any_rotation && len < cap)
        len += (size_t)snprintf(body + len, cap - len,
                                "set y2label 'Rotation amplitude (rad)'\nset logscale y2\n"
                                "set format y2 '10^{%%L}'\nset y2tics\nset ytics nomirror\n");
    for (int r = 0, shown = 0; r < n_modes && shown < MODES_SHOWN && len < cap; r++) {
        if (mode_hz[r] < f_lo || mode_hz[r] > f_hi) continue;
        shown++;
        /* labelled at the foot of the line, where every curve is far from it (at a mode the
         * responses peak); upright text, so that close modes do not overwrite each other */
        len += (size_t)snprintf(body + len, cap - len,
                                "set arrow from %.6g, graph 0 to %.6g, graph 1 nohead dt 3 lc "
                                "rgb 'gray50'\n"
                                "set label 'mode %d: %.4f Hz' at first %.6g, graph 0.03 left "
                                "rotate by 90 offset -0.5,0 font ',9' tc rgb 'gray30' front\n",
                                mode_hz[r], mode_hz[r], r + 1, mode_hz[r], mode_hz[r]);
    }
    if (len < cap) len += (size_t)snprintf(body + len, cap - len, "plot ");
    for (int k = 0, first = 1; k < n_out && len < cap; k++) {
        if (!drawn[k]) continue;
        int i = dofs[k];
        const char *role = roles[i] == RTHS_DOF_INTERFACE  ? "interface"
                           : roles[i] == RTHS_DOF_PHYSICAL ? "physical"
                                                           : "numerical";
        int rot = rotation && rotation[k];
        len += (size_t)snprintf(body + len, cap - len,
                                "%s'true_frf.csv' using 1:%d skip 1%s with lines lw %d title "
                                "'%s_{%d} (%s%s)'",
                                first ? "" : ", \\\n     ", 2 + 2 * k, rot ? " axes x1y2" : "",
                                roles[i] == RTHS_DOF_INTERFACE ? 3 : 1, rot ? "θ" : "x", i + 1,
                                role, rot ? ", rad, right" : "");
        first = 0;
    }
    if (len < cap) snprintf(body + len, cap - len, "\n");
    int rc = rths_result_add_figure(res, "true_frf", 1400, 800, body, err);
    free(body);
    free(drawn);
    return rc;
}

/* Column name of table t of r, or -1. */
static int column_index(const rths_result *r, int t, const char *name) {
    for (int c = 0; c < rths_result_columns(r, t); c++)
        if (!strcmp(rths_result_column_name(r, t, c), name)) return c;
    return -1;
}

static void print_modes(rths_result *r, int dofs, int iface_dof, double p, const char *forcing) {
    rths_result_printf(r, "True assembly: %d DoFs, interface DoF %d, p = %g, %s\n", dofs,
                       iface_dof + 1, p, forcing);
    rths_result_printf(r, "%6s %14s %14s %14s\n", "mode", "frequency_hz", "omega_rad_s",
                       "damping_%");
    int t = rths_result_table_index(r, "modes"), n = rths_result_rows(r, t);
    const double *hz = rths_result_column(r, t, column_index(r, t, "frequency_hz"));
    const double *omega = rths_result_column(r, t, column_index(r, t, "omega_rad_s"));
    const double *zeta = rths_result_column(r, t, column_index(r, t, "damping_ratio"));
    for (int k = 0; k < n && k < MODES_SHOWN; k++)
        rths_result_printf(r, "%6d %14.4f %14.3f %14.4f\n", k + 1, hz[k], omega[k], 100 * zeta[k]);
    if (n > MODES_SHOWN)
        rths_result_printf(r, "%6s (%d more modes in modes.csv)\n", "...", n - MODES_SHOWN);
}

/* The interface DoF's peak in true_frf (the first of equal maxima), as the summary has it. */
static void interface_peak(const rths_result *r, int iface_dof, double *amp, double *hz) {
    int t = rths_result_table_index(r, "true_frf"), rows = rths_result_rows(r, t);
    char name[40];
    snprintf(name, sizeof name, "x%d_amplitude_m", iface_dof + 1);
    const double *f = rths_result_column(r, t, 0);
    const double *x = rths_result_column(r, t, column_index(r, t, name));
    *amp = *hz = 0;
    for (int j = 0; x && j < rows; j++)
        if (x[j] > *amp) *amp = x[j], *hz = f[j];
}

/* The sparse path (model.h, "large sparse models"): the model never becomes dense; the lowest
 * modes by shift-invert Lanczos, the FRF from them and the static residual, checked by direct
 * sparse complex solves. */
static int model_sparse(rths_config *cfg, rths_model_choice *choice, double t0,
                        double choice_read_s, const char *config_path, const char *const *overrides,
                        int n_overrides, const char *out_dir, rths_result **out, rths_error *err) {
    rths_sparse_model model = {0};
    rths_result *result = NULL;
    rths_api_sparse_model_timing timing = {0};
    int n_out = 0, *dofs = NULL;
    static const char *const own[] = {"structure", "split", "forcing", "model", NULL};
    int rc = rths_sparse_model_read(cfg, choice, &model, err);
    if (!rc) rc = rths_api_check_config(cfg, own, err);
    if (!rc)
        rc = rths_api_model_compute_sparse(&model, choice, choice_read_s, config_path, overrides,
                                           n_overrides, &result, &timing, err);
    if (!rc && !(dofs = rths_sparse_model_output_dofs(&model, &n_out)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    char forcing[96];
    if (!rc) {
        rths_sparse_model_forcing_text(&model, forcing, sizeof forcing);
        rths_result_printf(result, "Solver: sparse (%s)\n", choice->reason);
        print_modes(result, model.n, model.int_dofs[0], model.mass_ratio, forcing);
        rths_result_log(result, "solver: sparse, because %s", choice->reason);
    }
    double peak_amp = 0, peak_hz = 0;
    if (!rc) {
        int modes = rths_result_table_index(result, "modes");
        int frf = rths_result_table_index(result, "true_frf");
        const double *f = rths_result_column(result, frf, 0);
        interface_peak(result, model.int_dofs[0], &peak_amp, &peak_hz);
        rc =
            plot_frf(result, model.roles, forcing, model.base_excitation ? -1 : model.forcing_dof,
                     rths_result_column(result, modes, column_index(result, modes, "frequency_hz")),
                     rths_result_rows(result, modes), dofs, n_out, NULL, f[0],
                     f[rths_result_rows(result, frf) - 1], err);
    }
    if (!rc) {
        char check[200] = "no direct check (model.frf.check_points: 0)";
        if (timing.frf_checks)
            snprintf(check, sizeof check,
                     "%d direct sparse complex solve%s: largest relative difference %.3g (at "
                     "%.4f Hz)",
                     timing.frf_checks, timing.frf_checks > 1 ? "s" : "",
                     timing.frf_check_max_error, timing.frf_check_worst_hz);
        else if (model.frf_direct)
            snprintf(check, sizeof check, "every point a direct solve");
        double total = rths_monotonic_s() - t0;
        rths_result_printf(result,
                           "Modes: %d lowest (ARPACK shift-invert Lanczos over MUMPS LDL^T, %s "
                           "ordering); largest relative residual ||K phi - lambda M phi|| / ||K "
                           "phi|| %.2g; Sturm count below %.6g Hz: %d\n",
                           timing.modes, timing.ordering, timing.modes_max_residual,
                           sqrt(timing.sturm_shift) / (2 * M_PI), timing.sturm_below);
        rths_result_printf(result, "FRF: %s, %d frequencies; %s\n", timing.frf_method,
                           timing.frf_points, check);
        if (!model.frf_direct && timing.frf_end_hz > timing.highest_mode_hz) {
            /* modes above the highest computed one but inside the range are left out */
            rths_result_printf(result,
                               "Warning: the FRF range ends at %g Hz, above the highest mode "
                               "computed (%.4f Hz): the modal FRF leaves out any mode between; "
                               "raise model.modes, drop it (every mode below 1.5 x "
                               "model.frf.end_hz is then computed) or lower model.frf.end_hz\n",
                               timing.frf_end_hz, timing.highest_mode_hz);
            rths_result_log(result,
                            "warning: FRF range ends at %g Hz, above the highest mode computed "
                            "(%.6g Hz)",
                            timing.frf_end_hz, timing.highest_mode_hz);
        }
        rths_result_printf(result,
                           "Interface (DoF %d) peak: %.4g m at %.4f Hz; %d frequencies in "
                           "%s/true_frf.csv\n",
                           model.int_dofs[0] + 1, peak_amp, peak_hz, timing.frf_points, out_dir);
        rths_result_printf(result,
                           "Time: read %.2f s, order %.2f s, factor %.2f s, eigen %.2f s, checks "
                           "%.2f s, FRF %.2f s, FRF check %.2f s; total %.2f s; peak memory %.0f "
                           "MB\n",
                           timing.read_s, timing.order_s, timing.factor_s, timing.eigen_s,
                           timing.check_s, timing.frf_s, timing.frf_check_s, total,
                           timing.peak_memory_mb);
        rths_result_log(result,
                        "modes: %d lowest, %s ordering, %ld factor entries, largest relative "
                        "residual %.3g, Sturm count %d below %.9g rad^2/s^2, modal damping "
                        "coupling %.3g",
                        timing.modes, timing.ordering, timing.factor_entries,
                        timing.modes_max_residual, timing.sturm_below, timing.sturm_shift,
                        timing.damping_coupling);
        rths_result_log(result, "FRF: %s at %d frequencies with %d DoFs; %s", timing.frf_method,
                        timing.frf_points, timing.frf_dofs, check);
        rths_result_log(result,
                        "timing: %d DoFs; read %.3f s, order %.3f s, factor %.3f s, eigen %.3f s, "
                        "checks %.3f s, FRF %.3f s, FRF check %.3f s; total %.3f s; peak memory "
                        "%.1f MB",
                        model.n, timing.read_s, timing.order_s, timing.factor_s, timing.eigen_s,
                        timing.check_s, timing.frf_s, timing.frf_check_s, total,
                        rths_peak_memory_mb());
    }
    free(dofs);
    rths_sparse_model_free(&model);
    if (rc) {
        rths_result_free(result);
        return rc;
    }
    *out = result;
    return RTHS_OK;
}

int rths_api_model_run(rths_api_command_config *cc, const char *out_dir, rths_result **out,
                       rths_error *err) {
    *out = NULL;
    if (!cc || cc->has_setup)
        return rths_error_set(err, RTHS_EINPUT,
                              "rths_api_model_run needs the configuration without the setup");
    rths_config *cfg = cc->config;
    const char *config_path = cc->path;
    const char *const *overrides = (const char *const *)cc->overrides;
    int n_overrides = cc->n_overrides;
    rths_setup setup = {0};
    rths_result *result = NULL;
    rths_api_model_timing timing = {0};
    rths_model_choice choice = {0};
    int n_out = 0, *dofs = NULL;
    double t0 = rths_monotonic_s();
    int rc = rths_model_choose_solver(cfg, &choice, err);
    double t_choice = rths_monotonic_s();
    if (!rc && choice.solver == RTHS_MODEL_SOLVER_SPARSE) {
        rc = model_sparse(cfg, &choice, t0, t_choice - t0, config_path, overrides, n_overrides,
                          out_dir, out, err);
        rths_model_choice_free(&choice);
        return rc;
    }
    /* a sparse model must never reach rths_setup_read, which forms dense matrices */
    if (!rc) rc = rths_setup_read(cfg, &setup, err);
    if (rc) {
        rths_model_choice_free(&choice);
        return rc;
    }
    char why[sizeof choice.reason];
    snprintf(why, sizeof why, "%s", choice.reason);
    rths_model_choice_dense(&setup.assembly, why, &choice);
    double t_read = rths_monotonic_s();
    static const char *const own[] = {"structure", "split", "forcing", "model", NULL};
    rc = rths_api_check_config(cfg, own, err);
    if (!rc)
        rc = rths_api_model_compute(&setup, config_path, overrides, n_overrides, &result, &timing,
                                    err);
    if (!rc && !(dofs = rths_setup_output_dofs(&setup, &n_out)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    char forcing[96];
    rths_setup_forcing_text(&setup, forcing, sizeof forcing);
    if (!rc) {
        rths_result_printf(result, "Solver: %s (%s)\n", rths_model_solver_name(choice.solver),
                           choice.reason);
        rths_result_log(result, "solver: %s, because %s", rths_model_solver_name(choice.solver),
                        choice.reason);
        print_modes(result, setup.assembly.n, setup.split.int_dofs[0], setup.split.mass_ratio,
                    forcing);
    }
    double peak_amp = 0, peak_hz = 0;
    if (!rc) {
        int modes = rths_result_table_index(result, "modes");
        int frf = rths_result_table_index(result, "true_frf");
        const double *f = rths_result_column(result, frf, 0);
        interface_peak(result, setup.split.int_dofs[0], &peak_amp, &peak_hz);
        char *rotation = malloc((size_t)n_out + 1);
        for (int k = 0; rotation && k < n_out; k++)
            rotation[k] = (char)rths_setup_dof_is_rotation(&setup, dofs[k]);
        rc = rotation ? plot_frf(result, setup.roles, forcing,
                                 setup.base_excitation ? -1 : setup.forcing_dof,
                                 rths_result_column(result, modes,
                                                    column_index(result, modes, "frequency_hz")),
                                 rths_result_rows(result, modes), dofs, n_out, rotation, f[0],
                                 f[rths_result_rows(result, frf) - 1], err)
                      : rths_error_set(err, RTHS_EFAIL, "out of memory");
        free(rotation);
    }
    if (!rc) {
        rths_result_printf(result,
                           "Interface (DoF %d) peak: %.4g m at %.4f Hz; %d frequencies in "
                           "%s/true_frf.csv\n",
                           setup.split.int_dofs[0] + 1, peak_amp, peak_hz, timing.frf_points,
                           out_dir);
        rths_result_log(result,
                        "timing: %d DoFs; reading the configuration %.3f s, modes (%s) %.3f s, "
                        "FRF preparation (%s) %.3f s, FRF at %d frequencies with %d DoFs %.3f s; "
                        "total %.3f s; peak memory %.1f MB",
                        setup.assembly.n, t_read - t0, timing.modes_method, timing.modes_s,
                        timing.frf_method, timing.frf_prepare_s, timing.frf_points, timing.frf_dofs,
                        timing.frf_s, rths_monotonic_s() - t0, rths_peak_memory_mb());
    }
    free(dofs);
    rths_model_choice_free(&choice);
    rths_setup_free(&setup);
    if (rc) {
        rths_result_free(result);
        return rc;
    }
    *out = result;
    return RTHS_OK;
}
