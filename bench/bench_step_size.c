/* The per-sample controller step against the numerical substructure's size: a storey chain (the
 * seed's storeys 1-2 physical, storey 3 the interface, n - 1 seed-like storeys above it
 * numerical, forced at the top), n = 2 .. 1000. Up to 16 numerical DoFs the step integrates the
 * substructure as it is; above, its Craig-Bampton reduction (reduce.h, auto cutoff: every mode up
 * to 500 Hz at 10 kHz, at most 32 DoFs). Prints the build time (reduction and discretisation),
 * the integrated size and ns per step against the 100 us budget of a 10 kHz loop. */
#include "rths/controller.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

/* A config of a chain with n numerical DoFs (interface included); 0 on success. */
static int write_chain(const char *path, int n) {
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    int storeys = n + 2;
    const char *keys[3] = {"mass_kg", "damping_n_s_per_m", "stiffness_n_per_m"};
    const double values[3] = {5.37, 3.7421, 45052};
    fprintf(f, "structure:\n  storeys:\n");
    for (int k = 0; k < 3; k++) {
        fprintf(f, "    %s: [", keys[k]);
        for (int i = 0; i < storeys; i++)
            fprintf(f, "%s%g", i ? ", " : "", values[k]);
        fprintf(f, "]\n");
    }
    fprintf(f,
            "split:\n  interface: [3]\n  mass_ratio: 0.5\nforcing:\n  dof: %d\n  amplitude_n: 1\n",
            storeys);
    return fclose(f);
}

static void bench_size(const char *path, int n) {
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (write_chain(path, n) || rths_config_load(path, NULL, 0, &cfg, &err) ||
        rths_setup_read(cfg, &s, &err)) {
        fprintf(stderr, "bench step_size: n = %d: %s\n", n, err.msg);
        return;
    }
    rths_controller_options co;
    rths_controller_defaults(&co);
    rths_controller *c;
    double t0 = rths_monotonic_s();
    if (rths_controller_create(&s, &co, &c, &err)) {
        fprintf(stderr, "bench step_size: n = %d: %s\n", n, err.msg);
        rths_setup_free(&s);
        rths_config_free(cfg);
        return;
    }
    double build_s = rths_monotonic_s() - t0;
    double a[1] = {1e-4}, b[1] = {0};
    rths_controller_set_forcing(c, 13.47, 1.0);
    rths_controller_set_target(c, 1, a, b);
    rths_controller_arm(c, 1);
    rths_sensor_sample in = {.n = s.split.np};
    const long steps = 400000;
    double sink = 0;
    t0 = rths_monotonic_s();
    for (long i = 0; i < steps; i++) {
        in.displacement_m[s.split.np - 1] = 1e-4 * sin(1e-3 * (double)i);
        sink += rths_controller_step(c, &in, NULL);
        rths_period p;
        while (rths_controller_pop_period(c, &p))
            sink += p.phys.a[1];
    }
    double ns = 1e9 * (rths_monotonic_s() - t0) / steps;
    int dofs = rths_controller_numerical_dofs(c);
    printf("%8d %10s %10d %12.3f %10.0f %10.2f%s\n", n, dofs < n ? "reduced" : "full", dofs,
           build_s, ns, 100.0 * ns / 1e5, sink == 1234.5 ? " " : "");
    rths_controller_destroy(c);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

void rths_bench_step_size(void) {
    char path[] = "/tmp/rths_bench_step_XXXXXX";
    int fd = mkstemp(path);
    if (fd < 0) return;
    close(fd);
    printf("%8s %10s %10s %12s %10s %10s\n", "num_dofs", "model", "integrated", "build_s",
           "ns/step", "budget_%");
    const int sizes[] = {2, 8, 16, 50, 200, 1000};
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++)
        bench_size(path, sizes[i]);
    remove(path);
}
