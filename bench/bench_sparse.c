/* sparse: the sparse engine (sparse.h) on 3-D frames from tools/gen_frame3d.py (Euler-Bernoulli
 * 3-D beams, nodes numbered at random, consistent mass) of about 10 000, 60 000 (the 50 x 5 x 40
 * slab block of issue 26's acceptance) and 100 000 DoFs: read
 * (rths_mtx_read_sparse of K and M), symbolic analysis (SCOTCH ordering), numerical LDL^T of K,
 * the lowest 20 modes by shift-invert Lanczos, each timed, and the process's peak resident memory
 * after each case (getrusage: the peak so far, so the 100k line holds the larger). The generator's
 * own time is printed apart. Run from the source tree (it calls tools/gen_frame3d.py with
 * /usr/bin/python3); RTHS_BENCH_SPARSE_MAX_DOFS=20000 skips the large cases.
 *
 * A second table, `rths frf` on the 60 000-DoF frame (RTHS_BENCH_SPARSE_MAX_DOFS >= 60000; the
 * 100 500-DoF one too at >= 100000): the two-storey 2 kg / 2000 N/m specimen on the rig tied to
 * ux of a roof node, the force (1e4 N) on the far roof node, noise off, natural continuation over
 * three points of a band between the frame's modes, in both split.numerical_solver forms
 * (frequency: one complex LDL^T of the numerical side per harmonic frequency, kept per frequency;
 * realtime: the controller's band-exact Krylov reduction over controller.reduction.check_points
 * complex LDL^Ts of the interior): wall time of reading the setup and of the run, the points
 * converged, the worst relative amplitude error against the truth (an independent direct sparse
 * solve of the whole assembly per frequency, not the split's iteration), the peak memory.
 * Steady-state detection tightened (iteration.settle.rel_tolerance 1e-5, min_wait_periods 20):
 * the frame's lightly damped modes near the band decay over tens of periods. */
#include "rths/config.h"
#include "rths/mtx.h"
#include "rths/run.h"
#include "rths/setup.h"
#include "rths/sparse.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double peak_mb(void) {
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return (double)u.ru_maxrss / 1024.0; /* ru_maxrss is in kB on Linux */
}

static void run_case(const char *label, int nx, int ny, int nz) {
    char dir[] = "/tmp/rths_bench_sparse_XXXXXX", cmd[512], kpath[300], mpath[300];
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return;
    }
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 tools/gen_frame3d.py --nx %d --ny %d --nz %d --seed 1 %s "
             ">/dev/null",
             nx, ny, nz, dir);
    double t0 = now_s();
    if (system(cmd)) {
        fprintf(stderr, "bench sparse: %s failed (run rths_bench from the source tree)\n", cmd);
        return;
    }
    double gen_s = now_s() - t0;
    snprintf(kpath, sizeof kpath, "%s/stiffness_n_per_m.mtx", dir);
    snprintf(mpath, sizeof mpath, "%s/mass_kg.mtx", dir);
    rths_sparse_sym k, m;
    rths_error err;
    t0 = now_s();
    if (rths_mtx_read_sparse(kpath, RTHS_MTX_POSITIVE_DIAGONAL, &k, &err) ||
        rths_mtx_read_sparse(mpath, RTHS_MTX_POSITIVE_DIAGONAL, &m, &err)) {
        fprintf(stderr, "bench sparse: %s\n", err.msg);
        return;
    }
    double read_s = now_s() - t0;
    rths_sparse_eigs_options opt = rths_sparse_eigs_defaults();
    opt.count = 20;
    double *lambda, *phi;
    int found;
    rths_sparse_eigs_stats st;
    t0 = now_s();
    if (rths_sparse_eigs(&k, &m, &opt, &lambda, &phi, &found, &st, &err)) {
        fprintf(stderr, "bench sparse: %s\n", err.msg);
        return;
    }
    double eig_total_s = now_s() - t0;
    printf("%-6s %8d %9d %7.2f %7.3f %8.3f %7.3f %8.3f %8.3f %5d %9.1f %8.0f  %.4f..%.4f\n", label,
           k.n, k.colptr[k.n], gen_s, read_s, st.analysis_s, st.factor_s, st.lanczos_s, eig_total_s,
           st.operator_applications, (double)st.factor_entries / 1e6, peak_mb(),
           sqrt(lambda[0]) / (2 * M_PI), sqrt(lambda[found - 1]) / (2 * M_PI));
    fflush(stdout);
    free(lambda);
    free(phi);
    rths_sparse_free(&k);
    rths_sparse_free(&m);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd)) fprintf(stderr, "bench sparse: could not remove %s\n", dir);
}

