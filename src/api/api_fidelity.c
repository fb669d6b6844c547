/* rths_api_fidelity: the hybrid test's steady-state FRF at a perfect interface match for every
 * integration scheme of the numerical substructure, against the true assembly (docs/method.md,
 * "Numerical substructure integration"); on a sparse model the real-time reduction's error
 * (api_fidelity_sparse.c). The one implementation of `rths fidelity`: the command
 * calls rths_api_fidelity_run (over rths_api_fidelity_compute) and writes its result with
 * rths_api_result_write. */
#include "api/api_fidelity_nonlinear.h"
#include "api/api_fidelity_sparse.h"
#include "api/api_internal.h"
#include "rths/controller.h"
#include "rths/fidelity.h"

#include <json-c/json.h>
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define N_CURVES (RTHS_SCHEME_COUNT + 1)

typedef struct {
    rths_fidelity_options sweep;
    double sample_rate_hz;
    int dof; /* 0-based: the (first) interface DoF */
    rths_reduction_options reduction;
    rths_controller_options controller; /* the step's, for the nonlinear comparison */
} fidelity_options;

static int read_options(rths_config *cfg, const rths_setup *setup, fidelity_options *o,
                        rths_error *err) {
    int rc = rths_fidelity_config_read(cfg, &setup->assembly, &o->sweep, err);
    if (rc) return rc;
    /* the controller's own reader: one default and range for the sample rate, and the rest of
     * the controller section is checked too */
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    if ((rc = rths_controller_config_read(cfg, &copt, err))) return rc;
    o->sample_rate_hz = copt.sample_rate_hz;
    o->dof = setup->split.int_dofs[0];
    o->reduction = copt.reduction;
    o->controller = copt;
    return rths_reduction_config_read(cfg, &o->reduction, err);
}

static const char *curve_name(int c) {
    return c == RTHS_FIDELITY_TRUE ? "true" : rths_scheme_name((rths_scheme)c);
}

/* Columns after the linear ones with nonlinear elements: at the nonlinear comparison's
 * frequencies, nan elsewhere. */
#define NL_COLUMNS 3
static const char *const nl_header[NL_COLUMNS] = {
    "nonlinear_true_amplitude_m", "nonlinear_step_amplitude_m", "nonlinear_step_error_relative"};

/* Table "fidelity": frequency_hz, true_amplitude_m, <scheme>_amplitude_m (fidelity.csv), then
 * with n_nl nonlinear points (else none) their NL_COLUMNS columns. */
static int add_table(rths_result *res, const rths_fidelity *f, const fidelity_options *o,
                     const double *freqs, int count, const rths_fidelity_nl_point *nl, int n_nl,
                     rths_error *err) {
    const char *header[N_CURVES + 1 + NL_COLUMNS] = {"frequency_hz", "true_amplitude_m"};
    char names[RTHS_SCHEME_COUNT][64];
    for (int s = 0; s < RTHS_SCHEME_COUNT; s++) {
        snprintf(names[s], sizeof names[s], "%s_amplitude_m", rths_scheme_name((rths_scheme)s));
        header[2 + s] = names[s];
    }
    for (int k = 0; k < NL_COLUMNS; k++)
        header[N_CURVES + 1 + k] = nl_header[k];
    rths_table t;
    int rc = rths_table_create("fidelity", count, N_CURVES + 1 + (n_nl > 0 ? NL_COLUMNS : 0),
                               header, &t, err);
    if (rc) return rc;
    double complex *x = malloc((size_t)rths_fidelity_dofs(f) * sizeof *x);
    if (!x) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < count && !rc; i++) {
        t.data[0][i] = freqs[i];
        for (int c = RTHS_FIDELITY_TRUE; c < RTHS_SCHEME_COUNT && !rc; c++) {
            rc = rths_fidelity_response(f, c, 2 * M_PI * freqs[i], x, err);
            t.data[2 + c][i] = cabs(x[o->dof]);
        }
        for (int k = 0; k < NL_COLUMNS && n_nl > 0; k++)
            t.data[N_CURVES + 1 + k][i] = NAN;
        for (int p = 0; p < n_nl; p++)
            if (nl[p].frequency_hz == freqs[i]) {
                t.data[N_CURVES + 1][i] = nl[p].true_amplitude_m;
                t.data[N_CURVES + 2][i] = nl[p].step_amplitude_m;
                t.data[N_CURVES + 3][i] = nl[p].error_relative;
            }
    }
    free(x);
    if (rc) {
        rths_table_free(&t);
        return rc;
    }
    return rths_result_take_table(res, &t, err);
}

