/* rths_api_chart: the stability chart of the delayed-feedback test as tables and a summary. The one
 * implementation of `rths chart`'s tables and summary: the command calls rths_api_chart_compute
 * and writes its result with rths_api_result_write, as rths_api_chart does. */
#include "api/api_internal.h"
#include "rths/stability.h"

#include <json-c/json.h>
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The chart's three tables, rows in the CLI's order (chart: p outer, tau inner). */
static int chart_tables(rths_result *r, const rths_chart *c, rths_error *err) {
    static const char *const h_chart[] = {"tau_s", "p", "max_real_part_per_s", "stable"};
    static const char *const h_bound[] = {"tau_s", "p", "omega_rad_s"};
    static const char *const h_crit[] = {"p", "critical_delay_s", "crossing_omega_rad_s"};
    size_t cells = (size_t)c->nt * (size_t)c->np;
    double *grid = calloc(4 * cells + 1, sizeof *grid);
    if (!grid) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int j = 0; j < c->np; j++)
        for (int i = 0; i < c->nt; i++) {
            size_t k = (size_t)i + (size_t)j * (size_t)c->nt;
            grid[k] = c->tau[i];
            grid[cells + k] = c->p[j];
            grid[2 * cells + k] = c->max_real[k];
            grid[3 * cells + k] = c->stable[k];
        }
    const double *d_chart[4] = {grid, grid + cells, grid + 2 * cells, grid + 3 * cells};
    const double *d_bound[3] = {c->b_tau, c->b_p, c->b_omega};
    const double *d_crit[3] = {c->p, c->critical_tau, c->critical_omega};
    int rc = rths_result_add_columns(r, "chart", (int)cells, 4, h_chart, d_chart, err);
    if (!rc) rc = rths_result_add_columns(r, "boundary", c->n_boundary, 3, h_bound, d_bound, err);
    if (!rc) rc = rths_result_add_columns(r, "critical", c->np, 3, h_crit, d_crit, err);
    free(grid);
    return rc;
}

/* Critical delays located stand-alone at four p (the configured one first), and the neutral
 * chains' roots z at the configured p. */
typedef struct {
    double p[4], tau_s[4], omega_rad_s[4];
    double rate_times_tau; /* the chain bound at the configured p */
    double complex z[64];
    int nz;
} probes;

static int probe_chart(rths_split_family *fam, const rths_chart_options *o, int n, probes *pr,
                       rths_error *err) {
    int rc = RTHS_OK;
    for (int k = 0; k < 4 && !rc; k++) {
        rths_dde d;
        if ((rc = rths_split_family_build(fam, pr->p[k], &d, err))) break;
        rc = rths_dde_critical_delay(&d, o->tau_min_s * 1e-3, 10 * o->tau_max_s, 400,
                                     o->chebyshev_nodes, &pr->tau_s[k], &pr->omega_rad_s[k], err);
        rths_dde_free(&d);
    }
    if (rc) return rc;
    rths_dde dcfg;
    if ((rc = rths_split_family_build(fam, pr->p[0], &dcfg, err))) return rc;
    rc = n <= 64 ? rths_dde_essential(&dcfg, &pr->rate_times_tau, pr->z, &pr->nz, err)
                 : rths_dde_essential(&dcfg, &pr->rate_times_tau, NULL, NULL, err);
    rths_dde_free(&dcfg);
    return rc;
}

