/* rths chart: stability chart of the conventional delayed-feedback hybrid test over (tau, p)
 * (docs/method.md, "Delayed-feedback stability"; seed Fig. 4) for the configured structure and
 * split. */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

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

/* The chart, its tables, summary, printed report and figure are the library's
 * (rths_api_chart_run over rths_api_chart_compute, the code behind rths_api_chart); the command
 * parses, prints and writes them through rths_api_result_write. */
int rths_cmd_chart(int argc, char **argv) {
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT, usage, NULL, 0);
    if (rc || cli.help) return rc;
    rths_error err;
    rths_error_clear(&err);
    rths_api_command_config *cfg = NULL;
    rths_api_run_folder *folder = NULL;
    rths_result *result = NULL;
    if ((rc = rths_cli_load(&cli, RTHS_API_READ_SETUP, &cfg, &err)))
        return rths_cli_fail(&cli, rc, &err);
    if (!(rc = rths_api_chart_run(cfg, rths_api_progress_enabled(cli.quiet), &result, &err)))
        rc = rths_cli_open_folder(&cli, cfg, argc, argv, &folder, &err);
    if (!rc) rc = rths_api_result_write(result, folder, &err);
    if (!rc) rths_cli_print(&cli, "%s", rths_result_text(result));
    /* results.mat is part of the outputs: one that cannot be written fails the command (exit 1,
     * one line; the other files stay), rather than a warning at close */
    if (!rc) rc = rths_api_run_folder_write_mat(folder, &err);
    rths_result_free(result);
    rths_api_run_folder_close(folder);
    rths_api_command_config_free(cfg);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    return RTHS_OK;
}
