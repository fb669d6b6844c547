/* rths chart: stability chart of the conventional delayed-feedback hybrid test over (tau, p)
 * (docs/method.md, "Delayed-feedback stability"; seed Fig. 4) for the configured structure and
 * split. */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/stability.h"

#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
    "Usage: rths chart CONFIG --out DIR [--set KEY=VALUE]... [--quiet]\n"
    "\n"
    "Substructurability of the conventional real-time hybrid test, in which the physical\n"
    "interface follows the numerical one through an actuator with a pure delay tau. For every\n"
    "(tau, p) on a grid (p = numerical share of the interface mass, docs/method.md erratum 1) the "
    "neutral\n"
    "delay equation of the configured split is labelled stable or unstable from its rightmost\n"
    "characteristic roots (Chebyshev collocation, then root tracking in tau) and its essential\n"
    "spectrum (the neutral root chains, from det(M_0 + z M_tau) = 0); the boundaries\n"
    "D(i omega) = 0 are traced by multi-dimensional bisection over (tau, p, omega); the critical\n"
    "delay (smallest delay that loses stability) is located for every p.\n"
    "\n"
    "Configuration keys (docs/config/stability.md): stability.tau_min_s, tau_max_s, tau_points,\n"
    "p_min, p_max, p_points, omega_min_rad_s, omega_max_rad_s, omega_points, mdbm_tau_points,\n"
    "mdbm_p_points, mdbm_refine, chebyshev_nodes. Defaults are the seed's ranges (tau 5e-5..3e-4 "
    "s,\n"
    "p 0.01..0.99, omega up to 550 rad/s) on a 200 x 200 grid.\n"
    "\n"
    "Writes DIR/chart.csv (tau_s, p, max_real_part_per_s, stable), boundary.csv (tau_s, p,\n"
    "omega_rad_s, ordered along connected curves), critical.csv (p, critical_delay_s,\n"
    "crossing_omega_rad_s; 0 = unstable for every delay, nan = no loss of stability found up\n"
    "to 10 x tau_max), summary.json (with the essential-spectrum statement), config.yaml,\n"
    "chart.gp/.png/.svg, run.log.\n"
    "\n"
    "Options:\n"
    "  --out DIR          output folder (created)\n"
    "  --set KEY=VALUE    override a configuration key (repeatable)\n"
    "  --quiet            print nothing on success (no progress line either)\n"
    "  --help             this text\n"
    "\n"
    "Exit status: 0 success, 1 failure, 2 bad usage or input (nothing written).\n";

