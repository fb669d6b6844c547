/* rths frf CONFIG --out DIR: the iterative hybrid test with continuation in forcing frequency, the
 * main job. Everything accepted goes to journal.jsonl as it happens; frf.csv, summary.json and the
 * figures are written at the end however the run ended (normally, by a rig fault, or by too many
 * failures), so nothing accepted is ever lost. */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/continuation.h"
#include "rths/controller.h"
#include "rths/report.h"
#include "rths/rig_remote.h"
#include "rths/rig_virtual.h"
#include "rths/setup.h"

#include <complex.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const char usage[] =
    "Usage: rths frf CONFIG --out DIR [--strategy paper|default] [--harmonics N] [--seed S]\n"
    "                [--resume] [--rig tcp://HOST:PORT] [--set key=value]... [--quiet]\n"
    "\n"
    "Iterative hybrid test with continuation: solves for the control target's Fourier\n"
    "coefficients at which the physical and numerical interface displacements agree, and\n"
    "continues the solution in forcing frequency from continuation.start_hz to end_hz,\n"
    "through folds (continuation.method: arclength) to trace the true assembly's response.\n"
    "\n"
    "Options:\n"
    "  --out DIR            output folder (created)\n"
    "  --strategy NAME      default: adaptive steady-state detection, Jacobian carried along the\n"
    "                       branch, targets and gains predicted from a model of the residual\n"
    "                       fitted to recent evaluations, response reported at zero mismatch,\n"
    "                       exact first-order-hold integrator, grounding damping\n"
    "                       1000 N s/m (the project's best);\n"
    "                       paper: the seed's flowchart (fixed waits, fresh finite-difference\n"
    "                       Jacobian at every point, secant predictor, the measured response,\n"
    "                       implicit Euler numerical substructure,\n"
    "                       the seed's grounding damping 200 N s/m); --set overrides either\n"
    "  --harmonics N        harmonics matched at the interface, 1..3 (default: "
    "iteration.harmonics, 1)\n"
    "  --seed S             noise seed of the virtual rig (default: rig.seed)\n"
    "  --resume             continue the interrupted run in DIR from its journal's last point\n"
    "  --rig URI            tcp://HOST:PORT: a controller process instead of the virtual rig\n"
    "  --set key=value      override a configuration key (repeatable)\n"
    "  --quiet              no progress line, no summary\n"
    "  --help               this text\n"
    "\n"
    "Writes into DIR: journal.jsonl (one line per accepted point, flushed; --resume reads it),\n"
    "frf.csv (one row per accepted point), truth.csv (the true assembly's response computed\n"
    "without the hybrid loop: analytic, or by shooting with a bilinear leg), frf.png/.svg\n"
    "(response with magnified interface-error bars), iterations.png (histogram of iterations per\n"
    "point), trace.csv + lissajous.png (time and phase plot at one point), summary.json,\n"
    "config.yaml, run.log.\n"
    "\n"
    "Exit status: 0 the run ended normally (also when it stopped early after\n"
    "continuation.max_failures failed points: see summary.json stop_reason); 1 rig fault or\n"
    "I/O failure (everything accepted so far is saved); 2 bad usage or configuration.\n";

/* Accepted points in index order (updates replace), the run's memory besides the journal. */
typedef struct {
    rths_point *pts;
    int n, cap;
    rths_journal *journal;
    int progress;
} frf_run;

static int remember(frf_run *run, const rths_point *pt);

static int on_point(void *user, const rths_point *pt, int is_update) {
    frf_run *run = user;
    rths_error err;
    if (rths_journal_append(run->journal, pt, is_update, &err)) {
        fprintf(stderr, "rths frf: %s\n", err.msg);
        return RTHS_EFAIL;
    }
    return remember(run, pt);
}

static void on_progress(void *user, int points, double frequency_hz, double residual_m,
                        int evaluations, int accepted) {
    frf_run *run = user;
    if (!run->progress) return;
    fprintf(stderr, "\r  point %4d  %9.5f Hz  residual %9.3e m  evaluations %5d  %-9s", points,
            frequency_hz, residual_m, evaluations, accepted ? "accepted" : "retrying");
    fflush(stderr);
}

/* Interface mismatch of harmonic k (m): |phys_k - num_k| as a complex amplitude. */
static double harmonic_error(const rths_point *pt, int k) {
    return hypot(pt->sol.eval.phys.a[k] - pt->sol.eval.num.a[k],
                 pt->sol.eval.phys.b[k] - pt->sol.eval.num.b[k]);
}

enum { FRF_COLUMNS = 22 };

