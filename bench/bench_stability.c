/* The seed's 4-storey stability chart at 200 x 200 (tau, p) with MDBM boundaries, on 1 and 2
 * threads: wall time, grid points per second, and a check that both runs give identical output. */
#include "rths/stability.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

void rths_bench_stability(void) {
    static const double m[4] = {5.37, 5.37, 5.37, 10.74};
    static const double c[4] = {4.4062, 3.7979, 3.7421, 3.7421};
    static const double k[4] = {53048, 45724, 45052, 45052};
    static const rths_dof_role roles[4] = {RTHS_DOF_PHYSICAL, RTHS_DOF_PHYSICAL, RTHS_DOF_INTERFACE,
                                           RTHS_DOF_NUMERICAL};
    rths_assembly a;
    rths_error err;
    if (rths_assembly_from_chain(4, m, c, k, &a, &err)) {
        printf("stability: %s\n", err.msg);
        return;
    }
    rths_split_family fam = {.assembly = &a, .roles = roles};
    rths_chart_options o;
    rths_chart_options_default(&o); /* the seed's ranges, 200 x 200 */
    const int threads[2] = {1, 2};
    double secs[2] = {0, 0};
    rths_chart ch[2];
    int ok[2] = {0, 0};
    for (int r = 0; r < 2; r++) {
#ifdef _OPENMP
        omp_set_num_threads(threads[r]);
#else
        if (threads[r] > 1) continue;
#endif
        double t0 = rths_monotonic_s();
        ok[r] = rths_chart_compute(rths_split_family_build, &fam, &o, &ch[r], &err) == RTHS_OK;
        secs[r] = rths_monotonic_s() - t0;
        if (!ok[r]) printf("stability: chart failed: %s\n", err.msg);
    }
    int pts = o.tau_points * o.p_points;
    printf("seed 4-storey chart %d x %d (tau x p), MDBM %d x %d x %d refine %d, Chebyshev %d\n",
           o.tau_points, o.p_points, o.mdbm_tau_points, o.mdbm_p_points, o.omega_points,
           o.mdbm_refine, o.chebyshev_nodes);
    printf("%-10s %12s %14s %12s\n", "threads", "seconds", "points/s", "boundary");
    for (int r = 0; r < 2; r++)
        if (ok[r])
            printf("%-10d %12.3f %14.0f %12d\n", threads[r], secs[r], pts / secs[r],
                   ch[r].n_boundary);
    if (ok[0] && ok[1]) {
        int same_b = ch[0].n_boundary == ch[1].n_boundary &&
                     !memcmp(ch[0].b_tau, ch[1].b_tau, sizeof(double) * (size_t)ch[0].n_boundary);
        int same_l = !memcmp(ch[0].stable, ch[1].stable, sizeof(int) * (size_t)pts);
        double dmax = 0;
        for (int i = 0; i < pts; i++)
            dmax = fmax(dmax, fabs(ch[0].max_real[i] - ch[1].max_real[i]) /
                                  (1e-300 + fabs(ch[0].max_real[i])));
        printf("speed-up %.2f x; across thread counts: labels identical %s, boundaries identical "
               "%s, max relative difference of max_real %.2g\n",
               secs[0] / secs[1], same_l ? "yes" : "NO", same_b ? "yes" : "NO", dmax);
        int j = (int)lround((0.67 - o.p_min) / (o.p_max - o.p_min) * (o.p_points - 1));
        printf("critical delay at p = %.4f: %.6e s (%.3f rad/s); label cross-check: %d changes, "
               "%d unexplained, %d boundary points inside the stable region\n",
               ch[0].p[j], ch[0].critical_tau[j], ch[0].critical_omega[j], ch[0].label_changes,
               ch[0].label_changes_unexplained, ch[0].boundary_unexplained);
    }
    for (int r = 0; r < 2; r++)
        if (ok[r]) rths_chart_free(&ch[r]);
    rths_assembly_free(&a);
}