static json_object *grid_json(const rths_chart_options *o) {
    json_object *g = json_object_new_object();
    json_object_object_add(g, "tau_min_s", json_object_new_double(o->tau_min_s));
    json_object_object_add(g, "tau_max_s", json_object_new_double(o->tau_max_s));
    json_object_object_add(g, "tau_points", json_object_new_int(o->tau_points));
    json_object_object_add(g, "p_min", json_object_new_double(o->p_min));
    json_object_object_add(g, "p_max", json_object_new_double(o->p_max));
    json_object_object_add(g, "p_points", json_object_new_int(o->p_points));
    json_object_object_add(g, "omega_min_rad_s", json_object_new_double(o->omega_min_rad_s));
    json_object_object_add(g, "omega_max_rad_s", json_object_new_double(o->omega_max_rad_s));
    json_object_object_add(g, "omega_points", json_object_new_int(o->omega_points));
    json_object_object_add(g, "mdbm_tau_points", json_object_new_int(o->mdbm_tau_points));
    json_object_object_add(g, "mdbm_p_points", json_object_new_int(o->mdbm_p_points));
    json_object_object_add(g, "mdbm_refine", json_object_new_int(o->mdbm_refine));
    json_object_object_add(g, "chebyshev_nodes", json_object_new_int(o->chebyshev_nodes));
    return g;
}

static void essential_statement(const rths_chart *c, double p_ess, const rths_chart_options *o,
                                char *stmt, size_t size) {
    if (isfinite(p_ess))
        snprintf(stmt, size,
                 "neutral root chains lie on Re(lambda) = -ln|z|/tau for the roots z of "
                 "det(M_0 + z M_tau) = 0; they are in the left half-plane (necessary for "
                 "stability at any delay) only for p > %.6f",
                 p_ess);
    else
        snprintf(stmt, size,
                 "neutral root chains lie on Re(lambda) = -ln|z|/tau for the roots z of "
                 "det(M_0 + z M_tau) = 0; their side does not change over p in [%g, %g]: %s",
                 o->p_min, o->p_max,
                 c->essential_rate_times_tau[0] < 0 ? "left half-plane (stable chains)"
                                                    : "right half-plane or on the axis "
                                                      "(unstable for every delay)");
}

static json_object *essential_json(const char *stmt, double p_ess, double p_cfg, const probes *pr) {
    json_object *ess = json_object_new_object();
    json_object_object_add(ess, "statement", json_object_new_string(stmt));
    json_object_object_add(ess, "p_limit", isfinite(p_ess) ? json_object_new_double(p_ess) : NULL);
    json_object_object_add(ess, "config_p", json_object_new_double(p_cfg));
    json_object_object_add(ess, "config_rate_times_tau",
                           isfinite(pr->rate_times_tau) ? json_object_new_double(pr->rate_times_tau)
                                                        : NULL);
    json_object *zs = json_object_new_array();
    for (int k = 0; k < pr->nz; k++) {
        json_object *zz = json_object_new_array();
        json_object_array_add(zz, json_object_new_double(creal(pr->z[k])));
        json_object_array_add(zz, json_object_new_double(cimag(pr->z[k])));
        json_object_array_add(zs, zz);
    }
    json_object_object_add(ess, "config_z_roots_re_im", zs);
    return ess;
}

static json_object *critical_json(const probes *pr) {
    json_object *cr = json_object_new_array();
    for (int k = 0; k < 4; k++) {
        json_object *e = json_object_new_object();
        json_object_object_add(e, "p", json_object_new_double(pr->p[k]));
        json_object_object_add(e, "critical_delay_s",
                               isnan(pr->tau_s[k]) ? NULL : json_object_new_double(pr->tau_s[k]));
        json_object_object_add(
            e, "crossing_omega_rad_s",
            isnan(pr->omega_rad_s[k]) ? NULL : json_object_new_double(pr->omega_rad_s[k]));
        json_object_array_add(cr, e);
    }
    return cr;
}

/* The chart's summary after the common head (version, command, time, configuration file,
 * overrides): what `rths chart` has always written. */
