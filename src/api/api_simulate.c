/* rths_api_simulate: one hybrid test on the virtual rig (or a controller process) at a fixed target
 * (iterative mode), or the conventional real-time hybrid test with the feedback loop closed
 * (feedback mode). The one implementation of `rths simulate`: the command parses its options,
 * calls rths_api_simulate_prepare and rths_api_simulate_run, and writes the result with
 * rths_api_result_write. */
#include "api/api_internal.h"
#include "rths/controller.h"
#include "rths/rig.h"
#include "rths/rig_remote.h"
#include "rths/rig_virtual.h"
#include "rths/stability.h"

#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

_Static_assert(RTHS_API_MAX_HARMONICS == RTHS_MAX_HARMONICS, "rths.h and signals.h agree");
_Static_assert(RTHS_API_MAX_INTERFACE_DOFS == RTHS_MAX_INTERFACE_DOFS,
               "rths.h and signals.h agree");

typedef struct {
    int feedback;
    double frequency_hz;
    int harmonics;   /* target harmonics (iterative) */
    int target_dofs; /* interface DoFs the target names */
    /* DoF d's coefficient k at [d * harmonics + k - 1] (rths_rig_set_target_dofs's layout) */
    double target_a[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_HARMONICS],
        target_b[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_HARMONICS];
    long periods, trace_periods;
    int has_delay;
    double delay_s;
} sim_args;

/* ---- outputs ---- */

/* coefficients.csv: period, frequency_hz, end_time_s, then for the physical and the numerical
 * interface displacement a0 and a_k, b_k for k = 1..harmonics (m), then the period's integrity
 * counts (rths_period: late, clipped-demand and saturated-sensor samples; NaN when the periods
 * were computed from a feedback run's trace, which has none: summary.json has the run's). */
static int add_coefficients(rths_result *res, const rths_period *p, int count, int harmonics,
                            int dofs, int counted, rths_error *err) {
    /* several interface DoFs: every DoF's physical and numerical sides after the first's */
    int per_side = 1 + 2 * harmonics, extra = dofs > 1 ? dofs : 0;
    int cols = 3 + 2 * per_side * (1 + extra) + 3;
    const char **header = calloc((size_t)cols, sizeof *header);
    char(*names)[32] = calloc((size_t)cols, sizeof *names);
    double *row = calloc((size_t)cols, sizeof *row);
    rths_table t = {0};
    int rc = (header && names && row) ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (rc) goto done;
    header[0] = "period", header[1] = "frequency_hz", header[2] = "end_time_s";
    int c = 3;
    static const char *const side[2] = {"phys", "num"};
    for (int d = -1; d < extra; d++) {
        char prefix[16] = "";
        if (d >= 0) snprintf(prefix, sizeof prefix, "dof%d_", d + 1);
        for (int s = 0; s < 2; s++) {
            snprintf(names[c], sizeof names[c], "%s%s_a0_m", prefix, side[s]);
            header[c] = names[c], c++;
            for (int k = 1; k <= harmonics; k++) {
                snprintf(names[c], sizeof names[c], "%s%s_a%d_m", prefix, side[s], k);
                header[c] = names[c], c++;
                snprintf(names[c], sizeof names[c], "%s%s_b%d_m", prefix, side[s], k);
                header[c] = names[c], c++;
            }
        }
    }
    header[c++] = "late_samples";
    header[c++] = "clipped_demand_samples";
    header[c++] = "saturated_sensor_samples";
    if ((rc = rths_table_create("coefficients", count, cols, header, &t, err))) goto done;
    for (int i = 0; i < count && !rc; i++) {
        row[0] = i + 1, row[1] = p[i].frequency_hz, row[2] = p[i].end_time_s;
        c = 3;
        for (int d = -1; d < extra; d++) {
            const rths_fourier *f[2] = {d < 0 ? &p[i].phys : &p[i].phys_dof[d],
                                        d < 0 ? &p[i].num : &p[i].num_dof[d]};
            for (int s = 0; s < 2; s++) {
                row[c++] = f[s]->a[0];
                for (int k = 1; k <= harmonics; k++)
                    row[c++] = f[s]->a[k], row[c++] = f[s]->b[k];
            }
        }
        row[c++] = counted ? p[i].late_samples : NAN;
        row[c++] = counted ? p[i].clipped_demand_samples : NAN;
        row[c++] = counted ? p[i].saturated_sensor_samples : NAN;
        for (int k = 0; k < cols; k++)
            t.data[k][i] = row[k];
    }
    rc = rths_result_take_table(res, &t, err);
done:
    free(header), free(names), free(row);
    return rc;
}

static int add_trace(rths_result *res, const rths_trace_sample *t, int count, rths_error *err) {
    static const char *const header[6] = {"time_s",   "x_phys_m", "x_num_m",
                                          "target_m", "force_n",  "demand"};
    rths_table tab;
    int rc = rths_table_create("trace", count, 6, header, &tab, err);
    if (rc) return rc;
    for (int i = 0; i < count; i++) {
        double row[6] = {t[i].time_s,   t[i].x_phys_m, t[i].x_num_m,
                         t[i].target_m, t[i].force_n,  t[i].demand};
        for (int k = 0; k < 6; k++)
            tab.data[k][i] = row[k];
    }
    return rths_result_take_table(res, &tab, err);
}

