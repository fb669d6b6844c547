/* The FRF test's tables: frf.csv (run.h's columns and rows, the optional blocks, the receptance)
 * and truth.csv. The Lissajous figure with trace.csv: frf_trace.c; summary.json: frf_summary.c;
 * the other figures: frf_figures.c; modal.csv and frf.uff: frf_modal.c. */
#include "run/frf_internal.h"

#include "run/frf_outputs_internal.h"
#include "run/frf_receptance.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Interface mismatch of harmonic k (m): |phys_k - num_k| as a complex amplitude. */
double frf_harmonic_error(const rths_point *pt, int k) {
    return hypot(pt->sol.eval.phys.a[k] - pt->sol.eval.num.a[k],
                 pt->sol.eval.phys.b[k] - pt->sol.eval.num.b[k]);
}

const char *const rths_run_frf_columns[RTHS_RUN_FRF_COLUMNS] = {"point",
                                                                "frequency_hz",
                                                                "amplitude_m",
                                                                "numerical_amplitude_m",
                                                                "phase_rad",
                                                                "interface_error_m",
                                                                "interface_error_h2_m",
                                                                "interface_error_h3_m",
                                                                "amplitude_h2_m",
                                                                "amplitude_h3_m",
                                                                "target_a1_m",
                                                                "target_b1_m",
                                                                "residual_norm_m",
                                                                "tolerance_m",
                                                                "evaluations",
                                                                "iterations",
                                                                "rig_time_s",
                                                                "converged",
                                                                "fold",
                                                                "segment",
                                                                "amplitude_se_m",
                                                                "measured_amplitude_m",
                                                                "se_honest",
                                                                "stable",
                                                                "late_samples",
                                                                "clipped_demand_samples",
                                                                "saturated_sensor_samples",
                                                                "resumed",
                                                                "below_noise_floor"};

void rths_run_frf_row(const rths_point *pt, double *row) {
    const rths_fourier *ph = &pt->sol.eval.phys, *nu = &pt->sol.eval.num;
    const rths_evaluation *acc = &pt->residual.eval; /* the accepted evaluation */
    const double values[RTHS_RUN_FRF_COLUMNS] = {
        /* amplitude_m: what the strategy reports (the response extrapolated to zero
         * mismatch by default, the measurement for paper); measured_amplitude_m: the
         * measurement */
        pt->index, pt->sol.frequency_hz, pt->sol.amplitude_m, hypot(nu->a[1], nu->b[1]),
        /* x = A cos + B sin = R cos(wt + phi) with phi = atan2(-B, A) */
        atan2(-ph->b[1], ph->a[1]), frf_harmonic_error(pt, 1), frf_harmonic_error(pt, 2),
        frf_harmonic_error(pt, 3), hypot(ph->a[2], ph->b[2]), hypot(ph->a[3], ph->b[3]),
        pt->sol.target_a[0], pt->sol.target_b[0], pt->sol.residual_norm_m, pt->sol.tolerance_m,
        pt->evaluations, pt->iterations, pt->rig_time_s, pt->sol.converged, pt->fold, pt->segment,
        pt->sol.amplitude_se_m, hypot(ph->a[1], ph->b[1]), pt->sol.amplitude_se_honest,
        rths_point_stable(pt),
        /* the tail (run.h) */
        (double)acc->late_samples, (double)acc->clipped_demand_samples,
        (double)acc->saturated_sensor_samples, pt->resumed, pt->sol.below_noise_floor};
    memcpy(row, values, sizeof values);
}

static const char *const dof_column_names[RTHS_MAX_INTERFACE_DOFS][RTHS_RUN_FRF_DOF_COLUMNS] = {
    {"dof1_amplitude_m", "dof1_numerical_amplitude_m", "dof1_phase_rad", "dof1_interface_error_m",
     "dof1_amplitude_se_m"},
    {"dof2_amplitude_m", "dof2_numerical_amplitude_m", "dof2_phase_rad", "dof2_interface_error_m",
     "dof2_amplitude_se_m"},
    {"dof3_amplitude_m", "dof3_numerical_amplitude_m", "dof3_phase_rad", "dof3_interface_error_m",
     "dof3_amplitude_se_m"},
    {"dof4_amplitude_m", "dof4_numerical_amplitude_m", "dof4_phase_rad", "dof4_interface_error_m",
     "dof4_amplitude_se_m"}};

static int dof_columns(int interface_dofs) {
    return interface_dofs > 1 && interface_dofs <= RTHS_MAX_INTERFACE_DOFS ? interface_dofs : 0;
}

int rths_run_frf_column_count(int interface_dofs) {
    return RTHS_RUN_FRF_COLUMNS + RTHS_RUN_FRF_DOF_COLUMNS * dof_columns(interface_dofs);
}