static int write_frf_csv(rths_report *rep, const frf_run *run, rths_error *err) {
    static const char *const header[FRF_COLUMNS] = {"point",
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
                                                    "measured_amplitude_m"};
    char *path = rths_report_path(rep, "frf.csv");
    rths_csv *csv = NULL;
    int rc = path ? rths_csv_open(path, FRF_COLUMNS, header, &csv, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < run->n && !rc; i++) {
        const rths_point *pt = &run->pts[i];
        const rths_fourier *ph = &pt->sol.eval.phys, *nu = &pt->sol.eval.num;
        double row[FRF_COLUMNS] = {
            /* amplitude_m: what the strategy reports (the response extrapolated to zero
             * mismatch by default, the measurement for paper); measured_amplitude_m: the
             * measurement */
            pt->index, pt->sol.frequency_hz, pt->sol.amplitude_m, hypot(nu->a[1], nu->b[1]),
            /* x = A cos + B sin = R cos(wt + phi) with phi = atan2(-B, A) */
            atan2(-ph->b[1], ph->a[1]), harmonic_error(pt, 1), harmonic_error(pt, 2),
            harmonic_error(pt, 3), hypot(ph->a[2], ph->b[2]), hypot(ph->a[3], ph->b[3]),
            pt->sol.target_a[0], pt->sol.target_b[0], pt->sol.residual_norm_m, pt->sol.tolerance_m,
            pt->evaluations, pt->iterations, pt->rig_time_s, pt->sol.converged, pt->fold,
            pt->segment, pt->sol.amplitude_se_m, hypot(ph->a[1], ph->b[1])};
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing frf.csv failed");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(path);
    return rc;
}

/* The true assembly's interface response, computed without the hybrid loop: analytic for a linear
 * structure, shooting + pseudo-arclength with the bilinear leg (through its folds). */
typedef struct {
    int n;
    double *freq_hz, *amp_m, *amp_h2_m, *amp_h3_m;
    int *stable;
} truth_curve;

static void truth_free(truth_curve *t) {
    free(t->freq_hz);
    free(t->amp_m);
    free(t->amp_h2_m);
    free(t->amp_h3_m);
    free(t->stable);
    memset(t, 0, sizeof *t);
}

static int truth_alloc(truth_curve *t, int n, rths_error *err) {
    t->n = n;
    t->freq_hz = calloc((size_t)n, sizeof(double));
    t->amp_m = calloc((size_t)n, sizeof(double));
    t->amp_h2_m = calloc((size_t)n, sizeof(double));
    t->amp_h3_m = calloc((size_t)n, sizeof(double));
    t->stable = calloc((size_t)n, sizeof(int));
    if (t->freq_hz && t->amp_m && t->amp_h2_m && t->amp_h3_m && t->stable) return RTHS_OK;
    truth_free(t);
    return rths_error_set(err, RTHS_EFAIL, "out of memory");
}

static int compute_truth(const rths_setup *s, double lo_hz, double hi_hz, truth_curve *t,
                         rths_error *err) {
    int iface = s->split.int_dofs[0], n = s->assembly.n;
    memset(t, 0, sizeof *t);
    if (s->has_bilinear) {
        rths_shooting_options opt = {.start_hz = lo_hz,
                                     .end_hz = hi_hz,
                                     .steps_per_period = 1024,
                                     .max_step = 0.02,
                                     .max_points = 4000};
        rths_periodic_point *pp = NULL;
        int count = 0;
        int rc = rths_bilinear_frf(&s->assembly, &s->leg, s->static_force, s->force, &opt, &pp,
                                   &count, err);
        if (!rc) rc = truth_alloc(t, count, err);
        for (int j = 0; j < count && !rc; j++) {
            t->freq_hz[j] = pp[j].omega_rad_s / (2 * M_PI);
            t->amp_m[j] = hypot(pp[j].cos_m[iface + n], pp[j].sin_m[iface + n]);
            t->amp_h2_m[j] = hypot(pp[j].cos_m[iface + 2 * n], pp[j].sin_m[iface + 2 * n]);
            t->amp_h3_m[j] = hypot(pp[j].cos_m[iface + 3 * n], pp[j].sin_m[iface + 3 * n]);
            t->stable[j] = pp[j].stable;
        }
        rths_periodic_points_free(pp, count);
        return rc;
    }
    rths_modes modes;
    double *f = NULL;
    int count = 0;
    int rc = rths_modal_analysis(&s->assembly, &modes, err);
    if (rc) return rc;
    rc = rths_frf_grid(&modes, lo_hz, hi_hz, 0, &f, &count, err);
    rths_modes_free(&modes);
    double complex *x = calloc((size_t)n, sizeof *x);
    if (!rc && !x) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = truth_alloc(t, count, err);
    for (int j = 0; j < count && !rc; j++) {
        rc = rths_frf(n, s->assembly.mass, s->assembly.damping, s->assembly.stiffness, s->force,
                      2 * M_PI * f[j], x, err);
        t->freq_hz[j] = f[j];
        t->amp_m[j] = cabs(x[iface]);
        t->stable[j] = 1;
    }
    free(x);
    free(f);
    return rc;
}

/* Deviation of a hybrid point from the truth curve, relative: the distance to the nearest
 * truth segment in the plane (10 ln f, ln A), so a 1 % amplitude error and a 0.1 % frequency
 * offset count alike. That is the vertical relative error where the curve is flat, and stays
 * meaningful where a folded curve is steep or multi-valued. */
static double truth_relative_error(const truth_curve *t, double f_hz, double amp_m) {
    double best = INFINITY;
    if (!(f_hz > 0 && amp_m > 0)) return best;
    double pu = 10 * log(f_hz), pv = log(amp_m);
    for (int j = 0; j + 1 < t->n; j++) {
        if (!(t->amp_m[j] > 0 && t->amp_m[j + 1] > 0)) continue;
        double u0 = 10 * log(t->freq_hz[j]), v0 = log(t->amp_m[j]);
        double du = 10 * log(t->freq_hz[j + 1]) - u0, dv = log(t->amp_m[j + 1]) - v0;
        double len2 = du * du + dv * dv;
        double x = len2 > 0 ? ((pu - u0) * du + (pv - v0) * dv) / len2 : 0;
        x = x < 0 ? 0 : x > 1 ? 1 : x;
        best = fmin(best, hypot(pu - u0 - x * du, pv - v0 - x * dv));
    }
    return best;
}

/* Linear structure: the analytic interface amplitude at the point's frequency (NAN if none). */
static double linear_truth_m(const rths_setup *s, const rths_point *pt) {
    double complex x[RTHS_MAX_SENSED_DOFS];
    rths_error err;
    if (s->has_bilinear || s->assembly.n > RTHS_MAX_SENSED_DOFS ||
        rths_frf(s->assembly.n, s->assembly.mass, s->assembly.damping, s->assembly.stiffness,
                 s->force, 2 * M_PI * pt->sol.frequency_hz, x, &err))
        return NAN;
    return cabs(x[s->split.int_dofs[0]]);
}

/* Linear: the exact relative amplitude error at the point's own frequency (analytic FRF).
 * Bilinear: the distance to the shooting curve (truth_relative_error). */
static double point_truth_error(const rths_setup *s, const truth_curve *t, const rths_point *pt) {
    double amp = pt->sol.amplitude_m;
    if (s->has_bilinear) return truth_relative_error(t, pt->sol.frequency_hz, amp);
    double truth = linear_truth_m(s, pt);
    return fabs(amp - truth) / truth;
}

static int write_truth_csv(rths_report *rep, const truth_curve *t, rths_error *err) {
    static const char *const header[5] = {"frequency_hz", "amplitude_m", "amplitude_h2_m",
                                          "amplitude_h3_m", "stable"};
    char *path = rths_report_path(rep, "truth.csv");
    rths_csv *csv = NULL;
    int rc = path ? rths_csv_open(path, 5, header, &csv, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int j = 0; j < t->n && !rc; j++) {
        double row[5] = {t->freq_hz[j], t->amp_m[j], t->amp_h2_m[j], t->amp_h3_m[j], t->stable[j]};
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing truth.csv");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(path);
    return rc;
}

static int plot_frf(rths_report *rep, const frf_run *run, const truth_curve *t, const char *title,
                    rths_error *err) {
    /* Interface errors are tiny next to the response: magnify them so the largest bar is about
     * 5 % of the peak, and say by how much in the legend (the seed used a fixed 2x). */
    double max_amp = 0, max_err = 0;
    for (int i = 0; i < run->n; i++) {
        max_amp = fmax(max_amp, run->pts[i].sol.amplitude_m);
        max_err = fmax(max_err, harmonic_error(&run->pts[i], 1));
    }
    double mag = 1;
    if (max_err > 0) {
        mag = 0.05 * max_amp / max_err;
        double decade = pow(10, floor(log10(mag)));
        mag = mag >= 1 ? floor(mag / decade) * decade : 1;
    }
    int any_unstable = 0, any_fold = 0;
    for (int j = 0; j < t->n; j++)
        any_unstable |= !t->stable[j];
    for (int i = 0; i < run->n; i++)
        any_fold |= run->pts[i].fold;
    char body[4096];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set title \"%s\" noenhanced\n"
             "set xlabel 'Forcing frequency (Hz)'\n"
             "set ylabel 'Interface displacement amplitude, fundamental (m)'\n"
             "set format y '%%.1e'\n"
             "set grid\n"
             "set key below\n"
             "set bmargin 8\n"
             "plot 'truth.csv' using 1:($5 == 1 ? $2 : 1/0) skip 1 with lines lw 2 lc rgb "
             "'black' title 'true assembly%s'%s, \\\n"
             "     'frf.csv' using 2:3:($6 * %g) skip 1 with yerrorbars pt 7 ps 0.8 lc rgb "
             "'#1f77b4' title 'hybrid test (bars: interface error x %g)'%s\n",
             title, any_unstable ? ", stable" : "",
             any_unstable ? ", \\\n     'truth.csv' using 1:($5 == 0 ? $2 : 1/0) skip 1 with "
                            "lines lw 2 dt 2 lc rgb 'gray40' title 'true assembly, unstable'"
                          : "",
             mag, mag,
             any_fold ? ", \\\n     'frf.csv' using 2:($19 == 1 ? $3 : 1/0) skip 1 with points "
                        "pt 6 ps 3 lw 2 lc rgb '#d62728' title 'fold located after this point'"
                      : "");
    int rc = rths_plot(rep, rths_report_dir(rep), "frf", 1200, 800, body, err);
    if (rc) return rc;
    int max_iterations = 0;
    for (int i = 0; i < run->n; i++)
        max_iterations =
            run->pts[i].iterations > max_iterations ? run->pts[i].iterations : max_iterations;
    /* the range hugs the bars: no empty tick left of 0 */
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set title 'Newton iterations per accepted point'\n"
             "set xlabel 'Iterations to converge'\n"
             "set ylabel 'Number of points'\n"
             "set boxwidth 0.8\n"
             "set style fill solid 0.6\n"
             "set xtics 1\n"
             "set xrange [-0.6:%g]\n"
             "set grid ytics\n"
             "set yrange [0:*]\n"
             "plot 'frf.csv' using 16:(1) skip 1 smooth frequency with boxes lc rgb '#1f77b4' "
             "title 'points'\n",
             max_iterations + 0.6);
    return rths_plot(rep, rths_report_dir(rep), "iterations", 900, 600, body, err);
}