static int plot(rths_result *res, const fidelity_options *o, double mass_ratio, double true_peak_hz,
                double true_peak_m, double half_width_hz, rths_error *err) {
    /* Left: a linear zoom on the peak, where the schemes differ and a log axis would hide it.
     * Right: each scheme's amplitude error against the true FRF over the whole sweep. */
    double lo = fmax(o->sweep.start_hz, true_peak_hz - half_width_hz);
    double hi = fmin(o->sweep.end_hz, true_peak_hz + half_width_hz);
    char body[4096];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set multiplot layout 1,2 title 'Integration fidelity of the "
             "numerical substructure: "
             "hybrid test at a perfect interface match, h = %g s, p = %g, "
             "interface DoF %d'\n"
             "set grid\n"
             "set xlabel 'forcing frequency (Hz)'\n"
             "set title 'interface amplitude near the peak'\n"
             "set ylabel 'interface amplitude (m)'\n"
             "set format y '%%.1e'\n"
             "set key top right\n"
             "set xrange [%.17g:%.17g]\n"
             "set yrange [0:%.17g]\n"
             "plot 'fidelity.csv' skip 1 using 1:2 with lines lw 4 lc rgb "
             "'#000000' title 'true "
             "(analytic)', \\\n"
             "  '' skip 1 using 1:3 with lines lw 2 lc rgb '#d62728' title "
             "'implicit Euler', \\\n"
             "  '' skip 1 using 1:4 with lines lw 2 dt 2 lc rgb '#2ca02c' title "
             "'trapezoidal', \\\n"
             "  '' skip 1 using 1:5 with lines lw 2 lc rgb '#1f77b4' title "
             "'exact ZOH', \\\n"
             "  '' skip 1 using 1:6 with lines lw 2 dt 3 lc rgb '#ff7f0e' title "
             "'exact FOH'\n"
             "set title 'amplitude error against the true FRF'\n"
             "set ylabel 'amplitude error (%%)'\n"
             "set format y '%%g'\n"
             "set key bottom right\n"
             "set xrange [%.17g:%.17g]\n"
             "set yrange [*:*]\n"
             "plot 'fidelity.csv' skip 1 using 1:(100*($3/$2-1)) with lines lw 2 "
             "lc rgb '#d62728' "
             "title 'implicit Euler', \\\n"
             "  '' skip 1 using 1:(100*($4/$2-1)) with lines lw 2 dt 2 lc rgb "
             "'#2ca02c' "
             "title 'trapezoidal', \\\n"
             "  '' skip 1 using 1:(100*($5/$2-1)) with lines lw 2 lc rgb "
             "'#1f77b4' title 'exact ZOH', "
             "\\\n"
             "  '' skip 1 using 1:(100*($6/$2-1)) with lines lw 2 dt 3 lc rgb "
             "'#ff7f0e' "
             "title 'exact FOH'\n"
             "unset multiplot\n",
             1.0 / o->sample_rate_hz, mass_ratio, o->dof + 1, lo, hi, 1.08 * true_peak_m,
             o->sweep.start_hz, o->sweep.end_hz);
    return rths_result_add_figure(res, "fidelity", 1400, 600, body, err);
}

/* The numerical substructure as the controller integrates it: reduced (Craig-Bampton, the same
 * cutoff rule as the controller's build) when the reduction applies, else NULL. */
