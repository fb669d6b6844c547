/* Two scaling benchmarks, printed as tables.
 *
 * model: the work of `rths model` (modal analysis, FRF preparation, the FRF at the 727
 * frequencies of the example's grid for 4 written DoFs) on the seed building whose top leg is a
 * rod of n - 3 elements (examples/rod_chain_1000 at n = 1000), against n; beside it the cost of
 * the former dense complex solve per frequency (timed on a few frequencies, extrapolated).
 *
 * plant: the virtual rig on the seed (examples/four_storey.yaml, default rig with noise): the
 * plant alone (read + advance per sample; without noise too, which shows what the five sensors'
 * normal draws cost) and the whole virtual rig (controller step + plant,
 * 2000 forcing periods at 13.47 Hz after 20 untimed), exact integrator against RK4 x 8, as samples
 * per second and real-time factor at the seed's 10 kHz.
 *
 * model (second table): `rths model`'s sparse path (model.h, "large sparse models") on 3-D frames
 * from tools/gen_frame3d.py with nodes numbered at random and a two-storey specimen tied to a roof
 * node (issue 26's acceptance case: 50 x 5 column lines x 40 storeys, 60 000 DoFs; 67 storeys,
 * 100 500 DoFs; and 10 080 DoFs): each stage's wall time (read, order, factor, eigen, checks,
 * FRF over the default grid) and the peak memory so far. Run from the source tree (the generator
 * is called with /usr/bin/python3); RTHS_BENCH_MODEL_MAX_DOFS=20000 skips the large cases.
 *
 * model (a "reduce" line after each frame's row): on the same frames, the real-time reduction right
 * in the band (krylov_reduce.h) over the band from half the first mode to the tenth, the error
 * checked by RTHS_KRYLOV_CHECK_POINTS_DEFAULT full sparse complex solves of the numerical side: its
 * wall time (the check's full solves, the basis), its size, the shifts used and the assembly's
 * worst interface response error over the check grid. */
#include "rths/krylov_reduce.h"
#include "rths/model.h"
#include "rths/rig_virtual.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define GRID_POINTS 727

/* The seed's storeys 1-3, then a rod of n - 3 elements (static stiffness and damping of the
 * seed's top leg, 0.1074 kg consistent mass) carrying the 10.74 kg top storey. */
static int rod_chain(int n, rths_assembly *a) {
    rths_error err;
    double *m = rths_mat_new(n, n), *c = rths_mat_new(n, n), *k = rths_mat_new(n, n);
    const double sm[3] = {5.37, 5.37, 5.37}, sc[3] = {4.4062, 3.7979, 3.7421},
                 sk[3] = {53048, 45724, 45052};
    int el = n - 3;
    double ke = 45052.0 * el, ce = 3.7421 * el, me = 0.1074 / el;
    for (int i = 0; i < 3; i++) {
        RTHS_AT(m, n, i, i) += sm[i];
        RTHS_AT(c, n, i, i) += sc[i];
        RTHS_AT(k, n, i, i) += sk[i];
        if (i > 0) {
            RTHS_AT(c, n, i - 1, i - 1) += sc[i];
            RTHS_AT(k, n, i - 1, i - 1) += sk[i];
            RTHS_AT(c, n, i, i - 1) -= sc[i], RTHS_AT(c, n, i - 1, i) -= sc[i];
            RTHS_AT(k, n, i, i - 1) -= sk[i], RTHS_AT(k, n, i - 1, i) -= sk[i];
        }
    }
    RTHS_AT(m, n, n - 1, n - 1) += 10.74;
    for (int e = 0; e < el; e++) {
        int lo = 2 + e, up = 3 + e;
        double *mats[2] = {c, k}, vals[2] = {ce, ke};
        for (int t = 0; t < 2; t++) {
            RTHS_AT(mats[t], n, lo, lo) += vals[t], RTHS_AT(mats[t], n, up, up) += vals[t];
            RTHS_AT(mats[t], n, lo, up) -= vals[t], RTHS_AT(mats[t], n, up, lo) -= vals[t];
        }
        RTHS_AT(m, n, lo, lo) += me / 3, RTHS_AT(m, n, up, up) += me / 3;
        RTHS_AT(m, n, lo, up) += me / 6, RTHS_AT(m, n, up, lo) += me / 6;
    }
    int rc = rths_assembly_from_matrices(n, m, c, k, a, &err);
    free(m), free(c), free(k);
    return rc;
}

