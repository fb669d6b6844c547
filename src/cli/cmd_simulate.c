/* rths simulate: one hybrid test on the virtual rig at a fixed target (iterative mode), or the
 * conventional real-time hybrid test with the feedback loop closed (feedback mode). The command
 * parses its options; the run, its tables, summary, printed report and figure are the library's
 * (rths_api_simulate_prepare / _run, the code behind rths_api_simulate). */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

#include <stdio.h>
#include <string.h>

static const char usage[] =
    "Usage: rths simulate CONFIG --frequency F --target A1,B1[,A2,B2,...][;...] "
    "--periods N --out DIR\n"
    "                     [--trace-periods K] [--seed S] [--rig tcp://HOST:PORT [--reset-fault]]\n"
    "                     [--pace F] [--set KEY=VALUE]... [--quiet]\n"
    "       rths simulate CONFIG --mode feedback [--delay TAU] --frequency F "
    "--periods N --out DIR\n"
    "                     [--seed S] [--set KEY=VALUE]... [--quiet]\n"
    "\n"
    "Iterative mode (default): runs the hybrid test on the virtual rig with "
    "the forcing at F Hz and\n"
    "the physical interface controlled to the fixed target\n"
    "  x*(t) = sum_k A_k cos(k w t) + B_k sin(k w t)   (metres, w = 2 pi F)\n"
    "for N whole forcing periods, then records a time trace over K more "
    "periods (default\n"
    "min(N, 5)). At the target that matches the interface, both sides move "
    "alike.\n"
    "\n"
    "Feedback mode: the conventional real-time hybrid test, where the physical "
    "interface follows\n"
    "the numerical interface displacement in real time. With --delay TAU: the "
    "seed's model of it,\n"
    "an ideal actuator with a pure delay of TAU seconds, simulated in "
    "continuous time (step much\n"
    "finer than TAU). Without --delay: through the virtual rig's shaker and PD "
    "controller.\n"
    "summary.json says whether it diverged (growth beyond bounds or a limit "
    "trip) and the growth\n"
    "rate of the response.\n"
    "\n"
    "Writes DIR/coefficients.csv (one row per period: Fourier coefficients of "
    "the physical and\n"
    "numerical interface displacements, m; with several interface DoFs the first DoF's, then\n"
    "dof<d>_phys_* and dof<d>_num_* for every interface DoF d, 1-based in ascending DoF\n"
    "number), trace.csv (the first interface DoF) (time_s, x_phys_m, "
    "x_num_m, target_m,\n"
    "force_n, demand), summary.json, config.yaml, simulate.gp/.png/.svg (time "
    "traces and the\n"
    "Lissajous plot of physical vs numerical interface displacement), "
    "run.log.\n"
    "\n"
    "Options:\n"
    "  --frequency F        forcing frequency, Hz (> 0)\n"
    "  --target LIST        target coefficients A1,B1[,A2,B2,...], m "
    "(iterative mode; an even\n"
    "                       count, at most 2 x 5 harmonics); with several interface DoFs one\n"
    "                       list per DoF in ascending DoF number, separated by ';' (the same\n"
    "                       harmonics in each), e.g. '1e-5,0;2e-5,0'\n"
    "  --periods N          forcing periods to run (>= 1)\n"
    "  --rig URI            tcp://HOST:PORT: run against a controller process (rths "
    "controller)\n"
    "                       instead of the in-process virtual rig (iterative mode)\n"
    "  --reset-fault        with --rig: reset the controller's latched fault (RESET_FAULT)\n"
    "                       first, logged in run.log; refused (exit 1, the controller's\n"
    "                       answer) while its cause persists\n"
    "  --pace F             run the virtual rig at F x real time (1: real time); results are\n"
    "                       the same (rig.pace; default unpaced)\n"
    "  --trace-periods K    periods in the recorded trace (iterative mode; "
    "default min(N, 5))\n"
    "  --mode MODE          iterative (default) or feedback\n"
    "  --delay TAU          feedback mode: pure actuator delay, s (> 0)\n"
    "  --seed S             noise generator seed (unsigned integer; default "
    "from rig.seed)\n"
    "  --out DIR            output folder (created)\n"
    "  --set KEY=VALUE      override a configuration key (repeatable)\n"
    "  --quiet              print nothing on success\n"
    "  --help               this text\n"
    "\n"
    "Exit status: 0 success (also when a feedback test diverged: that is a "
    "result), 1 failure,\n"
    "2 bad usage or input (nothing written).\n";

