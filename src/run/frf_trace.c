/* The Lissajous trace of one accepted point (fig. 8 of the seed): recorded on the rig, written as
 * trace.csv and the lissajous figure; and the choice of that point. */
#include "run/frf_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* trace.csv: time_s, x_phys_m, x_num_m, target_m, force_n, demand (the first interface DoF);
 * with several interface DoFs also dof<d>_x_phys_m, _x_num_m, _target_m, _force_n for every d
 * (m or rad, N or N m, as the DoF). */
static int write_trace_csv(rths_report *rep, const rths_trace_sample *tr, int n, int dofs,
                           rths_error *err) {
    static const char *const base[6] = {"time_s",   "x_phys_m", "x_num_m",
                                        "target_m", "force_n",  "demand"};
    static const char *const per[4] = {"x_phys_m", "x_num_m", "target_m", "force_n"};
    enum { MAX_COLS = 6 + 4 * RTHS_MAX_INTERFACE_DOFS };
    char names[MAX_COLS][32];
    const char *header[MAX_COLS];
    int cols = 6 + (dofs > 1 ? 4 * dofs : 0);
    for (int c = 0; c < 6; c++)
        header[c] = base[c];
    for (int d = 0; dofs > 1 && d < dofs; d++)
        for (int k = 0; k < 4; k++) {
            snprintf(names[6 + 4 * d + k], sizeof names[0], "dof%d_%s", d + 1, per[k]);
            header[6 + 4 * d + k] = names[6 + 4 * d + k];
        }
    char *path = rths_report_path(rep, "trace.csv");
    rths_csv *csv = NULL;
    int rc = path ? rths_csv_open(path, cols, header, &csv, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < n && !rc; i++) {
        double row[MAX_COLS] = {tr[i].time_s - tr[0].time_s,
                                tr[i].x_phys_m,
                                tr[i].x_num_m,
                                tr[i].target_m,
                                tr[i].force_n,
                                tr[i].demand};
        for (int d = 0; dofs > 1 && d < dofs; d++) {
            int have = tr[i].dofs == dofs; /* a producer that carries one DoF: empty cells */
            row[6 + 4 * d] = have ? tr[i].x_phys_dof_m[d] : NAN;
            row[6 + 4 * d + 1] = have ? tr[i].x_num_dof_m[d] : NAN;
            row[6 + 4 * d + 2] = have ? tr[i].target_dof_m[d] : NAN;
            row[6 + 4 * d + 3] = have ? tr[i].force_dof_n[d] : NAN;
        }
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing trace.csv");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(path);
    return rc;
}

/* One interface DoF's row of the Lissajous figure: time traces and the phase plot, its columns
 * in trace.csv (phys, num, target), in the unit the largest of them, max_abs (m or rad), reads
 * in (report.h: µm below a millimetre, mm above). */
static int lissajous_row(char *out, size_t size, const rths_setup *setup, int d, int phys_col,
                         int num_col, int target_col, double max_abs) {
    int dof = setup->split.int_dofs[d];
    int rot = rths_setup_dof_is_rotation(setup, dof);
    const char *what = rot ? "Rotation" : "Displacement";
    char unit[24];
    double scale = rths_plot_unit(max_abs, rot ? "rad" : "m", unit, sizeof unit);
    char name[48];
    snprintf(name, sizeof name, "interface DoF %d (DoF %d)", d + 1, dof + 1);
    return snprintf(out, size,
                    "set xlabel 'Time (s)'\n"
                    "set ylabel '%s (%s)'\n"
                    "set size nosquare\n"
                    /* the legend in a band left free above the traces, clear of the data and
                       of the axis labels */
                    "set offsets 0, 0, graph 0.3, 0\n"
                    "set key inside top center horizontal samplen 2\n"
                    "set title '%s: time traces'\n"
                    "plot 'trace.csv' using 1:($%d * %g) skip 1 with lines lw 2 lc rgb '#1f77b4' "
                    "title 'physical', \\\n"
                    "     'trace.csv' using 1:($%d * %g) skip 1 with lines lw 2 dt 2 lc rgb "
                    "'#ff7f0e' title 'numerical', \\\n"
                    "     'trace.csv' using 1:($%d * %g) skip 1 with lines lw 1 lc rgb 'gray50' "
                    "title 'target x^*'\n"
                    "set xlabel 'Physical (%s)'\n"
                    "set ylabel 'Numerical (%s)'\n"
                    "set title '%s: numerical against physical'\n"
                    "set size square\n"
                    "set offsets 0, 0, 0, 0\n"
                    "unset key\n"
                    "plot 'trace.csv' using ($%d * %g):($%d * %g) skip 1 with lines lw 2 lc rgb "
                    "'#1f77b4'\n",
                    what, unit, name, phys_col, scale, num_col, scale, target_col, scale, unit,
                    unit, name, phys_col, scale, num_col, scale);
}

/* Fig. 8 of the seed: time traces and the phase (Lissajous) plot of the physical against the
 * numerical interface displacement at one converged point; a row per interface DoF. */
int frf_trace_record(rths_rig *rig, const rths_settle_options *settle, int harmonics,
                     double amplitude_n, const rths_point *pt, frf_trace *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    double t0 = rths_rig_time_s(rig);
    rths_evaluation ev;
    double f_hz = pt->sol.omega_rad_s / (2 * M_PI);
    int dofs = rths_rig_interface_dofs(rig);
    /* every interface DoF's targets (target_a[d N + k - 1]; one DoF: the usual layout) */
    int rc = rths_evaluate_dofs(rig, settle, harmonics, dofs, f_hz, amplitude_n, pt->sol.target_a,
                                pt->sol.target_b, &ev, err);
    enum { MAX_SAMPLES = 4000 };
    out->samples = calloc(MAX_SAMPLES, sizeof *out->samples);
    if (!rc && !out->samples) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_rig_record_trace(rig, 3.0 / f_hz, MAX_SAMPLES, out->samples, &out->n, err);
    out->rig_time_s = rths_rig_time_s(rig) - t0;
    out->dofs = dofs;
    out->point = pt->index;
    out->frequency_hz = f_hz;
    if (rc) frf_trace_free(out);
    return rc;
}

void frf_trace_free(frf_trace *t) {
    free(t->samples);
    t->samples = NULL;
    t->n = 0;
}

/* The largest |value| of interface DoF d's physical, numerical and target traces (the columns
 * its Lissajous row draws; several: the per-DoF ones, else the first DoF's). */
static double trace_max_abs(const frf_trace *t, int several, int d) {
    double max_abs = 0;
    for (int i = 0; i < t->n; i++) {
        const rths_trace_sample *x = &t->samples[i];
        if (several && x->dofs != t->dofs) continue; /* empty cells in trace.csv */
        const double v[3] = {several ? x->x_phys_dof_m[d] : x->x_phys_m,
                             several ? x->x_num_dof_m[d] : x->x_num_m,
                             several ? x->target_dof_m[d] : x->target_m};
        for (int k = 0; k < 3; k++)
            if (isfinite(v[k])) max_abs = fmax(max_abs, fabs(v[k]));
    }
    return max_abs;
}

int frf_trace_write(rths_report *rep, const rths_setup *setup, const frf_trace *t,
                    rths_error *err) {
    int dofs = t->dofs, n = t->n;
    const rths_trace_sample *tr = t->samples;
    int several = dofs > 1 && n > 0 && tr[0].dofs == dofs;
    int rc = write_trace_csv(rep, tr, n, dofs, err);
    if (rc) return rc;
    char body[8192];
    int used = snprintf(body, sizeof body,
                        "set datafile separator ','\n"
                        "set multiplot layout %d,2 title 'Converged point %d at %.4f Hz: "
                        "interface motions'\n"
                        "set grid\n",
                        several ? dofs : 1, t->point, t->frequency_hz);
    for (int d = 0; d < (several ? dofs : 1) && used < (int)sizeof body; d++) {
        /* DoF 0 alone: columns 2-4; several: dof<d>_* at 7 + 4 d */
        int c0 = several ? 7 + 4 * d : 2;
        used += lissajous_row(body + used, sizeof body - (size_t)used, setup, d, c0, c0 + 1, c0 + 2,
                              trace_max_abs(t, several, d));
    }
    if (used < (int)sizeof body)
        snprintf(body + used, sizeof body - (size_t)used, "unset multiplot\n");
    return rths_plot(rep, rths_report_dir(rep), "lissajous", 1400, several ? 520 * dofs : 650, body,
                     err);
}

int frf_choose_trace_point(const frf_state *run, double trace_hz) {
    int best = -1;
    double best_score = -INFINITY;
    for (int i = 0; i < run->n; i++) {
        const rths_point *pt = &run->pts[i];
        if (!pt->sol.converged) continue;
        double score = trace_hz > 0 ? -fabs(pt->sol.omega_rad_s / (2 * M_PI) - trace_hz)
                                    : rths_point_amplitude_m(pt);
        if (score > best_score) {
            best_score = score;
            best = i;
        }
    }
    return best;
}
