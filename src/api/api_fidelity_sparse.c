/* `rths fidelity` on a sparse model (api_fidelity_sparse.h): the real-time reduction's interface
 * FRF error over the sweep. The true assembly's dense FRF and the schemes' discrete steps of
 * rths_fidelity need dense matrices of the model's order, which the sparse path never forms, so
 * on a sparse model only the reduction is reported (docs/method.md, "Numerical substructure
 * integration"). */
#include "api/api_fidelity_sparse.h"
#include "rths/controller.h"
#include "rths/fidelity.h"
#include "rths/krylov_reduce.h"

#include <json-c/json.h>
#include <complex.h>
#include <math.h>
#include <stdlib.h>

enum {
    COL_HZ,
    COL_REDUCED_RECEPTANCE,
    COL_EXACT_RECEPTANCE,
    COL_RECEPTANCE_ERROR,
    COL_REDUCED_FORCED,
    COL_EXACT_FORCED,
    COL_FORCED_ERROR,
    N_COLS
};
static const char *const header[N_COLS] = {"frequency_hz",
                                           "reduced_receptance_amplitude_m_per_n",
                                           "exact_receptance_amplitude_m_per_n",
                                           "receptance_error_relative",
                                           "reduced_forced_amplitude_m_per_n",
                                           "exact_forced_amplitude_m_per_n",
                                           "forced_error_relative"};

/* |a - b| / |b|: the complex difference, phase included; 0 when both vanish */
static double relative(double complex a, double complex b) {
    double d = cabs(a - b), r = cabs(b);
    return r > 0 ? d / r : (d > 0 ? INFINITY : 0);
}

static json_object *finite_or_null(double x) {
    return isfinite(x) ? json_object_new_double(x) : NULL;
}

/* The numerical side's share of the forcing per unit amplitude in the reduction's coordinates
 * (T^T f, f the model's force on the numerical side's DoFs), so the reduced forced response is
 * comparable with rths_sparse_model_receptance_eval's. NULL without one comparable: under base
 * excitation the side carries -M_num 1 (its own inertia), not the assembly's rows. */
static double *reduced_forcing(const rths_sparse_model *m, const rths_reduced *red, const int *dofs,
                               int *n_loads, rths_error *err) {
    *n_loads = 0;
    if (m->base_excitation) return NULL;
    double *f = rths_mat_new(red->n, 1), *rl = rths_mat_new(red->nr, 1);
    if (!f || !rl) {
        rths_mat_free(f), rths_mat_free(rl);
        rths_error_set(err, RTHS_EFAIL, "out of memory");
        return NULL;
    }
    for (int i = 0; i < red->n; i++)
        f[i] = m->force[dofs[i]] / m->forcing_amplitude_n;
    rths_mat_mul(red->nr, 1, red->n, 1.0, red->transform, 1, f, 0, 0.0, rl);
    rths_mat_free(f);
    *n_loads = 1;
    return rl;
}

int rths_api_fidelity_check_sections(rths_config *cfg, const char *const *own, rths_error *err) {
    /* the controller's reader asks for continuation.start_hz and end_hz (the Krylov band), which
     * would make every other continuation key, read by rths frf alone, an unknown key here */
    rths_config_mark_known(cfg, "continuation");
    return rths_config_check_sections(cfg, own, err);
}