enum {
    OPT_FREQ,
    OPT_TARGET,
    OPT_PERIODS,
    OPT_TRACE,
    OPT_MODE,
    OPT_DELAY,
    OPT_RIG,
    OPT_PACE,
    OPT_RESET_FAULT,
    OPT_COUNT
};

typedef struct {
    int feedback;
    double frequency_hz;
    int harmonics;   /* target harmonics (iterative) */
    int target_dofs; /* interface DoFs the target names (';'-separated lists) */
    /* DoF d's coefficient k at [d * harmonics + k - 1] (rths_rig_set_target_dofs's layout) */
    double target_a[RTHS_API_MAX_INTERFACE_DOFS * RTHS_API_MAX_HARMONICS],
        target_b[RTHS_API_MAX_INTERFACE_DOFS * RTHS_API_MAX_HARMONICS];
    long periods, trace_periods;
    int has_delay;
    double delay_s;
} sim_args;

/* --target: one list A1,B1[,A2,B2,...] per interface DoF, lists separated by ';' */
static int parse_target(const char *text, sim_args *a, rths_error *err) {
    char buf[1024];
    if (strlen(text) >= sizeof buf)
        return rths_error_set(err, RTHS_EINPUT, "option --target: longer than %zu characters",
                              sizeof buf - 1);
    strcpy(buf, text);
    a->target_dofs = 0;
    for (char *list = buf, *next; list; list = next) {
        /* split by hand: strtok would merge ';;' and hand an empty list to the next DoF */
        next = strchr(list, ';');
        if (next) *next++ = '\0';
        if (!*list)
            return rths_error_set(err, RTHS_EINPUT,
                                  "option --target: list %d is empty; give A1,B1[,...] for every "
                                  "interface DoF",
                                  a->target_dofs + 1);
        int d = a->target_dofs, count, rc;
        if (d == RTHS_API_MAX_INTERFACE_DOFS)
            return rths_error_set(err, RTHS_EINPUT,
                                  "option --target: more than %d ';'-separated lists (one per "
                                  "interface DoF)",
                                  RTHS_API_MAX_INTERFACE_DOFS);
        double v[2 * RTHS_API_MAX_HARMONICS];
        if ((rc = rths_cli_double_list("--target", list, v, 2 * RTHS_API_MAX_HARMONICS, &count,
                                       err)))
            return rc;
        if (count % 2)
            return rths_error_set(err, RTHS_EINPUT,
                                  "option --target: %d values in list %d; give pairs A_k,B_k per "
                                  "harmonic",
                                  count, d + 1);
        if (d > 0 && count / 2 != a->harmonics)
            return rths_error_set(err, RTHS_EINPUT,
                                  "option --target: list %d has %d harmonics, list 1 has %d; give "
                                  "every interface DoF the same harmonics",
                                  d + 1, count / 2, a->harmonics);
        a->harmonics = count / 2;
        for (int k = 0; k < a->harmonics; k++)
            a->target_a[d * a->harmonics + k] = v[2 * k],
                                           a->target_b[d * a->harmonics + k] = v[2 * k + 1];
        a->target_dofs++;
    }
    if (a->target_dofs == 0)
        return rths_error_set(err, RTHS_EINPUT, "option --target: no coefficients");
    return RTHS_OK;
}

static int parse_args(rths_cli_opt *opts, sim_args *a, rths_error *err) {
    int rc;
    memset(a, 0, sizeof *a);
    if (opts[OPT_MODE].value) {
        if (!strcmp(opts[OPT_MODE].value, "feedback"))
            a->feedback = 1;
        else if (strcmp(opts[OPT_MODE].value, "iterative"))
            return rths_error_set(err, RTHS_EINPUT,
                                  "option --mode: '%s' is not a mode (iterative or feedback)",
                                  opts[OPT_MODE].value);
    }
    if (!opts[OPT_FREQ].value)
        return rths_error_set(err, RTHS_EINPUT, "missing --frequency F (forcing frequency, Hz)");
    if ((rc = rths_cli_double_ex("--frequency", opts[OPT_FREQ].value, 0, 1e5,
                                 RTHS_API_RANGE_LO_OPEN, &a->frequency_hz, err)))
        return rc;
    if (!opts[OPT_PERIODS].value)
        return rths_error_set(err, RTHS_EINPUT, "missing --periods N (forcing periods to run)");
    if ((rc = rths_cli_int("--periods", opts[OPT_PERIODS].value, 1, 100000, &a->periods, err)))
        return rc;
    if (a->feedback) {
        if (opts[OPT_TARGET].value)
            return rths_error_set(err, RTHS_EINPUT,
                                  "option --target: not used in feedback mode (the target is the "
                                  "numerical interface displacement itself)");
        if (opts[OPT_TRACE].value)
            return rths_error_set(err, RTHS_EINPUT,
                                  "option --trace-periods: feedback mode traces the whole run");
        if (opts[OPT_DELAY].value) {
            if ((rc = rths_cli_double_ex("--delay", opts[OPT_DELAY].value, 0, 1.0,
                                         RTHS_API_RANGE_LO_OPEN, &a->delay_s, err)))
                return rc;
            a->has_delay = 1;
        }
        return RTHS_OK;
    }
    if (opts[OPT_DELAY].value)
        return rths_error_set(
            err, RTHS_EINPUT,
            "option --delay: only with --mode feedback (the iterative test has no "
            "feedback loop to delay)");
    if (!opts[OPT_TARGET].value)
        return rths_error_set(
            err, RTHS_EINPUT,
            "missing --target A1,B1[,A2,B2,...] (target Fourier coefficients, m)");
    if ((rc = parse_target(opts[OPT_TARGET].value, a, err))) return rc;
    a->trace_periods = a->periods < 5 ? a->periods : 5;
    if (opts[OPT_TRACE].value && (rc = rths_cli_int("--trace-periods", opts[OPT_TRACE].value, 1,
                                                    1000, &a->trace_periods, err)))
        return rc;
    return RTHS_OK;
}

