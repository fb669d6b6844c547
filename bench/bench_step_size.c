/* The per-sample controller step against the numerical substructure's size: a storey chain (the
 * seed's storeys 1-2 physical, storey 3 the interface, n - 1 seed-like storeys above it
 * numerical, forced at the top), n = 2 .. 1000. Up to 16 numerical DoFs the step integrates the
 * substructure as it is; above, its Craig-Bampton reduction (reduce.h, auto cutoff: every mode up
 * to 500 Hz at 10 kHz, at most 32 DoFs). Prints the build time (reduction and discretisation),
 * the integrated size and ns per step against the 100 us budget of a 10 kHz loop. Then the same
 * chains (up to 16 numerical DoFs) with RTHS_MAX_NONLINEAR elements on the numerical side (cubic,
 * friction, gap, bilinear in turn between neighbouring numerical storeys): the mean and the
 * slowest single step, and the most Newton steps a sample took (docs/method.md, "Nonlinear
 * elements in the real-time step"). */
#include "rths/controller.h"
#include "rths/nonlinear.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

/* A config of a chain with n numerical DoFs (interface included), with `elements` nonlinear
 * elements between neighbouring numerical storeys (storey 3 the interface); 0 on success. */
static int write_chain(const char *path, int n, int elements) {
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
    if (elements > 0) {
        static const char *const kinds[4] = {"type: cubic, stiffness_n_per_m3: 1e12",
                                             "type: friction, slip_force_n: 0.2",
                                             "type: gap, stiffness_n_per_m: 2e4, clearance_m: 0",
                                             "type: bilinear, compression_ratio: 2"};
        fprintf(f, "  nonlinear:\n");
        for (int e = 0; e < elements; e++) {
            int upper = 4 + e % (n - 1); /* storeys 4 .. n + 2, each on the one below */
            fprintf(f, "    - {%s, dofs: [%d, %d]}\n", kinds[e % 4], upper, upper - 1);
        }
    }
    fprintf(f,
            "split:\n  interface: [3]\n  mass_ratio: 0.5\nforcing:\n  dof: %d\n  amplitude_n: 1\n",
            storeys);
    return fclose(f);
}

static int by_value(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static void bench_size(const char *path, int n, int elements) {
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (write_chain(path, n, elements) || rths_config_load(path, NULL, 0, &cfg, &err) ||
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
    float *each_s = elements ? malloc(sizeof(float) * (size_t)steps) : NULL;
    t0 = rths_monotonic_s();
    for (long i = 0; i < steps; i++) {
        in.displacement_m[s.split.np - 1] = 1e-4 * sin(1e-3 * (double)i);
        /* with elements every step is timed on its own: the slow tail is the worst case (a kink
         * crossed, the most Newton steps), plus the clock's own cost and any preemption, which
         * the 99.9th percentile leaves out */
        double ts = each_s ? rths_monotonic_s() : 0;
        sink += rths_controller_step(c, &in, NULL);
        if (each_s) each_s[i] = (float)(rths_monotonic_s() - ts);
        rths_period p;
        while (rths_controller_pop_period(c, &p))
            sink += p.phys.a[1];
    }
    double ns = 1e9 * (rths_monotonic_s() - t0) / steps;
    int dofs = rths_controller_numerical_dofs(c);
    if (each_s) {
        qsort(each_s, (size_t)steps, sizeof *each_s, by_value);
        double tail = each_s[steps - steps / 1000];
        printf("%8d %10d %10.0f %12.0f %10d %10.2f%s\n", n, elements, ns, 1e9 * tail,
               rths_controller_nonlinear_newton_steps(c), 100.0 * 1e9 * tail / 1e5,
               sink == 1234.5 ? " " : "");
    } else
        printf("%8d %10s %10d %12.3f %10.0f %10.2f%s\n", n, dofs < n ? "reduced" : "full", dofs,
               build_s, ns, 100.0 * ns / 1e5, sink == 1234.5 ? " " : "");
    free(each_s);
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
        bench_size(path, sizes[i], 0);
    printf("\nnonlinear elements on the numerical side (%d at most, Newton bound per sample):\n",
           RTHS_MAX_NONLINEAR);
    printf("%8s %10s %10s %12s %10s %10s\n", "num_dofs", "elements", "ns/step", "p99.9_ns",
           "newton_max", "budget_%");
    const int nl_sizes[] = {2, 8, 16};
    for (size_t i = 0; i < sizeof nl_sizes / sizeof nl_sizes[0]; i++)
        bench_size(path, nl_sizes[i], RTHS_MAX_NONLINEAR);
    remove(path);
}