/* Fig. 8 of the seed: time traces and the phase (Lissajous) plot of the physical against the
 * numerical interface displacement at one converged point. */
static int trace_point(rths_report *rep, rths_rig *rig, const rths_settle_options *settle,
                       int harmonics, double amplitude_n, const rths_point *pt,
                       double *trace_rig_time_s, rths_error *err) {
    double t0 = rths_rig_time_s(rig);
    rths_evaluation ev;
    double f_hz = pt->sol.omega_rad_s / (2 * M_PI);
    int rc = rths_evaluate(rig, settle, harmonics, f_hz, amplitude_n, pt->sol.target_a,
                           pt->sol.target_b, &ev, err);
    enum { MAX_SAMPLES = 4000 };
    rths_trace_sample *tr = calloc(MAX_SAMPLES, sizeof *tr);
    int n = 0;
    if (!rc && !tr) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_rig_record_trace(rig, 3.0 / f_hz, MAX_SAMPLES, tr, &n, err);
    *trace_rig_time_s = rths_rig_time_s(rig) - t0;
    static const char *const header[6] = {"time_s",   "x_phys_m", "x_num_m",
                                          "target_m", "force_n",  "demand"};
    char *path = rc ? NULL : rths_report_path(rep, "trace.csv");
    rths_csv *csv = NULL;
    if (!rc) rc = rths_csv_open(path, 6, header, &csv, err);
    for (int i = 0; i < n && !rc; i++) {
        double row[6] = {tr[i].time_s - tr[0].time_s,
                         tr[i].x_phys_m,
                         tr[i].x_num_m,
                         tr[i].target_m,
                         tr[i].force_n,
                         tr[i].demand};
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing trace.csv");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(path);
    free(tr);
    if (rc) return rc;
    char body[4096];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set multiplot layout 1,2 title 'Converged point %d at %.4f Hz: interface "
             "displacements'\n"
             "set xlabel 'Time (s)'\n"
             "set ylabel 'Displacement ({/Symbol m}m)'\n"
             "set grid\n"
             "set key below\n"
             "plot 'trace.csv' using 1:($2 * 1e6) skip 1 with lines lw 2 title 'physical x_3', "
             "\\\n"
             "     'trace.csv' using 1:($3 * 1e6) skip 1 with lines lw 2 dt 2 title 'numerical "
             "{/Symbol x}_3', \\\n"
             "     'trace.csv' using 1:($4 * 1e6) skip 1 with lines lw 1 lc rgb 'gray50' title "
             "'target x^*'\n"
             "set xlabel 'Physical x_3 ({/Symbol m}m)'\n"
             "set ylabel 'Numerical {/Symbol x}_3 ({/Symbol m}m)'\n"
             "set size square\n"
             "unset key\n"
             "plot 'trace.csv' using ($2 * 1e6):($3 * 1e6) skip 1 with lines lw 2 lc rgb "
             "'#1f77b4'\n"
             "unset multiplot\n",
             pt->index, f_hz);
    return rths_plot(rep, rths_report_dir(rep), "lissajous", 1400, 650, body, err);
}