static int write_csvs(rths_report *rep, const rths_chart *c, rths_error *err) {
    static const char *const h_chart[] = {"tau_s", "p", "max_real_part_per_s", "stable"};
    static const char *const h_bound[] = {"tau_s", "p", "omega_rad_s"};
    static const char *const h_crit[] = {"p", "critical_delay_s", "crossing_omega_rad_s"};
    const char *names[3] = {"chart.csv", "boundary.csv", "critical.csv"};
    const char *const *heads[3] = {h_chart, h_bound, h_crit};
    const int ncol[3] = {4, 3, 3};
    int rc = RTHS_OK;
    for (int f = 0; f < 3 && !rc; f++) {
        char *path = rths_report_path(rep, names[f]);
        rths_csv *csv = NULL;
        rc = path ? rths_csv_open(path, ncol[f], heads[f], &csv, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
        int bad = 0;
        if (!rc && f == 0) {
            /* p outer, tau inner: gnuplot's image plot wants one scan per p */
            for (int j = 0; j < c->np && !bad; j++)
                for (int i = 0; i < c->nt && !bad; i++) {
                    size_t k = (size_t)i + (size_t)j * (size_t)c->nt;
                    double row[4] = {c->tau[i], c->p[j], c->max_real[k], c->stable[k]};
                    bad = rths_csv_row(csv, row);
                }
        } else if (!rc && f == 1) {
            for (int b = 0; b < c->n_boundary && !bad; b++) {
                double row[3] = {c->b_tau[b], c->b_p[b], c->b_omega[b]};
                bad = rths_csv_row(csv, row);
            }
        } else if (!rc) {
            for (int j = 0; j < c->np && !bad; j++) {
                double row[3] = {c->p[j], c->critical_tau[j], c->critical_omega[j]};
                bad = rths_csv_row(csv, row);
            }
        }
        if (!rc && bad) rc = rths_error_set(err, RTHS_EFAIL, "writing %s failed", path);
        if (csv) {
            if (rc)
                rths_csv_abort(csv);
            else
                rc = rths_csv_close(csv, err);
        }
        free(path);
    }
    /* the boundary curves for the figure: blank lines between curves, and between points of one
     * curve that are far apart in (tau, p) (the chain is built in (tau, p, omega)) */
    if (!rc) {
        char *path = rths_report_path(rep, "boundary_curves.dat");
        rths_atomic_file *af = NULL;
        FILE *fp = NULL;
        rc = path ? rths_atomic_open(path, &af, &fp, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
        if (!rc) {
            double dt = (c->tau[c->nt - 1] - c->tau[0]) / 40.0;
            double dp = c->np > 1 ? (c->p[c->np - 1] - c->p[0]) / 40.0 : 1.0;
            fprintf(fp, "# tau_s,p,omega_rad_s (boundary points of chart.csv; blank line = new "
                        "curve)\n");
            for (int b = 0; b < c->n_boundary; b++) {
                if (b > 0 && (c->b_curve[b] != c->b_curve[b - 1] ||
                              fabs(c->b_tau[b] - c->b_tau[b - 1]) > dt ||
                              fabs(c->b_p[b] - c->b_p[b - 1]) > dp))
                    fprintf(fp, "\n");
                fprintf(fp, "%.17g,%.17g,%.17g\n", c->b_tau[b], c->b_p[b], c->b_omega[b]);
            }
            rc = rths_atomic_commit(af, err);
        }
        free(path);
    }
    return rc;
}

static int plot(rths_report *rep, const rths_chart *c, double p_ess, const rths_split *sp,
                rths_error *err) {
    char ifaces[128] = "";
    for (int i = 0; i < sp->n_int && strlen(ifaces) < 100; i++)
        snprintf(ifaces + strlen(ifaces), sizeof ifaces - strlen(ifaces), "%s%d", i ? ", " : "",
                 sp->int_dofs[i] + 1);
    char ess_line[512] = "";
    if (isfinite(p_ess))
        snprintf(ess_line, sizeof ess_line,
                 ", \\\n  %.17g with lines lw 3 dt 2 lc rgb '#e6b800' title "
                 "'essential-spectrum limit p = %.4f'",
                 p_ess, p_ess);
    double dtau = (c->tau[c->nt - 1] - c->tau[0]) / (c->nt - 1);
    double dp = c->np > 1 ? (c->p[c->np - 1] - c->p[0]) / (c->np - 1) : 0.01;
    char body[4096];
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set title 'Delayed-feedback hybrid test of the %d-DoF structure, interface DoF %s: "
             "stability chart (green: stable)'\n"
             "set xlabel 'feedback delay {/Symbol t} (s)'\n"
             "set ylabel 'mass ratio p = numerical share of the interface mass'\n"
             "set format x '%%.1e'\n"
             "set xrange [%.17g:%.17g]\n"
             "set yrange [%.17g:%.17g]\n"
             "set key outside bottom center horizontal\n"
             "set palette defined (0 '#ffffff', 1 '#9be39b')\n"
             "set cbrange [0:1]\n"
             "unset colorbox\n"
             "set grid front\n"
             "plot 'chart.csv' skip 1 using 1:2:4 with image notitle, \\\n"
             "  1/0 with boxes fs solid lc rgb '#9be39b' title 'stable', \\\n"
             "  'boundary_curves.dat' using 1:2 with linespoints "
             "lw 2 pt 7 ps 0.25 lc rgb '#d62728' title 'boundary D(i{/Symbol w}) = 0 (MDBM)', "
             "\\\n"
             "  'critical.csv' skip 1 using ($2 > 0 ? $2 : 1/0):1 with lines lw 1.5 dt 3 lc rgb "
             "'#000000' title "
             "'critical delay'%s\n",
             sp->n, ifaces, c->tau[0] - 0.5 * dtau, c->tau[c->nt - 1] + 0.5 * dtau,
             c->p[0] - 0.5 * dp, c->p[c->np - 1] + 0.5 * dp, ess_line);
    return rths_plot(rep, rths_report_dir(rep), "chart", 1000, 800, body, err);
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

int rths_cmd_chart(int argc, char **argv) {
    static const char *const own_sections[] = {"stability", NULL};
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT, usage, NULL, 0);
    if (rc || cli.help) return rc;
    rths_error err;
    rths_error_clear(&err);
    rths_config *cfg = NULL;
    rths_setup setup;
    rths_report *rep = NULL;
    rths_chart chart;
    int have_chart = 0;
    json_object *summary = NULL;
    double *cint = NULL, *kint = NULL;
    rths_chart_options o;
    if ((rc = rths_cli_load(&cli, &cfg, &setup, &err))) return rths_cli_fail(&cli, rc, &err);
    if ((rc = rths_chart_config_read(cfg, &o, &err)) ||
        (rc = rths_cli_check_config_own(cfg, own_sections, &err)))
        goto done;
    /* the configured split's interface damping/stiffness shares hold for every p */
    int ni = setup.split.n_int;
    rths_split_family fam;
    if ((rc = rths_split_family_of(&setup.assembly, setup.roles, &setup.split, &fam, &cint, &kint,
                                   &err)))
        goto done;
    o.progress = rths_progress_enabled(cli.quiet);
    double t0 = rths_monotonic_s();
    if ((rc = rths_chart_compute(rths_split_family_build, &fam, &o, &chart, &err))) goto done;
    have_chart = 1;
    double seconds = rths_monotonic_s() - t0;
    double p_ess = rths_chart_essential_limit(&chart);

    /* critical delays at a few p of interest and at the configured one, the chains at it */
    probes pr = {{setup.split.mass_ratio, 0.6, 0.67, 0.8}, {0}, {0}, 0, {0}, 0};
    if ((rc = probe_chart(&fam, &o, setup.assembly.n, &pr, &err))) goto done;

    if ((rc = rths_cli_open_report(&cli, cfg, argc, argv, &rep, &err))) goto done;
    if ((rc = write_csvs(rep, &chart, &err))) goto done;
    int n_stable = 0;
    for (int k = 0; k < chart.nt * chart.np; k++)
        n_stable += chart.stable[k];

    char stmt[512];
    essential_statement(&chart, p_ess, &o, stmt, sizeof stmt);
    summary = rths_cli_summary_new(&cli);
    json_object_object_add(summary, "grid", grid_json(&o));
    json_object_object_add(summary, "interface_dofs", json_object_new_int(ni));
    json_object_object_add(summary, "points", json_object_new_int(chart.nt * chart.np));
    json_object_object_add(summary, "stable_points", json_object_new_int(n_stable));
    json_object_object_add(summary, "boundary_points", json_object_new_int(chart.n_boundary));
    json_object_object_add(summary, "boundary_max_scaled_residual",
                           json_object_new_double(chart.b_max_residual));
    json_object *xc = json_object_new_object();
    json_object_object_add(xc, "label_changes", json_object_new_int(chart.label_changes));
    json_object_object_add(xc, "label_changes_without_boundary",
                           json_object_new_int(chart.label_changes_unexplained));
    json_object_object_add(xc, "boundary_points_inside_stable_region",
                           json_object_new_int(chart.boundary_unexplained));
    json_object_object_add(summary, "labels_vs_boundaries", xc);
    json_object_object_add(summary, "essential_spectrum",
                           essential_json(stmt, p_ess, setup.split.mass_ratio, &pr));
    json_object_object_add(summary, "critical_delays", critical_json(&pr));
    json_object_object_add(summary, "compute_seconds", json_object_new_double(seconds));
    if ((rc = rths_cli_write_summary(rep, "summary.json", summary, &err))) goto done;

    rths_cli_print(&cli,
                   "Stability chart: %d x %d (tau %g..%g s, p %g..%g), %d stable, %d "
                   "boundary points, %.2f s\n",
                   chart.nt, chart.np, o.tau_min_s, o.tau_max_s, o.p_min, o.p_max, n_stable,
                   chart.n_boundary, seconds);
    rths_cli_print(&cli, "Essential spectrum: %s\n", stmt);
    rths_cli_print(&cli, "%-10s %18s %22s\n", "p", "critical_delay_s", "crossing_omega_rad_s");
    for (int k = 0; k < 4; k++)
        rths_cli_print(&cli, "%-10.4g %18.6e %22.4f%s\n", pr.p[k], pr.tau_s[k], pr.omega_rad_s[k],
                       k == 0 ? "   (configured split)" : "");
    rths_cli_print(&cli,
                   "Labels vs boundaries: %d label changes, %d without a boundary, %d "
                   "boundary points inside the stable region\n",
                   chart.label_changes, chart.label_changes_unexplained,
                   chart.boundary_unexplained);
    rths_report_log(rep, "chart %dx%d in %.3f s, %d stable, %d boundary points", chart.nt, chart.np,
                    seconds, n_stable, chart.n_boundary);
    rc = plot(rep, &chart, p_ess, &setup.split, &err);
    /* results.mat is part of the outputs: one that cannot be written fails the command (exit 1,
     * one line; the other files stay), rather than a warning at close */
    if (!rc) rc = rths_report_write_mat(rep, &err);
done:
    if (summary) json_object_put(summary);
    if (have_chart) rths_chart_free(&chart);
    free(cint);
    free(kint);
    if (rep) rths_report_close(rep);
    rths_cli_unload(cfg, &setup);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    return RTHS_OK;
}
