/* rths_api_model: modes and analytic FRF of the true assembly as tables, the same numbers as
 * `rths model` writes to modes.csv and true_frf.csv. */
#include "api/api_internal.h"

#include <complex.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Column c of a table being filled: a block of rows doubles per column. */
#define COL(block, rows, c) ((block) + (size_t)(c) * (size_t)(rows))

static int modes_table(rths_result *r, const rths_modes *m, rths_error *err) {
    int n = m->n, cols = 4 + n;
    const char **names = calloc((size_t)cols, sizeof *names);
    char(*phi)[32] = calloc((size_t)n + 1, sizeof *phi);
    const double **data = calloc((size_t)cols, sizeof *data);
    double *index = calloc((size_t)n + 1, sizeof *index);
    int rc =
        names && phi && data && index ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        static const char *const fixed[4] = {"mode", "frequency_hz", "omega_rad_s",
                                             "damping_ratio"};
        for (int i = 0; i < 4; i++)
            names[i] = fixed[i];
        for (int r2 = 0; r2 < n; r2++)
            index[r2] = r2 + 1;
        data[0] = index;
        data[1] = m->frequency_hz;
        data[2] = m->omega_rad_s;
        data[3] = m->damping_ratio;
        /* phi<i>: DoF i of every mode, i.e. row i of the shape matrix */
        for (int i = 0; i < n; i++) {
            snprintf(phi[i], sizeof phi[i], "phi%d_per_sqrt_kg", i + 1);
            names[4 + i] = phi[i];
        }
    }
    double *rows_of_shapes = rc ? NULL : calloc((size_t)n * n + 1, sizeof *rows_of_shapes);
    if (!rc && !rows_of_shapes) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < n && !rc; i++) {
        for (int mode = 0; mode < n; mode++)
            COL(rows_of_shapes, n, i)[mode] = RTHS_AT(m->shapes, n, i, mode);
        data[4 + i] = COL(rows_of_shapes, n, i);
    }
    if (!rc) rc = rths_result_add_columns(r, "modes", n, cols, names, data, err);
    free(rows_of_shapes);
    free(names);
    free(phi);
    free(data);
    free(index);
    return rc;
}

/* The same DoFs, solver and numbers as `rths model`'s true_frf.csv (rths_frf_sweep). */
static int frf_table(rths_result *r, const rths_setup *s, const rths_modes *m, const double *freqs,
                     int count, double *peak_amp, double *peak_hz, rths_error *err) {
    int n_out = 0;
    int *dofs = rths_setup_output_dofs(s, &n_out);
    int cols = 1 + 2 * n_out;
    const char **names = calloc((size_t)cols, sizeof *names);
    char(*text)[40] = calloc((size_t)(2 * n_out) + 1, sizeof *text);
    const double **data = calloc((size_t)cols, sizeof *data);
    double *block = calloc((size_t)cols * (size_t)count + 1, sizeof *block);
    double complex *x = calloc((size_t)n_out + 1, sizeof *x);
    rths_frf_sweep *sweep = NULL;
    int rc = dofs && names && text && data && block && x
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_frf_sweep_create(&s->assembly, m, s->force, n_out, dofs, &sweep, err);
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
    rths_frf_sweep_destroy(sweep);
    free(dofs);
    free(names);
    free(text);
    free(data);
    free(block);
    free(x);
    return rc;
}

static struct json_object *model_summary(const rths_setup *s, const rths_modes *m, int points,
                                         double peak_amp, double peak_hz) {
    json_object *root = rths_json_summary_new("model");
    if (root) rths_model_summary_add(root, s, m, points, peak_amp, peak_hz);
    return root;
}

int rths_api_model(const rths_api_config *cfg, const char *out_dir, rths_result **out,
                   rths_error *err) {
    *out = NULL;
    if (!cfg) return rths_error_set(err, RTHS_EINPUT, "no configuration given");
    static const char *const own[] = {"structure", "split", "forcing", "model", NULL};
    rths_config *c;
    rths_setup setup;
    rths_modes modes = {0};
    rths_result *r = NULL;
    double *freqs = NULL, peak_amp = 0, peak_hz = 0;
    int count = 0;
    int rc = rths_api_load(cfg, &c, &setup, err);
    if (rc) return rc;
    rc = rths_api_check_config(c, own, err);
    if (!rc) rc = rths_modal_analysis(&setup.assembly, &modes, err);
    if (!rc)
        rc = rths_frf_grid(&modes, setup.frf_start_hz, setup.frf_end_hz, setup.frf_points, &freqs,
                           &count, err);
    if (!rc) rc = rths_result_new(&r, err);
    if (!rc) rc = modes_table(r, &modes, err);
    if (!rc) rc = frf_table(r, &setup, &modes, freqs, count, &peak_amp, &peak_hz, err);
    if (!rc)
        rc = rths_result_set_summary(r, model_summary(&setup, &modes, count, peak_amp, peak_hz),
                                     err);
    if (!rc && out_dir) rc = rths_result_write_folder(r, c, out_dir, "model", err);
    free(freqs);
    rths_modes_free(&modes);
    rths_api_unload(c, &setup);
    if (rc) {
        rths_result_free(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}