static void bench_model_size(int n) {
    rths_assembly a;
    if (rod_chain(n, &a)) return;
    double *force = calloc((size_t)n, sizeof *force);
    force[n - 1] = 1.0;
    int dofs[4] = {0, 1, 2, n - 1};
    double complex x[4];
    rths_modes modes;
    rths_frf_sweep *sw = NULL;
    rths_error err;
    double t0 = rths_monotonic_s();
    if (rths_modal_analysis(&a, &modes, &err)) {
        printf("%6d  modal analysis failed: %s\n", n, err.msg);
        return;
    }
    double t1 = rths_monotonic_s();
    if (rths_frf_sweep_create(&a, &modes, force, 4, dofs, &sw, &err)) return;
    double t2 = rths_monotonic_s();
    for (int j = 0; j < GRID_POINTS; j++)
        rths_frf_sweep_eval(sw, 2 * M_PI * (0.5 + 34.5 * j / (GRID_POINTS - 1)), x, &err);
    double t3 = rths_monotonic_s();
    /* the former way: one dense complex solve per frequency */
    double complex *full = malloc((size_t)n * sizeof *full);
    int dense_runs = n >= 2000 ? 1 : 3;
    for (int j = 0; j < dense_runs; j++)
        rths_frf(n, a.mass, a.damping, a.stiffness, force, 2 * M_PI * (1.0 + j), full, &err);
    double dense_each = (rths_monotonic_s() - t3) / dense_runs;
    printf("%6d %10.4f %10.4f %10.4f %10.4f   %-16s %12.2f\n", n, t1 - t0, t2 - t1, t3 - t2,
           t3 - t0, n > 8 ? rths_frf_method_name(rths_frf_sweep_method(sw)) : "",
           dense_each * GRID_POINTS);
    free(full), free(force);
    rths_frf_sweep_destroy(sw);
    rths_modes_free(&modes);
    rths_assembly_free(&a);
}

typedef struct {
    const char *label;
    int n, nr;
    double lo_hz, hi_hz, total_s, peak_mb;
    rths_krylov_report rep;
} reduction_row;
enum { MAX_REDUCTION_ROWS = 4 };
static reduction_row reductions[MAX_REDUCTION_ROWS];
static int n_reductions;