/* Leading columns, the per-DoF block, the tail (run.h). */
const char *rths_run_frf_column_name(int interface_dofs, int i) {
    int count = rths_run_frf_column_count(interface_dofs);
    if (i < 0 || i >= count) return NULL;
    if (i < RTHS_RUN_FRF_LEADING_COLUMNS) return rths_run_frf_columns[i];
    if (i >= count - RTHS_RUN_FRF_TAIL_COLUMNS)
        return rths_run_frf_columns[RTHS_RUN_FRF_COLUMNS - (count - i)];
    i -= RTHS_RUN_FRF_LEADING_COLUMNS;
    return dof_column_names[i / RTHS_RUN_FRF_DOF_COLUMNS][i % RTHS_RUN_FRF_DOF_COLUMNS];
}

void rths_run_frf_row_dofs(const rths_point *pt, int interface_dofs, double *row) {
    rths_run_frf_row(pt, row);
    const rths_solution *s = &pt->sol;
    const rths_evaluation *ev = &s->eval;
    int dofs = dof_columns(interface_dofs), M = s->harmonics, N = dofs ? M / dofs : 0;
    /* the tail moves behind the per-DoF block */
    double tail[RTHS_RUN_FRF_TAIL_COLUMNS];
    memcpy(tail, row + RTHS_RUN_FRF_LEADING_COLUMNS, sizeof tail);
    memcpy(row + RTHS_RUN_FRF_LEADING_COLUMNS + RTHS_RUN_FRF_DOF_COLUMNS * dofs, tail, sizeof tail);
    /* the matched estimate stands for the reported amplitude when the strategy reports it */
    int matched = s->have_matched && s->amplitude_m == s->matched_amplitude_m;
    /* a record carrying another number of DoFs than the split leaves its cells empty, not stale */
    for (int i = 0; i < RTHS_RUN_FRF_DOF_COLUMNS * dofs; i++)
        row[RTHS_RUN_FRF_LEADING_COLUMNS + i] = NAN;
    for (int d = 0; d < dofs && ev->interface_dofs == dofs; d++) {
        const rths_fourier *ph = &ev->phys_dof[d], *nu = &ev->num_dof[d];
        double *r = row + RTHS_RUN_FRF_LEADING_COLUMNS + RTHS_RUN_FRF_DOF_COLUMNS * d;
        int j = d * N; /* DoF d's fundamental among the solution's pairs (iterate.h) */
        r[0] = matched ? hypot(s->matched_a[j], s->matched_b[j]) : hypot(ph->a[1], ph->b[1]);
        r[1] = hypot(nu->a[1], nu->b[1]);
        r[2] = atan2(-ph->b[1], ph->a[1]);
        r[3] = hypot(ph->a[1] - nu->a[1], ph->b[1] - nu->b[1]);
        /* the standard error of r[0], with every known source (iterate.h, rths_solution) */
        r[4] = s->interface_dofs == dofs ? s->dof_amplitude_se_m[d] : NAN;
    }
}

/* Columns that options add after the fixed ones (each block only when its option is on, so a
 * run without it writes frf.csv as before, byte for byte). */
static const char *const floquet_columns[] = {"floquet_max_abs_experimental", "floquet_max_abs_se",
                                              "stable_experimental", "floquet_trustworthy"};
enum { FRF_FLOQUET_COLUMNS = 4, FRF_EXTRA_COLUMNS = FRF_FLOQUET_COLUMNS };

/* The experimental Floquet columns of point i: NaN where it was not measured; the label 1
 * stable, 0 unstable, -1 undetermined (floquet.h). */
static void floquet_row(const frf_state *run, int i, double *out) {
    const frf_floquet_point *f = frf_measured_floquet_point(run, i);
    out[0] = f ? f->max_abs : NAN;
    out[1] = f ? f->max_abs_se : NAN;
    out[2] = f ? f->label : NAN;
    out[3] = f ? f->trustworthy : NAN;
}

/* The leading and per-DoF columns, the optional blocks, the tail (run.h), then the receptance
 * (frf_receptance.h): the receptance came last, after the tail, so every column before it keeps
 * its position (gnuplot scripts and tests address frf.csv's columns by number). */