static int compare_int(const void *a, const void *b) {
    return (*(const int *)a > *(const int *)b) - (*(const int *)a < *(const int *)b);
}

typedef struct {
    const char *strategy;
    int report_matched;
    int harmonics;
    double wall_time_s, trace_rig_time_s;
    int resumed_points;
    const rths_continuation_result *result;
    const rths_setup *setup;
} run_facts;

static int write_summary(const rths_cli *cli, rths_report *rep, const frf_run *run,
                         const truth_curve *t, const run_facts *facts, double *max_truth_error,
                         rths_error *err) {
    const rths_continuation_result *res = facts->result;
    json_object *root = rths_cli_summary_new(cli);
    int converged = 0, evaluations = 0, within_3se = 0;
    double rig_time = 0, max_h[4] = {0, 0, 0, 0};
    int *evals = calloc((size_t)(run->n ? run->n : 1), sizeof *evals);
    *max_truth_error = 0;
    for (int i = 0; i < run->n; i++) {
        const rths_point *pt = &run->pts[i];
        converged += pt->sol.converged;
        evaluations += pt->evaluations;
        rig_time += pt->rig_time_s;
        if (evals) evals[i] = pt->evaluations;
        for (int k = 1; k <= 3; k++)
            max_h[k] = fmax(max_h[k], harmonic_error(pt, k));
        double e = point_truth_error(facts->setup, t, pt);
        if (isfinite(e)) *max_truth_error = fmax(*max_truth_error, e);
        double truth = linear_truth_m(facts->setup, pt);
        within_3se += fabs(pt->sol.amplitude_m - truth) <= 3 * pt->sol.amplitude_se_m;
    }
    double median = 0;
    if (evals && run->n) {
        qsort(evals, (size_t)run->n, sizeof *evals, compare_int);
        median = run->n % 2 ? evals[run->n / 2] : 0.5 * (evals[run->n / 2 - 1] + evals[run->n / 2]);
    }
    free(evals);
    json_object_object_add(root, "strategy", json_object_new_string(facts->strategy));
    json_object_object_add(root, "harmonics", json_object_new_int(facts->harmonics));
    json_object_object_add(root, "mass_ratio",
                           json_object_new_double(facts->setup->split.mass_ratio));
    json_object_object_add(root, "forcing_amplitude_n",
                           json_object_new_double(facts->setup->forcing_amplitude_n));
    json_object_object_add(root, "bilinear", json_object_new_boolean(facts->setup->has_bilinear));
    json_object_object_add(root, "points", json_object_new_int(run->n));
    json_object_object_add(root, "converged_points", json_object_new_int(converged));
    json_object_object_add(root, "resumed_points", json_object_new_int(facts->resumed_points));
    /* Totals over the accepted points (journal included on --resume); failed attempts are in
     * their point's counts, since a point's counters include its retries. */
    json_object_object_add(root, "evaluations_total", json_object_new_int(evaluations));
    json_object_object_add(root, "evaluations_per_point_median", json_object_new_double(median));
    json_object_object_add(root, "evaluations_per_point_mean",
                           json_object_new_double(run->n ? (double)evaluations / run->n : 0));
    json_object_object_add(root, "rig_time_s", json_object_new_double(rig_time));
    json_object_object_add(root, "rig_time_per_point_s",
                           json_object_new_double(run->n ? rig_time / run->n : 0));
    json_object_object_add(root, "trace_rig_time_s",
                           json_object_new_double(facts->trace_rig_time_s));
    json_object_object_add(root, "wall_time_s", json_object_new_double(facts->wall_time_s));
    json_object_object_add(root, "failed_corrections", json_object_new_int(res->failures));
    json_object_object_add(root, "reached_end", json_object_new_boolean(res->reached_end));
    json_object_object_add(root, "stop_reason", json_object_new_string(res->stop_reason));
    json_object *folds = json_object_new_array();
    for (int i = 0; i < run->n; i++) {
        if (!run->pts[i].fold) continue;
        /* the journal keeps fold flags; the located fold itself is in the result when this
         * process found it, else the midpoint of the bracketing points stands in */
        double f = 0, a = 0;
        int found = 0;
        for (int k = 0; k < res->n_folds; k++)
            if (res->folds[k].after_point == i) {
                f = res->folds[k].frequency_hz;
                a = res->folds[k].amplitude_m;
                found = 1;
            }
        if (!found && i + 1 < run->n) {
            f = 0.25 * (run->pts[i].sol.omega_rad_s + run->pts[i + 1].sol.omega_rad_s) / M_PI;
            a = 0.5 *
                (rths_point_amplitude_m(&run->pts[i]) + rths_point_amplitude_m(&run->pts[i + 1]));
        }
        json_object *fold = json_object_new_object();
        json_object_object_add(fold, "frequency_hz", json_object_new_double(f));
        json_object_object_add(fold, "amplitude_m", json_object_new_double(a));
        json_object_object_add(fold, "after_point", json_object_new_int(i));
        json_object_array_add(folds, fold);
    }
    json_object_object_add(root, "folds", folds);
    json_object_object_add(root, "max_interface_error_h1_m", json_object_new_double(max_h[1]));
    json_object_object_add(root, "max_interface_error_h2_m", json_object_new_double(max_h[2]));
    json_object_object_add(root, "max_interface_error_h3_m", json_object_new_double(max_h[3]));
    json_object_object_add(
        root, "truth",
        json_object_new_string(facts->setup->has_bilinear
                                   ? "shooting with the bilinear leg (truth.csv)"
                                   : "analytic FRF of the assembly (truth.csv)"));
    json_object_object_add(root, "max_relative_error_vs_truth",
                           json_object_new_double(*max_truth_error));
    json_object_object_add(
        root, "amplitude_reported",
        json_object_new_string(facts->report_matched
                                   ? "matched: the physical interface response extrapolated to "
                                     "zero interface mismatch through the corrector's Jacobians"
                                   : "measured: the physical interface response at the accepted "
                                     "target"));
    /* only where the truth is exact (analytic, linear structure) */
    if (!facts->setup->has_bilinear)
        json_object_object_add(root, "points_within_3_standard_errors",
                               json_object_new_int(within_3se));
    json_object_object_add(
        root, "truth_error_measure",
        json_object_new_string(facts->setup->has_bilinear
                                   ? "distance to the truth curve in the plane (10 ln f, ln A): "
                                     "1 % in amplitude or 0.1 % in frequency count alike"
                                   : "|A - A_true(f)| / A_true(f) at each point's frequency"));
    int rc = rths_cli_write_summary(rep, "summary.json", root, err);
    json_object_put(root);
    return rc;
}

