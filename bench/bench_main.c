/* rths_bench: every benchmark of the project in one executable. `rths_bench [FILTER]` runs those
 * whose name contains FILTER (all when absent). Each bench/<name>.c defines one
 * `void rths_bench_<name>(void)` and adds a line to the table below. */
#include <stdio.h>
#include <string.h>

/* weak: a bench whose file is not in the build is listed as absent instead of breaking it */
void rths_bench_stability(void) __attribute__((weak));
void rths_bench_controller(void) __attribute__((weak));
void rths_bench_frf(void) __attribute__((weak));
void rths_bench_link(void) __attribute__((weak));
void rths_bench_model(void) __attribute__((weak));
void rths_bench_plant(void) __attribute__((weak));
void rths_bench_view(void) __attribute__((weak));
void rths_bench_step_size(void) __attribute__((weak));
void rths_bench_sparse(void) __attribute__((weak));

typedef struct {
    const char *name;
    void (*fn)(void);
} bench_entry;

int main(int argc, char **argv) {
    const bench_entry benches[] = {
        {"controller", rths_bench_controller},
        {"frf", rths_bench_frf},
        {"stability", rths_bench_stability},
        {"link", rths_bench_link},
        {"model", rths_bench_model},
        {"plant", rths_bench_plant},
        {"view", rths_bench_view},
        {"step_size", rths_bench_step_size},
        {"sparse", rths_bench_sparse},
    };
    const char *filter = argc > 1 ? argv[1] : NULL;
    if (filter && (!strcmp(filter, "--help") || !strcmp(filter, "-h"))) {
        printf("Usage: rths_bench [FILTER]\nBenchmarks:");
        for (size_t i = 0; i < sizeof benches / sizeof benches[0]; i++)
            printf(" %s", benches[i].name);
        printf("\n");
        return 0;
    }
    int ran = 0;
    for (size_t i = 0; i < sizeof benches / sizeof benches[0]; i++) {
        if (filter && !strstr(benches[i].name, filter)) continue;
        if (!benches[i].fn) continue;
        printf("== %s ==\n", benches[i].name);
        fflush(stdout);
        benches[i].fn();
        ran++;
    }
    if (!ran) {
        fprintf(stderr, "rths_bench: no benchmark matches '%s'\n", filter);
        return 2;
    }
    return 0;
}
