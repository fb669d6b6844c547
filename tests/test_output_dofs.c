/* output.dofs (docs/method.md, "Outputs"): every listed assembly DoF's fundamental, measured
 * beside the interface's (a numerical DoF from the controller's own state, a physical DoF below
 * the interface from its laser, the interface DoF from its physical signal), equals the analytic
 * FRF at the point's frequency: noise off, on the seed's linear building forced on storey 4 and
 * excited through its base (relative displacements), across the sweep of each example. The
 * columns the run folder gets (frf_dof_columns.h) are checked against the truth's own, the
 * numerical DoF's raw sums against the numerical substructure's own equations; with noise the
 * standard-error column covers the error; a reduced numerical side reads its DoFs through the
 * reduction basis exactly as the unreduced step does. Bad lists are refused by name. */
#include "testlib.h"

#include "rths/controller.h"
#include "rths/run.h"
#include "rths/truth.h"
#include "run/frf_dof_columns.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct {
    const rths_setup *setup;
    frf_dof_columns cols;
    int points;
    double max_amp_error, max_phase_error, max_se;
    double max_interface_error; /* the interface DoF's column against amplitude_m */
    int interface_column;       /* its block in cols, -1: none */
    int values, within_3_se;    /* output amplitudes, and those within 3 SE of the truth */
    /* numerical output DoFs against the numerical substructure's own response to its measured
       interface motion and the forcing (largest relative complex difference) */
    double max_numerical_error;
    int numerical_checked;
    /* record: every point's frequency and raw output fundamentals (c = a - i b) */
    int record;
    double freq_hz[64];
    double complex raw[64][RTHS_MAX_OUTPUT_DOFS];
} watcher;

/* Numerical output DoF j's fundamental as the numerical substructure's equations give it from
 * the measured numerical interface motion: D_nn q_n = f_n - D_ni x_i with D = K - w^2 M + i w C
 * over the split's numerical order (interface DoFs first). -1: DoF j is not numerical. */
static int numerical_fundamental(const rths_setup *s, const rths_evaluation *ev, double f_hz,
                                 int dof, double complex *out) {
    const rths_split *sp = &s->split;
    int ni = sp->n_int, nn = sp->nn, nq = nn - ni, at = -1;
    for (int i = 0; i < sp->n_num; i++)
        if (sp->num_dofs[i] == dof) at = i;
    if (at < 0 || ni != 1) return -1;
    const double w = 2 * M_PI * f_hz;
    double complex *d = calloc((size_t)nq * (size_t)nq, sizeof *d),
                   *q = calloc((size_t)nq, sizeof *q);
    const double complex x_i = ev->num.a[1] - I * ev->num.b[1];
    for (int r = 0; r < nq; r++) {
        for (int c = 0; c < nq; c++) {
            size_t e = (size_t)(ni + r) + (size_t)(ni + c) * (size_t)nn;
            d[r + c * nq] =
                sp->stiffness_num[e] - w * w * sp->mass_num[e] + I * w * sp->damping_num[e];
        }
        size_t e = (size_t)(ni + r); /* column 0: the interface */
        q[r] = s->force[sp->num_dofs[r]] -
               (sp->stiffness_num[e] - w * w * sp->mass_num[e] + I * w * sp->damping_num[e]) * x_i;
    }
    int rc = rths_cmat_solve(nq, 1, d, q);
    *out = q[at];
    free(d), free(q);
    return rc ? -1 : 0;
}

