/* `paper` vs `default` strategy on the linear example (12-14 Hz, p = 0.5, default sensor noise),
 * same rig and tolerance: evaluations and rig seconds per point, wall seconds for the curve, and
 * the accuracy against the analytic FRF. Goal: default needs at most half the evaluations and a
 * third of the rig time per point of paper, at equal or better accuracy. */
#include "rths/continuation.h"
#include "rths/rig_virtual.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    rths_point pts[512];
    int n;
} collected;

static int collect(void *user, const rths_point *pt, int is_update) {
    (void)is_update;
    collected *c = user;
    if (pt->index < 512) {
        c->pts[pt->index] = *pt;
        if (pt->index >= c->n) c->n = pt->index + 1;
    }
    return 0;
}

static int cmp_int(const void *a, const void *b) {
    return (*(const int *)a > *(const int *)b) - (*(const int *)a < *(const int *)b);
}

typedef struct {
    int points, evaluations;
    double median_evals, mean_evals, rig_per_point, wall, max_error;
} outcome;

static int run(int paper, outcome *o) {
    const char *dir = getenv("RTHS_SOURCE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/examples/four_storey_linear.yaml", dir ? dir : ".");
    /* what rths frf --strategy paper sets: the seed's integrator and grounding damping */
    const char *ov[2] = {"controller.scheme=implicit_euler",
                         "controller.grounding_kd_n_s_per_m=200"};
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    rths_rig *rig;
    if (rths_config_load(path, ov, paper ? 2 : 0, &cfg, &err) || rths_setup_read(cfg, &s, &err) ||
        rths_virtual_rig_create(cfg, &s, 0, 0, &rig, &err)) {
        fprintf(stderr, "bench frf: %s\n", err.msg);
        return 1;
    }
    rths_settle_options so;
    rths_newton_options no;
    rths_continuation_options co;
    int harmonics = 1;
    rths_settle_defaults(&so, paper);
    rths_newton_defaults(&no, paper);
    rths_continuation_defaults(&co);
    co.model_predictor = !paper;
    if (rths_iterate_config_read(cfg, &so, &no, &harmonics, &err) ||
        rths_continuation_config_read(cfg, &co, &err)) {
        fprintf(stderr, "bench frf: %s\n", err.msg);
        return 1;
    }
    collected *c = calloc(1, sizeof *c);
    rths_continuation_result res;
    double t0 = rths_monotonic_s();
    int rc = rths_continuation_run(rig, &co, &so, &no, harmonics, s.forcing_amplitude_n, NULL, 0,
                                   collect, NULL, c, &res, &err);
    o->wall = rths_monotonic_s() - t0;
    if (rc) fprintf(stderr, "bench frf: %s\n", err.msg);
    int evals[512];
    double rig_s = 0;
    o->evaluations = 0;
    o->max_error = 0;
    for (int i = 0; i < c->n; i++) {
        evals[i] = c->pts[i].evaluations;
        o->evaluations += evals[i];
        rig_s += c->pts[i].rig_time_s;
        double complex x[4];
        rths_frf(4, s.assembly.mass, s.assembly.damping, s.assembly.stiffness, s.force,
                 2 * M_PI * c->pts[i].sol.frequency_hz, x, &err);
        double truth = cabs(x[2]);
        o->max_error = fmax(o->max_error, fabs(c->pts[i].sol.amplitude_m - truth) / truth);
    }
    o->points = c->n;
    qsort(evals, (size_t)c->n, sizeof evals[0], cmp_int);
    o->median_evals =
        c->n ? (c->n % 2 ? evals[c->n / 2] : 0.5 * (evals[c->n / 2 - 1] + evals[c->n / 2])) : 0;
    o->mean_evals = c->n ? (double)o->evaluations / c->n : 0;
    o->rig_per_point = c->n ? rig_s / c->n : 0;
    free(c);
    rths_rig_destroy(rig);
    rths_setup_free(&s);
    rths_config_free(cfg);
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
    printf("%-34s %12.2f %12.2f %10.2f\n", "wall seconds, whole curve", o[0].wall, o[1].wall,
           o[1].wall / o[0].wall);
    printf("%-34s %11.3f%% %11.3f%%\n", "max error vs analytic FRF", 100 * o[0].max_error,
           100 * o[1].max_error);
}
