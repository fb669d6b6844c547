/* Benchmark of the controller process (make bench): the per-sample step's cost inside the
 * controller, and the wall-clock loop's lateness at the configured rate (10 kHz for the seed)
 * while a host drives it over loopback TCP. Called from bench_main.c as rths_bench_link(). */
#include "rths/config.h"
#include "rths/controller.h"
#include "rths/plant.h"
#include "rths/rig_remote.h"
#include "rths/server.h"
#include "rths/setup.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/utsname.h>

void rths_bench_link(void);

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void kernel_notice(void) {
    struct utsname u;
    int rt = 0;
    FILE *f = fopen("/sys/kernel/realtime", "r");
    if (f) {
        rt = fgetc(f) == '1';
        fclose(f);
    }
    if (!uname(&u) && strstr(u.version, "PREEMPT_RT")) rt = 1;
    printf("link: kernel %s %s: %s\n", u.release, u.version,
           rt ? "a PREEMPT_RT (real-time) kernel"
              : "NOT a real-time kernel (no PREEMPT_RT): lateness below is best effort on a "
                "general-purpose kernel, shared with other jobs");
}

static rths_config *load_seed(void) {
    const char *root = getenv("RTHS_SOURCE_DIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/examples/four_storey.yaml", root ? root : ".");
    const char *sets[] = {"server.watchdog_s=5"};
    rths_config *cfg = NULL;
    rths_error err;
    if (rths_config_load(path, sets, 1, &cfg, &err)) {
        printf("link: cannot load %s: %s\n", path, err.msg);
        return NULL;
    }
    return cfg;
}

static void report_costs(const char *what, double *cost, int n, double h) {
    qsort(cost, (size_t)n, sizeof *cost, cmp_double);
    double sum = 0;
    for (int i = 0; i < n; i++)
        sum += cost[i];
    printf("link:   %-34s mean %6.0f ns, p50 %6.0f ns, p99 %6.0f ns, p99.9 %6.0f ns, max %7.0f ns "
           "(p99 = %.1f%% of the sample period)\n",
           what, sum / n * 1e9, cost[n / 2] * 1e9, cost[(int)(0.99 * n)] * 1e9,
           cost[(int)(0.999 * n)] * 1e9, cost[n - 1] * 1e9, 100.0 * cost[(int)(0.99 * n)] / h);
}

/* The per-sample work back to back (no pacing), the controller step and the simulated plant
 * timed apart: on a real rig the plant's share is the DAQ card's I/O instead. */
static void bench_step_cost(void) {
    rths_config *cfg = load_seed();
    if (!cfg) return;
    rths_setup setup;
    rths_controller_options copt;
    rths_plant_options popt;
    rths_controller *ctl = NULL;
    rths_plant *plant = NULL;
    rths_error err;
    rths_controller_defaults(&copt);
    rths_plant_defaults(&popt);
    if (rths_setup_read(cfg, &setup, &err) || rths_controller_config_read(cfg, &copt, &err) ||
        rths_plant_config_read(cfg, &popt, &err) ||
        rths_controller_create(&setup, &copt, &ctl, &err) ||
        rths_plant_create(&setup, &popt, copt.sample_rate_hz, &plant, &err)) {
        printf("link: cannot build the step: %s\n", err.msg);
        rths_config_free(cfg);
        return;
    }
    const double h = 1.0 / copt.sample_rate_hz;
    double a[1] = {1e-4}, b[1] = {0.0};
    rths_controller_set_forcing(ctl, 13.47, 1.0);
    rths_controller_set_target(ctl, 1, a, b);
    rths_controller_arm(ctl, 1);
    enum { N = 200000 };
    double *c_step = malloc(N * sizeof *c_step), *c_plant = malloc(N * sizeof *c_plant);
    rths_sensor_sample in;
    rths_controller_output o;
    for (int i = 0; i < 20000; i++) { /* warm up: caches, ramp, the first periods */
        rths_plant_read(plant, &in);
        rths_plant_advance(plant, rths_controller_step(ctl, &in, &o));
    }
    for (int i = 0; i < N; i++) {
        double t0 = rths_monotonic_s();
        rths_plant_read(plant, &in);
        double t1 = rths_monotonic_s();
        double u = rths_controller_step(ctl, &in, &o);
        double t2 = rths_monotonic_s();
        rths_plant_advance(plant, u);
        double t3 = rths_monotonic_s();
        c_step[i] = t2 - t1;
        c_plant[i] = (t1 - t0) + (t3 - t2);
    }
    rths_period p;
    while (rths_controller_pop_period(ctl, &p)) {
    }
    char plant_integrator[48];
    if (popt.substeps_per_sample > 0)
        snprintf(plant_integrator, sizeof plant_integrator, "RK4 x%d", popt.substeps_per_sample);
    else
        snprintf(plant_integrator, sizeof plant_integrator, "exact");
    printf("link: per-sample cost, %d samples back to back at 13.47 Hz (%s integrator, %s plant); "
           "includes ~20-40 ns of clock reads:\n",
           N, copt.scheme == RTHS_SCHEME_DEFAULT ? "default" : "configured", plant_integrator);
    report_costs("controller step (the RT work):", c_step, N, h);
    report_costs("simulated plant (read + advance):", c_plant, N, h);
    free(c_step);
    free(c_plant);
    rths_plant_destroy(plant);
    rths_controller_destroy(ctl);
    rths_setup_free(&setup);
    rths_config_free(cfg);
}

