/* rths frf CONFIG --out DIR: the iterative hybrid test with continuation in forcing frequency, the
 * main job. This file parses the options, loads the configuration and prints; the test itself is
 * rths_api_frf_run (the C API over src/run's rths_run_frf). */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

#include <signal.h>
#include <stdio.h>
#include <string.h>

static const char usage[] =
    "Usage: rths frf CONFIG --out DIR [--strategy paper|default] [--harmonics N] [--seed S]\n"
    "                [--resume] [--rig tcp://HOST:PORT] [--pace F] [--set key=value]...\n"
    "                [--reset-fault] [--force] [--quiet]\n"
    "\n"
    "Iterative hybrid test with continuation: solves for the control target's Fourier\n"
    "coefficients at which the physical and numerical interface displacements agree, and\n"
    "continues the solution in forcing frequency from continuation.start_hz to end_hz,\n"
    "through folds (continuation.method: arclength) to trace the true assembly's response.\n"
    "\n"
    "Options:\n"
    "  --out DIR            output folder (created)\n"
    "  --strategy NAME      default: adaptive steady-state detection, Jacobian carried along the\n"
    "                       branch, targets and gains predicted from a model of the residual\n"
    "                       fitted to recent evaluations, response reported at zero mismatch,\n"
    "                       exact first-order-hold integrator, grounding damping\n"
    "                       1000 N s/m, changes spread over 3 periods (the project's best);\n"
    "                       paper: the seed's flowchart (fixed waits, fresh finite-difference\n"
    "                       Jacobian at every point, secant predictor, the measured response,\n"
    "                       implicit Euler numerical substructure,\n"
    "                       grounding damping 200 N s/m, changes at once); --set wins\n"
    "  --harmonics N        harmonics matched at the interface, 1..3 (default: "
    "iteration.harmonics, 1)\n"
    "  --seed S             noise seed of the virtual rig (default: rig.seed)\n"
    "  --resume             continue the interrupted run in DIR from its journal's last point\n"
    "  --rig URI            tcp://HOST:PORT: a controller process (repeated: rig.sites)\n"
    "  --reset-fault        with --rig: reset the controller's latched fault (RESET_FAULT, e.g.\n"
    "                       a watchdog trip of an earlier run) before the run, logged in\n"
    "                       run.log; refused (exit 1, the controller's answer) while its\n"
    "                       cause persists\n"
    "  --pace F             run the virtual rig at F x real time (1: real time), e.g. to watch\n"
    "                       it with rths view; results are the same (rig.pace; default unpaced)\n"
    "  --force              run even when the true assembly's interface response over the\n"
    "                       range exceeds controller.limits.displacement_m (refused otherwise,\n"
    "                       before anything is written), and accept a point whose response is\n"
    "                       below the measured noise floor (iteration.min_snr; otherwise the\n"
    "                       run stops there with exit 1), flagged in frf.csv below_noise_floor\n"
    "  --set key=value      override a configuration key (repeatable)\n"
    "  --quiet              no progress line, no summary\n"
    "  --help               this text\n"
    "\n"
    "Writes into DIR: journal.jsonl (one line per accepted point, flushed; --resume reads it),\n"
    "evaluations.csv (a row per evaluation: role, mismatch, rig time; flushed),\n"
    "frf.csv (one row per accepted point), truth.csv (the true assembly's response computed\n"
    "without the hybrid loop), frf.png, bode.png, nyquist.png, modal.csv (modes identified\n"
    "from the hybrid FRF), frf.uff (UFF58), iterations.png, trace.csv + lissajous.png (one\n"
    "point in time), summary.json,\n"
    "config.yaml, run.log, results.mat (every table for MATLAB/h5py), live.json (the run in\n"
    "progress, for rths view), run.lock (while the run owns DIR; removed when it ends);\n"
    "absolute.csv with a base excitation (forcing.type: base).\n"
    "\n"
    "Ctrl-C (SIGINT) or SIGTERM stops after the point in progress and writes everything\n"
    "accepted (exit 130); a second Ctrl-C kills at once (the journal still resumes).\n"
    "\n"
    "Exit status: 0 the run reached continuation.end_hz (or continuation.max_points); 1 rig\n"
    "fault, I/O failure, no point accepted at all, or the sweep stopped short of its end\n"
    "(failed corrections, the step below continuation.min_step: the message names the most\n"
    "frequent cause, e.g. a limit; everything accepted so far is saved); 2 bad usage or\n"
    "configuration, a journal of another configuration, or DIR in use by another run; 130\n"
    "interrupted (everything accepted saved).\n";

