/* rths fidelity: the hybrid test's steady-state FRF at a perfect interface match for every
 * integration scheme of the numerical substructure, against the true assembly (docs/method.md,
 * "Numerical substructure integration"). The tables, summary, printed report and figure come
 * from the library (rths_api_fidelity_run, the code behind rths_api_fidelity); the command
 * parses, prints and writes the folder. */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

#include <stdio.h>

static const char usage[] =
    "Usage: rths fidelity CONFIG --out DIR [--set KEY=VALUE]... [--quiet]\n"
    "\n"
    "What the numerical substructure's integration scheme does to the result "
    "of a hybrid test\n"
    "(docs/method.md, \"Numerical substructure integration\"). For each scheme (implicit_euler, "
    "trapezoidal, exact_zoh, "
    "exact_foh) the converged\n"
    "hybrid test is computed in the frequency domain: the physical "
    "substructure in continuous "
    "time,\n"
    "the numerical substructure discretised at the controller's sample step "
    "and driven by the\n"
    "sampled interface force, the interface displacements matched. Its "
    "interface amplitude is\n"
    "compared with the true assembly's analytic FRF.\n"
    "\n"
    "Configuration keys (docs/config/fidelity.md): fidelity.start_hz, "
    "fidelity.end_hz (default\n"
    "+-10 % around the second natural frequency), fidelity.points (default "
    "1001);\n"
    "controller.sample_rate_hz (default 10000).\n"
    "\n"
    "Writes DIR/fidelity.csv (frequency_hz, true_amplitude_m, "
    "<scheme>_amplitude_m), "
    "summary.json,\n"
    "config.yaml, fidelity.gp/.png/.svg, run.log. Prints each scheme's peak "
    "and its error.\n"
    "\n"
    "On a sparse model (model.solver, docs/config/fidelity.md) the real-time Krylov reduction's\n"
    "interface FRF error over its band instead: fidelity.csv has the reduced and exact receptance\n"
    "and forced response and their relative errors, at fidelity.points (default 2 x\n"
    "controller.reduction.check_points - 1) over fidelity.start_hz..end_hz (default the band).\n"
    "\n"
    "Options:\n"
    "  --out DIR          output folder (created)\n"
    "  --set KEY=VALUE    override a configuration key (repeatable)\n"
    "  --quiet            print nothing on success\n"
    "  --help             this text\n"
    "\n"
    "Exit status: 0 success, 1 failure, 2 bad usage or input (nothing "
    "written).\n";

int rths_cmd_fidelity(int argc, char **argv) {
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
    if (!(rc = rths_api_fidelity_run(cfg, &result, &err)))
        rc = rths_cli_open_folder(&cli, cfg, argc, argv, &folder, &err);
    if (!rc) rths_cli_print(&cli, "%s", rths_result_text(result));
    if (!rc) rc = rths_api_result_write(result, folder, &err);
    /* results.mat is part of the outputs: one that cannot be written fails the command (exit 1,
     * one line; the other files stay), rather than a warning at close */
    if (!rc) rc = rths_api_run_folder_write_mat(folder, &err);
    rths_result_free(result);
    rths_api_run_folder_close(folder);
    rths_api_command_config_free(cfg);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    return RTHS_OK;
}