/* The seed's Fig. 8: the phase (Lissajous) plot of physical against numerical interface
 * displacement with the ideal x_phys = x_num line, and their time profiles. In mm so the tick
 * labels stay short. */
static int plot(rths_result *res, const char *title, double lissajous_from_s, double max_abs_m,
                rths_error *err) {
    /* micrometres below a millimetre, so tick labels stay short */
    double scale = max_abs_m < 1e-3 ? 1e6 : 1e3;
    const char *unit = max_abs_m < 1e-3 ? "µm" : "mm";
    char body[4096];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set multiplot layout 1,2 title '%s'\n"
             "set grid\n"
             "set title 'phase plot (t >= %.4g s)'\n"
             "set xlabel 'numerical interface displacement x_{num} (%s)'\n"
             "set ylabel 'physical interface displacement x_{phys} (%s)'\n"
             "set size ratio -1\n"
             "set key top left\n"
             "plot x with lines lw 1 lc rgb '#000000' title 'ideal: x_{phys} = x_{num}', \\\n"
             "  'trace.csv' skip 1 using ($1 >= %.17g ? $3*%g : NaN):($2*%g) with lines lw 2 "
             "lc rgb '#1f77b4' title 'x_{phys} vs x_{num}'\n"
             "set size noratio\n"
             "set title 'time profiles'\n"
             "set xlabel 'time (s)'\n"
             "set ylabel 'interface displacement (%s)'\n"
             "set key top right\n"
             "plot 'trace.csv' skip 1 using 1:($2*%g) with lines lw 2 lc rgb '#1f77b4' "
             "title 'physical x_{phys}', \\\n"
             "  '' skip 1 using 1:($3*%g) with lines lw 2 dt 2 lc rgb '#2ca02c' "
             "title 'numerical x_{num}', \\\n"
             "  '' skip 1 using 1:($4*%g) with lines lw 1 dt 3 lc rgb '#7f7f7f' title 'target x*'\n"
             "unset multiplot\n",
             title, lissajous_from_s, unit, unit, lissajous_from_s, scale, scale, unit, scale,
             scale, scale);
    return rths_result_add_figure(res, "simulate", 1400, 620, body, err);
}

static double interface_error(const rths_fourier *p, const rths_fourier *n, int k) {
    return hypot(p->a[k] - n->a[k], p->b[k] - n->b[k]);
}

/* ---- the runs ---- */

typedef struct {
    rths_period *periods;
    int n_periods;
    rths_trace_sample *trace;
    int n_trace;
    rths_rig_fault fault;
    double rig_time_s;         /* rig clock, or simulated time of the pure-delay model */
    int beyond_bounds;         /* pure-delay model: |x| beyond 1e3 x the steady amplitude */
    double steady_amplitude_m; /* pure-delay model: true assembly's interface amplitude */
} sim_result;

static void sim_result_free(sim_result *r) {
    free(r->periods);
    free(r->trace);
    memset(r, 0, sizeof *r);
}

/* One column of the trace (which, 0..3: time, x_phys, x_num, force), malloc'ed. */
static double *trace_column(const rths_trace_sample *t, int n, int which) {
    double *c = malloc((size_t)(n > 0 ? n : 1) * sizeof *c);
    for (int i = 0; c && i < n; i++)
        c[i] = which == 0   ? t[i].time_s
               : which == 1 ? t[i].x_phys_m
               : which == 2 ? t[i].x_num_m
                            : t[i].force_n;
    return c;
}

/* Fourier coefficients of whole forcing periods from the uniformly sampled trace of a feedback
 * run (no rig computed running sums), in the rig's per-period form. */
static int periods_from_trace(const rths_trace_sample *t, int n, double f_hz, int harmonics,
                              rths_period **out, int *count, rths_error *err) {
    double *col[4] = {NULL};
    /* at most the periods up to one sample spacing past the last sample */
    double dt = n > 1 ? (t[n - 1].time_s - t[0].time_s) / (n - 1) : 0;
    int total = (int)floor((t[n - 1].time_s + dt) * f_hz) + 1, width = 1 + 2 * harmonics;
    int *samples = calloc((size_t)total, sizeof *samples);
    double *coef[3] = {calloc((size_t)total * (size_t)width, sizeof(double)),
                       calloc((size_t)total * (size_t)width, sizeof(double)),
                       calloc((size_t)total * 3, sizeof(double))};
    *out = calloc((size_t)total, sizeof **out);
    *count = 0;
    int ok = samples && coef[0] && coef[1] && coef[2] && *out;
    for (int c = 0; c < 4; c++)
        ok = ok && (col[c] = trace_column(t, n, c)) != NULL;
    if (ok) {
        /* the force's fundamental only, as the rig's load-cell sums */
        *count =
            rths_whole_period_fourier(col[0], col[1], n, f_hz, harmonics, total, coef[0], samples);
        rths_whole_period_fourier(col[0], col[2], n, f_hz, harmonics, total, coef[1], NULL);
        rths_whole_period_fourier(col[0], col[3], n, f_hz, 1, total, coef[2], NULL);
    }
    for (int j = 0; j < *count; j++) {
        rths_period *p = &(*out)[j];
        rths_fourier *f[3] = {&p->phys, &p->num, &p->force};
        for (int s = 0; s < 3; s++) {
            int h = s < 2 ? harmonics : 1;
            const double *c = coef[s] + (size_t)j * (size_t)(1 + 2 * h);
            f[s]->a[0] = c[0];
            for (int k = 1; k <= h; k++)
                f[s]->a[k] = c[2 * k - 1], f[s]->b[k] = c[2 * k];
        }
        p->frequency_hz = f_hz;
        p->end_time_s = (j + 1) * (1.0 / f_hz);
        p->samples = samples[j];
    }
    for (int c = 0; c < 4; c++)
        free(col[c]);
    free(coef[0]), free(coef[1]), free(coef[2]), free(samples);
    return ok ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
}