/* Ctrl-C (or SIGTERM) ends the run cleanly after the point in progress: everything accepted is
 * written out (frf.csv, summary.json, figures) and --resume continues it. A second signal kills at
 * once (the default action is restored by the first). */
static volatile sig_atomic_t interrupted;

static void on_interrupt(int sig) {
    interrupted = sig;
    signal(sig, SIG_DFL);
}

static int should_cancel(void *user) {
    (void)user;
    return interrupted != 0;
}

static void print_progress(void *user, int points, double frequency_hz, double residual_m,
                           int evaluations, int accepted) {
    (void)user;
    fprintf(stderr, "\r  point %4d  %9.5f Hz  residual %9.3e m  evaluations %5d  %-9s", points,
            frequency_hz, residual_m, evaluations, accepted ? "accepted" : "retrying");
    fflush(stderr);
}

/* The options of the command: strategy, harmonics, resume, rig. Returns 0 or an exit status. */
typedef struct {
    const char *strategy;
    long harmonics;
    int resume;
    int force;
    int reset_fault;
    const char *rig_uri;
    int n_site_rigs; /* --rig given once per site (taken out before parsing) */
} frf_args;

static int parse_args(rths_cli *cli, int argc, char **argv, frf_args *a) {
    enum {
        OPT_STRATEGY,
        OPT_HARMONICS,
        OPT_RESUME,
        OPT_RIG,
        OPT_PACE,
        OPT_FORCE,
        OPT_RESET_FAULT,
        N_OPTS
    };
    rths_cli_opt opts[N_OPTS] = {
        [OPT_STRATEGY] = {"--strategy", "NAME", NULL},
        [OPT_HARMONICS] = {"--harmonics", "N", NULL},
        [OPT_RESUME] = {"--resume", NULL, NULL},
        [OPT_RIG] = {"--rig", "URI", NULL},
        [OPT_PACE] = {"--pace", "F", NULL},
        [OPT_FORCE] = {"--force", NULL, NULL},
        [OPT_RESET_FAULT] = {"--reset-fault", NULL, NULL},
    };
    int rc = rths_cli_parse(cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT | RTHS_CLI_SEED, usage,
                            opts, N_OPTS);
    if (rc || cli->help) return rc;
    rths_error err = {0};
    a->strategy = opts[OPT_STRATEGY].value ? opts[OPT_STRATEGY].value : "default";
    if (strcmp(a->strategy, "default") && strcmp(a->strategy, "paper"))
        return rths_cli_fail(cli,
                             rths_error_set(&err, RTHS_EINPUT,
                                            "option --strategy: '%s' is neither 'default' "
                                            "nor 'paper'",
                                            a->strategy),
                             &err);
    if (opts[OPT_HARMONICS].value &&
        (rc = rths_cli_int("--harmonics", opts[OPT_HARMONICS].value, 1, RTHS_API_FRF_MAX_HARMONICS,
                           &a->harmonics, &err)))
        return rths_cli_fail(cli, rc, &err);
    a->resume = opts[OPT_RESUME].value != NULL;
    a->force = opts[OPT_FORCE].value != NULL;
    a->rig_uri = opts[OPT_RIG].value;
    a->reset_fault = opts[OPT_RESET_FAULT].value != NULL;
    if (a->reset_fault && !a->rig_uri && !a->n_site_rigs)
        return rths_cli_fail(cli,
                             rths_error_set(&err, RTHS_EINPUT,
                                            "option --reset-fault needs --rig tcp://HOST:PORT "
                                            "(a virtual rig starts without a fault)"),
                             &err);
    if (a->rig_uri && strncmp(a->rig_uri, "tcp://", 6))
        return rths_cli_fail(cli,
                             rths_error_set(&err, RTHS_EINPUT,
                                            "option --rig: '%s' is not tcp://HOST:PORT",
                                            a->rig_uri),
                             &err);
    if (opts[OPT_PACE].value &&
        (rc = rths_cli_add_pace(cli, opts[OPT_PACE].value, a->rig_uri || a->n_site_rigs, &err)))
        return rths_cli_fail(cli, rc, &err);
    /* The paper strategy integrates the numerical substructure as the seed did; an explicit
     * --set controller.scheme=... still wins, because overrides apply in order. */
    if (!strcmp(a->strategy, "paper")) {
        int n_paper;
        const char *const *paper = rths_api_frf_paper_overrides(&n_paper);
        if (cli->n_sets + n_paper > RTHS_CLI_MAX_SETS)
            return rths_cli_fail(cli, rths_error_set(&err, RTHS_EINPUT, "too many --set"), &err);
        memmove(cli->sets + n_paper, cli->sets, (size_t)cli->n_sets * sizeof cli->sets[0]);
        for (int i = 0; i < n_paper; i++)
            cli->sets[i] = paper[i];
        cli->n_sets += n_paper;
    }
    return RTHS_OK;
}

