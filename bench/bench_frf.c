/* `paper` vs `default` strategy on the linear example (12-14 Hz, p = 0.5, default sensor noise),
 * same rig and tolerance: evaluations and rig seconds per point, wall seconds for the curve, and
 * the accuracy against the analytic FRF. Goal: default needs at most half the evaluations and a
 * third of the rig time per point of paper, at equal or better accuracy. */
#include "rths/run.h"
#include "rths/truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    int n, evals[512];
    double rig_s, max_error;
    const rths_setup *setup;
} collected;

/* Every accepted point as rths_run_frf reports it: cost and error against the analytic FRF. */
static int collect(void *user, const rths_point *pt, int is_update) {
    collected *c = user;
    if (is_update || pt->index >= 512) return 0;
    c->evals[c->n++] = pt->evaluations;
    c->rig_s += pt->rig_time_s;
    double truth = rths_truth_linear_amplitude_m(c->setup, pt->sol.frequency_hz);
    c->max_error = fmax(c->max_error, fabs(pt->sol.amplitude_m - truth) / truth);
    return 0;
}

static int cmp_int(const void *a, const void *b) {
    return (*(const int *)a > *(const int *)b) - (*(const int *)a < *(const int *)b);
}

typedef struct {
    int points, evaluations;
    double median_evals, mean_evals, rig_per_point, wall, max_error;
} outcome;

/* One whole test through rths_run_frf (as rths frf runs it) into a scratch folder. */
static int run(int paper, outcome *o) {
    const char *dir = getenv("RTHS_SOURCE_DIR");
    char path[1024], out[] = "/tmp/rths_bench_frf_XXXXXX";
    snprintf(path, sizeof path, "%s/examples/four_storey_linear.yaml", dir ? dir : ".");
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (!mkdtemp(out) ||
        rths_config_load(path, rths_run_paper_overrides, paper ? RTHS_RUN_PAPER_OVERRIDES : 0, &cfg,
                         &err) ||
        rths_setup_read(cfg, &s, &err)) {
        fprintf(stderr, "bench frf: cannot set up the run\n");
        return -1;
    }
    char run_dir[1100];
    snprintf(run_dir, sizeof run_dir, "%s/run", out);
    collected *c = calloc(1, sizeof *c);
    c->setup = &s;
    rths_run_frf_options opt = {
        .cfg = cfg, .setup = &s, .out_dir = run_dir, .strategy = paper ? "paper" : "default"};
    rths_run_callbacks cb = {.on_point = collect, .user = c};
    rths_run_frf_result r;
    int rc = rths_run_frf(&opt, &cb, &r, &err);
    if (rc) fprintf(stderr, "bench frf: %s\n", err.msg);
    o->wall = r.wall_time_s;
    o->points = c->n;
    o->evaluations = r.evaluations;
    o->max_error = c->max_error;
    qsort(c->evals, (size_t)c->n, sizeof c->evals[0], cmp_int);
    int n = c->n;
    o->median_evals =
        n ? (n % 2 ? c->evals[n / 2] : 0.5 * (c->evals[n / 2 - 1] + c->evals[n / 2])) : 0;
    o->mean_evals = n ? (double)o->evaluations / n : 0;
    o->rig_per_point = n ? c->rig_s / n : 0;
    free(c);
    rths_setup_free(&s);
    rths_config_free(cfg);
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", out);
    if (system(cmd) != 0) fprintf(stderr, "bench frf: could not remove %s\n", out);
    return rc;
}

void rths_bench_frf(void) {
    outcome o[2];
    const char *names[2] = {"paper", "default"};
    for (int i = 0; i < 2; i++)
        if (run(i == 0, &o[i])) return;
    printf("linear example, 12-14 Hz, p = 0.5, default sensor noise, same tolerance\n");
    printf("%-34s %12s %12s %10s\n", "", names[0], names[1], "ratio");
    printf("%-34s %12d %12d\n", "points", o[0].points, o[1].points);
    printf("%-34s %12.1f %12.1f %10.2f\n", "evaluations per point, median", o[0].median_evals,
           o[1].median_evals, o[1].median_evals / o[0].median_evals);
    printf("%-34s %12.2f %12.2f %10.2f\n", "evaluations per point, mean", o[0].mean_evals,
           o[1].mean_evals, o[1].mean_evals / o[0].mean_evals);
    printf("%-34s %12.2f %12.2f %10.2f\n", "rig seconds per point", o[0].rig_per_point,
           o[1].rig_per_point, o[1].rig_per_point / o[0].rig_per_point);
    printf("%-34s %12.2f %12.2f %10.2f\n", "wall seconds, continuation", o[0].wall, o[1].wall,
           o[1].wall / o[0].wall);
    printf("%-34s %11.3f%% %11.3f%%\n", "max error vs analytic FRF", 100 * o[0].max_error,
           100 * o[1].max_error);
}