static void bench_sparse_frame(const char *label, int nx, int ny, int nz) {
    char dir[] = "/tmp/rths_bench_model_XXXXXX", cmd[512], cfg_path[300];
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return;
    }
    snprintf(cmd, sizeof cmd,
             "/usr/bin/python3 tools/gen_frame3d.py --nx %d --ny %d --nz %d --seed 1 --specimen "
             "20000 2e6 %s >/dev/null",
             nx, ny, nz, dir);
    if (system(cmd)) {
        fprintf(stderr, "bench model: %s failed (run rths_bench from the source tree)\n", cmd);
        return;
    }
    snprintf(cfg_path, sizeof cfg_path, "%s/frame.yaml", dir);
    rths_error err;
    rths_config *cfg = NULL;
    rths_model_choice choice;
    rths_sparse_model model;
    rths_sparse_modes modes;
    rths_sparse_frf *sweep = NULL;
    double *freqs = NULL;
    int count = 0, n_out = 0, *dofs = NULL;
    double t0 = rths_monotonic_s();
    if (rths_config_load(cfg_path, NULL, 0, &cfg, &err) ||
        rths_model_choose_solver(cfg, &choice, &err) ||
        rths_sparse_model_read(cfg, &choice, &model, &err)) {
        fprintf(stderr, "bench model: %s\n", err.msg);
        return;
    }
    double read_s = rths_monotonic_s() - t0;
    if (rths_sparse_model_modes(&model, &modes, NULL, &err)) {
        fprintf(stderr, "bench model: %s\n", err.msg);
        return;
    }
    double t1 = rths_monotonic_s();
    rths_modes view = {.n = modes.count,
                       .omega_rad_s = modes.omega_rad_s,
                       .frequency_hz = modes.frequency_hz,
                       .damping_ratio = modes.damping_ratio};
    dofs = rths_sparse_model_output_dofs(&model, &n_out);
    if (!dofs ||
        rths_frf_grid(&view, 0, modes.frequency_hz[modes.count - 1], 0, &freqs, &count, &err) ||
        rths_sparse_frf_create(&model, &modes, n_out, dofs, &sweep, &err)) {
        fprintf(stderr, "bench model: FRF: %s\n", err.msg);
        return;
    }
    double complex *x = calloc((size_t)n_out, sizeof *x);
    for (int j = 0; x && j < count; j++)
        rths_sparse_frf_eval(sweep, 2 * M_PI * freqs[j], x, &err);
    double frf_s = rths_monotonic_s() - t1;
    printf("%-6s %8d %7.2f %8.2f %7.2f %8.2f %8.2f %7.3f %5d %8.2f %8.0f  %d/%d %.2g\n", label,
           model.n, read_s, modes.stats.analysis_s, modes.stats.factor_s, modes.stats.lanczos_s,
           modes.check_s, frf_s, count, rths_monotonic_s() - t0, rths_peak_memory_mb(),
           modes.sturm_below, modes.count, modes.max_residual);
    fflush(stdout);
    /* the reduction (krylov_reduce.h) over the band 0.5 f1 .. f10 */
    if (n_reductions < MAX_REDUCTION_ROWS && modes.count >= 10) {
        reduction_row *row = &reductions[n_reductions++];
        rths_krylov_options ko;
        rths_krylov_defaults(&ko);
        ko.start_hz = 0.5 * modes.frequency_hz[0];
        ko.end_hz = modes.frequency_hz[9];
        rths_reduced red;
        double t2 = rths_monotonic_s();
        int rc = rths_sparse_model_krylov_reduce(&model, &ko, &red, NULL, &row->rep, &err);
        *row = (reduction_row){.label = label,
                               .n = model.n,
                               .lo_hz = ko.start_hz,
                               .hi_hz = ko.end_hz,
                               .total_s = rths_monotonic_s() - t2,
                               .nr = rc ? -1 : red.nr,
                               .rep = row->rep,
                               .peak_mb = rths_peak_memory_mb()};
        if (rc) fprintf(stderr, "bench model: reduction: %s\n", err.msg);
        /* printed at once: a large case's reduction takes minutes */
        printf("reduce %-5s band %.3f-%.3f Hz: %d check points %.2f s, basis %.2f s, total %.2f "
               "s; %d DoFs, %d shifts, max error %.2g at %.3f Hz; peak %.0f MB\n",
               row->label, row->lo_hz, row->hi_hz, row->rep.check_points, row->rep.truth_s,
               row->rep.basis_s, row->total_s, row->nr, row->rep.shifts, row->rep.max_error,
               row->rep.at_hz, row->peak_mb);
        fflush(stdout);
        rths_reduced_free(&red);
    }
    free(x);
    free(freqs);
    free(dofs);
    rths_sparse_frf_destroy(sweep);
    rths_sparse_modes_free(&modes);
    rths_sparse_model_free(&model);
    rths_model_choice_free(&choice);
    rths_config_free(cfg);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd)) fprintf(stderr, "bench model: could not remove %s\n", dir);
}

static void bench_model_sparse(void) {
    const char *max_env = getenv("RTHS_BENCH_MODEL_MAX_DOFS");
    long max_dofs = max_env ? atol(max_env) : 200000;
    printf("\nrths model's sparse path on 3-D frames with a two-storey specimen "
           "(tools/gen_frame3d.py, random numbering), lowest 20 modes, wall seconds:\n");
    printf("%-6s %8s %7s %8s %7s %8s %8s %7s %5s %8s %8s  %s\n", "case", "dofs", "read_s",
           "order_s", "fact_s", "eigen_s", "checks_s", "frf_s", "freqs", "total_s", "peak_MB",
           "sturm/modes residual");
    bench_sparse_frame("10k", 10, 6, 28);
    if (max_dofs >= 60000) bench_sparse_frame("60k", 50, 5, 40);
    if (max_dofs >= 100000) bench_sparse_frame("100k", 50, 5, 67);
}

void rths_bench_model(void) {
    printf("rths model's work on the rod chain (seed storeys 1-3 + a rod of n - 3 elements), "
           "wall seconds; FRF at %d frequencies, 4 DoFs written:\n",
           GRID_POINTS);
    printf("%6s %10s %10s %10s %10s   %-16s %12s\n", "n", "modes_s", "prepare_s", "frf_s",
           "total_s", "frf method", "dense_frf_s");
    const int sizes[4] = {50, 200, 1000, 4000};
    for (int i = 0; i < 4; i++) {
        bench_model_size(sizes[i]);
        fflush(stdout);
    }
    printf("(dense_frf_s: the former dense complex solve at every frequency, extrapolated)\n");
    bench_model_sparse();
}