int rths_api_fidelity_sparse(rths_config *cfg, const rths_setup *setup, const char *config_path,
                             const char *const *overrides, int n_overrides, rths_result **out,
                             rths_error *err) {
    static const char *const own_sections[] = {"fidelity", "controller", NULL};
    const rths_sparse_model *m = setup->sparse;
    *out = NULL;
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    int rc = rths_controller_config_read(cfg, &copt, err);
    if (rc) return rc;
    const rths_krylov_options *ko = &copt.krylov;
    /* the controller's own refusal, in fidelity's words */
    if (!(ko->end_hz > ko->start_hz))
        return rths_error_set(err, RTHS_EINPUT,
                              "this model takes the sparse path (%d DoFs): rths fidelity reports "
                              "the reduction the controller integrates in real time, exact over "
                              "the tested band, and no band is given: set continuation.start_hz "
                              "and continuation.end_hz",
                              setup->assembly.n);
    if (setup->split.n_int != 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "rths fidelity on a sparse model takes one interface DoF, not %d",
                              setup->split.n_int);
    rths_fidelity_options sweep;
    if ((rc = rths_fidelity_config_read_band(cfg, ko->start_hz, ko->end_hz,
                                             2 * ko->check_points - 1, &sweep, err)) ||
        (rc = rths_api_fidelity_check_sections(cfg, own_sections, err)))
        return rc;

    rths_reduced red = {0};
    rths_krylov_report rep;
    int *dofs = NULL, n_loads = 0;
    double *rl = NULL;
    rths_sparse_model_receptance *exact = NULL;
    rths_result *res = NULL;
    rths_table t = {0};
    int have_table = 0;
    json_object *summary = NULL;
    /* the reduction exactly as the controller builds it (step.c, krylov_numerical), refused the
     * same way above controller.reduction.max_error */
    if ((rc = rths_sparse_model_krylov_reduce(m, ko, &red, &dofs, &rep, err))) goto done;
    rl = reduced_forcing(m, &red, dofs, &n_loads, err);
    if (!rl && !m->base_excitation) {
        rc = RTHS_EFAIL;
        goto done;
    }
    if ((rc = rths_sparse_model_receptance_create(m, &exact, err)) ||
        (rc = rths_table_create("fidelity", sweep.points, N_COLS, header, &t, err)))
        goto done;
    have_table = 1;
    double worst[2] = {0, 0}, worst_hz[2] = {sweep.start_hz, sweep.start_hz};
    for (int i = 0; i < sweep.points && !rc; i++) {
        double hz = sweep.start_hz + (sweep.end_hz - sweep.start_hz) * i / (sweep.points - 1);
        double w = 2 * M_PI * hz;
        double complex reduced[2] = {NAN, NAN}, truth[2] = {NAN, NAN};
        rc = rths_krylov_interface_response(&red, n_loads, rl, NULL, w, reduced, err);
        if (!rc) rc = rths_sparse_model_receptance_eval(exact, w, &truth[0], &truth[1], err);
        t.data[COL_HZ][i] = hz;
        for (int k = 0; k < 2 && !rc; k++) {
            int on = k == 0 || n_loads > 0;
            double e = on ? relative(reduced[k], truth[k]) : NAN;
            t.data[COL_REDUCED_RECEPTANCE + 3 * k][i] = on ? cabs(reduced[k]) : NAN;
            t.data[COL_EXACT_RECEPTANCE + 3 * k][i] = on ? cabs(truth[k]) : NAN;
            t.data[COL_RECEPTANCE_ERROR + 3 * k][i] = e;
            if (on && !(e <= worst[k])) worst[k] = e, worst_hz[k] = hz;
        }
    }
    if (rc || (rc = rths_result_new(&res, err)) || (rc = rths_result_take_table(res, &t, err)))
        goto done;
    have_table = 0;

    summary = rths_api_summary_new("fidelity", config_path, overrides, n_overrides);
    if (!summary) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    int k_worst = n_loads > 0 && !(worst[1] <= worst[0]) ? 1 : 0;
    json_object_object_add(summary, "interface_dof",
                           json_object_new_int(setup->split.int_dofs[0] + 1));
    json_object_object_add(summary, "start_hz", json_object_new_double(sweep.start_hz));
    json_object_object_add(summary, "end_hz", json_object_new_double(sweep.end_hz));
    json_object_object_add(summary, "points", json_object_new_int(sweep.points));
    json_object_object_add(
        summary, "note",
        json_object_new_string("sparse model: the real-time reduction's error only (the discrete "
                               "step's schemes need the dense assembly)"));
    if (setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY) {
        static const char frequency_note[] =
            "split.numerical_solver is frequency: rths frf solves this numerical side exactly per "
            "harmonic; the reduction is the one the real-time form would integrate";
        json_object_object_add(summary, "numerical_solver_note",
                               json_object_new_string(frequency_note));
    }
    json_object *r = json_object_new_object(), *shifts = json_object_new_array();
    for (int s = 0; s < rep.shifts; s++)
        json_object_array_add(shifts, json_object_new_double(rep.shift_hz[s]));
    json_object_object_add(r, "method", json_object_new_string("krylov"));
    json_object_object_add(r, "full_dofs", json_object_new_int(red.n));
    json_object_object_add(r, "dofs", json_object_new_int(red.nr));
    json_object_object_add(r, "shift_hz", shifts);
    json_object_object_add(r, "band_start_hz", json_object_new_double(ko->start_hz));
    json_object_object_add(r, "band_end_hz", json_object_new_double(ko->end_hz));
    json_object_object_add(r, "max_error", json_object_new_double(ko->max_error));
    json_object_object_add(r, "check_points", json_object_new_int(rep.check_points));
    json_object_object_add(r, "check_error_relative", finite_or_null(rep.max_error));
    json_object_object_add(r, "check_error_hz", finite_or_null(rep.at_hz));
    json_object_object_add(r, "max_receptance_error_relative", json_object_new_double(worst[0]));
    json_object_object_add(r, "max_receptance_error_hz", json_object_new_double(worst_hz[0]));
    json_object_object_add(r, "max_forced_error_relative",
                           n_loads > 0 ? json_object_new_double(worst[1]) : NULL);
    json_object_object_add(r, "max_forced_error_hz",
                           n_loads > 0 ? json_object_new_double(worst_hz[1]) : NULL);
    json_object_object_add(r, "max_interface_frf_error_relative",
                           json_object_new_double(worst[k_worst]));
    json_object_object_add(r, "max_interface_frf_error_hz",
                           json_object_new_double(worst_hz[k_worst]));
    json_object_object_add(summary, "reduction", r);

    rths_result_printf(res,
                       "Real-time reduction of the sparse numerical substructure: %d DoFs reduced "
                       "to %d (Krylov, %d shift(s)), band %g..%g Hz, interface DoF %d\n",
                       red.n, red.nr, rep.shifts, ko->start_hz, ko->end_hz,
                       setup->split.int_dofs[0] + 1);
    rths_result_printf(res,
                       "interface receptance error up to %.3e (at %g Hz) over %d frequencies of "
                       "%g..%g Hz\n",
                       worst[0], worst_hz[0], sweep.points, sweep.start_hz, sweep.end_hz);
    if (n_loads > 0)
        rths_result_printf(res, "interface response to the forcing: error up to %.3e (at %g Hz)\n",
                           worst[1], worst_hz[1]);
    rths_result_printf(res,
                       "check (the assembly's interface response, %d points): %.3e at %g Hz, "
                       "controller.reduction.max_error %g\n",
                       rep.check_points, rep.max_error, rep.at_hz, ko->max_error);
    rths_result_printf(res, "note: on a sparse model rths fidelity reports the reduction only\n");
    if (setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY)
        rths_result_printf(res, "note: split.numerical_solver is frequency: rths frf solves this "
                                "numerical side exactly per harmonic\n");
    rths_result_log(res,
                    "reduction: sparse numerical substructure of %d DoFs reduced to %d DoFs "
                    "(Krylov, %d shift(s), band %g-%g Hz); interface FRF error up to %.3e at %g Hz "
                    "over %d frequencies of %g-%g Hz (check %.3e at %g Hz, max %g)",
                    red.n, red.nr, rep.shifts, ko->start_hz, ko->end_hz, worst[k_worst],
                    worst_hz[k_worst], sweep.points, sweep.start_hz, sweep.end_hz, rep.max_error,
                    rep.at_hz, ko->max_error);
    rc = rths_result_set_summary(res, summary, err);
    summary = NULL;
    if (rc) goto done;
    char body[2048];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set title 'Real-time reduction of the sparse numerical substructure: %d of %d DoFs "
             "(Krylov), interface FRF error'\n"
             "set grid\n"
             "set logscale y\n"
             "set format y '%%.0e'\n"
             "set xlabel 'forcing frequency (Hz)'\n"
             "set ylabel 'relative error'\n"
             "plot 'fidelity.csv' skip 1 using 1:4 with linespoints lw 2 lc rgb '#1f77b4' "
             "title 'interface receptance'%s\n",
             red.nr, red.n,
             n_loads > 0 ? ", \\\n  '' skip 1 using 1:7 with linespoints lw 2 lc rgb '#d62728' "
                           "title 'response to the forcing'"
                         : "");
    rc = rths_result_add_figure(res, "fidelity", 1000, 600, body, err);
done:
    if (summary) json_object_put(summary);
    if (have_table) rths_table_free(&t);
    rths_sparse_model_receptance_destroy(exact);
    rths_mat_free(rl);
    free(dofs);
    rths_reduced_free(&red);
    if (rc) {
        rths_result_free(res);
        return rc;
    }
    *out = res;
    return RTHS_OK;
}
