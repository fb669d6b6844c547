/* rths_api_model: modes and analytic FRF of the true assembly as tables. The one implementation of
 * `rths model`'s tables and summary: the command's rths_api_model_run calls rths_api_model_compute
 * and writes the result with rths_api_result_write, as rths_api_model does. */
#include "api/api_internal.h"
#include "api/api_model_sparse.h"

#include <complex.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Column c of a table being filled: a block of rows doubles per column. */
#define COL(block, rows, c) ((block) + (size_t)(c) * (size_t)(rows))

/* modes.csv: every mode, the shape at the output DoFs (all of them up to 64 DoFs; above, the
 * physical substructure's and the forcing DoF: rths_setup_output_dofs). */
static int modes_table(rths_result *r, const rths_modes *m, const int *dofs, int n_out,
                       rths_error *err) {
    int n = m->n, cols = 4 + n_out;
    const char **names = calloc((size_t)cols, sizeof *names);
    char(*phi)[32] = calloc((size_t)n_out + 1, sizeof *phi);
    const double **data = calloc((size_t)cols, sizeof *data);
    double *index = calloc((size_t)n + 1, sizeof *index);
    double *shapes = calloc((size_t)n * (size_t)n_out + 1, sizeof *shapes);
    int rc = names && phi && data && index && shapes
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        static const char *const fixed[4] = {"mode", "frequency_hz", "omega_rad_s",
                                             "damping_ratio"};
        for (int i = 0; i < 4; i++)
            names[i] = fixed[i];
        for (int mode = 0; mode < n; mode++)
            index[mode] = mode + 1;
        data[0] = index;
        data[1] = m->frequency_hz;
        data[2] = m->omega_rad_s;
        data[3] = m->damping_ratio;
        /* phi<i>: DoF i of every mode, i.e. row i of the shape matrix */
        for (int i = 0; i < n_out; i++) {
            snprintf(phi[i], sizeof phi[i], "phi%d_per_sqrt_kg", dofs[i] + 1);
            names[4 + i] = phi[i];
            for (int mode = 0; mode < n; mode++)
                COL(shapes, n, i)[mode] = RTHS_AT(m->shapes, n, dofs[i], mode);
            data[4 + i] = COL(shapes, n, i);
        }
        rc = rths_result_add_columns(r, "modes", n, cols, names, data, err);
    }
    free(shapes);
    free(names);
    free(phi);
    free(data);
    free(index);
    return rc;
}

/* The grid's largest amplitude lies up to half a grid step from the true peak: 0.06 % low on the
 * seed's second mode. Golden-section search for the maximum of |x| between the grid neighbours
 * of the grid's maximum (one peak there: the grid resolves every mode), to a bracket of 1e-10 of
 * the frequency; the result is never below the grid's own maximum. */
static int refine_peak(rths_frf_sweep *sweep, int iface, const double *freqs, int count,
                       double *peak_amp, double *peak_hz, double complex *x, rths_error *err) {
    int at = 0;
    while (at < count && freqs[at] != *peak_hz)
        at++;
    if (count < 3 || at == count) return RTHS_OK;
    double lo = freqs[at > 0 ? at - 1 : 0], hi = freqs[at < count - 1 ? at + 1 : count - 1];
    const double g = 0.5 * (sqrt(5.0) - 1.0);
    double f1 = hi - g * (hi - lo), f2 = lo + g * (hi - lo), a1, a2;
    int rc = rths_frf_sweep_eval(sweep, 2 * M_PI * f1, x, err);
    a1 = cabs(x[iface]);
    if (!rc) rc = rths_frf_sweep_eval(sweep, 2 * M_PI * f2, x, err);
    a2 = cabs(x[iface]);
    while (!rc && hi - lo > 1e-10 * hi) {
        if (a1 > a2) {
            hi = f2, f2 = f1, a2 = a1, f1 = hi - g * (hi - lo);
            rc = rths_frf_sweep_eval(sweep, 2 * M_PI * f1, x, err);
            a1 = cabs(x[iface]);
        } else {
            lo = f1, f1 = f2, a1 = a2, f2 = lo + g * (hi - lo);
            rc = rths_frf_sweep_eval(sweep, 2 * M_PI * f2, x, err);
            a2 = cabs(x[iface]);
        }
    }
    if (rc) return rc;
    double best_amp = a1 > a2 ? a1 : a2, best_hz = a1 > a2 ? f1 : f2;
    if (best_amp > *peak_amp) *peak_amp = best_amp, *peak_hz = best_hz;
    return RTHS_OK;
}