static int create_virtual_rig(rths_config *cfg, const rths_setup *setup, int has_seed,
                              uint64_t seed, int feedback, rths_rig **rig, rths_error *err) {
    int rc = rths_virtual_rig_create(cfg, setup, has_seed, seed, rig, err);
    if (rc) return rc;
    if (feedback) {
        rths_controller *c = rths_virtual_rig_controller(*rig);
        if (!c) return rths_error_set(err, RTHS_EFAIL, "this rig has no feedback mode");
        rths_controller_set_feedback(c, 1);
    }
    return RTHS_OK;
}

/* Feedback mode through the rig's shaker and PD: the whole run is recorded at the controller's
 * sample rate (up to a cap), so divergence and its growth are seen from the start. */
static int run_feedback_rig(rths_rig *rig, const rths_setup *setup, const sim_args *a,
                            sim_result *r, rths_error *err) {
    (void)setup;
    double duration = (double)a->periods / a->frequency_hz;
    /* 200 samples per period resolve the harmonics and the envelope; the cap bounds memory */
    int max_samples = (int)fmin(200.0 * (double)a->periods + 100, 400000);
    r->trace = calloc((size_t)max_samples, sizeof *r->trace);
    if (!r->trace) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = rths_rig_record_trace(rig, duration, max_samples, r->trace, &r->n_trace, err);
    r->fault = rths_rig_get_fault(rig);
    r->rig_time_s = rths_rig_time_s(rig);
    /* a limit trip is a result here (the loop went unstable), not a failure of the command */
    if (rc && r->fault != RTHS_RIG_OK) {
        rths_error_clear(err);
        rc = RTHS_OK;
    }
    return rc;
}

/* Iterative mode: N periods at the fixed target, then a trace of K more periods. */
static int run_iterative(rths_rig *rig, const rths_setup *setup, const sim_args *a, sim_result *r,
                         rths_error *err) {
    int rc;
    (void)setup;
    r->periods = calloc((size_t)a->periods, sizeof *r->periods);
    if (!r->periods) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    if ((rc = rths_rig_run_periods(rig, (int)a->periods, r->periods, err))) return rc;
    r->n_periods = (int)a->periods;
    /* about 400 trace samples per period: smooth curves at any forcing frequency */
    int max_samples = (int)(400 * a->trace_periods);
    r->trace = calloc((size_t)max_samples, sizeof *r->trace);
    if (!r->trace) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    rc = rths_rig_record_trace(rig, a->trace_periods / a->frequency_hz, max_samples, r->trace,
                               &r->n_trace, err);
    r->fault = rths_rig_get_fault(rig);
    r->rig_time_s = rths_rig_time_s(rig);
    return rc;
}

/* Hook for the pure-delay feedback model (helper B's rths_delay_feedback_simulate); filled in
 * when it lands. Fills a uniformly sampled trace starting at t = 0. */
/* The seed's model of the conventional test (docs/method.md, "Delayed-feedback stability"): an
 * ideal actuator makes the physical interface follow the numerical one with a pure delay; simulated
 * by the stability module in continuous time. The actuator's command (target) is the numerical
 * interface now; there is no load cell or demand in this model, so those columns are NaN. */
static int run_feedback_delay(const rths_setup *setup, const sim_args *a, sim_result *r,
                              rths_error *err) {
    rths_delay_sim_result res;
    memset(&res, 0, sizeof res);
    int rc = rths_delay_feedback_simulate(&setup->assembly, &setup->split, setup->force,
                                          a->frequency_hz, a->delay_s,
                                          (double)a->periods / a->frequency_hz, 0.0, &res, err);
    if (rc) return rc;
    r->trace = calloc((size_t)(res.n > 0 ? res.n : 1), sizeof *r->trace);
    if (!r->trace) {
        rths_delay_sim_result_free(&res);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int i = 0; i < res.n; i++)
        r->trace[i] = (rths_trace_sample){.time_s = res.t_s[i],
                                          .x_phys_m = res.x_phys_m[i],
                                          .x_num_m = res.x_num_m[i],
                                          .target_m = res.x_num_m[i],
                                          .force_n = NAN,
                                          .demand = NAN};
    r->n_trace = res.n;
    r->beyond_bounds = res.diverged;
    r->steady_amplitude_m = res.steady_amplitude_m;
    r->rig_time_s = res.end_time_s;
    rths_delay_sim_result_free(&res);
    return RTHS_OK;
}

