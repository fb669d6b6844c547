/* rths tune: PD and grounding gains from the model, checked stable with a stated margin against
 * the sampled loop, the actuator and the delay (docs/method.md, "Tuning the gains"). */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

static const char usage[] =
    "Usage: rths tune CONFIG [--out DIR] [--delay S] [--set KEY=VALUE]... [--quiet]\n"
    "\n"
    "Gains for the controller from the model (docs/method.md, \"Tuning the gains\"):\n"
    "  - the physical PD (controller.kp_v_per_m, kd_v_s_per_m): the physical substructure on the\n"
    "    configured rig (interface mass, actuator, lag, delay, hold), sampled exactly at the\n"
    "    controller's rate and closed by its discrete PD; the pair with the widest bandwidth "
    "whose\n"
    "    closed loop is stable (spectral radius < 1) with a gain margin >= 6 dB and a phase\n"
    "    margin >= 45 deg;\n"
    "  - the grounding (controller.grounding_kp_n_per_m, grounding_kd_n_s_per_m): a critically\n"
    "    damped tie on the numerical interface mass: the softest whose slowest transient decays "
    "at\n"
    "    90 per cent of the fastest rate found, stable at twice the gains (acting one sample late, "
    "as\n"
    "    the controller does).\n"
    "The configured gains' margins are reported too. With several interface DoFs (actuator and\n"
    "sensor transforms included) a PD per DoF (kp_per_dof, kd_per_dof, grounding_*_per_dof):\n"
    "each loop's margins with it broken and the others closed, and the coupled loop (every DoF\n"
    "closed) stable at twice every gain; loop at a time from the configured gains, each pick\n"
    "the widest bandwidth whose coupled loop's slowest transient decays at 90 per cent of the\n"
    "fastest rate found.\n"
    "\n"
    "Prints the keys to paste as a YAML fragment on stdout (comments say the margins). With\n"
    "--out DIR also writes DIR/tuned.yaml (the fragment), summary.json, loop.csv (the configured\n"
    "and the tuned loop's gain, phase and sensitivity over frequency) and its figure loop.png,\n"
    ".svg, .gp, config.yaml, run.log.\n"
    "\n"
    "Options:\n"
    "  --out DIR          output folder (created)\n"
    "  --delay S          the physical loop's transport delay, s, in [0, 0.1], a fraction of a\n"
    "                     sample included (a lab's measured delay); default: the configured\n"
    "                     delay as the virtual rig holds it, rounded to whole samples\n"
    "  --set KEY=VALUE    override a configuration key (repeatable)\n"
    "  --quiet            print nothing on success\n"
    "  --help             this text\n"
    "\n"
    "Exit status: 0 gains found (even when the configured ones are unstable: that is reported),\n"
    "1 no gains meet the rule, 2 bad usage or input (nothing written).\n";

/* The gains, the table, the summary, the keys to paste and the figure come from the library
 * (rths_api_tune_run, the same code as rths_api_tune); the command prints the keys and writes
 * the folder. */
int rths_cmd_tune(int argc, char **argv) {
    rths_cli_opt opts[] = {{"--out", "DIR", NULL}, {"--delay", "S", NULL}};
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG, usage, opts, 2);
    if (rc || cli.help) return rc;
    cli.out_dir = opts[0].value;
    rths_error err = {0};
    double delay_s = -1;
    if (opts[1].value && (rc = rths_cli_double("--delay", opts[1].value, 0, 0.1, &delay_s, &err)))
        return rths_cli_fail(&cli, rc, &err);
    rths_api_command_config *cfg = NULL;
    rths_api_run_folder *folder = NULL;
    rths_result *result = NULL;
    rc = rths_cli_load(&cli, RTHS_API_READ_SETUP, &cfg, &err);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    rc = rths_api_tune_run(cfg, delay_s, &result, &err);
    if (!rc && cli.out_dir) rc = rths_cli_open_folder(&cli, cfg, argc, argv, &folder, &err);
    if (!rc) rths_cli_print(&cli, "%s", rths_result_text(result));
    if (!rc && folder) rc = rths_api_result_write(result, folder, &err);
    if (folder)
        rths_api_run_folder_log(folder, "finished with status %d%s%s", rc, rc ? ": " : "",
                                rc ? err.msg : "");
    if (rc) rths_cli_fail(&cli, rc, &err);
    rths_result_free(result);
    rths_api_command_config_free(cfg);
    rths_api_run_folder_close(folder);
    return rc;
}
