/* The per-sample controller step alone (ns per step) and with the virtual plant (samples per
 * second, real-time factor at the seed's 10 kHz), seed structure, default options. */
#include "rths/rig_virtual.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

void rths_bench_controller(void) {
    const char *dir = getenv("RTHS_SOURCE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/examples/four_storey.yaml", dir ? dir : ".");
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (rths_config_load(path, NULL, 0, &cfg, &err) || rths_setup_read(cfg, &s, &err)) {
        fprintf(stderr, "bench controller: %s\n", err.msg);
        return;
    }
    for (int sc = 0; sc < RTHS_SCHEME_COUNT; sc++) {
        rths_controller_options co;
        rths_controller_defaults(&co);
        co.scheme = (rths_scheme)sc;
        rths_controller *c;
        if (rths_controller_create(&s, &co, &c, &err)) return;
        double a[1] = {1e-4}, b[1] = {0};
        rths_controller_set_forcing(c, 13.47, 1.0);
        rths_controller_set_target(c, 1, a, b);
        rths_controller_arm(c, 1);
        rths_sensor_sample in = {.n = 3};
        const long n = 2000000;
        double sink = 0, t0 = rths_monotonic_s();
        for (long i = 0; i < n; i++) {
            in.displacement_m[2] = 1e-4 * sin(1e-3 * (double)i);
            sink += rths_controller_step(c, &in, NULL);
            rths_period p;
            while (rths_controller_pop_period(c, &p))
                sink += p.phys.a[1];
        }
        double dt = rths_monotonic_s() - t0;
        printf("controller step alone, %-15s %7.1f ns per step (%ld steps)%s\n",
               rths_scheme_name((rths_scheme)sc), 1e9 * dt / n, n, sink == 12345 ? " " : "");
        rths_controller_destroy(c);
    }
    rths_rig *rig;
    if (rths_virtual_rig_create(cfg, &s, 0, 0, &rig, &err)) return;
    double a[1] = {1e-4}, b[1] = {0};
    rths_rig_set_forcing(rig, 13.47, 1.0, &err);
    rths_rig_set_target(rig, 1, a, b, &err);
    rths_period *p = calloc(200, sizeof *p);
    double t0 = rths_monotonic_s(), r0 = rths_rig_time_s(rig);
    rths_rig_run_periods(rig, 200, p, &err);
    double wall = rths_monotonic_s() - t0, simulated = rths_rig_time_s(rig) - r0;
    printf(
        "virtual rig (step + plant, noise, exact plant): %.0f samples/s, real-time factor %.1f at "
        "10 kHz\n",
        simulated * 1e4 / wall, simulated / wall);
    free(p);
    rths_rig_destroy(rig);
    rths_setup_free(&s);
    rths_config_free(cfg);
}