static void chart_summary_add(json_object *summary, const rths_chart_options *o,
                              const rths_chart *chart, const rths_setup *setup, const probes *pr,
                              const rths_api_chart_facts *f) {
    json_object_object_add(summary, "grid", grid_json(o));
    json_object_object_add(summary, "interface_dofs", json_object_new_int(setup->split.n_int));
    json_object_object_add(summary, "points", json_object_new_int(chart->nt * chart->np));
    json_object_object_add(summary, "stable_points", json_object_new_int(f->stable_points));
    json_object_object_add(summary, "boundary_points", json_object_new_int(chart->n_boundary));
    json_object_object_add(summary, "boundary_max_scaled_residual",
                           json_object_new_double(chart->b_max_residual));
    json_object *xc = json_object_new_object();
    json_object_object_add(xc, "label_changes", json_object_new_int(chart->label_changes));
    json_object_object_add(xc, "label_changes_without_boundary",
                           json_object_new_int(chart->label_changes_unexplained));
    json_object_object_add(xc, "boundary_points_inside_stable_region",
                           json_object_new_int(chart->boundary_unexplained));
    json_object_object_add(summary, "labels_vs_boundaries", xc);
    json_object_object_add(
        summary, "essential_spectrum",
        essential_json(f->essential_statement, f->p_essential, setup->split.mass_ratio, pr));
    json_object_object_add(summary, "critical_delays", critical_json(pr));
    json_object_object_add(summary, "compute_seconds", json_object_new_double(f->seconds));
}

