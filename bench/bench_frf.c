/* `paper` vs `default` strategy, `default` with the controller's changes at once
 * (controller.transition_periods: 0, docs/method.md "Smooth transitions") and `default` with the
 * fitted evaluation (iteration.settle.strategy: fit, "The fitted evaluation"), same rig and
 * tolerance, on the linear example (12-14 Hz, p = 0.5) and the bilinear example (3 N, through both
 * folds), each with the default sensor noise and with the laboratory preset (rig.noise: lab):
 * evaluations and rig seconds per point, wall seconds for the curve, the largest error against the
 * truth (the analytic FRF; the shooting solution in the demo's (10 ln f, ln A) measure) and the
 * share of points within 3 standard errors of the truth at their frequency on their branch (those
 * farther than 5 mHz from a fold). Goal: default needs at most a third of paper's rig time per
 * point, at equal or better accuracy; under lab noise at most 3 evaluations per point (median). The
 * two-interface example (two shakers, 4 unknowns per point): default at most 2 evaluations per
 * point (median) with the default noise. */
#include "rths/run.h"
#include "rths/truth.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_POINTS = 1600 };

typedef struct {
    int n, evals[MAX_POINTS], compared, within_3se;
    double rig_s, periods;
    const rths_setup *setup;
    const rths_truth_curve *truth;
} collected;

/* Every accepted point as rths_run_frf reports it: cost, and its standard errors against the
 * truth on its branch away from folds (updates only change fold flags). */
static int collect(void *user, const rths_point *pt, int is_update) {
    collected *c = user;
    if (is_update || pt->index >= MAX_POINTS) return 0;
    c->evals[c->n++] = pt->evaluations;
    c->rig_s += pt->rig_time_s;
    c->periods += pt->rig_time_s * pt->sol.frequency_hz;
    double f = pt->sol.frequency_hz, a = pt->sol.amplitude_m;
    double truth = rths_truth_branch_amplitude_m(c->setup, c->truth, f, a, NULL);
    if (isfinite(truth) && rths_truth_fold_distance_hz(c->truth, f) > 5e-3) {
        c->compared++;
        c->within_3se += fabs(a - truth) <= 3 * pt->sol.amplitude_se_m;
    }
    return 0;
}

static int cmp_int(const void *a, const void *b) {
    return (*(const int *)a > *(const int *)b) - (*(const int *)a < *(const int *)b);
}

typedef struct {
    int points, evaluations;
    double median_evals, mean_evals, rig_per_point, periods_per_point, wall, max_error, within_3se;
} outcome;

static void summarise(const collected *c, const rths_run_frf_result *r, outcome *o) {
    int n = c->n;
    int *sorted = malloc(sizeof(int) * (size_t)(n ? n : 1));
    memcpy(sorted, c->evals, sizeof(int) * (size_t)n);
    qsort(sorted, (size_t)n, sizeof sorted[0], cmp_int);
    o->wall = r->wall_time_s;
    o->points = n;
    o->evaluations = r->evaluations;
    o->max_error = r->max_relative_error_vs_truth;
    o->median_evals = n ? (n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2])) : 0;
    o->mean_evals = n ? (double)o->evaluations / n : 0;
    o->rig_per_point = n ? c->rig_s / n : 0;
    o->periods_per_point = n ? c->periods / n : 0;
    o->within_3se = c->compared ? (double)c->within_3se / c->compared : 0;
    free(sorted);
}

/* One whole test of an example through rths_run_frf (as rths frf runs it) into a scratch folder;
 * strategy 0 paper, 1 default with changes at once, 2 default, 3 default with the fitted
 * evaluation. */