static json_object *fourier_json(const rths_fourier *f, int harmonics) {
    json_object *o = json_object_new_object(), *a = json_object_new_array(),
                *b = json_object_new_array();
    for (int k = 1; k <= harmonics; k++) {
        json_object_array_add(a, json_object_new_double(f->a[k]));
        json_object_array_add(b, json_object_new_double(f->b[k]));
    }
    json_object_object_add(o, "a0_m", json_object_new_double(f->a[0]));
    json_object_object_add(o, "a_m", a);
    json_object_object_add(o, "b_m", b);
    return o;
}

/* Decimates a fine trace to at most max_rows rows for trace.csv and the figure. */
static rths_trace_sample *decimate(const rths_trace_sample *t, int n, int max_rows, int *n_out) {
    int stride = n > max_rows ? (n + max_rows - 1) / max_rows : 1;
    rths_trace_sample *d = malloc((size_t)(n / stride + 1) * sizeof *d);
    *n_out = 0;
    if (!d) return NULL;
    for (int i = 0; i < n; i += stride)
        d[(*n_out)++] = t[i];
    return d;
}

/* What clipped or saturated over the run (signals.h, rths_period; and the actuator's force clip,
 * rig.actuator.limits), from every period the rig's controller closed: a virtual rig counts
 * those of its traces too, a remote one those it delivered. */
typedef struct {
    rths_rig_integrity rig;
    long force_clipped_samples; /* virtual rig: the actuator's force command clipped */
    int known;                  /* 0: no rig (the pure-delay model has no converters) */
} sim_integrity;

static void integrity_of(rths_rig *rig, sim_integrity *out) {
    memset(out, 0, sizeof *out);
    if (!rig) return;
    out->known = 1;
    if (rths_virtual_rig_integrity(rig, &out->rig)) rths_rig_integrity_totals(rig, &out->rig);
    rths_plant *plant = rths_virtual_rig_plant(rig);
    if (plant) {
        rths_actuator_status st;
        rths_plant_actuator_status(plant, &st);
        out->force_clipped_samples = st.force_clipped_samples;
    }
}

static long clipped_samples(const sim_integrity *t) {
    return t->rig.clipped_demand_samples + t->rig.saturated_sensor_samples +
           t->force_clipped_samples;
}

static json_object *integrity_json(const sim_integrity *t) {
    json_object *o = json_object_new_object();
    json_object_object_add(o, "periods", json_object_new_int64(t->rig.periods));
    json_object_object_add(o, "samples", json_object_new_int64(t->rig.samples));
    json_object_object_add(o, "late_samples", json_object_new_int64(t->rig.late_samples));
    json_object_object_add(o, "clipped_demand_samples",
                           json_object_new_int64(t->rig.clipped_demand_samples));
    json_object_object_add(o, "saturated_sensor_samples",
                           json_object_new_int64(t->rig.saturated_sensor_samples));
    json_object_object_add(o, "force_clipped_samples",
                           json_object_new_int64(t->force_clipped_samples));
    return o;
}

/* summary.json's divergence fields and the printed verdict of a feedback test (the verdict is
 * the stability module's, from the full-resolution trace). A run whose converters saturated or
 * whose demand or force was clipped is never called bounded (issue 23.4: a limit cycle held by
 * the force ADC's full scale was reported as "stayed bounded"): clipping, not the loop, may be
 * what bounds it. */
static int add_divergence(json_object *summary, rths_result *res, const rths_setup *setup,
                          const sim_args *a, const sim_result *r, double noise_m,
                          const sim_integrity *integrity, rths_error *err) {
    double *col[3] = {trace_column(r->trace, r->n_trace, 0), trace_column(r->trace, r->n_trace, 2),
                      trace_column(r->trace, r->n_trace, 1)};
    int ok = col[0] && col[1] && col[2];
    rths_feedback_verdict v;
    if (ok)
        rths_feedback_assess(&setup->assembly, col[0], col[1], col[2], r->n_trace, a->frequency_hz,
                             a->periods / a->frequency_hz, r->fault != RTHS_RIG_OK,
                             r->beyond_bounds, noise_m, &v);
    for (int c = 0; c < 3; c++)
        free(col[c]);
    if (!ok) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    json_object_object_add(summary, "diverged", json_object_new_boolean(v.diverged));
    json_object_object_add(summary, "growth_rate_per_s",
                           json_object_new_double(v.growth_rate_per_s));
    json_object_object_add(summary, "growth_fit_span_s", json_object_new_double(v.fit_span_s));
    json_object_object_add(summary, "divergence_reason",
                           v.reason ? json_object_new_string(v.reason) : NULL);
    if (v.note) json_object_object_add(summary, "note", json_object_new_string(v.note));
    json_object_object_add(summary, "max_abs_x_num_m", json_object_new_double(v.max_abs_x_num_m));
    json_object_object_add(summary, "simulated_s", json_object_new_double(v.reached_s));
    if (r->steady_amplitude_m > 0)
        json_object_object_add(summary, "true_steady_amplitude_m",
                               json_object_new_double(r->steady_amplitude_m));
    long clipped = clipped_samples(integrity);
    int held = !v.reason && clipped > 0;
    json_object_object_add(summary, "bounded", json_object_new_boolean(!v.reason && !clipped));
    json_object_object_add(summary, "clipped", json_object_new_boolean(clipped > 0));
    char clip_text[300] = "";
    if (clipped > 0)
        snprintf(clip_text, sizeof clip_text,
                 "%ld sample(s) clipped or saturated (%ld clipped demand, %ld saturated sensor, "
                 "%ld actuator force clipped): the response may be held by the limits, not "
                 "bounded by the loop",
                 clipped, integrity->rig.clipped_demand_samples,
                 integrity->rig.saturated_sensor_samples, integrity->force_clipped_samples);
    rths_result_printf(res, "feedback test %s: growth rate %.4g 1/s%s%s%s%s\n",
                       v.reason ? "DIVERGED"
                       : held   ? "CLIPPED, not bounded"
                                : "stayed bounded over this run",
                       v.growth_rate_per_s, (v.reason || v.note) ? "; " : "",
                       v.reason ? v.reason : (v.note ? v.note : ""), clipped ? "; " : "",
                       clip_text);
    return RTHS_OK;
}