static int watch_point(void *user, const rths_point *pt, int is_update) {
    watcher *w = user;
    if (is_update) return RTHS_OK;
    w->points++;
    double row[FRF_DOF_MAX_COLUMNS], truth[FRF_DOF_MAX_COLUMNS];
    frf_dof_columns_row(&w->cols, pt, row);
    frf_dof_columns_truth_row(&w->cols, w->setup, pt->sol.frequency_hz, truth);
    for (int j = 0; j < w->cols.dofs; j++) {
        const double *r = row + 3 * j, *t = truth + 3 * j;
        assert_true(isfinite(r[0]) && isfinite(r[1]) && isfinite(r[2]));
        w->max_amp_error = fmax(w->max_amp_error, fabs(r[0] - t[0]) / t[0]);
        double dphi = remainder(r[1] - t[1], 2 * M_PI);
        w->max_phase_error = fmax(w->max_phase_error, fabs(dphi));
        w->max_se = fmax(w->max_se, r[2] / r[0]);
        double complex q_model;
        if (!numerical_fundamental(w->setup, &pt->sol.eval, pt->sol.frequency_hz, w->cols.dof[j],
                                   &q_model)) {
            const rths_fourier *x = &pt->sol.eval.output_dof[j];
            w->max_numerical_error =
                fmax(w->max_numerical_error, cabs(x->a[1] - I * x->b[1] - q_model) / cabs(q_model));
            w->numerical_checked++;
        }
        w->values++;
        w->within_3_se += fabs(r[0] - t[0]) <= 3 * r[2];
        if (getenv("DOFS_DEBUG"))
            printf("f %.4f dof %d amp %.6e truth %.6e rel %+.2e dphi %+.2e\n", pt->sol.frequency_hz,
                   w->cols.dof[j] + 1, r[0], t[0], (r[0] - t[0]) / t[0], dphi);
    }
    if (w->record && w->points <= 64) {
        w->freq_hz[w->points - 1] = pt->sol.frequency_hz;
        for (int j = 0; j < w->cols.dofs; j++)
            w->raw[w->points - 1][j] =
                pt->sol.eval.output_dof[j].a[1] - I * pt->sol.eval.output_dof[j].b[1];
    }
    if (w->interface_column >= 0) {
        /* the interface DoF's column is frf.csv's amplitude_m (matched by default) */
        w->max_interface_error =
            fmax(w->max_interface_error,
                 fabs(row[3 * w->interface_column] - pt->sol.amplitude_m) / pt->sol.amplitude_m);
    }
    return RTHS_OK;
}

/* Runs the example with the overrides; the watcher's columns from the controller's options as
 * the run reads them. */
static void run_example(const char *example, const char *const *sets, int n_sets, watcher *w) {
    rths_error err = {0};
    rths_config *cfg;
    rths_setup setup;
    if (rths_config_load(rths_test_source_path(example), sets, n_sets, &cfg, &err) ||
        rths_setup_read(cfg, &setup, &err))
        fail_msg("%s", err.msg);
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    if (rths_controller_config_read(cfg, &copt, &err)) fail_msg("%s", err.msg);
    frf_dof_columns_init(&w->cols, &copt);
    w->setup = &setup;
    w->interface_column = -1;
    for (int j = 0; j < w->cols.dofs; j++)
        if (w->cols.dof[j] == setup.split.int_dofs[0]) w->interface_column = j;
    char out[] = "/tmp/rths_output_dofs_XXXXXX";
    assert_non_null(mkdtemp(out));
    char dir[600];
    snprintf(dir, sizeof dir, "%s/run", out);
    rths_run_frf_options opt = {
        .cfg = cfg, .setup = &setup, .out_dir = dir, .overrides = sets, .n_overrides = n_sets};
    rths_run_callbacks cb = {.on_point = watch_point, .user = w};
    rths_run_frf_result r;
    if (rths_run_frf(&opt, &cb, &r, &err)) fail_msg("%s", err.msg);
    if (r.status != RTHS_RUN_COMPLETED) fail_msg("%s: %s", example, r.stop_reason);
    char cmd[700];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", out);
    assert_int_equal(system(cmd), 0);
    rths_setup_free(&setup);
    rths_config_free(cfg);
}

