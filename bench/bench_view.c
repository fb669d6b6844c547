/* What watching a run costs it: live.json replaced after every evaluation (report/live.c).
 * 1. One replacement of live.json (format ~5 kB of JSON, write, rename) in /tmp, microseconds.
 * 2. The linear example's whole curve (default strategy, virtual rig at full speed) run plainly
 *    and through the observing rig: wall seconds, evaluations (must be equal: the observing rig
 *    is transparent), and the cost of 1. as a share of the wall time of one evaluation.
 * Goal: well under 1 % of an evaluation even at full simulation speed (a lab evaluation takes
 * seconds of real time, so there the share is smaller still by orders of magnitude). */
#include "rths/continuation.h"
#include "rths/live.h"
#include "rths/rig_virtual.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct {
    rths_live *live;
} watch;

static int ignore_point(void *user, const rths_point *pt, int is_update) {
    (void)user;
    (void)pt;
    (void)is_update;
    return 0;
}

static void progress(void *user, int points, double frequency_hz, double residual_m,
                     int evaluations, int accepted) {
    watch *w = user;
    (void)evaluations;
    rths_live_progress(w->live, points, frequency_hz, residual_m, accepted);
}

/* The whole curve; live NULL runs it plainly. Returns wall seconds, *evaluations filled. */
static double run_curve(rths_live *live, int *evaluations) {
    const char *src = getenv("RTHS_SOURCE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/examples/four_storey_linear.yaml", src ? src : ".");
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    rths_rig *rig;
    if (rths_config_load(path, NULL, 0, &cfg, &err) || rths_setup_read(cfg, &s, &err) ||
        rths_virtual_rig_create(cfg, &s, 0, 0, &rig, &err)) {
        fprintf(stderr, "bench view: %s\n", err.msg);
        return -1;
    }
    if (live && rths_live_wrap_rig(live, rig, &rig, &err)) return -1;
    rths_settle_options so;
    rths_newton_options no;
    rths_continuation_options co;
    int harmonics = 1;
    rths_settle_defaults(&so, 0);
    rths_newton_defaults(&no, 0);
    rths_continuation_defaults(&co);
    co.model_predictor = 1;
    if (rths_iterate_config_read(cfg, &so, &no, &harmonics, &err) ||
        rths_continuation_config_read(cfg, &co, &err)) {
        fprintf(stderr, "bench view: %s\n", err.msg);
        return -1;
    }
    watch w = {live};
    rths_continuation_result res;
    double t0 = rths_monotonic_s();
    if (rths_continuation_run(rig, &co, &so, &no, harmonics, s.forcing_amplitude_n, NULL, 0,
                              ignore_point, live ? progress : NULL, &w, &res, &err))
        fprintf(stderr, "bench view: %s\n", err.msg);
    double wall = rths_monotonic_s() - t0;
    *evaluations = res.evaluations;
    rths_rig_destroy(rig);
    rths_setup_free(&s);
    rths_config_free(cfg);
    return wall;
}

static double per_write_s(rths_live *live, int calls) {
    rths_live_evaluation ev = {.frequency_hz = 12.9, .harmonics = 1, .rig_time_s = 100};
    for (int k = 0; k <= RTHS_MAX_HARMONICS; k++) {
        ev.phys.a[k] = 1e-5 / (k + 1);
        ev.phys.b[k] = -3e-6 / (k + 1);
        ev.num.a[k] = 1.01e-5 / (k + 1);
        ev.num.b[k] = -2.9e-6 / (k + 1);
    }
    rths_error err;
    double t0 = rths_monotonic_s();
    for (int i = 0; i < calls; i++) {
        ev.phys.a[1] = 1e-5 * (1 + 1e-3 * i);
        if (rths_live_evaluation_done(live, &ev, &err)) {
            fprintf(stderr, "bench view: %s\n", err.msg);
            return NAN;
        }
    }
    return (rths_monotonic_s() - t0) / calls;
}

void rths_bench_view(void) {
    char dir[] = "/tmp/rths-bench-view-XXXXXX";
    if (!mkdtemp(dir)) return;
    rths_live *live;
    rths_error err;
    if (rths_live_open(dir, &live, &err)) {
        fprintf(stderr, "bench view: %s\n", err.msg);
        return;
    }
    rths_live_set_interval(live, 0); /* every call writes */
    double write_s = per_write_s(live, 2000);
    size_t bytes = strlen(rths_live_text(live));
    rths_live_set_interval(live, 0.1); /* as a run has it */
    int evals_plain = 0, evals_watched = 0;
    double plain = run_curve(NULL, &evals_plain);
    double watched = run_curve(live, &evals_watched);
    rths_live_close(live);
    char path[256];
    snprintf(path, sizeof path, "%s/live.json", dir);
    remove(path);
    rmdir(dir);
    double per_eval = plain / evals_plain;
    printf(
        "live.json: %zu bytes, %.1f us per replacement (mean of 2000, format + write + rename)\n",
        bytes, 1e6 * write_s);
    printf("linear example, default strategy, virtual rig at full speed:\n");
    printf("  plain    %7.2f s wall, %d evaluations, %.2f ms wall per evaluation\n", plain,
           evals_plain, 1e3 * per_eval);
    printf("  watched  %7.2f s wall, %d evaluations (live.json at most 10 per second)\n", watched,
           evals_watched);
    printf("  one replacement = %.3f %% of an evaluation's wall time; with at most one per 0.1 s, "
           "at most %.3f %% of the run's wall time (goal: < 1 %%)\n",
           100 * write_s / per_eval, 100 * write_s / fmax(per_eval, 0.1));
}
