/* rths chart: stability chart of the conventional delayed-feedback hybrid test over (tau, p)
 * (docs/method.md, "Delayed-feedback stability"; seed Fig. 4) for the configured structure and
 * split. */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"
#include "rths/stability.h"

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

/* The boundary curves for the figure (boundary_curves.dat): blank lines between curves, and
 * between points of one curve that are far apart in (tau, p) (the chain is built in
 * (tau, p, omega)). */
static int write_boundary_curves(rths_report *rep, const rths_chart *c, rths_error *err) {
    char *path = rths_report_path(rep, "boundary_curves.dat");
    rths_atomic_file *af = NULL;
    FILE *fp = NULL;
    int rc = path ? rths_atomic_open(path, &af, &fp, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
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
        rc = rths_atomic_commit(af, err);
    }
    free(path);
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
    return rths_plot(rep, rths_report_dir(rep), "chart", 1300, 800, body, err);
}

/* The chart, its tables and summary are computed by the library (rths_api_chart_compute, the same
 * code as rths_api_chart) and written by its writer (rths_api_result_write); the command reads the
 * configuration, prints, draws the figure and keeps run.log. */
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
    rths_result *result = NULL;
    rths_api_chart_facts f;
    rths_chart_options o;
    if ((rc = rths_cli_load(&cli, &cfg, &setup, &err))) return rths_cli_fail(&cli, rc, &err);
    if ((rc = rths_chart_config_read(cfg, &o, &err)) ||
        (rc = rths_cli_check_config_own(cfg, own_sections, &err)))
        goto done;
    o.progress = rths_progress_enabled(cli.quiet);
    if ((rc = rths_api_chart_compute(&setup, &o, cli.config_path, cli.sets, cli.n_sets, &result,
                                     &chart, &f, &err)))
        goto done;
    if ((rc = rths_cli_open_report(&cli, cfg, argc, argv, &rep, &err))) goto done;
    if (!(rc = rths_api_result_write_tables(result, rep, &err)) &&
        !(rc = write_boundary_curves(rep, &chart, &err)))
        rc = rths_api_result_write_summary(result, rep, &err);
    if (rc) goto done;
    rths_cli_print(&cli,
                   "Stability chart: %d x %d (tau %g..%g s, p %g..%g), %d stable, %d "
                   "boundary points, %.2f s\n",
                   chart.nt, chart.np, o.tau_min_s, o.tau_max_s, o.p_min, o.p_max, f.stable_points,
                   chart.n_boundary, f.seconds);
    rths_cli_print(&cli, "Essential spectrum: %s\n", f.essential_statement);
    rths_cli_print(&cli, "%-10s %18s %22s\n", "p", "critical_delay_s", "crossing_omega_rad_s");
    for (int k = 0; k < 4; k++)
        rths_cli_print(&cli, "%-10.4g %18.6e %22.4f%s\n", f.probe_p[k], f.probe_critical_delay_s[k],
                       f.probe_crossing_omega_rad_s[k], k == 0 ? "   (configured split)" : "");
    rths_cli_print(&cli,
                   "Labels vs boundaries: %d label changes, %d without a boundary, %d "
                   "boundary points inside the stable region\n",
                   chart.label_changes, chart.label_changes_unexplained,
                   chart.boundary_unexplained);
    rths_report_log(rep, "chart %dx%d in %.3f s, %d stable, %d boundary points", chart.nt, chart.np,
                    f.seconds, f.stable_points, chart.n_boundary);
    rc = plot(rep, &chart, f.p_essential, &setup.split, &err);
    /* results.mat is part of the outputs: one that cannot be written fails the command (exit 1,
     * one line; the other files stay), rather than a warning at close */
    if (!rc) rc = rths_report_write_mat(rep, &err);
done:
    if (result) rths_chart_free(&chart);
    rths_result_free(result);
    if (rep) rths_report_close(rep);
    rths_cli_unload(cfg, &setup);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    return RTHS_OK;
}