int frf_write_frf_csv(rths_report *rep, const frf_state *run, rths_error *err) {
    char *path = rths_report_path(rep, "frf.csv");
    rths_csv *csv = NULL;
    int dofs = run->setup->split.n_int, fixed = rths_run_frf_column_count(dofs);
    int head = fixed - RTHS_RUN_FRF_TAIL_COLUMNS, columns = head;
    frf_receptance_columns rec;
    frf_receptance_columns_init(&rec, run->setup);
    const char *names[RTHS_RUN_FRF_MAX_COLUMNS + FRF_EXTRA_COLUMNS + FRF_DOF_MAX_COLUMNS +
                      FRF_RECEPTANCE_MAX_COLUMNS + 1];
    for (int i = 0; i < head; i++)
        names[i] = rths_run_frf_column_name(dofs, i);
    if (run->floquet.enabled)
        for (int k = 0; k < FRF_FLOQUET_COLUMNS; k++)
            names[columns++] = floquet_columns[k];
    const int dof_at = columns; /* output.dofs' columns after the optional ones */
    for (int k = 0; k < run->dof_cols.count; k++)
        names[columns++] = frf_dof_column_name(&run->dof_cols, k);
    int tail = columns;
    for (int k = 0; k < RTHS_RUN_FRF_TAIL_COLUMNS; k++)
        names[columns++] = rths_run_frf_column_name(dofs, head + k);
    const int rec_at = columns;
    for (int k = 0; k < rec.count; k++)
        names[columns++] = rec.names[k];
    names[columns++] = "true_amplitude_m";
    int rc = path ? rths_csv_open(path, columns, names, &csv, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < run->n && !rc; i++) {
        double row[RTHS_RUN_FRF_MAX_COLUMNS + FRF_EXTRA_COLUMNS + FRF_DOF_MAX_COLUMNS +
                   FRF_RECEPTANCE_MAX_COLUMNS + 1],
            tail_values[RTHS_RUN_FRF_TAIL_COLUMNS];
        rths_run_frf_row_dofs(&run->pts[i], dofs, row);
        memcpy(tail_values, row + head, sizeof tail_values);
        if (run->floquet.enabled) floquet_row(run, i, row + head);
        frf_dof_columns_row(&run->dof_cols, &run->pts[i], row + dof_at);
        memcpy(row + tail, tail_values, sizeof tail_values);
        frf_receptance_row(&rec, run->setup, &run->pts[i], row + rec_at);
        /* the truth at the point's frequency on its branch (the first interface DoF) */
        const rths_solution *sol = &run->pts[i].sol;
        row[rec_at + rec.count] =
            run->setup->has_bilinear
                ? rths_truth_branch_amplitude_m(run->setup, &run->truth, sol->frequency_hz,
                                                sol->amplitude_m, NULL)
                : rths_truth_linear_amplitude_m(run->setup, sol->frequency_hz);
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing frf.csv failed");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(path);
    /* the same points as a receptance for modal-analysis packages, and their modes */
    if (!rc && run->setup->sparse)
        /* frf_modal.c identifies against the dense assembly's modes, which a sparse model never
         * forms (the lowest modes are `rths model`'s) */
        rths_report_log(rep, "no frf.uff and modal.csv: the model is sparse (model.solver), its "
                             "modes come from `rths model`");
    else if (!rc)
        rc = frf_write_modal_outputs(rep, run, err);
    return rc;
}

/* truth.csv: the first interface DoF's curve; with several interface DoFs (a linear structure)
 * also dof<d>_amplitude_m of each (frf.csv's names); the receptance of every interface DoF
 * (frf.csv's names; NaN with a bilinear leg); then output.dofs' columns, which end the row as
 * before (tests/cli/frf_output_dofs.sh reads them from the end). */
int frf_write_truth_csv(rths_report *rep, const frf_state *run, const rths_truth_curve *t,
                        rths_error *err) {
    const frf_dof_columns *oc = &run->dof_cols;
    frf_receptance_columns rec;
    frf_receptance_columns_init(&rec, run->setup);
    const char
        *header[5 + RTHS_MAX_INTERFACE_DOFS + FRF_DOF_MAX_COLUMNS + FRF_RECEPTANCE_MAX_COLUMNS] = {
            "frequency_hz", "amplitude_m", "amplitude_h2_m", "amplitude_h3_m", "stable"};
    int dofs = dof_columns(t->dofs);
    for (int d = 0; d < dofs; d++)
        header[5 + d] = rths_run_frf_column_name(dofs, RTHS_RUN_FRF_LEADING_COLUMNS +
                                                           RTHS_RUN_FRF_DOF_COLUMNS * d);
    char *path = rths_report_path(rep, "truth.csv");
    rths_csv *csv = NULL;
    for (int k = 0; k < oc->count; k++)
        header[5 + dofs + rec.count + k] = frf_dof_column_name(oc, k);
    const int rec_at = 5 + dofs;
    for (int k = 0; k < rec.count; k++)
        header[rec_at + k] = rec.names[k];
    int rc = path ? rths_csv_open(path, rec_at + rec.count + oc->count, header, &csv, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int j = 0; j < t->n && !rc; j++) {
        double row[5 + RTHS_MAX_INTERFACE_DOFS + FRF_DOF_MAX_COLUMNS + FRF_RECEPTANCE_MAX_COLUMNS] =
            {t->freq_hz[j], t->amp_m[j], t->amp_h2_m[j], t->amp_h3_m[j], t->stable[j]};
        for (int d = 0; d < dofs; d++)
            row[5 + d] = t->amp_dof_m[d * t->n + j];
        frf_receptance_truth_row(&rec, run->setup, t->freq_hz[j], row + rec_at);
        frf_dof_columns_truth_row(oc, run->setup, t->freq_hz[j], row + rec_at + rec.count);
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing truth.csv");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(path);
    return rc;
}