static int build_reduction(const rths_setup *setup, const fidelity_options *o, rths_reduced *red,
                           int *applies, rths_error *err) {
    const rths_split *s = &setup->split;
    *applies = rths_reduction_applies(&o->reduction, s->nn);
    if (!*applies) return RTHS_OK;
    return rths_reduce_craig_bampton(s->nn, s->n_int, s->mass_num, s->damping_num, s->stiffness_num,
                                     rths_reduction_cutoff_hz(&o->reduction, o->sample_rate_hz),
                                     RTHS_REALTIME_MAX_DOFS - s->n_int, o->reduction.cutoff_hz <= 0,
                                     red, err);
}

/* The reduction's own error (continuous time, no scheme): its peak against the true one and the
 * largest relative interface FRF error over the grid; printed and added to the summary. */
static int report_reduction(rths_result *res, const rths_fidelity *f, const rths_reduced *red,
                            const fidelity_options *o, const double *freqs, int count,
                            const double *true_peak, json_object *summary, rths_error *err) {
    double peak_hz, peak_m, worst = 0, worst_hz = 0;
    int rc = rths_fidelity_peak(f, RTHS_FIDELITY_REDUCED, o->dof, o->sweep.start_hz,
                                o->sweep.end_hz, o->sweep.points, &peak_hz, &peak_m, err);
    double complex *x = malloc(sizeof *x * (size_t)rths_fidelity_dofs(f));
    double complex *t = malloc(sizeof *t * (size_t)rths_fidelity_dofs(f));
    if (!rc && (!x || !t)) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < count && !rc; i++) {
        rc = rths_fidelity_response(f, RTHS_FIDELITY_REDUCED, 2 * M_PI * freqs[i], x, err);
        if (!rc) rc = rths_fidelity_response(f, RTHS_FIDELITY_TRUE, 2 * M_PI * freqs[i], t, err);
        double e = rc ? 0 : cabs(x[o->dof] - t[o->dof]) / cabs(t[o->dof]);
        if (e > worst) worst = e, worst_hz = freqs[i];
    }
    free(x), free(t);
    if (rc) return rc;
    double peak_error = 100.0 * (peak_m - true_peak[0]) / true_peak[0];
    json_object *r = json_object_new_object();
    json_object_object_add(r, "method", json_object_new_string("craig_bampton"));
    json_object_object_add(r, "dofs", json_object_new_int(red->nr));
    json_object_object_add(r, "modes", json_object_new_int(red->n_modes));
    json_object_object_add(r, "cutoff_hz", json_object_new_double(red->cutoff_hz));
    json_object_object_add(r, "peak_hz", json_object_new_double(peak_hz));
    json_object_object_add(r, "peak_error_percent", json_object_new_double(peak_error));
    json_object_object_add(r, "max_interface_frf_error_relative", json_object_new_double(worst));
    json_object_object_add(summary, "reduction", r);
    rths_result_printf(res,
                       "%-16s %14.6f %18.6e %+16.3f   (Craig-Bampton, %d DoFs, modes <= %g Hz; "
                       "interface FRF error <= %.2e, at %g Hz)\n",
                       "reduction", peak_hz, peak_m, peak_error, red->nr, red->cutoff_hz, worst,
                       worst_hz);
    rths_result_log(res,
                    "reduction: %d DoFs (%d modes up to %g Hz), peak %+.4f %%, interface FRF "
                    "error up to %.3e at %g Hz",
                    red->nr, red->n_modes, red->cutoff_hz, peak_error, worst, worst_hz);
    return RTHS_OK;
}

/* The nonlinear comparison's frequencies: nonlinear_points of the uniform grid, evenly spread with
 * both ends, computed as rths_fidelity_frequencies computes the grid so that each is one of its
 * rows exactly; then the step against the truth at each (api_fidelity_nonlinear.h). */
static int nonlinear_points(const rths_setup *setup, const fidelity_options *o,
                            rths_fidelity_nl_point **nl, int *n_nl, rths_error *err) {
    const int m = o->sweep.nonlinear_points, points = o->sweep.points;
    double *hz = malloc(sizeof *hz * (size_t)m);
    *nl = calloc((size_t)m, sizeof **nl);
    *n_nl = 0;
    if (!hz || !*nl) {
        free(hz);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int k = 0; k < m; k++) {
        int i = (int)lround((double)k * (points - 1) / (m - 1));
        hz[k] = o->sweep.start_hz + (o->sweep.end_hz - o->sweep.start_hz) * i / (points - 1);
    }
    int rc = rths_fidelity_nl_compute(setup, &o->controller, hz, m, *nl, err);
    free(hz);
    if (!rc) *n_nl = m;
    return rc;
}