/* --resume: the journal's points, after checking they belong to this kind of run. The journal is
 * rewritten without a torn last line (atomically), so appending continues on a clean record. */
static int load_resume(const char *journal_path, const char *strategy, int harmonics,
                       rths_point **pts, int *n, rths_error *err) {
    char *jstrategy = NULL;
    int rc = rths_journal_read(journal_path, pts, n, &jstrategy, err);
    if (rc) return rc;
    if (strcmp(jstrategy, strategy))
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s was written by a '%s' run; resume it with --strategy %s",
                            journal_path, jstrategy, jstrategy);
    else if (*n > 0 && (*pts)[0].sol.harmonics != harmonics)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s matched %d harmonic(s); resume it with --harmonics %d",
                            journal_path, (*pts)[0].sol.harmonics, (*pts)[0].sol.harmonics);
    free(jstrategy);
    if (rc) return rc;
    size_t len = strlen(journal_path) + 16;
    char *tmp = malloc(len);
    if (!tmp) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    snprintf(tmp, len, "%s.rewrite", journal_path);
    remove(tmp);
    rths_journal *j = NULL;
    rc = rths_journal_open(tmp, strategy, &j, err);
    for (int i = 0; i < *n && !rc; i++)
        rc = rths_journal_append(j, &(*pts)[i], 0, err);
    if (j) rths_journal_close(j);
    if (!rc && rename(tmp, journal_path))
        rc = rths_error_set(err, RTHS_EFAIL, "cannot replace %s", journal_path);
    if (rc) remove(tmp);
    free(tmp);
    return rc;
}