static void check(const watcher *w, const char *what) {
    printf("%s: %d points, largest amplitude error %.3g, phase error %.3g rad, SE/amplitude "
           "%.3g, interface column against amplitude_m %.3g\n",
           what, w->points, w->max_amp_error, w->max_phase_error, w->max_se,
           w->max_interface_error);
    printf("  numerical DoFs against the numerical substructure: %d values, largest %.3g\n",
           w->numerical_checked, w->max_numerical_error);
    assert_int_equal(w->cols.count, 12);
    assert_true(w->points >= 40);
    /* the acceptance: 0.1 % of the analytic FRF, noise off */
    assert_true(w->max_amp_error < 1e-3);
    assert_true(w->max_phase_error < 1e-3);
    /* noise off: the periods' scatter is the settling tail only */
    assert_true(w->max_se < 1e-3);
    /* the numerical DoF's raw measurement is what the numerical substructure's equations give
       for the measured numerical interface motion (the integration's and the averaging's
       error: 8e-5 on both examples) */
    assert_int_equal(w->numerical_checked, w->points);
    assert_true(w->max_numerical_error < 1e-3);
    /* the interface DoF's column is frf.csv's amplitude_m (but for the complex ratio's rounding) */
    assert_true(w->max_interface_error < 1e-12);
}

/* The seed's building, 1 N on storey 4, split at storey 3: DoFs 1-2 physical, 3 the interface,
 * 4 numerical. */
static void linear_every_storey(void **state) {
    (void)state;
    static const char *const sets[] = {"rig.noise=false", "output.dofs=[1, 2, 3, 4]"};
    watcher w = {0};
    run_example("examples/four_storey_linear.yaml", sets, 2, &w);
    check(&w, "four_storey_linear");
}

/* Through the base: every storey's displacement relative to the ground, as the hybrid test and
 * its truth report it; the list's order is kept (4 first). */
static void base_excited_every_storey(void **state) {
    (void)state;
    static const char *const sets[] = {"rig.noise=false", "output.dofs=[4, 3, 2, 1]"};
    watcher w = {0};
    run_example("examples/four_storey_base_excited.yaml", sets, 2, &w);
    assert_int_equal(w.cols.dof[0], 3);
    assert_string_equal(frf_dof_column_name(&w.cols, 0), "x4_amplitude_m");
    assert_string_equal(frf_dof_column_name(&w.cols, 4), "x3_phase_rad");
    assert_string_equal(frf_dof_column_name(&w.cols, 11), "x1_amplitude_se_m");
    assert_null(frf_dof_column_name(&w.cols, 12));
    check(&w, "four_storey_base_excited");
}

/* With the default noise (lasers 1e-7 m, the rest of rig.noise's defaults) the standard error
 * column covers the deviation from the truth: nearly every amplitude within 3 SE (a normal
 * error is beyond 3 SE in 0.3 % of cases; the matched extrapolation's error is in the SE too). */
static void linear_with_noise(void **state) {
    (void)state;
    static const char *const sets[] = {"output.dofs=[1, 2, 3, 4]"};
    watcher w = {0};
    run_example("examples/four_storey_linear.yaml", sets, 1, &w);
    printf("four_storey_linear with noise: %d of %d amplitudes within 3 SE, largest error %.3g, "
           "largest SE/amplitude %.3g\n",
           w.within_3_se, w.values, w.max_amp_error, w.max_se);
    assert_true(w.values >= 160);
    assert_true(w.within_3_se >= 0.95 * w.values);
}

/* A 20-storey chain split at storey 3: its 17 numerical storeys and the interface are more than
 * the 16 the step integrates as they are, so by default (controller.reduction auto) it integrates
 * their Craig-Bampton reduction and reads each numerical output DoF through its row of the basis,
 * q = T r. Every fixed-interface mode lies below the cutoff, so the reduced model is the same
 * dynamics in another basis: the run must give what the unreduced step (reduction none, 18 DoFs)
 * gives, point by point, for every listed DoF. Forced on the roof across the second mode. */