/* A number for the summary; null for nan (a point without a truth), which JSON cannot carry. */
static json_object *finite_or_null(double x) {
    return isfinite(x) ? json_object_new_double(x) : NULL;
}

/* The nonlinear comparison in the summary ("nonlinear") and the printed report. */
static void report_nonlinear(rths_result *res, const fidelity_options *o,
                             const rths_fidelity_nl_point *nl, int n_nl, json_object *summary) {
    json_object *r = json_object_new_object(), *pts = json_object_new_array();
    double worst = 0, worst_hz = 0, truncation = 0;
    int settled = 1;
    rths_result_printf(res,
                       "Nonlinear elements: the step (%s, %g Hz) simulating the whole assembly "
                       "against harmonic balance (%d harmonics, %d samples per period)\n",
                       rths_scheme_name(o->controller.scheme), o->sample_rate_hz,
                       RTHS_FIDELITY_NL_HARMONICS, RTHS_FIDELITY_NL_SAMPLES);
    rths_result_printf(res, "%14s %18s %18s %14s %12s\n", "frequency_hz", "true_amplitude_m",
                       "step_amplitude_m", "error_rel", "settled_s");
    for (int p = 0; p < n_nl; p++) {
        const rths_fidelity_nl_point *q = &nl[p];
        json_object *j = json_object_new_object();
        json_object_object_add(j, "frequency_hz", json_object_new_double(q->frequency_hz));
        json_object_object_add(j, "true_amplitude_m", finite_or_null(q->true_amplitude_m));
        json_object_object_add(j, "step_amplitude_m", finite_or_null(q->step_amplitude_m));
        json_object_object_add(j, "error_relative", finite_or_null(q->error_relative));
        json_object_object_add(j, "truth_truncation_relative", finite_or_null(q->truth_truncation));
        json_object_object_add(j, "settled", json_object_new_boolean(q->settled));
        json_object_object_add(j, "settled_s", json_object_new_double(q->settled_s));
        json_object_array_add(pts, j);
        rths_result_printf(res, "%14.6f %18.9e %18.9e %14.3e %12.2f%s\n", q->frequency_hz,
                           q->true_amplitude_m, q->step_amplitude_m, q->error_relative,
                           q->settled_s, q->settled ? "" : " (not periodic)");
        if (q->error_relative > worst) worst = q->error_relative, worst_hz = q->frequency_hz;
        truncation = fmax(truncation, q->truth_truncation);
        settled &= q->settled;
    }
    json_object_object_add(r, "truth", json_object_new_string("harmonic_balance"));
    json_object_object_add(r, "harmonics", json_object_new_int(RTHS_FIDELITY_NL_HARMONICS));
    json_object_object_add(r, "samples_per_period", json_object_new_int(RTHS_FIDELITY_NL_SAMPLES));
    json_object_object_add(r, "scheme",
                           json_object_new_string(rths_scheme_name(o->controller.scheme)));
    json_object_object_add(r, "max_error_relative", json_object_new_double(worst));
    json_object_object_add(r, "max_error_hz", json_object_new_double(worst_hz));
    json_object_object_add(r, "max_truth_truncation_relative", json_object_new_double(truncation));
    json_object_object_add(r, "all_settled", json_object_new_boolean(settled));
    json_object_object_add(r, "points", pts);
    json_object_object_add(summary, "nonlinear", r);
    rths_result_printf(res, "step error up to %.3e (at %g Hz); truth's truncation up to %.1e\n",
                       worst, worst_hz, truncation);
    rths_result_log(res,
                    "nonlinear: step error up to %.6e at %g Hz over %d frequencies, harmonic "
                    "balance %d harmonics (truncation up to %.2e)",
                    worst, worst_hz, n_nl, RTHS_FIDELITY_NL_HARMONICS, truncation);
}

