/* `rths model` on the sparse path (api_model_sparse.h): the same tables as rths_api_model_compute
 * ("modes" with the lowest modes, "true_frf" at the output DoFs) from a model kept sparse. */
#include "api/api_model_sparse.h"
#include "api/api_internal.h"

#include <complex.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define COL(block, rows, c) ((block) + (size_t)(c) * (size_t)(rows))

static int modes_table(rths_result *r, const rths_sparse_modes *m, const int *dofs, int n_out,
                       rths_error *err) {
    int count = m->count, cols = 4 + n_out, n = m->n;
    const char **names = calloc((size_t)cols, sizeof *names);
    char(*phi)[32] = calloc((size_t)n_out + 1, sizeof *phi);
    const double **data = calloc((size_t)cols, sizeof *data);
    double *index = calloc((size_t)count + 1, sizeof *index);
    double *shapes = calloc((size_t)count * (size_t)n_out + 1, sizeof *shapes);
    int rc = names && phi && data && index && shapes
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        static const char *const fixed[4] = {"mode", "frequency_hz", "omega_rad_s",
                                             "damping_ratio"};
        for (int i = 0; i < 4; i++)
            names[i] = fixed[i];
        for (int mode = 0; mode < count; mode++)
            index[mode] = mode + 1;
        data[0] = index;
        data[1] = m->frequency_hz;
        data[2] = m->omega_rad_s;
        data[3] = m->damping_ratio;
        for (int i = 0; i < n_out; i++) {
            snprintf(phi[i], sizeof phi[i], "phi%d_per_sqrt_kg", dofs[i] + 1);
            names[4 + i] = phi[i];
            for (int mode = 0; mode < count; mode++)
                COL(shapes, count, i)[mode] = m->shapes[(size_t)dofs[i] + (size_t)mode * n];
            data[4 + i] = COL(shapes, count, i);
        }
        rc = rths_result_add_columns(r, "modes", count, cols, names, data, err);
    }
    free(shapes);
    free(names);
    free(phi);
    free(data);
    free(index);
    return rc;
}

/* Golden-section refinement of the interface peak between the grid neighbours of the grid's
 * maximum, as api_model.c's refine_peak (the modal FRF costs O(modes x DoFs out) per call). */
static int refine_peak(rths_sparse_frf *sweep, int iface, const double *freqs, int count,
                       double *peak_amp, double *peak_hz, double complex *x, rths_error *err) {
    int at = 0;
    while (at < count && freqs[at] != *peak_hz)
        at++;
    if (count < 3 || at == count) return RTHS_OK;
    double lo = freqs[at > 0 ? at - 1 : 0], hi = freqs[at < count - 1 ? at + 1 : count - 1];
    const double g = 0.5 * (sqrt(5.0) - 1.0);
    double f1 = hi - g * (hi - lo), f2 = lo + g * (hi - lo), a1, a2;
    int rc = rths_sparse_frf_eval(sweep, 2 * M_PI * f1, x, err);
    a1 = cabs(x[iface]);
    if (!rc) rc = rths_sparse_frf_eval(sweep, 2 * M_PI * f2, x, err);
    a2 = cabs(x[iface]);
    while (!rc && hi - lo > 1e-10 * hi) {
        if (a1 > a2) {
            hi = f2, f2 = f1, a2 = a1, f1 = hi - g * (hi - lo);
            rc = rths_sparse_frf_eval(sweep, 2 * M_PI * f1, x, err);
            a1 = cabs(x[iface]);
        } else {
            lo = f1, f1 = f2, a1 = a2, f2 = lo + g * (hi - lo);
            rc = rths_sparse_frf_eval(sweep, 2 * M_PI * f2, x, err);
            a2 = cabs(x[iface]);
        }
    }
    if (rc) return rc;
    double best_amp = a1 > a2 ? a1 : a2, best_hz = a1 > a2 ? f1 : f2;
    if (best_amp > *peak_amp) *peak_amp = best_amp, *peak_hz = best_hz;
    return RTHS_OK;
}