static int load_seed(const char *const *ov, int n_ov, rths_config **cfg, rths_setup *s) {
    const char *dir = getenv("RTHS_SOURCE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/examples/four_storey.yaml", dir ? dir : ".");
    rths_error err;
    if (rths_config_load(path, ov, n_ov, cfg, &err) || rths_setup_read(*cfg, s, &err)) {
        fprintf(stderr, "bench plant: %s\n", err.msg);
        return -1;
    }
    return 0;
}

/* Plant alone: samples per second of read + advance under a 13.47 Hz demand. */
static double plant_rate(const rths_setup *s, int substeps, int noise) {
    rths_plant_options po;
    rths_plant_defaults(&po);
    po.substeps_per_sample = substeps;
    po.noise = noise;
    rths_plant *p;
    rths_error err;
    if (rths_plant_create(s, &po, 1e4, &p, &err)) return 0;
    const long n = 2000000;
    double sink = 0, w = 2 * M_PI * 13.47e-4, t0 = rths_monotonic_s();
    for (long i = 0; i < n; i++) {
        rths_sensor_sample in;
        rths_plant_read(p, &in);
        sink += in.interface_force_n;
        rths_plant_advance(p, 0.05 * cos(w * (double)i));
    }
    double rate = n / (rths_monotonic_s() - t0);
    rths_plant_destroy(p);
    return sink == 12345.678 ? 0 : rate;
}

/* The whole virtual rig: controller step + plant over 200 periods. */
static double rig_rate(const char *integrator) {
    char ov[64];
    snprintf(ov, sizeof ov, "rig.plant_integrator=%s", integrator);
    const char *ovs[1] = {ov};
    rths_config *cfg;
    rths_setup s;
    rths_rig *rig;
    rths_error err;
    if (load_seed(ovs, 1, &cfg, &s)) return 0;
    if (rths_virtual_rig_create(cfg, &s, 0, 0, &rig, &err)) {
        fprintf(stderr, "bench plant: %s\n", err.msg);
        return 0;
    }
    double a[1] = {1e-4}, b[1] = {0};
    rths_rig_set_forcing(rig, 13.47, 1.0, &err);
    rths_rig_set_target(rig, 1, a, b, &err);
    /* a long run's rate: the first periods also pay for first touches of the rig's buffers
     * (page faults), which 200 periods alone counted as a third of the time */
    enum { WARM_UP_PERIODS = 20, TIMED_PERIODS = 2000 };
    rths_period *p = calloc(TIMED_PERIODS, sizeof *p);
    rths_rig_run_periods(rig, WARM_UP_PERIODS, p, &err);
    double t0 = rths_monotonic_s(), r0 = rths_rig_time_s(rig);
    rths_rig_run_periods(rig, TIMED_PERIODS, p, &err);
    double rate = (rths_rig_time_s(rig) - r0) * 1e4 / (rths_monotonic_s() - t0);
    free(p);
    rths_rig_destroy(rig);
    rths_setup_free(&s);
    rths_config_free(cfg);
    return rate;
}

void rths_bench_plant(void) {
    rths_config *cfg;
    rths_setup s;
    if (load_seed(NULL, 0, &cfg, &s)) return;
    printf("virtual rig on the seed at 10 kHz, default rig (noise on), one core:\n");
    printf("%-34s %14s %18s\n", "", "samples_per_s", "real_time_factor");
    /* the whole rig first: on this 2-core VM the same loops ran 1.5x slower after the plant-alone
     * cases in the same process (4.8e6 against 7.5e6 samples/s; the plant alone moved by +-30 %
     * with the order too), so compare figures from one order only */
    const char *integrators[2] = {"exact", "rk4"};
    for (int i = 0; i < 2; i++) {
        double r = rig_rate(integrators[i]);
        printf("controller step + plant, %-9s %14.0f %18.1f\n", integrators[i], r, r / 1e4);
    }
    const struct {
        const char *name;
        int substeps, noise;
    } plants[3] = {{"plant alone, exact", 0, 1},
                   {"plant alone, RK4 x 8", 8, 1},
                   {"plant alone, exact, noise off", 0, 0}};
    for (int i = 0; i < 3; i++) {
        double r = plant_rate(&s, plants[i].substeps, plants[i].noise);
        printf("%-34s %14.0f %18.1f\n", plants[i].name, r, r / 1e4);
    }
    rths_setup_free(&s);
    rths_config_free(cfg);
}