/* Everything the rig can refuse is checked before the output folder exists: the frequency and the
 * target's top harmonic against the controller's sample rate, then the forcing and the target. */
static int arm_rig(rths_rig *rig, rths_config *cfg, const rths_setup *setup, const sim_args *a,
                   rths_error *err) {
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    int rc = rths_controller_config_read(cfg, &copt, err);
    if (rc) return rc;
    int top = a->feedback ? 1 : a->harmonics;
    if (!(a->frequency_hz < 0.25 * copt.sample_rate_hz))
        return rths_error_set(err, RTHS_EINPUT,
                              "option --frequency: %g Hz must be below a quarter of the "
                              "controller's sample rate (controller.sample_rate_hz = %g Hz)",
                              a->frequency_hz, copt.sample_rate_hz);
    if (top * a->frequency_hz >= 0.5 * copt.sample_rate_hz)
        return rths_error_set(err, RTHS_EINPUT,
                              "option --target: harmonic %d of %g Hz is at or beyond the "
                              "controller's Nyquist frequency (%g Hz)",
                              top, a->frequency_hz, 0.5 * copt.sample_rate_hz);
    if ((rc = rths_rig_set_forcing(rig, a->frequency_hz, setup->forcing_amplitude_n, err)))
        return rc;
    if (a->feedback) return RTHS_OK;
    int dofs = setup->split.n_int;
    if (a->target_dofs != dofs)
        return rths_error_set(err, RTHS_EINPUT,
                              "option --target: %d ';'-separated list%s for %d interface DoF%s; "
                              "give one list A1,B1[,...] per interface DoF",
                              a->target_dofs, a->target_dofs == 1 ? "" : "s", dofs,
                              dofs == 1 ? "" : "s");
    /* one DoF included: it passes that on to rths_rig_set_target */
    return rths_rig_set_target_dofs(rig, dofs, a->harmonics, a->target_a, a->target_b, err);
}

/* {"dof": 1-based DoF number, "a_m": [...], "b_m": [...]} of list d of --target */
static json_object *target_json(const sim_args *a, int d) {
    json_object *ta = json_object_new_array(), *tb = json_object_new_array();
    for (int k = 0; k < a->harmonics; k++) {
        json_object_array_add(ta, json_object_new_double(a->target_a[d * a->harmonics + k]));
        json_object_array_add(tb, json_object_new_double(a->target_b[d * a->harmonics + k]));
    }
    json_object *tg = json_object_new_object();
    json_object_object_add(tg, "a_m", ta);
    json_object_object_add(tg, "b_m", tb);
    return tg;
}

/* With several interface DoFs: the last period's interface error of every DoF and harmonic, m
 * (summary.json "final_interface_error_dofs_m": [[DoF 1's harmonics], ...]), printed per DoF. */
static void add_dof_errors(json_object *summary, rths_result *res, const rths_setup *setup,
                           const rths_period *last, int harmonics) {
    json_object *all = json_object_new_array();
    for (int d = 0; d < setup->split.n_int; d++) {
        json_object *errs = json_object_new_array();
        for (int k = 1; k <= harmonics; k++)
            json_object_array_add(errs, json_object_new_double(interface_error(
                                            &last->phys_dof[d], &last->num_dof[d], k)));
        json_object_array_add(all, errs);
        rths_result_printf(
            res,
            "  interface DoF %d (DoF %d): physical a1 = %.6e m, b1 = %.6e m; numerical "
            "a1 = %.6e m, "
            "b1 = %.6e m; interface error %.3e m\n",
            d + 1, setup->split.int_dofs[d] + 1, last->phys_dof[d].a[1], last->phys_dof[d].b[1],
            last->num_dof[d].a[1], last->num_dof[d].b[1],
            interface_error(&last->phys_dof[d], &last->num_dof[d], 1));
    }
    json_object_object_add(summary, "final_interface_error_dofs_m", all);
}