int rths_api_fidelity_compute(rths_config *cfg, const rths_setup *setup, const char *config_path,
                              const char *const *overrides, int n_overrides, rths_result **out,
                              rths_error *err) {
    static const char *const own_sections[] = {"fidelity", "controller", NULL};
    *out = NULL;
    /* a sparse model: its real-time reduction's error (api_fidelity_sparse.h) */
    if (setup->sparse)
        return rths_api_fidelity_sparse(cfg, setup, config_path, overrides, n_overrides, out, err);
    rths_result *res = NULL;
    rths_fidelity *f = NULL;
    rths_reduced red = {0};
    int reduced = 0;
    double *freqs = NULL;
    json_object *summary = NULL;
    rths_fidelity_nl_point *nl = NULL;
    int n_nl = 0;
    const char *nl_why = NULL;
    fidelity_options o;
    int rc;
    if ((rc = read_options(cfg, setup, &o, err)) ||
        (rc = rths_api_fidelity_check_sections(cfg, own_sections, err)))
        goto done;
    double h = 1.0 / o.sample_rate_hz;
    if ((rc = build_reduction(setup, &o, &red, &reduced, err)) ||
        (rc = rths_fidelity_create_reduced(&setup->split, setup->force, h, reduced ? &red : NULL,
                                           &f, err)))
        goto done;

    /* every curve's peak, refined beyond the grid, so the reported errors are the model's and the
     * table contains each exact peak */
    double peak_hz[N_CURVES], peak_m[N_CURVES];
    for (int c = RTHS_FIDELITY_TRUE; c < RTHS_SCHEME_COUNT && !rc; c++)
        rc = rths_fidelity_peak(f, c, o.dof, o.sweep.start_hz, o.sweep.end_hz, o.sweep.points,
                                &peak_hz[c + 1], &peak_m[c + 1], err);
    if (rc) goto done;
    int unique;
    if ((rc = rths_fidelity_frequencies(&o.sweep, peak_hz, N_CURVES, &freqs, &unique, err)))
        goto done;
    if (setup->has_bilinear && rths_fidelity_nl_applies(setup, &nl_why) &&
        (rc = nonlinear_points(setup, &o, &nl, &n_nl, err)))
        goto done;
    if ((rc = rths_result_new(&res, err)) ||
        (rc = add_table(res, f, &o, freqs, unique, nl, n_nl, err)))
        goto done;

    summary = rths_api_summary_new("fidelity", config_path, overrides, n_overrides);
    if (!summary) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    json_object *curves = json_object_new_object();
    json_object_object_add(summary, "sample_rate_hz", json_object_new_double(o.sample_rate_hz));
    json_object_object_add(summary, "time_step_s", json_object_new_double(h));
    json_object_object_add(summary, "mass_ratio", json_object_new_double(setup->split.mass_ratio));
    json_object_object_add(summary, "interface_dof", json_object_new_int(o.dof + 1));
    json_object_object_add(summary, "start_hz", json_object_new_double(o.sweep.start_hz));
    json_object_object_add(summary, "end_hz", json_object_new_double(o.sweep.end_hz));
    json_object_object_add(summary, "points", json_object_new_int(unique));
    json_object_object_add(summary, "default_scheme",
                           json_object_new_string(rths_scheme_name(RTHS_SCHEME_DEFAULT)));
    rths_result_printf(res,
                       "Integration fidelity: interface DoF %d, p = %g, h = %g s (%g Hz), "
                       "%g..%g Hz\n",
                       o.dof + 1, setup->split.mass_ratio, h, o.sample_rate_hz, o.sweep.start_hz,
                       o.sweep.end_hz);
    rths_result_printf(res, "%-16s %14s %18s %16s\n", "scheme", "peak_hz", "peak_amplitude_m",
                       "peak_error_%");
    double widest = 0;
    for (int c = RTHS_FIDELITY_TRUE; c < RTHS_SCHEME_COUNT; c++) {
        double e = 100.0 * (peak_m[c + 1] - peak_m[0]) / peak_m[0];
        json_object *o_c = json_object_new_object();
        json_object_object_add(o_c, "peak_hz", json_object_new_double(peak_hz[c + 1]));
        json_object_object_add(o_c, "peak_amplitude_m", json_object_new_double(peak_m[c + 1]));
        json_object_object_add(o_c, "peak_error_percent", json_object_new_double(e));
        json_object_object_add(o_c, "peak_shift_hz",
                               json_object_new_double(peak_hz[c + 1] - peak_hz[0]));
        json_object_object_add(curves, curve_name(c), o_c);
        rths_result_printf(res, "%-16s %14.6f %18.6e %+16.3f\n", curve_name(c), peak_hz[c + 1],
                           peak_m[c + 1], e);
        widest = fmax(widest, fabs(peak_hz[c + 1] - peak_hz[0]));
        rths_result_log(res, "%s: peak %.9g m at %.9g Hz (%+.4f %%)", curve_name(c), peak_m[c + 1],
                        peak_hz[c + 1], e);
    }
    json_object_object_add(summary, "curves", curves);
    if (reduced && (rc = report_reduction(res, f, &red, &o, freqs, unique, peak_m, summary, err)))
        goto done;
    if (setup->has_bilinear) {
        /* the frequency-domain model is linear: the leg's extension stiffness is what it sees */
        static const char leg_note[] = "the bilinear leg is not modelled: the structure is taken "
                                       "as linear with the leg's extension stiffness";
        static const char elements_note[] = "the nonlinear elements are not modelled: the "
                                            "structure is taken as linear (K and C without their "
                                            "forces)";
        /* structure.bilinear alone keeps its note; structure.nonlinear's elements get theirs */
        int leg_only = setup->n_nonlinear == 1 && setup->nonlinear[0].type == RTHS_NL_BILINEAR &&
                       setup->leg.upper_dof == setup->nonlinear[0].dof_i &&
                       setup->leg.stiffness_n_per_m > 0;
        const char *note = leg_only ? leg_note : elements_note;
        json_object_object_add(summary, "note", json_object_new_string(note));
        rths_result_printf(res, "note: %s\n", note);
        if (n_nl > 0) report_nonlinear(res, &o, nl, n_nl, summary);
        if (nl_why) {
            json_object_object_add(summary, "nonlinear_skipped", json_object_new_string(nl_why));
            rths_result_printf(res, "nonlinear comparison skipped: %s\n", nl_why);
        }
    }
    rc = rths_result_set_summary(res, summary, err);
    summary = NULL;
    if (rc) goto done;
    /* zoom: a few half-power bandwidths of the true peak (found on the analytic curve), wide enough
     * for every scheme's shifted peak */
    double half_power_hz = rths_fidelity_half_power_hz(
        f, RTHS_FIDELITY_TRUE, o.dof, peak_hz[0], peak_m[0], o.sweep.end_hz,
        0.1 * ((o.sweep.end_hz - o.sweep.start_hz) / (o.sweep.points - 1)));
    double half_width = fmax(6 * half_power_hz, 3 * widest);
    if (!(half_width > 0)) half_width = 0.5 * (o.sweep.end_hz - o.sweep.start_hz);
    rc = plot(res, &o, setup->split.mass_ratio, peak_hz[0], peak_m[0], half_width, err);
done:
    if (summary) json_object_put(summary);
    free(freqs);
    free(nl);
    rths_fidelity_free(f);
    rths_reduced_free(&red);
    if (rc) {
        rths_result_free(res);
        return rc;
    }
    *out = res;
    return RTHS_OK;
}

int rths_api_fidelity(const rths_api_config *cfg, const char *out_dir, rths_result **out,
                      rths_error *err) {
    *out = NULL;
    if (!cfg) return rths_error_set(err, RTHS_EINPUT, "no configuration given");
    rths_config *c;
    rths_setup setup;
    rths_result *r = NULL;
    int rc = rths_api_load(cfg, &c, &setup, err);
    if (rc) return rc;
    rc = rths_api_fidelity_compute(c, &setup, cfg->path, (const char *const *)cfg->overrides,
                                   cfg->n_overrides, &r, err);
    rc = rths_api_finish(r, rc, c, out_dir, "fidelity", out, err);
    rths_api_unload(c, &setup);
    return rc;
}
