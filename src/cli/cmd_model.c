/* rths model CONFIG --out DIR: modes and analytic FRF of the true assembly, the ground truth every
 * hybrid result is judged against. */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

#include <stdio.h>

static const char usage[] =
    "Usage: rths model CONFIG --out DIR [--set key=value]... [--quiet]\n"
    "\n"
    "Modal analysis and analytic frequency response of the true assembly described by CONFIG\n"
    "(structure, split, forcing sections; see docs/config.md).\n"
    "\n"
    "Prints the modes and writes into DIR:\n"
    "  modes.csv      mode, frequency_hz, omega_rad_s, damping_ratio, phi<i> (mass-normalised)\n"
    "  true_frf.csv   frequency_hz, x<i>_amplitude_m, x<i>_phase_rad, response to the configured\n"
    "                 force; range model.frf.{start_hz,end_hz,points}, by default up to 1.25 x\n"
    "                 the highest mode with every peak resolved\n"
    "                 (DoFs i: all of them up to 64 DoFs; above, the physical substructure's\n"
    "                 and the forcing DoF, in both files)\n"
    "  true_frf.gp/.png/.svg   the FRF figure\n"
    "  summary.json, config.yaml (as resolved), run.log (with the time of each stage)\n"
    "\n"
    "Options:\n"
    "  --out DIR          output folder (created)\n"
    "  --set key=value    override a configuration key (repeatable), e.g. split.mass_ratio=0.33\n"
    "  --quiet            print nothing but errors\n"
    "  --help             this text\n"
    "\n"
    "Exit status: 0 success, 1 failure, 2 bad usage or configuration (nothing written).\n";

/* The path's choice, the modes, the analytic FRF, the printed report, run.log's lines and the
 * figure are the library's (rths_api_model_run over rths_api_model_compute, the code behind
 * rths_api_model); the command parses, prints and writes them through rths_api_result_write. */
int rths_cmd_model(int argc, char **argv) {
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT, usage, NULL, 0);
    if (rc || cli.help) return rc;
    rths_error err = {0};
    rths_api_command_config *cfg = NULL;
    rths_api_run_folder *folder = NULL;
    rths_result *result = NULL;
    /* the setup is not read here: the library chooses the solver path first */
    rc = rths_cli_load(&cli, 0, &cfg, &err);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    rc = rths_api_model_run(cfg, cli.out_dir, &result, &err);
    if (!rc) rc = rths_cli_open_folder(&cli, cfg, argc, argv, &folder, &err);
    if (!rc) rths_cli_print(&cli, "%s", rths_result_text(result));
    if (!rc) rc = rths_api_result_write(result, folder, &err);
    /* results.mat is part of the outputs: one that cannot be written fails the command (exit 1,
     * one line; the other files stay), rather than a warning at close */
    if (!rc) rc = rths_api_run_folder_write_mat(folder, &err);
    if (folder)
        rths_api_run_folder_log(folder, "finished with status %d%s%s", rc, rc ? ": " : "",
                                rc ? err.msg : "");
    if (rc) rths_cli_fail(&cli, rc, &err);
    rths_result_free(result);
    rths_api_command_config_free(cfg);
    rths_api_run_folder_close(folder);
    return rc;
}