/* summary.json's description of the run and its last period (printed too). */
static void add_run_summary(json_object *summary, rths_result *res, const rths_setup *setup,
                            const sim_args *a, const sim_result *r, rths_rig *rig, int harmonics) {
    json_object_object_add(summary, "mode",
                           json_object_new_string(a->feedback ? "feedback" : "iterative"));
    json_object_object_add(summary, "frequency_hz", json_object_new_double(a->frequency_hz));
    json_object_object_add(summary, "forcing_amplitude_n",
                           json_object_new_double(setup->forcing_amplitude_n));
    json_object_object_add(summary, "mass_ratio", json_object_new_double(setup->split.mass_ratio));
    json_object_object_add(summary, "periods", json_object_new_int(r->n_periods));
    json_object_object_add(summary, "harmonics", json_object_new_int(harmonics));
    if (rig)
        json_object_object_add(summary, "rig", json_object_new_string(rths_rig_description(rig)));
    json_object_object_add(
        summary, "fault",
        json_object_new_string(r->fault == RTHS_RIG_OK ? "none" : rths_rig_fault_name(r->fault)));
    json_object_object_add(summary, "rig_time_s", json_object_new_double(r->rig_time_s));
    if (!a->feedback) {
        /* the first interface DoF's target (as with one), then every DoF's with several */
        json_object_object_add(summary, "target", target_json(a, 0));
        if (a->target_dofs > 1) {
            json_object *all = json_object_new_array();
            for (int d = 0; d < a->target_dofs; d++)
                json_object_array_add(all, target_json(a, d));
            json_object_object_add(summary, "target_dofs", all);
        }
    }
    if (r->n_periods > 0) {
        const rths_period *last = &r->periods[r->n_periods - 1];
        json_object *errs = json_object_new_array(), *rel = json_object_new_array();
        for (int k = 1; k <= harmonics; k++) {
            double e = interface_error(&last->phys, &last->num, k);
            double amp = hypot(last->num.a[k], last->num.b[k]);
            json_object_array_add(errs, json_object_new_double(e));
            json_object_array_add(rel, json_object_new_double(amp > 0 ? e / amp : NAN));
        }
        json_object_object_add(summary, "final_interface_error_m", errs);
        json_object_object_add(summary, "final_interface_error_relative", rel);
        json_object_object_add(summary, "final_phys", fourier_json(&last->phys, harmonics));
        json_object_object_add(summary, "final_num", fourier_json(&last->num, harmonics));
        rths_result_printf(res,
                           "%d periods at %g Hz; last period: physical a1 = %.6e m, b1 = %.6e m; "
                           "numerical a1 = %.6e m, b1 = %.6e m; interface error %.3e m\n",
                           r->n_periods, a->frequency_hz, last->phys.a[1], last->phys.b[1],
                           last->num.a[1], last->num.b[1],
                           interface_error(&last->phys, &last->num, 1));
        if (!a->feedback && setup->split.n_int > 1)
            add_dof_errors(summary, res, setup, last, harmonics);
    }
}

struct rths_api_simulation {
    rths_config *cfg;        /* the caller's */
    const rths_setup *setup; /* the caller's */
    sim_args a;
    int has_seed;
    uint64_t seed;
    int pure_delay;               /* feedback through the seed's pure-delay model: no rig */
    int remote;                   /* a controller process */
    rths_rig *rig;                /* NULL with pure_delay */
    char reset_note[700];         /* the controller's answer to RESET_FAULT, logged */
    const char *config_path;      /* named in the summary (the caller's) */
    const char *const *overrides; /* the caller's */
    int n_overrides;
};

void rths_api_simulate_options_default(rths_api_simulate_options *o) {
    memset(o, 0, sizeof *o);
}