enum { STRATEGIES = 4 };
static int run(const char *example, int strategy, int lab, outcome *o) {
    int paper = strategy == 0;
    const char *dir = getenv("RTHS_SOURCE_DIR");
    char path[1024], out[] = "/tmp/rths_bench_frf_XXXXXX";
    snprintf(path, sizeof path, "%s/examples/%s", dir ? dir : ".", example);
    const char *overrides[RTHS_RUN_PAPER_OVERRIDES + 2];
    int n_overrides = 0;
    for (int i = 0; paper && i < RTHS_RUN_PAPER_OVERRIDES; i++)
        overrides[n_overrides++] = rths_run_paper_overrides[i];
    if (lab) overrides[n_overrides++] = "rig.noise=lab";
    if (strategy == 1) overrides[n_overrides++] = "controller.transition_periods=0";
    if (strategy == 3) overrides[n_overrides++] = "iteration.settle.strategy=fit";
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (!mkdtemp(out) || rths_config_load(path, overrides, n_overrides, &cfg, &err) ||
        rths_setup_read(cfg, &s, &err)) {
        fprintf(stderr, "bench frf: cannot set up the run of %s\n", example);
        return -1;
    }
    char run_dir[1100];
    snprintf(run_dir, sizeof run_dir, "%s/run", out);
    collected *c = calloc(1, sizeof *c);
    rths_truth_curve truth;
    double lo = 0, hi = 0;
    if (rths_config_get_double(cfg, "continuation.start_hz", 0, 12, 0, 1e6, &lo, &err) ||
        rths_config_get_double(cfg, "continuation.end_hz", 0, 14, 0, 1e6, &hi, &err) ||
        rths_truth_compute(&s, fmin(lo, hi) * 0.99, fmax(lo, hi) * 1.01, &truth, &err)) {
        fprintf(stderr, "bench frf: no truth for %s: %s\n", example, err.msg);
        return -1;
    }
    c->setup = &s;
    c->truth = &truth;
    rths_run_frf_options opt = {
        .cfg = cfg, .setup = &s, .out_dir = run_dir, .strategy = paper ? "paper" : "default"};
    rths_run_callbacks cb = {.on_point = collect, .user = c};
    rths_run_frf_result r;
    int rc = rths_run_frf(&opt, &cb, &r, &err);
    if (rc) fprintf(stderr, "bench frf: %s\n", err.msg);
    summarise(c, &r, o);
    free(c);
    rths_truth_free(&truth);
    rths_setup_free(&s);
    rths_config_free(cfg);
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", out);
    if (system(cmd) != 0) fprintf(stderr, "bench frf: could not remove %s\n", out);
    return rc;
}

/* One row: the four strategies' values and the default's over changes at once ("def/once"). */
static void print_row(const char *what, const char *fmt, const outcome *o, size_t offset,
                      int ratio) {
    char cell[32];
    printf("%-34s", what);
    for (int i = 0; i < STRATEGIES; i++) {
        double v = *(const double *)((const char *)&o[i] + offset);
        snprintf(cell, sizeof cell, fmt, v);
        printf(" %12s", cell);
    }
    if (ratio) {
        double a = *(const double *)((const char *)&o[1] + offset),
               b = *(const double *)((const char *)&o[2] + offset);
        printf(" %10.2f", b / a);
    }
    printf("\n");
}

static void print_table(const char *title, const outcome *o) {
    printf("\n%s\n", title);
    printf("%-34s %12s %12s %12s %12s %10s\n", "", "paper", "at once", "default", "fit",
           "def/once");
    printf("%-34s %12d %12d %12d %12d\n", "points", o[0].points, o[1].points, o[2].points,
           o[3].points);
    print_row("evaluations per point, median", "%.1f", o, offsetof(outcome, median_evals), 1);
    print_row("evaluations per point, mean", "%.2f", o, offsetof(outcome, mean_evals), 1);
    print_row("rig seconds per point", "%.2f", o, offsetof(outcome, rig_per_point), 1);
    print_row("forcing periods per point", "%.1f", o, offsetof(outcome, periods_per_point), 1);
    print_row("wall seconds, continuation", "%.2f", o, offsetof(outcome, wall), 1);
    outcome pct[STRATEGIES];
    for (int i = 0; i < STRATEGIES; i++) {
        pct[i] = o[i];
        pct[i].max_error *= 100;
        pct[i].within_3se *= 100;
    }
    print_row("max error vs truth", "%.3f%%", pct, offsetof(outcome, max_error), 0);
    print_row("within 3 SE (> 5 mHz from folds)", "%.1f%%", pct, offsetof(outcome, within_3se), 0);
}

void rths_bench_frf(void) {
    static const struct {
        const char *example, *title;
        int lab;
    } cases[] = {
        {"four_storey_linear.yaml", "linear example, 12-14 Hz, p = 0.5, default sensor noise", 0},
        {"four_storey_linear.yaml", "linear example, 12-14 Hz, p = 0.5, rig.noise: lab", 1},
        {"four_storey_bilinear.yaml", "bilinear example, 3 N, 13.5-14.6 Hz, default sensor noise",
         0},
        {"four_storey_bilinear.yaml", "bilinear example, 3 N, 13.5-14.6 Hz, rig.noise: lab", 1},
        {"two_interface_storeys.yaml",
         "two interface DoFs (storeys 2 and 3), 12-14 Hz, default sensor noise (first DoF's "
         "errors)",
         0},
        {"cantilever_two_shakers.yaml",
         "two-shaker cantilever (displacement and rotation through transforms), 2.8-3.2 Hz, "
         "default sensor noise (first DoF's errors)",
         0},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        outcome o[STRATEGIES];
        int failed = 0;
        for (int i = 0; i < STRATEGIES && !failed; i++)
            failed = run(cases[k].example, i, cases[k].lab, &o[i]) != 0;
        if (!failed) print_table(cases[k].title, o);
    }
}