/* The paced loop, driven by a host over loopback for a few seconds. */
static void bench_paced_loop(double seconds) {
    rths_config *cfg = load_seed();
    if (!cfg) return;
    rths_server_options opt;
    rths_server_options_defaults(&opt);
    rths_error err;
    rths_server *s = NULL;
    if (rths_server_config_read(cfg, &opt, &err) ||
        (opt.port = 0, opt.quiet = 1, rths_server_create(cfg, &opt, &s, &err)) ||
        rths_server_start(s, &err)) {
        printf("link: server: %s\n", err.msg);
        rths_server_destroy(s);
        rths_config_free(cfg);
        return;
    }
    char uri[64];
    snprintf(uri, sizeof uri, "tcp://127.0.0.1:%d", rths_server_port(s));
    rths_rig *rig = NULL;
    double a[1] = {1e-4}, b[1] = {0.0};
    const double f = 13.47;
    int periods = (int)ceil(seconds * f);
    rths_period *per = malloc((size_t)periods * sizeof *per);
    double t0 = rths_monotonic_s();
    int ok = !rths_remote_rig_create(uri, NULL, &rig, &err) &&
             !rths_rig_set_forcing(rig, f, 1.0, &err) && !rths_rig_set_target(rig, 1, a, b, &err) &&
             !rths_rig_run_periods(rig, periods, per, &err);
    double wall = rths_monotonic_s() - t0;
    rths_server_stats st;
    rths_server_get_stats(s, &st);
    if (!ok) printf("link: host run failed: %s\n", err.msg);
    double h = rths_server_sample_period_s(s);
    printf("link: paced loop at %.0f Hz for %.2f s wall (%llu samples = %.2f s controller time), "
           "host on loopback TCP receiving %d periods\n",
           1.0 / h, wall, (unsigned long long)st.samples, (double)st.samples * h, periods);
    printf("link: real-time: SCHED_FIFO %s, memory locked %s, CPU pinned %s\n",
           st.rt_fifo ? "yes" : "no", st.rt_mlock ? "yes" : "no", st.rt_pinned ? "yes" : "no");
    printf("link: wake-up lateness p50 %.0f us, p90 %.0f us, p99 %.0f us, p99.9 %.0f us, worst "
           "%.0f us (1 us bins, upper edges); overruns %llu (%.3f%%), resyncs %llu\n",
           st.lateness_p50_s * 1e6, st.lateness_p90_s * 1e6, st.lateness_p99_s * 1e6,
           st.lateness_p999_s * 1e6, st.worst_lateness_s * 1e6, (unsigned long long)st.overruns,
           st.samples ? 100.0 * (double)st.overruns / (double)st.samples : 0.0,
           (unsigned long long)st.resyncs);
    printf("link: per-sample work inside the paced loop (controller step + simulated plant): mean "
           "%.2f us, p50 %.1f us, p99 %.1f us, max "
           "%.1f us\n",
           st.step_mean_s * 1e6, st.step_p50_s * 1e6, st.step_p99_s * 1e6, st.step_max_s * 1e6);
    free(per);
    rths_rig_destroy(rig);
    rths_server_destroy(s);
    rths_config_free(cfg);
}

void rths_bench_link(void) {
    kernel_notice();
    bench_step_cost();
    bench_paced_loop(3.0);
}