int rths_api_chart_compute(const rths_setup *setup, const rths_chart_options *options,
                           const char *config_path, const char *const *overrides, int n_overrides,
                           rths_result **out, rths_chart *keep, rths_api_chart_facts *facts,
                           rths_error *err) {
    *out = NULL;
    if (rths_setup_require_dense(setup, "rths chart", err)) return RTHS_EINPUT;
    rths_chart_options o = *options;
    rths_chart chart;
    int have_chart = 0;
    rths_result *r = NULL;
    double *cint = NULL, *kint = NULL;
    rths_api_chart_facts f = {0};
    /* the configured split's interface damping/stiffness shares hold for every p */
    rths_split_family fam;
    int rc = rths_split_family_of(&setup->assembly, setup->roles, &setup->split, &fam, &cint, &kint,
                                  err);
    double t0 = rths_monotonic_s();
    if (!rc) {
        rc = rths_chart_compute(rths_split_family_build, &fam, &o, &chart, err);
        have_chart = !rc;
    }
    f.seconds = rths_monotonic_s() - t0;
    /* critical delays at a few p of interest and at the configured one, the chains at it */
    probes pr = {{setup->split.mass_ratio, 0.6, 0.67, 0.8}, {0}, {0}, 0, {0}, 0};
    if (!rc) rc = probe_chart(&fam, &o, setup->assembly.n, &pr, err);
    if (!rc) {
        f.p_essential = rths_chart_essential_limit(&chart);
        for (int k = 0; k < chart.nt * chart.np; k++)
            f.stable_points += chart.stable[k];
        essential_statement(&chart, f.p_essential, &o, f.essential_statement,
                            sizeof f.essential_statement);
        for (int k = 0; k < 4; k++) {
            f.probe_p[k] = pr.p[k];
            f.probe_critical_delay_s[k] = pr.tau_s[k];
            f.probe_crossing_omega_rad_s[k] = pr.omega_rad_s[k];
        }
    }
    if (!rc) rc = rths_result_new(&r, err);
    if (!rc) rc = chart_tables(r, &chart, err);
    if (!rc) {
        json_object *summary = rths_api_summary_new("chart", config_path, overrides, n_overrides);
        if (summary) chart_summary_add(summary, &o, &chart, setup, &pr, &f);
        rc = rths_result_set_summary(r, summary, err);
    }
    if (have_chart) {
        if (!rc && keep)
            *keep = chart;
        else
            rths_chart_free(&chart);
    }
    free(cint);
    free(kint);
    if (facts) *facts = f;
    if (rc) {
        rths_result_free(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}

/* The boundary curves for the figure (boundary_curves.dat): blank lines between curves, and
 * between points of one curve that are far apart in (tau, p) (the chain is built in
 * (tau, p, omega)). */
static int boundary_curves(rths_result *res, const rths_chart *c, rths_error *err) {
    char *text = NULL;
    size_t len = 0;
    FILE *fp = open_memstream(&text, &len);
    int rc = fp ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        double dt = (c->tau[c->nt - 1] - c->tau[0]) / 40.0;
        double dp = c->np > 1 ? (c->p[c->np - 1] - c->p[0]) / 40.0 : 1.0;
        fprintf(fp, "# tau_s,p,omega_rad_s (boundary points of chart.csv; blank line = new "
                    "curve)\n");
        for (int b = 0; b < c->n_boundary; b++) {
            if (b > 0 &&
                (c->b_curve[b] != c->b_curve[b - 1] || fabs(c->b_tau[b] - c->b_tau[b - 1]) > dt ||
                 fabs(c->b_p[b] - c->b_p[b - 1]) > dp))
                fprintf(fp, "\n");
            fprintf(fp, "%.17g,%.17g,%.17g\n", c->b_tau[b], c->b_p[b], c->b_omega[b]);
        }
        if (fclose(fp) || !text) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        if (!rc) rc = rths_result_add_file(res, "boundary_curves.dat", text, err);
    }
    free(text);
    return rc;
}

static int plot(rths_result *res, const rths_chart *c, double p_ess, const rths_split *sp,
                rths_error *err) {
    char ifaces[128] = "";
    for (int i = 0; i < sp->n_int && strlen(ifaces) < 100; i++)
        snprintf(ifaces + strlen(ifaces), sizeof ifaces - strlen(ifaces), "%s%d", i ? ", " : "",
                 sp->int_dofs[i] + 1);
    char ess_line[512] = "";
    if (isfinite(p_ess))
        snprintf(ess_line, sizeof ess_line,
                 ", \\\n  %.17g with lines lw 3 dt 2 lc rgb '#e6b800' title "
                 "'essential spectrum: p = %.4f'",
                 p_ess, p_ess);
    double dtau = (c->tau[c->nt - 1] - c->tau[0]) / (c->nt - 1);
    double dp = c->np > 1 ? (c->p[c->np - 1] - c->p[0]) / (c->np - 1) : 0.01;
    /* the figures' convention (report.h): the delay in a unit that fits its magnitude, the
     * legend right of the plot, clear of the axis labels */
    char unit[24];
    double scale =
        rths_plot_unit(fmax(fabs(c->tau[0]), fabs(c->tau[c->nt - 1])), "s", unit, sizeof unit);
    char body[4096];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set title 'Delayed-feedback hybrid test of the %d-DoF structure, interface DoF %s: "
             "stability chart'\n"
             "set xlabel 'Feedback delay {/Symbol t} (%s)'\n"
             "set ylabel 'Mass ratio p (numerical share of the interface mass)'\n"
             "set xrange [%.17g:%.17g]\n"
             "set yrange [%.17g:%.17g]\n"
             "set lmargin at screen 0.08\nset rmargin at screen 0.70\n"
             "set key at screen 0.72, graph 1 left top Left reverse samplen 2 spacing 1.2\n"
             "set palette defined (0 '#ffffff', 1 '#9be39b')\n"
             "set cbrange [0:1]\n"
             "unset colorbox\n"
             "set grid front\n"
             "plot 'chart.csv' skip 1 using ($1 * %g):2:4 with image notitle, \\\n"
             "  1/0 with boxes fs solid lc rgb '#9be39b' title 'stable', \\\n"
             "  1/0 with boxes fs solid border lc rgb '#bbbbbb' fc rgb '#ffffff' title 'unstable', "
             "\\\n"
             "  'boundary_curves.dat' using ($1 * %g):2 with linespoints "
             "lw 2 pt 7 ps 0.25 lc rgb '#d62728' title 'boundary D(i{/Symbol w}) = 0 (MDBM)', "
             "\\\n"
             "  'critical.csv' skip 1 using ($2 > 0 ? $2 * %g : 1/0):1 with lines lw 1.5 dt 3 lc "
             "rgb '#000000' title 'critical delay'%s\n",
             sp->n, ifaces, unit, scale * (c->tau[0] - 0.5 * dtau),
             scale * (c->tau[c->nt - 1] + 0.5 * dtau), c->p[0] - 0.5 * dp,
             c->p[c->np - 1] + 0.5 * dp, scale, scale, scale, ess_line);
    return rths_result_add_figure(res, "chart", 1300, 800, body, err);
}