static int frf_table(rths_result *r, const rths_sparse_model *m, rths_sparse_frf *sweep,
                     const int *dofs, int n_out, const double *freqs, int count, double *peak_amp,
                     double *peak_hz, rths_error *err) {
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
        if (dofs[i] == m->int_dofs[0]) iface = i;
    *peak_amp = *peak_hz = 0;
    for (int j = 0; j < count && !rc; j++) {
        rc = rths_sparse_frf_eval(sweep, 2 * M_PI * freqs[j], x, err);
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

/* The modal FRF checked by direct sparse complex solves: at the interface peak, then at grid
 * frequencies spread over the band. Largest relative difference over the output DoFs. */
static int check_frf(const rths_sparse_model *m, rths_sparse_frf *sweep, int n_out,
                     const double *freqs, int count, double peak_hz,
                     rths_api_sparse_model_timing *t, rths_error *err) {
    int checks = m->frf_direct ? 0 : m->frf_check_points;
    double complex *a = calloc((size_t)n_out + 1, sizeof *a),
                   *b = calloc((size_t)n_out + 1, sizeof *b);
    int rc = a && b ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int c = 0; c < checks && !rc; c++) {
        double hz = c == 0 ? peak_hz : freqs[(size_t)((long)c * (count - 1) / checks)];
        if (!(hz > 0)) continue;
        rc = rths_sparse_frf_eval(sweep, 2 * M_PI * hz, a, err);
        if (!rc) rc = rths_sparse_frf_direct(sweep, 2 * M_PI * hz, b, err);
        double diff = 0, scale = 0;
        for (int o = 0; o < n_out && !rc; o++) {
            if (cabs(a[o] - b[o]) > diff) diff = cabs(a[o] - b[o]);
            if (cabs(b[o]) > scale) scale = cabs(b[o]);
        }
        double rel = scale > 0 ? diff / scale : diff;
        if (!rc && (t->frf_checks == 0 || rel > t->frf_check_max_error))
            t->frf_check_max_error = rel, t->frf_check_worst_hz = hz;
        if (!rc) t->frf_checks++;
    }
    free(a);
    free(b);
    return rc;
}

static struct json_object *summary(const rths_sparse_model *m, const rths_sparse_modes *modes,
                                   const rths_model_choice *choice,
                                   const rths_api_sparse_model_timing *t, double peak_amp,
                                   double peak_hz, const char *config_path,
                                   const char *const *overrides, int n_overrides) {
    json_object *root = rths_api_summary_new("model", config_path, overrides, n_overrides);
    if (!root) return NULL;
    json_object *list = json_object_new_array();
    for (int r = 0; r < modes->count; r++) {
        json_object *mode = json_object_new_object();
        json_object_object_add(mode, "mode", json_object_new_int(r + 1));
        json_object_object_add(mode, "frequency_hz",
                               json_object_new_double(modes->frequency_hz[r]));
        json_object_object_add(mode, "damping_ratio",
                               json_object_new_double(modes->damping_ratio[r]));
        json_object_array_add(list, mode);
    }
    json_object_object_add(root, "config", json_object_new_string("matrices"));
    json_object_object_add(root, "dofs", json_object_new_int(m->n));
    json_object_object_add(root, "mass_ratio", json_object_new_double(m->mass_ratio));
    json_object_object_add(root, "interface_dof", json_object_new_int(m->int_dofs[0] + 1));
    if (m->base_excitation) {
        json_object_object_add(root, "excitation", json_object_new_string("base"));
        json_object_object_add(root, "base_acceleration_amplitude_m_s2",
                               json_object_new_double(m->forcing_amplitude_n));
    } else {
        json_object_object_add(root, "excitation", json_object_new_string("force"));
        json_object_object_add(root, "forcing_dof", json_object_new_int(m->forcing_dof + 1));
        json_object_object_add(root, "forcing_amplitude_n",
                               json_object_new_double(m->forcing_amplitude_n));
    }
    json_object_object_add(root, "modes", list);
    json_object_object_add(root, "frf_points", json_object_new_int(t->frf_points));
    json_object_object_add(root, "interface_peak_amplitude_m", json_object_new_double(peak_amp));
    json_object_object_add(root, "interface_peak_frequency_hz", json_object_new_double(peak_hz));
    json_object *solver = json_object_new_object();
    json_object_object_add(solver, "path", json_object_new_string("sparse"));
    json_object_object_add(solver, "reason", json_object_new_string(choice->reason));
    json_object_object_add(solver, "half_bandwidth", json_object_new_int(choice->half_bandwidth));
    json_object_object_add(
        solver, "ordering",
        json_object_new_string(rths_sparse_ordering_name(modes->stats.ordering)));
    json_object_object_add(solver, "factor_entries", json_object_new_int64(t->factor_entries));
    json_object_object_add(solver, "modes_max_relative_residual",
                           json_object_new_double(modes->max_residual));
    json_object_object_add(solver, "sturm_count", json_object_new_int(modes->sturm_below));
    json_object_object_add(solver, "sturm_shift_rad2_s2",
                           json_object_new_double(modes->sturm_shift));
    json_object_object_add(solver, "modal_damping_coupling_max",
                           json_object_new_double(modes->max_damping_coupling));
    json_object_object_add(solver, "frf_method", json_object_new_string(t->frf_method));
    json_object_object_add(solver, "frf_direct_checks", json_object_new_int(t->frf_checks));
    if (t->frf_checks) {
        json_object_object_add(solver, "frf_check_max_relative_error",
                               json_object_new_double(t->frf_check_max_error));
        json_object_object_add(solver, "frf_check_worst_frequency_hz",
                               json_object_new_double(t->frf_check_worst_hz));
    }
    json_object_object_add(root, "solver", solver);
    json_object *times = json_object_new_object();
    const char *const stage[7] = {"read", "order", "factor", "eigen", "checks", "frf", "frf_check"};
    const double value[7] = {t->read_s,  t->order_s, t->factor_s,   t->eigen_s,
                             t->check_s, t->frf_s,   t->frf_check_s};
    for (int k = 0; k < 7; k++)
        json_object_object_add(times, stage[k], json_object_new_double(value[k]));
    json_object_object_add(root, "timing_s", times);
    json_object_object_add(root, "peak_memory_mb", json_object_new_double(t->peak_memory_mb));
    return root;
}

int rths_api_model_compute_sparse(const rths_sparse_model *m, const rths_model_choice *choice,
                                  double choice_read_s, const char *config_path,
                                  const char *const *overrides, int n_overrides, rths_result **out,
                                  rths_api_sparse_model_timing *timing, rths_error *err) {
    *out = NULL;
    rths_api_sparse_model_timing t = {0};
    rths_sparse_modes modes = {0};
    rths_sparse_frf *sweep = NULL;
    rths_result *r = NULL;
    double *freqs = NULL, peak_amp = 0, peak_hz = 0;
    int count = 0, n_out = 0, *dofs = NULL;
    t.read_s = choice_read_s + m->read_matrices_s;
    int rc = rths_sparse_model_modes(m, &modes, NULL, err);
    if (!rc) {
        t.order_s = modes.stats.analysis_s;
        t.factor_s = modes.stats.factor_s;
        t.eigen_s = modes.stats.lanczos_s;
        t.check_s = modes.check_s;
        t.factor_entries = modes.stats.factor_entries;
        t.modes = modes.count;
        t.modes_max_residual = modes.max_residual;
        t.damping_coupling = modes.max_damping_coupling;
        t.sturm_below = modes.sturm_below;
        t.sturm_shift = modes.sturm_shift;
        snprintf(t.ordering, sizeof t.ordering, "%s",
                 rths_sparse_ordering_name(modes.stats.ordering));
    }
    double t0 = rths_monotonic_s();
    if (!rc) {
        /* the grid over the modes found; by default up to the highest of them: above it the
         * modes not computed would respond dynamically, which the modal FRF leaves out */
        rths_modes view = {.n = modes.count,
                           .omega_rad_s = modes.omega_rad_s,
                           .frequency_hz = modes.frequency_hz,
                           .damping_ratio = modes.damping_ratio};
        double end = m->frf_end_hz > 0 ? m->frf_end_hz : modes.frequency_hz[modes.count - 1];
        t.highest_mode_hz = modes.frequency_hz[modes.count - 1];
        t.frf_end_hz = end;
        rc = rths_frf_grid(&view, m->frf_start_hz, end, m->frf_points, &freqs, &count, err);
    }
    if (!rc && !(dofs = rths_sparse_model_output_dofs(m, &n_out)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_sparse_frf_create(m, &modes, n_out, dofs, &sweep, err);
    snprintf(t.frf_method, sizeof t.frf_method, "%s",
             m->frf_direct ? "direct: sparse complex LDL^T per frequency"
                           : "modal: lowest modes + residual of the rest (2 moments)");
    if (!rc) rc = rths_result_new(&r, err);
    if (!rc) rc = modes_table(r, &modes, dofs, n_out, err);
    if (!rc) rc = frf_table(r, m, sweep, dofs, n_out, freqs, count, &peak_amp, &peak_hz, err);
    t.frf_s = rths_monotonic_s() - t0;
    t.frf_points = count;
    t.frf_dofs = n_out;
    double t1 = rths_monotonic_s();
    if (!rc) rc = check_frf(m, sweep, n_out, freqs, count, peak_hz, &t, err);
    t.frf_check_s = rths_monotonic_s() - t1;
    t.peak_memory_mb = rths_peak_memory_mb();
    if (!rc)
        rc = rths_result_set_summary(
            r,
            summary(m, &modes, choice, &t, peak_amp, peak_hz, config_path, overrides, n_overrides),
            err);
    free(freqs);
    free(dofs);
    rths_sparse_frf_destroy(sweep);
    if (timing) *timing = t;
    rths_sparse_modes_free(&modes);
    if (rc) {
        rths_result_free(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}