/* true_frf.csv: the analytic FRF at the output DoFs on the grid freqs (rths_frf_sweep); the
 * interface DoF's peak for the summary. */
static int frf_table(rths_result *r, const rths_setup *s, rths_frf_sweep *sweep, const int *dofs,
                     int n_out, const double *freqs, int count, double *peak_amp, double *peak_hz,
                     rths_error *err) {
    int cols = 1 + 2 * n_out;
    const char **names = calloc((size_t)cols, sizeof *names);
    char(*text)[40] = calloc((size_t)(2 * n_out) + 1, sizeof *text);
    const double **data = calloc((size_t)cols, sizeof *data);
    double *block = calloc((size_t)cols * (size_t)count + 1, sizeof *block);
    double complex *x = calloc((size_t)n_out + 1, sizeof *x);
    int rc = names && text && data && block && x ? RTHS_OK
                                                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    int iface = 0;
    for (int i = 0; i < n_out; i++)
        if (dofs[i] == s->split.int_dofs[0]) iface = i;
    *peak_amp = *peak_hz = 0;
    for (int j = 0; j < count && !rc; j++) {
        rc = rths_frf_sweep_eval(sweep, 2 * M_PI * freqs[j], x, err);
        COL(block, count, 0)[j] = freqs[j];
        for (int i = 0; i < n_out && !rc; i++) {
            COL(block, count, 1 + 2 * i)[j] = cabs(x[i]);
            COL(block, count, 2 + 2 * i)[j] = carg(x[i]);
        }
        if (!rc && cabs(x[iface]) > *peak_amp) *peak_amp = cabs(x[iface]), *peak_hz = freqs[j];
    }
    if (!rc) rc = refine_peak(sweep, iface, freqs, count, peak_amp, peak_hz, x, err);
    if (!rc) {
        names[0] = "frequency_hz";
        for (int i = 0; i < n_out; i++) {
            snprintf(text[2 * i], sizeof text[0], "x%d_amplitude_m", dofs[i] + 1);
            snprintf(text[2 * i + 1], sizeof text[0], "x%d_phase_rad", dofs[i] + 1);
            names[1 + 2 * i] = text[2 * i];
            names[2 + 2 * i] = text[2 * i + 1];
        }
        for (int c = 0; c < cols; c++)
            data[c] = COL(block, count, c);
        rc = rths_result_add_columns(r, "true_frf", count, cols, names, data, err);
    }
    free(names);
    free(text);
    free(data);
    free(block);
    free(x);
    return rc;
}

/* The summary every run folder of `rths model` gets: who asked (configuration file, overrides) and
 * the model's facts. */
static struct json_object *model_summary(const rths_setup *s, const rths_modes *m, int points,
                                         double peak_amp, double peak_hz, const char *config_path,
                                         const char *const *overrides, int n_overrides) {
    json_object *root = rths_api_summary_new("model", config_path, overrides, n_overrides);
    if (!root) return NULL;
    rths_model_summary_add(root, s, m, points, peak_amp, peak_hz);
    return root;
}