/* The options as the command's parser checks them (the command names its options first). */
static int args_from_options(const rths_api_simulate_options *o, sim_args *a, rths_error *err) {
    memset(a, 0, sizeof *a);
    a->feedback = o->feedback != 0;
    if (!(o->frequency_hz > 0 && o->frequency_hz <= 1e5))
        return rths_error_set(err, RTHS_EINPUT, "frequency_hz: must be in (0, 100000] (got %g)",
                              o->frequency_hz);
    a->frequency_hz = o->frequency_hz;
    if (o->periods < 1 || o->periods > 100000)
        return rths_error_set(err, RTHS_EINPUT, "periods: must be in [1, 100000] (got %d)",
                              o->periods);
    a->periods = o->periods;
    if (a->feedback) {
        if (o->target_dofs || o->harmonics)
            return rths_error_set(err, RTHS_EINPUT,
                                  "target: not used in feedback mode (the target is the numerical "
                                  "interface displacement itself)");
        if (o->trace_periods)
            return rths_error_set(err, RTHS_EINPUT,
                                  "trace_periods: feedback mode traces the whole run");
        if (o->delay_s != 0) {
            if (!(o->delay_s > 0 && o->delay_s <= 1.0))
                return rths_error_set(err, RTHS_EINPUT, "delay_s: must be in (0, 1] (got %g)",
                                      o->delay_s);
            a->has_delay = 1, a->delay_s = o->delay_s;
        }
        return RTHS_OK;
    }
    if (o->delay_s != 0)
        return rths_error_set(err, RTHS_EINPUT,
                              "delay_s: only in feedback mode (the iterative test has no feedback "
                              "loop to delay)");
    if (o->harmonics < 1 || o->harmonics > RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT, "target: %d harmonics; give 1 to %d per DoF",
                              o->harmonics, RTHS_MAX_HARMONICS);
    if (o->target_dofs < 1 || o->target_dofs > RTHS_MAX_INTERFACE_DOFS)
        return rths_error_set(err, RTHS_EINPUT,
                              "target: %d interface DoFs; give 1 to %d (one per interface DoF)",
                              o->target_dofs, RTHS_MAX_INTERFACE_DOFS);
    if (!o->target_a || !o->target_b)
        return rths_error_set(err, RTHS_EINPUT, "target: no coefficients given");
    a->harmonics = o->harmonics, a->target_dofs = o->target_dofs;
    for (int i = 0; i < o->harmonics * o->target_dofs; i++) {
        if (!isfinite(o->target_a[i]) || !isfinite(o->target_b[i]))
            return rths_error_set(err, RTHS_EINPUT, "target: coefficient %d is not finite", i + 1);
        a->target_a[i] = o->target_a[i], a->target_b[i] = o->target_b[i];
    }
    a->trace_periods = a->periods < 5 ? a->periods : 5;
    if (o->trace_periods) {
        if (o->trace_periods < 1 || o->trace_periods > 1000)
            return rths_error_set(err, RTHS_EINPUT, "trace_periods: must be in [1, 1000] (got %d)",
                                  o->trace_periods);
        a->trace_periods = o->trace_periods;
    }
    return RTHS_OK;
}

void rths_api_simulation_free(rths_api_simulation *s) {
    if (!s) return;
    if (s->rig) rths_rig_destroy(s->rig);
    free(s);
}

int rths_api_simulation_prepare(rths_config *cfg, const rths_setup *setup,
                                const rths_api_simulate_options *o, const char *config_path,
                                const char *const *overrides, int n_overrides,
                                rths_api_simulation **out, rths_error *err) {
    *out = NULL;
    if (rths_setup_require_dense(setup, "rths simulate", err)) return RTHS_EINPUT;
    rths_api_simulation *s = calloc(1, sizeof *s);
    if (!s) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    s->cfg = cfg, s->setup = setup;
    s->config_path = config_path, s->overrides = overrides, s->n_overrides = n_overrides;
    s->has_seed = o->has_seed != 0, s->seed = o->seed;
    int rc = args_from_options(o, &s->a, err);
    if (rc) goto done;
    const sim_args *a = &s->a;
    s->pure_delay = a->feedback && a->has_delay;
    const char *rig_uri = o->rig_uri;
    s->remote = rig_uri != NULL;
    if (o->reset_fault && !rig_uri) {
        rc = rths_error_set(err, RTHS_EINPUT,
                            "option --reset-fault needs --rig tcp://HOST:PORT (a virtual rig "
                            "starts without a fault)");
        goto done;
    }
    if (rig_uri && a->feedback) {
        rc = rths_error_set(err, RTHS_EINPUT,
                            "option --rig: feedback mode runs only on the in-process virtual rig");
        goto done;
    }
    if (rig_uri) {
        /* a controller process: its own rig and controller sections apply there */
        if ((rc = rths_remote_rig_create(rig_uri, NULL, &s->rig, err))) goto done;
        if (o->reset_fault &&
            (rc = rths_rig_clear_fault(s->rig, s->reset_note, sizeof s->reset_note, err)))
            goto done;
        if (rths_rig_interface_dofs(s->rig) != setup->split.n_int) {
            rc = rths_error_set(err, RTHS_EINPUT,
                                "controller %s drives %d interface DoF(s); this configuration's "
                                "split.interface has %d",
                                rig_uri, rths_rig_interface_dofs(s->rig), setup->split.n_int);
            goto done;
        }
    } else if (!s->pure_delay && (rc = create_virtual_rig(cfg, setup, s->has_seed, s->seed,
                                                          a->feedback, &s->rig, err))) {
        goto done;
    }
    if (s->rig && (rc = arm_rig(s->rig, cfg, setup, a, err))) goto done;
    /* the virtual rig read the rig and controller sections: a misspelt key there is an error */
    static const char *const rig_sections[] = {"rig", "controller", NULL};
    rc = rths_config_check_sections(cfg, s->rig && !rig_uri ? rig_sections : NULL, err);
done:
    if (rc) {
        rths_api_simulation_free(s);
        return rc;
    }
    *out = s;
    return RTHS_OK;
}