int rths_cmd_simulate(int argc, char **argv) {
    rths_cli_opt opts[OPT_COUNT] = {
        [OPT_FREQ] = {"--frequency", "F", NULL},
        [OPT_TARGET] = {"--target", "LIST", NULL},
        [OPT_PERIODS] = {"--periods", "N", NULL},
        [OPT_TRACE] = {"--trace-periods", "K", NULL},
        [OPT_MODE] = {"--mode", "MODE", NULL},
        [OPT_DELAY] = {"--delay", "TAU", NULL},
        [OPT_RIG] = {"--rig", "URI", NULL},
        [OPT_PACE] = {"--pace", "F", NULL},
        [OPT_RESET_FAULT] = {"--reset-fault", NULL, NULL},
    };
    rths_cli cli;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT | RTHS_CLI_SEED, usage,
                            opts, OPT_COUNT);
    if (rc || cli.help) return rc;
    rths_error err;
    rths_error_clear(&err);
    sim_args a;
    if ((rc = parse_args(opts, &a, &err))) return rths_cli_fail(&cli, rc, &err);
    if (opts[OPT_PACE].value &&
        (rc = rths_cli_add_pace(&cli, opts[OPT_PACE].value, opts[OPT_RIG].value != NULL, &err)))
        return rths_cli_fail(&cli, rc, &err);
    rths_api_simulate_options o;
    rths_api_simulate_options_default(&o);
    o.frequency_hz = a.frequency_hz;
    o.periods = (int)a.periods;
    o.feedback = a.feedback;
    o.delay_s = a.has_delay ? a.delay_s : 0;
    if (!a.feedback) {
        o.harmonics = a.harmonics, o.target_dofs = a.target_dofs;
        o.target_a = a.target_a, o.target_b = a.target_b;
        o.trace_periods = (int)a.trace_periods;
    }
    o.has_seed = cli.has_seed, o.seed = cli.seed;
    o.rig_uri = opts[OPT_RIG].value;
    o.reset_fault = opts[OPT_RESET_FAULT].value != NULL;

    rths_api_command_config *cfg = NULL;
    rths_api_simulation *sim = NULL;
    rths_api_run_folder *folder = NULL;
    rths_result *result = NULL;
    if ((rc = rths_cli_load(&cli, RTHS_API_READ_SETUP, &cfg, &err)))
        return rths_cli_fail(&cli, rc, &err);
    if (!(rc = rths_api_simulate_prepare(cfg, &o, &sim, &err)) &&
        !(rc = rths_cli_open_folder(&cli, cfg, argc, argv, &folder, &err)))
        rc = rths_api_simulate_run(sim, folder, &result, &err);
    if (!rc) rths_cli_print(&cli, "%s", rths_result_text(result));
    if (!rc) rc = rths_api_result_write(result, folder, &err);
    /* results.mat last: a failed write fails the command with its reason (not a warning) */
    if (!rc) rc = rths_api_run_folder_write_mat(folder, &err);
    rths_result_free(result);
    rths_api_simulation_free(sim);
    rths_api_run_folder_close(folder);
    rths_api_command_config_free(cfg);
    if (rc) return rths_cli_fail(&cli, rc, &err);
    return RTHS_OK;
}