/* Fills the run's memory with the journal's points (already durable: not journaled again). */
static int remember(frf_run *run, const rths_point *pt) {
    if (pt->index >= run->cap) {
        int cap = run->cap ? 2 * run->cap : 64;
        while (cap <= pt->index)
            cap *= 2;
        rths_point *p = realloc(run->pts, (size_t)cap * sizeof *p);
        if (!p) return RTHS_EFAIL;
        run->pts = p;
        run->cap = cap;
    }
    run->pts[pt->index] = *pt;
    if (pt->index >= run->n) run->n = pt->index + 1;
    return RTHS_OK;
}

static int choose_trace_point(const frf_run *run, double trace_hz) {
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

int rths_cmd_frf(int argc, char **argv) {
    enum { OPT_STRATEGY, OPT_HARMONICS, OPT_RESUME, OPT_RIG, N_OPTS };
    rths_cli_opt opts[N_OPTS] = {
        [OPT_STRATEGY] = {"--strategy", "NAME", NULL},
        [OPT_HARMONICS] = {"--harmonics", "N", NULL},
        [OPT_RESUME] = {"--resume", NULL, NULL},
        [OPT_RIG] = {"--rig", "URI", NULL},
    };
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT | RTHS_CLI_SEED, usage,
                            opts, N_OPTS);
    if (rc || cli.help) return rc;
    rths_error err = {0};
    const char *strategy = opts[OPT_STRATEGY].value ? opts[OPT_STRATEGY].value : "default";
    if (strcmp(strategy, "default") && strcmp(strategy, "paper"))
        return rths_cli_fail(&cli,
                             rths_error_set(&err, RTHS_EINPUT,
                                            "option --strategy: '%s' is neither 'default' "
                                            "nor 'paper'",
                                            strategy),
                             &err);
    int paper = !strcmp(strategy, "paper");
    long harmonics_cli = 0;
    if (opts[OPT_HARMONICS].value &&
        (rc = rths_cli_int("--harmonics", opts[OPT_HARMONICS].value, 1, 3, &harmonics_cli, &err)))
        return rths_cli_fail(&cli, rc, &err);
    int resume = opts[OPT_RESUME].value != NULL;
    const char *rig_uri = opts[OPT_RIG].value;
    if (rig_uri && strncmp(rig_uri, "tcp://", 6))
        return rths_cli_fail(
            &cli,
            rths_error_set(&err, RTHS_EINPUT, "option --rig: '%s' is not tcp://HOST:PORT", rig_uri),
            &err);
    /* The paper strategy integrates the numerical substructure as the seed did; an explicit
     * --set controller.scheme=... still wins, because overrides apply in order. */
    if (paper) {
        if (cli.n_sets >= RTHS_CLI_MAX_SETS)
            return rths_cli_fail(&cli, rths_error_set(&err, RTHS_EINPUT, "too many --set"), &err);
        if (cli.n_sets + 2 > RTHS_CLI_MAX_SETS)
            return rths_cli_fail(&cli, rths_error_set(&err, RTHS_EINPUT, "too many --set"), &err);
        /* and the seed's grounding damping (Table 2) */
        memmove(cli.sets + 2, cli.sets, (size_t)cli.n_sets * sizeof cli.sets[0]);
        cli.sets[0] = "controller.scheme=implicit_euler";
        cli.sets[1] = "controller.grounding_kd_n_s_per_m=200";
        cli.n_sets += 2;
    }

    rths_config *cfg = NULL;
    rths_setup setup = {0};
    rths_rig *rig = NULL;
    rths_report *rep = NULL;
    rths_point *resume_pts = NULL;
    int n_resume = 0;
    frf_run run = {0};
    truth_curve truth = {0};
    char *journal_path = NULL;
    rc = rths_cli_load(&cli, &cfg, &setup, &err);
    if (rc) return rths_cli_fail(&cli, rc, &err);

    rths_settle_options settle;
    rths_newton_options newton;
    rths_continuation_options cont;
    int harmonics = 1;
    double trace_hz = 0;
    rths_settle_defaults(&settle, paper);
    rths_newton_defaults(&newton, paper);
    rths_continuation_defaults(&cont);
    cont.model_predictor = !paper;
    rc = rths_iterate_config_read(cfg, &settle, &newton, &harmonics, &err);
    if (!rc && harmonics_cli) harmonics = (int)harmonics_cli;
    if (!rc) rc = rths_continuation_config_read(cfg, &cont, &err);
    if (!rc)
        rc =
            rths_config_get_double(cfg, "output.trace_frequency_hz", 0, 0, 0, 1e5, &trace_hz, &err);
    /* The rig is created before anything is written: its configuration errors are input errors. */
    if (!rc && !rig_uri)
        rc = rths_virtual_rig_create(cfg, &setup, cli.has_seed, cli.seed, &rig, &err);
    if (!rc) {
        /* the controller process reads rig and controller sections itself */
        static const char *const own[] = {"iteration", "continuation", "output", NULL};
        rc = rths_cli_check_config_own(cfg, own, &err);
    }
    if (!rc && rig_uri) rc = rths_remote_rig_create(rig_uri, NULL, &rig, &err);
    if (!rc) {
        size_t len = strlen(cli.out_dir) + 32;
        journal_path = malloc(len);
        if (!journal_path)
            rc = rths_error_set(&err, RTHS_EFAIL, "out of memory");
        else
            snprintf(journal_path, len, "%s/journal.jsonl", cli.out_dir);
    }
    struct stat st;
    if (!rc && !resume && stat(journal_path, &st) == 0)
        rc = rths_error_set(&err, RTHS_EINPUT,
                            "%s already holds a run (journal.jsonl): continue it with --resume, "
                            "or choose another --out",
                            cli.out_dir);
    if (!rc && resume && stat(journal_path, &st) != 0)
        rc = rths_error_set(&err, RTHS_EINPUT, "--resume: %s has no journal.jsonl to resume",
                            cli.out_dir);
    if (!rc && resume)
        rc = load_resume(journal_path, strategy, harmonics, &resume_pts, &n_resume, &err);
    if (!rc) rc = rths_cli_open_report(&cli, cfg, argc, argv, &rep, &err);
    /* the last step may pass end_hz (and the first correction move below start_hz): a margin
     * keeps every accepted point inside the truth curve it is judged against */
    double lo = fmin(cont.start_hz, cont.end_hz), hi = fmax(cont.start_hz, cont.end_hz);
    double margin = 0.1 * (hi - lo);
    lo = fmax(lo - margin, 0.5 * lo);
    hi += margin;
    if (!rc) rc = compute_truth(&setup, lo, hi, &truth, &err);
    if (!rc) rc = write_truth_csv(rep, &truth, &err);
    if (!rc) rc = rths_journal_open(journal_path, strategy, &run.journal, &err);
    for (int i = 0; i < n_resume && !rc; i++)
        if (remember(&run, &resume_pts[i])) rc = rths_error_set(&err, RTHS_EFAIL, "out of memory");

    rths_continuation_result result;
    memset(&result, 0, sizeof result);
    double t_start = rths_monotonic_s();
    int run_rc = RTHS_OK;
    rths_error run_err = {0};
    if (!rc) {
        run.progress = rths_progress_enabled(cli.quiet);
        rths_report_log(rep, "start: strategy %s, %d harmonic(s), %s continuation %g -> %g Hz%s",
                        strategy, harmonics,
                        cont.method == RTHS_CONT_ARCLENGTH ? "pseudo-arclength" : "natural",
                        cont.start_hz, cont.end_hz, resume ? ", resumed" : "");
        run_rc = rths_continuation_run(rig, &cont, &settle, &newton, harmonics,
                                       setup.forcing_amplitude_n, resume_pts, n_resume, on_point,
                                       on_progress, &run, &result, &run_err);
        if (run.progress) fprintf(stderr, "\n");
        rths_report_log(rep, "continuation ended: %s%s%s", result.stop_reason, run_rc ? "; " : "",
                        run_rc ? run_err.msg : "");
    }
    double wall = rths_monotonic_s() - t_start;
    /* Whatever ended the run, everything accepted is written out. A rig fault makes the trace
     * impossible, so it is skipped then. */
    double trace_rig_time = 0, max_truth_error = 0;
    if (!rc) rc = write_frf_csv(rep, &run, &err);
    if (!rc) {
        run_facts facts = {.strategy = strategy,
                           .report_matched = newton.report_matched,
                           .harmonics = harmonics,
                           .wall_time_s = wall,
                           .resumed_points = n_resume,
                           .result = &result,
                           .setup = &setup};
        int pick = run_rc ? -1 : choose_trace_point(&run, trace_hz);
        if (pick >= 0) {
            rths_error trace_err;
            if (trace_point(rep, rig, &settle, harmonics, setup.forcing_amplitude_n, &run.pts[pick],
                            &trace_rig_time, &trace_err))
                rths_report_log(rep, "no trace figure: %s", trace_err.msg);
        }
        facts.trace_rig_time_s = trace_rig_time;
        rc = write_summary(&cli, rep, &run, &truth, &facts, &max_truth_error, &err);
    }
    if (!rc && run.n > 0) {
        char title[256];
        snprintf(title, sizeof title, "Hybrid test, %s strategy, p = %g, %d harmonic(s)%s",
                 strategy, setup.split.mass_ratio, harmonics,
                 setup.has_bilinear ? ", bilinear leg" : "");
        rc = plot_frf(rep, &run, &truth, title, &err);
    }
    if (!rc) {
        int conv = 0, evals = 0;
        double rig_time = 0;
        for (int i = 0; i < run.n; i++) {
            conv += run.pts[i].sol.converged;
            evals += run.pts[i].evaluations;
            rig_time += run.pts[i].rig_time_s;
        }
        rths_cli_print(&cli,
                       "%d points (%d converged, %d resumed), %d evaluations, %.1f s rig time, "
                       "%.1f s wall; %d fold(s); max deviation from the true response %.3g %%\n"
                       "stopped: %s\nresults in %s\n",
                       run.n, conv, n_resume, evals, rig_time, wall, result.n_folds,
                       100 * max_truth_error, result.stop_reason, cli.out_dir);
    }
    if (run.journal) rths_journal_close(run.journal);
    if (rep) rths_report_log(rep, "finished with status %d", rc ? rc : run_rc);
    if (rc)
        rths_cli_fail(&cli, rc, &err);
    else if (run_rc) {
        rths_cli_fail(&cli, run_rc, &run_err);
        rc = run_rc;
    }
    truth_free(&truth);
    free(run.pts);
    free(resume_pts);
    free(journal_path);
    if (rig) rths_rig_destroy(rig);
    rths_cli_unload(cfg, &setup);
    rths_report_close(rep);
    return rc;
}