int rths_api_simulation_run(rths_api_simulation *s, rths_report *rep, rths_result **out,
                            rths_error *err) {
    *out = NULL;
    const sim_args *a = &s->a;
    const rths_setup *setup = s->setup;
    rths_rig *rig = s->rig;
    rths_result *res = NULL;
    json_object *summary = NULL;
    sim_result r;
    memset(&r, 0, sizeof r);
    rths_trace_sample *shown = NULL;
    int n_shown = 0;
    int rc = rths_result_new(&res, err);
    if (rc) return rc;
    if (rep && s->reset_note[0]) rths_report_log(rep, "%s", s->reset_note);
    if (rep)
        rths_report_log(rep, "simulate: mode %s, %g Hz, %ld periods",
                        a->feedback ? "feedback" : "iterative", a->frequency_hz, a->periods);

    int harmonics = a->feedback ? 1 : a->harmonics;
    if (s->pure_delay)
        rc = run_feedback_delay(setup, a, &r, err);
    else if (!a->feedback)
        rc = run_iterative(rig, setup, a, &r, err);
    else
        rc = run_feedback_rig(rig, setup, a, &r, err);
    if (rc) goto done;
    /* measuring is over: the rig to its safe state before the outputs are written (a slow
     * figure must not keep a controller's actuator excited; docs/protocol.md, DISARM) */
    rths_error disarm_err = {0};
    if (rig && rths_rig_disarm(rig, &disarm_err) && rep)
        rths_report_log(rep, "warning: disarming the rig failed: %s", disarm_err.msg);
    if (a->feedback && r.n_trace > 0 && !r.periods &&
        (rc = periods_from_trace(r.trace, r.n_trace, a->frequency_hz, harmonics, &r.periods,
                                 &r.n_periods, err)))
        goto done;
    shown = decimate(r.trace, r.n_trace, 10000, &n_shown);
    if (!shown) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    if ((rc = add_coefficients(res, r.periods, r.n_periods, harmonics,
                               a->feedback ? 1 : setup->split.n_int, !a->feedback, err)) ||
        (rc = add_trace(res, shown, n_shown, err)))
        goto done;

    summary = rths_api_summary_new("simulate", s->config_path, s->overrides, s->n_overrides);
    if (!summary) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    if (s->has_seed) json_object_object_add(summary, "seed", json_object_new_uint64(s->seed));
    add_run_summary(summary, res, setup, a, &r, rig, harmonics);
    sim_integrity integrity;
    integrity_of(rig, &integrity);
    if (integrity.known) {
        json_object_object_add(summary, "integrity", integrity_json(&integrity));
        rths_result_log(res,
                        "integrity: %ld periods, %ld samples: %ld late, %ld with a clipped demand, "
                        "%ld with a saturated sensor, %ld with the actuator force clipped",
                        integrity.rig.periods, integrity.rig.samples, integrity.rig.late_samples,
                        integrity.rig.clipped_demand_samples,
                        integrity.rig.saturated_sensor_samples, integrity.force_clipped_samples);
    }
    if (a->feedback) {
        if ((rc = add_divergence(summary, res, setup, a, &r,
                                 rig ? rths_rig_noise_level_m(rig) : 0.0, &integrity, err)))
            goto done;
        json_object_object_add(summary, "delay_s",
                               s->pure_delay ? json_object_new_double(a->delay_s) : NULL);
    }
    rc = rths_result_set_summary(res, summary, err);
    summary = NULL;
    if (rc) goto done;
    char title[256];
    if (a->feedback)
        snprintf(title, sizeof title, "Feedback hybrid test%s, p = %g, %g Hz",
                 s->pure_delay ? " with a pure delay" : " through the rig", setup->split.mass_ratio,
                 a->frequency_hz);
    else
        snprintf(title, sizeof title, "Iterative hybrid test at a fixed target, p = %g, %g Hz",
                 setup->split.mass_ratio, a->frequency_hz);
    /* the phase plot shows the last (up to) five periods: the steady state, or the growth */
    double t_last = n_shown > 0 ? shown[n_shown - 1].time_s : 0, max_abs = 0;
    for (int i = 0; i < n_shown; i++) {
        const double v[3] = {shown[i].x_phys_m, shown[i].x_num_m, shown[i].target_m};
        for (int k = 0; k < 3; k++)
            if (isfinite(v[k])) max_abs = fmax(max_abs, fabs(v[k]));
    }
    rc = plot(res, title, fmax(n_shown ? shown[0].time_s : 0, t_last - 5.0 / a->frequency_hz),
              max_abs, err);
done:
    if (summary) json_object_put(summary);
    free(shown);
    sim_result_free(&r);
    if (rc) {
        rths_result_free(res);
        return rc;
    }
    *out = res;
    return RTHS_OK;
}

int rths_api_simulate(const rths_api_config *cfg, const rths_api_simulate_options *o,
                      rths_result **out, rths_error *err) {
    *out = NULL;
    if (!cfg || !o) return rths_error_set(err, RTHS_EINPUT, "no configuration or options given");
    rths_config *c;
    rths_setup setup;
    rths_api_simulation *s = NULL;
    rths_result *r = NULL;
    int rc = rths_api_load(cfg, &c, &setup, err);
    if (rc) return rc;
    if (!(rc = rths_api_simulation_prepare(c, &setup, o, cfg->path,
                                           (const char *const *)cfg->overrides, cfg->n_overrides,
                                           &s, err)))
        rc = rths_api_simulation_run(s, NULL, &r, err);
    rths_api_simulation_free(s); /* the rig stops before the folder is written */
    rc = rths_api_finish(r, rc, c, o->out_dir, "simulate", out, err);
    rths_api_unload(c, &setup);
    return rc;
}