/* One `rths frf` run of a generated frame's configuration in the given form (see the header). */
static void frf_run(const char *label, const char *dir, const char *form, double lo_hz,
                    double hi_hz, int check_points) {
    char path[400], out[420], sets[20][96];
    snprintf(path, sizeof path, "%s/frame.yaml", dir);
    snprintf(out, sizeof out, "%s/run_%s", dir, form);
    int n = 0;
    snprintf(sets[n++], 96, "model.solver=sparse");
    snprintf(sets[n++], 96, "model.frf.points=3");
    snprintf(sets[n++], 96, "split.numerical_solver=%s", form);
    snprintf(sets[n++], 96, "split.mass_ratio=0.999");
    snprintf(sets[n++], 96, "split.interface_stiffness_physical_n_per_m=[[2.0e3]]");
    snprintf(sets[n++], 96, "split.interface_damping_physical_n_s_per_m=[[0.2]]");
    snprintf(sets[n++], 96, "forcing.amplitude_n=1e4");
    snprintf(sets[n++], 96, "rig.interface_mass=physical_share");
    snprintf(sets[n++], 96, "rig.noise=false");
    snprintf(sets[n++], 96, "continuation.start_hz=%g", lo_hz);
    snprintf(sets[n++], 96, "continuation.end_hz=%g", hi_hz);
    snprintf(sets[n++], 96, "continuation.method=natural");
    snprintf(sets[n++], 96, "continuation.initial_step_hz=%g", 0.5 * (hi_hz - lo_hz));
    snprintf(sets[n++], 96, "continuation.max_step_hz=%g", 0.5 * (hi_hz - lo_hz));
    snprintf(sets[n++], 96, "controller.reduction.check_points=%d", check_points);
    /* steady when a period changes the coefficients by 1e-5 (default 3e-4), after 20 periods at
     * least: with the defaults the real-time form's evaluations on the 100k frame stopped on
     * the frame's slow transients, 0.6 % and 3.6 % off at two points, 3e-7..3e-5 with these */
    snprintf(sets[n++], 96, "iteration.settle.rel_tolerance=1e-5");
    snprintf(sets[n++], 96, "iteration.settle.min_wait_periods=20");
    const char *overrides[20];
    for (int i = 0; i < n; i++)
        overrides[i] = sets[i];
    rths_config *cfg = NULL;
    rths_setup setup;
    rths_error err;
    double t0 = now_s();
    if (rths_config_load(path, overrides, n, &cfg, &err) || rths_setup_read(cfg, &setup, &err)) {
        printf("%-6s %-9s setup failed: %s\n", label, form, err.msg);
        rths_config_free(cfg);
        return;
    }
    double setup_s = now_s() - t0;
    rths_run_frf_options opt = {.cfg = cfg, .setup = &setup, .out_dir = out};
    rths_run_frf_result r;
    t0 = now_s();
    int rc = rths_run_frf(&opt, NULL, &r, &err);
    double run_s = now_s() - t0;
    if (rc && !r.outputs_written)
        printf("%-6s %-9s run failed: %s\n", label, form, err.msg);
    else
        printf("%-6s %8d %-9s %7.1f %8.1f %4d/%-4d %11.2e %8.0f  %s\n", label, setup.assembly.n,
               form, setup_s, run_s, r.converged_points, r.points, r.max_relative_error_vs_truth,
               peak_mb(), r.status == RTHS_RUN_COMPLETED ? "completed" : r.stop_reason);
    fflush(stdout);
    rths_setup_free(&setup);
    rths_config_free(cfg);
}

static void frf_case(const char *label, int nx, int ny, int nz, double lo_hz, double hi_hz,
                     int check_points) {
    char dir[] = "/tmp/rths_bench_sparse_frf_XXXXXX", cmd[512];
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return;
    }
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 tools/gen_frame3d.py --nx %d --ny %d --nz %d --seed 1 "
             "--specimen 2 2e3 %s >/dev/null",
             nx, ny, nz, dir);
    if (system(cmd)) {
        fprintf(stderr, "bench sparse: %s failed (run rths_bench from the source tree)\n", cmd);
        return;
    }
    frf_run(label, dir, "frequency", lo_hz, hi_hz, check_points);
    frf_run(label, dir, "realtime", lo_hz, hi_hz, check_points);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd)) fprintf(stderr, "bench sparse: could not remove %s\n", dir);
}

void rths_bench_sparse(void) {
    const char *max_env = getenv("RTHS_BENCH_SPARSE_MAX_DOFS");
    long max_dofs = max_env ? atol(max_env) : 200000;
    printf("3-D frames (tools/gen_frame3d.py, consistent mass, random numbering), lowest 20 "
           "modes; SCOTCH ordering, MUMPS LDL^T, ARPACK shift-invert Lanczos\n");
    printf("%-6s %8s %9s %7s %7s %8s %7s %8s %8s %5s %9s %8s  %s\n", "case", "dofs", "K_nnz",
           "gen_s", "read_s", "analys_s", "fact_s", "lanczos_s", "eigs_s", "ops", "L_Mentry",
           "peak_MB", "f1..f20_hz");
    run_case("10k", 10, 6, 28); /* 1680 free nodes: 10 080 DoFs */
    /* the acceptance frame of issue 26: a slab block of 50 x 5 column lines, 40 storeys */
    if (max_dofs >= 60000) run_case("60k", 50, 5, 40);   /* 10 000 free nodes: 60 000 DoFs */
    if (max_dofs >= 100000) run_case("100k", 50, 5, 67); /* 16 750 free nodes: 100 500 DoFs */
    if (max_dofs < 60000) return;
    printf("rths frf on the frames, 2 kg / 2000 N/m specimen on the rig, 1e4 N on the far roof "
           "node, noise off, 3 points; error against the direct sparse solve of the assembly\n");
    printf("%-6s %8s %-9s %7s %8s %9s %11s %8s  %s\n", "case", "dofs", "form", "setup_s", "run_s",
           "conv/pts", "max_rel_err", "peak_MB", "status");
    /* between the 60k frame's 8th and 9th modes (0.164, 0.184 Hz); 5 check points of the
     * real-time reduction (each a complex LDL^T of the interior) */
    frf_case("60k", 50, 5, 40, 0.15, 0.17, 5);
    if (max_dofs >= 100000) frf_case("100k", 50, 5, 67, 0.15, 0.17, 5);
}