static void reduced_numerical_side(void **state) {
    (void)state;
    const char *sets[] = {
        "rig.noise=false",
        "structure.storeys.mass_kg=[5.37, 5.37, 5.37, 5.37, 5.37, 5.37, 5.37, 5.37, 5.37, 5.37, "
        "5.37, 5.37, 5.37, 5.37, 5.37, 5.37, 5.37, 5.37, 5.37, 5.37]",
        "structure.storeys.damping_n_s_per_m=[100, 100, 100, 100, 100, 100, 100, 100, 100, 100, "
        "100, 100, 100, 100, 100, 100, 100, 100, 100, 100]",
        "structure.storeys.stiffness_n_per_m=[45052, 45052, 45052, 45052, 45052, 45052, 45052, "
        "45052, 45052, 45052, 45052, 45052, 45052, 45052, 45052, 45052, 45052, 45052, 45052, "
        "45052]",
        "forcing.dof=20",
        "continuation.start_hz=3.1",
        "continuation.end_hz=3.6",
        "output.dofs=[1, 3, 4, 11, 20]",
        "controller.reduction.method=none"};
    watcher full = {0}, reduced = {0};
    full.record = reduced.record = 1;
    run_example("examples/four_storey_linear.yaml", sets, 9, &full);
    sets[8] = "controller.reduction.method=auto";
    run_example("examples/four_storey_linear.yaml", sets, 9, &reduced);
    assert_true(full.points >= 10);
    assert_int_equal(reduced.points, full.points);
    double worst = 0;
    for (int i = 0; i < full.points; i++) {
        assert_true(fabs(reduced.freq_hz[i] - full.freq_hz[i]) < 1e-9);
        for (int j = 0; j < 5; j++)
            worst = fmax(worst, cabs(reduced.raw[i][j] - full.raw[i][j]) / cabs(full.raw[i][j]));
    }
    printf("20 storeys: %d points, reduced against unreduced numerical side: largest relative "
           "difference %.3g\n",
           full.points, worst);
    /* the two integrate the same dynamics; rounding in the basis change and the continuation's
       own decisions on it stay far below the measurement's tolerance */
    assert_true(worst < 1e-6);
}

/* Without output.dofs: no columns, and the periods carry none. */
static void default_adds_nothing(void **state) {
    (void)state;
    rths_error err = {0};
    rths_config *cfg;
    if (rths_config_load(rths_test_source_path("examples/four_storey_linear.yaml"), NULL, 0, &cfg,
                         &err))
        fail_msg("%s", err.msg);
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    assert_int_equal(rths_controller_config_read(cfg, &copt, &err), RTHS_OK);
    frf_dof_columns cols;
    frf_dof_columns_init(&cols, &copt);
    assert_int_equal(cols.count, 0);
    assert_null(frf_dof_column_name(&cols, 0));
    rths_config_free(cfg);
}

/* A bad list names the key and the entry; a DoF beyond the assembly is refused at create. */
static void bad_lists_refused(void **state) {
    (void)state;
    static const struct {
        const char *set, *words;
    } cases[] = {{"output.dofs=[1, 0]", "entry 2 is 0"},
                 {"output.dofs=[2, 3, 2]", "DoF 2 is listed twice"},
                 {"output.dofs=[1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17]", "at most 16"}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        rths_error err = {0};
        rths_config *cfg;
        const char *sets[] = {cases[i].set};
        if (rths_config_load(rths_test_source_path("examples/four_storey_linear.yaml"), sets, 1,
                             &cfg, &err))
            fail_msg("%s", err.msg);
        rths_controller_options copt;
        rths_controller_defaults(&copt);
        assert_int_equal(rths_controller_config_read(cfg, &copt, &err), RTHS_EINPUT);
        assert_non_null(strstr(err.msg, "output.dofs"));
        assert_non_null(strstr(err.msg, cases[i].words));
        rths_config_free(cfg);
    }
    rths_error err = {0};
    rths_config *cfg;
    rths_setup setup;
    const char *sets[] = {"output.dofs=[5]"};
    if (rths_config_load(rths_test_source_path("examples/four_storey_linear.yaml"), sets, 1, &cfg,
                         &err) ||
        rths_setup_read(cfg, &setup, &err))
        fail_msg("%s", err.msg);
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    assert_int_equal(rths_controller_config_read(cfg, &copt, &err), RTHS_OK);
    rths_controller *c = NULL;
    assert_int_equal(rths_controller_create(&setup, &copt, &c, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "output.dofs: DoF 5 is beyond the assembly's 4 DoFs"));
    rths_setup_free(&setup);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(default_adds_nothing), cmocka_unit_test(bad_lists_refused),
        cmocka_unit_test(linear_every_storey),  cmocka_unit_test(base_excited_every_storey),
        cmocka_unit_test(linear_with_noise),    cmocka_unit_test(reduced_numerical_side),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