/* --rig given several times names the sites of a multi-site test (rig.sites): they are taken
 * out of the arguments here (the shared parser takes an option once) into uris, in order. The
 * filtered arguments go to argv_out (argc + 1 entries). Returns how many --rig there were. */
static int take_site_rigs(int argc, char **argv, char **argv_out, int *argc_out, const char **uris,
                          int cap) {
    int n = 0, rigs = 0;
    for (int i = 0; i < argc; i++)
        rigs += !strcmp(argv[i], "--rig") || !strncmp(argv[i], "--rig=", 6);
    for (int i = 0; i < argc; i++) {
        if (rigs > 1 && !strcmp(argv[i], "--rig") && i + 1 < argc) {
            if (n < cap) uris[n] = argv[i + 1];
            n++, i++;
        } else if (rigs > 1 && !strncmp(argv[i], "--rig=", 6)) {
            if (n < cap) uris[n] = argv[i] + 6;
            n++;
        } else {
            argv_out[(*argc_out)++] = argv[i];
        }
    }
    argv_out[*argc_out] = NULL;
    return n;
}

int rths_cmd_frf(int argc, char **argv) {
    rths_cli cli;
    frf_args a = {0};
    const char *site_uris[RTHS_API_MAX_INTERFACE_DOFS];
    char *args[argc + 1];
    int n_args = 0;
    int n_sites = take_site_rigs(argc, argv, args, &n_args, site_uris, RTHS_API_MAX_INTERFACE_DOFS);
    if (n_sites > RTHS_API_MAX_INTERFACE_DOFS) {
        fprintf(stderr, "rths frf: --rig given %d times; a multi-site test has at most %d sites\n",
                n_sites, RTHS_API_MAX_INTERFACE_DOFS);
        return RTHS_EINPUT;
    }
    for (int k = 0; k < n_sites; k++)
        if (strncmp(site_uris[k], "tcp://", 6)) {
            fprintf(stderr, "rths frf: option --rig: '%s' is not tcp://HOST:PORT\n", site_uris[k]);
            return RTHS_EINPUT;
        }
    int all_argc = argc; /* run.log records the command as given */
    char **all_argv = argv;
    argc = n_args;
    argv = args;
    a.n_site_rigs = n_sites;
    int rc = parse_args(&cli, argc, argv, &a);
    if (rc || cli.help) return rc;
    rths_api_command_config *cfg = NULL;
    rths_error err = {0};
    if ((rc = rths_cli_load(&cli, RTHS_API_READ_SETUP, &cfg, &err)))
        return rths_cli_fail(&cli, rc, &err);
    int progress = rths_api_progress_enabled(cli.quiet);
    rths_api_frf_run_options opt = {.out_dir = cli.out_dir,
                                    .strategy = a.strategy,
                                    .harmonics = (int)a.harmonics,
                                    .resume = a.resume,
                                    .force = a.force,
                                    .rig_uri = a.rig_uri,
                                    .reset_fault = a.reset_fault,
                                    .site_uris = site_uris,
                                    .n_site_uris = n_sites,
                                    .has_seed = cli.has_seed,
                                    .seed = cli.seed,
                                    .argc = all_argc,
                                    .argv = all_argv,
                                    .on_progress = progress ? print_progress : NULL,
                                    .should_cancel = should_cancel};
    signal(SIGINT, on_interrupt);
    signal(SIGTERM, on_interrupt);
    rths_api_frf_run_summary r;
    rc = rths_api_frf_run(cfg, &opt, &r, &err);
    if (progress && r.outputs_written) fprintf(stderr, "\n");
    if (r.outputs_written && r.points > 0)
        rths_cli_print(&cli,
                       "%d points (%d converged, %d resumed), %d evaluations, %.1f s rig time, "
                       "%.1f s wall; %d fold(s); max deviation from the true response %.3g %%\n"
                       "stopped: %s\nresults in %s\n",
                       r.points, r.converged_points, r.resumed_points, r.evaluations, r.rig_time_s,
                       r.wall_time_s, r.folds, 100 * r.max_relative_error_vs_truth, r.stop_reason,
                       cli.out_dir);
    if (!rc && r.cancelled)
        fprintf(stderr,
                "rths frf: interrupted; everything accepted is in %s (--resume continues)\n",
                cli.out_dir);
    if (rc) rths_cli_fail(&cli, rc, &err);
    rths_api_command_config_free(cfg);
    if (!rc && r.cancelled) rc = 130; /* as the shell reports an interrupt */
    return rc;
}