int rths_api_model_compute(const rths_setup *setup, const char *config_path,
                           const char *const *overrides, int n_overrides, rths_result **out,
                           rths_api_model_timing *timing, rths_error *err) {
    *out = NULL;
    rths_api_model_timing t = {0};
    rths_modes modes = {0};
    rths_frf_sweep *sweep = NULL;
    rths_result *r = NULL;
    double *freqs = NULL, peak_amp = 0, peak_hz = 0;
    int count = 0, n_out = 0, *dofs = NULL;
    double t0 = rths_monotonic_s();
    int rc = rths_modal_analysis(&setup->assembly, &modes, err);
    double t_modes = rths_monotonic_s();
    t.modes_s = t_modes - t0;
    snprintf(t.modes_method, sizeof t.modes_method, "%s",
             rths_assembly_half_bandwidth(&setup->assembly) <= setup->assembly.n / 8
                 ? "banded, dsbgvd"
                 : "dense, dsygvd");
    if (!rc)
        rc = rths_frf_grid(&modes, setup->frf_start_hz, setup->frf_end_hz, setup->frf_points,
                           &freqs, &count, err);
    if (!rc && !(dofs = rths_setup_output_dofs(setup, &n_out)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc)
        rc =
            rths_frf_sweep_create(&setup->assembly, &modes, setup->force, n_out, dofs, &sweep, err);
    double t_prepare = rths_monotonic_s();
    t.frf_prepare_s = t_prepare - t_modes;
    if (!rc)
        snprintf(t.frf_method, sizeof t.frf_method, "%s",
                 rths_frf_method_name(rths_frf_sweep_method(sweep)));
    if (!rc) rc = rths_result_new(&r, err);
    if (!rc) rc = modes_table(r, &modes, dofs, n_out, err);
    if (!rc) rc = frf_table(r, setup, sweep, dofs, n_out, freqs, count, &peak_amp, &peak_hz, err);
    t.frf_s = rths_monotonic_s() - t_prepare;
    t.frf_points = count;
    t.frf_dofs = n_out;
    if (!rc)
        rc = rths_result_set_summary(r,
                                     model_summary(setup, &modes, count, peak_amp, peak_hz,
                                                   config_path, overrides, n_overrides),
                                     err);
    free(freqs);
    free(dofs);
    rths_frf_sweep_destroy(sweep);
    rths_modes_free(&modes);
    if (timing) *timing = t;
    if (rc) {
        rths_result_free(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}

/* rths_api_model on the sparse path (rths_model_choose_solver chose it on c): the structure
 * never reaches rths_setup_read, which forms dense matrices. */
static int api_model_sparse(const rths_api_config *cfg, rths_config *c, rths_model_choice *choice,
                            double choice_read_s, const char *out_dir, rths_result **out,
                            rths_error *err) {
    static const char *const own[] = {"structure", "split", "forcing", "model", NULL};
    rths_sparse_model model;
    rths_result *r = NULL;
    int rc = rths_sparse_model_read(c, choice, &model, err);
    if (rc) return rc;
    rc = rths_api_check_config(c, own, err);
    if (!rc)
        rc = rths_api_model_compute_sparse(&model, choice, choice_read_s, cfg->path,
                                           (const char *const *)cfg->overrides, cfg->n_overrides,
                                           &r, NULL, err);
    rc = rths_api_finish(r, rc, c, out_dir, "model", out, err);
    rths_sparse_model_free(&model);
    return rc;
}

int rths_api_model(const rths_api_config *cfg, const char *out_dir, rths_result **out,
                   rths_error *err) {
    *out = NULL;
    if (!cfg) return rths_error_set(err, RTHS_EINPUT, "no configuration given");
    static const char *const own[] = {"structure", "split", "forcing", "model", NULL};
    rths_config *c;
    rths_setup setup;
    rths_result *r = NULL;
    /* the path first (model.solver, a Matrix Market structure's size and pattern): a sparse
     * model is read without rths_setup_read */
    double t0 = rths_monotonic_s();
    rths_model_choice choice;
    int rc =
        rths_config_load(cfg->path, (const char *const *)cfg->overrides, cfg->n_overrides, &c, err);
    if (rc) return rc;
    rc = rths_model_choose_solver(c, &choice, err);
    if (!rc && choice.solver == RTHS_MODEL_SOLVER_SPARSE)
        rc = api_model_sparse(cfg, c, &choice, rths_monotonic_s() - t0, out_dir, out, err);
    int sparse = !rc && choice.solver == RTHS_MODEL_SOLVER_SPARSE;
    rths_model_choice_free(&choice);
    rths_config_free(c);
    if (rc || sparse) return rc;
    rc = rths_api_load(cfg, &c, &setup, err);
    if (rc) return rc;
    /* model.solver, read on this configuration too so the key check knows it */
    static const char *const solvers[] = {"auto", "dense", "sparse", NULL};
    int asked = 0;
    rc = rths_config_get_choice(c, "model.solver", 0, 0, solvers, &asked, err);
    if (!rc) rc = rths_api_check_config(c, own, err);
    if (!rc)
        rc = rths_api_model_compute(&setup, cfg->path, (const char *const *)cfg->overrides,
                                    cfg->n_overrides, &r, NULL, err);
    rc = rths_api_finish(r, rc, c, out_dir, "model", out, err);
    rths_api_unload(c, &setup);
    return rc;
}