int rths_api_chart_run(rths_api_command_config *cc, int progress, rths_result **out,
                       rths_error *err) {
    static const char *const own_sections[] = {"stability", NULL};
    *out = NULL;
    if (!cc || !cc->has_setup)
        return rths_error_set(err, RTHS_EINPUT, "rths_api_chart_run needs the setup read");
    rths_config *cfg = cc->config;
    const rths_setup *setup = &cc->setup;
    rths_chart_options o;
    rths_chart chart;
    rths_api_chart_facts f;
    rths_result *res = NULL;
    int rc;
    if ((rc = rths_chart_config_read(cfg, &o, err)) ||
        (rc = rths_api_check_config(cfg, own_sections, err)))
        return rc;
    o.progress = progress;
    if ((rc = rths_api_chart_compute(setup, &o, cc->path, (const char *const *)cc->overrides,
                                     cc->n_overrides, &res, &chart, &f, err)))
        return rc;
    rths_result_printf(res,
                       "Stability chart: %d x %d (tau %g..%g s, p %g..%g), %d stable, %d "
                       "boundary points, %.2f s\n",
                       chart.nt, chart.np, o.tau_min_s, o.tau_max_s, o.p_min, o.p_max,
                       f.stable_points, chart.n_boundary, f.seconds);
    rths_result_printf(res, "Essential spectrum: %s\n", f.essential_statement);
    rths_result_printf(res, "%-10s %18s %22s\n", "p", "critical_delay_s", "crossing_omega_rad_s");
    for (int k = 0; k < 4; k++)
        rths_result_printf(res, "%-10.4g %18.6e %22.4f%s\n", f.probe_p[k],
                           f.probe_critical_delay_s[k], f.probe_crossing_omega_rad_s[k],
                           k == 0 ? "   (configured split)" : "");
    rths_result_printf(res,
                       "Labels vs boundaries: %d label changes, %d without a boundary, %d "
                       "boundary points inside the stable region\n",
                       chart.label_changes, chart.label_changes_unexplained,
                       chart.boundary_unexplained);
    rths_result_log(res, "chart %dx%d in %.3f s, %d stable, %d boundary points", chart.nt, chart.np,
                    f.seconds, f.stable_points, chart.n_boundary);
    rc = boundary_curves(res, &chart, err);
    if (!rc) rc = plot(res, &chart, f.p_essential, &setup->split, err);
    rths_chart_free(&chart);
    if (rc) {
        rths_result_free(res);
        return rc;
    }
    *out = res;
    return RTHS_OK;
}

int rths_api_chart(const rths_api_config *cfg, const char *out_dir, rths_result **out,
                   rths_error *err) {
    *out = NULL;
    if (!cfg) return rths_error_set(err, RTHS_EINPUT, "no configuration given");
    static const char *const own[] = {"stability", NULL};
    rths_config *c;
    rths_setup setup;
    rths_chart_options o;
    rths_result *r = NULL;
    int rc = rths_api_load(cfg, &c, &setup, err);
    if (rc) return rc;
    if (!(rc = rths_chart_config_read(c, &o, err))) rc = rths_api_check_config(c, own, err);
    o.progress = 0;
    if (!rc)
        rc = rths_api_chart_compute(&setup, &o, cfg->path, (const char *const *)cfg->overrides,
                                    cfg->n_overrides, &r, NULL, NULL, err);
    rc = rths_api_finish(r, rc, c, out_dir, "chart", out, err);
    rths_api_unload(c, &setup);
    return rc;
}
