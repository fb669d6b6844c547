/* rths controller: the real-time controller process (docs/protocol.md). The command parses its
 * options; the process is rths_api_controller_serve (src/api/api_controller.c). */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

#include <stdio.h>
#include <string.h>

/* 1 when argv names the configuration with --config (else it is the positional CONFIG). */
static int has_config_option(int argc, char **argv) {
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--config") || !strncmp(argv[i], "--config=", 9)) return 1;
    return 0;
}

/* The command line through the shared parser (cli_common.h); the controller's own checks of
 * --listen and --duration. Fills args and the overrides (--io becomes io.plugin). */
typedef struct controller_args {
    rths_cli cli;
    const char *config_path, *view_listen, *listen;
    double duration_s;     /* -1: until a signal */
    double latency_test_s; /* --latency-test; -1: none */
    long site;             /* --site N (1-based); 0: the whole configuration */
    char io_set[2 * 4096 + 16];
} controller_args;

enum { OPT_CONFIG, OPT_LISTEN, OPT_IO, OPT_VIEW, OPT_DURATION, OPT_LATENCY, OPT_SITE, N_OPTS };

/* 1 when argv asks for the latency test (which needs no configuration). */
static int has_latency_test(int argc, char **argv) {
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--latency-test") || !strncmp(argv[i], "--latency-test=", 15))
            return 1;
    return 0;
}

static int parse_args(int argc, char **argv, controller_args *args) {
    char usage[8192];
    rths_api_controller_usage(usage, sizeof usage, RTHS_CLI_MAX_SETS);
    rths_cli_opt opts[N_OPTS] = {[OPT_CONFIG] = {"--config", "CONFIG", NULL},
                                 [OPT_LISTEN] = {"--listen", "ADDR:PORT", NULL},
                                 [OPT_IO] = {"--io", "PLUGIN.so", NULL},
                                 [OPT_VIEW] = {"--view", "ADDR:PORT", NULL},
                                 [OPT_DURATION] = {"--duration", "SECONDS", NULL},
                                 [OPT_LATENCY] = {"--latency-test", "SECONDS", NULL},
                                 [OPT_SITE] = {"--site", "N", NULL}};
    rths_cli *cli = &args->cli;
    /* CONFIG is either --config's value or the one positional argument, never both; the
     * latency test takes it only by --config, and runs without one */
    int flags = has_config_option(argc, argv) || has_latency_test(argc, argv) ? 0 : RTHS_CLI_CONFIG;
    int rc = rths_cli_parse(cli, argc, argv, flags, usage, opts, N_OPTS);
    if (rc || cli->help) return rc;
    args->config_path = flags ? cli->config_path : opts[OPT_CONFIG].value;
    args->view_listen = opts[OPT_VIEW].value;
    args->duration_s = -1.0;
    args->latency_test_s = -1.0;
    rths_error err;
    args->listen = opts[OPT_LISTEN].value;
    if (args->listen && (rc = rths_api_controller_check_listen(args->listen, &err)))
        return rths_cli_fail(cli, rc, &err);
    if (opts[OPT_DURATION].value &&
        (rc = rths_cli_double_ex("--duration", opts[OPT_DURATION].value, 0.0, 1e7,
                                 RTHS_API_RANGE_LO_OPEN, &args->duration_s, &err)))
        return rths_cli_fail(cli, rc, &err);
    if (opts[OPT_LATENCY].value &&
        (rc = rths_cli_double_ex("--latency-test", opts[OPT_LATENCY].value, 0.0, 3600.0,
                                 RTHS_API_RANGE_LO_OPEN, &args->latency_test_s, &err)))
        return rths_cli_fail(cli, rc, &err);
    if (opts[OPT_SITE].value && (rc = rths_cli_int("--site", opts[OPT_SITE].value, 1,
                                                   RTHS_API_MAX_INTERFACE_DOFS, &args->site, &err)))
        return rths_cli_fail(cli, rc, &err);
    const char *io_path = opts[OPT_IO].value;
    /* an unset variable in a lab's script (--io "$PLUGIN") must not run the simulated plant,
     * and a bare name must not load whatever the system's library path holds */
    if (io_path && !io_path[0]) {
        rths_error_set(&err, RTHS_EINPUT,
                       "--io '': the plug-in path is empty; give the plug-in's shared object by "
                       "a path (e.g. --io ./lab_daq.so), or leave --io out for the simulated "
                       "plant");
        return rths_cli_fail(cli, RTHS_EINPUT, &err);
    }
    if (io_path && !strchr(io_path, '/')) {
        rths_error_set(&err, RTHS_EINPUT,
                       "--io '%.200s': not a path; name the plug-in's shared object by a path "
                       "containing '/' (e.g. --io ./%.200s); it is never looked up in the "
                       "system's library path",
                       io_path, io_path);
        return rths_cli_fail(cli, RTHS_EINPUT, &err);
    }
    if (io_path) {
        /* --io is the override io.plugin, single-quoted for YAML (a quote doubled) */
        if (strlen(io_path) > 4096 || cli->n_sets >= RTHS_CLI_MAX_SETS) {
            rths_error_set(&err, RTHS_EINPUT, "--io '%.40s...': too long, or too many --set",
                           io_path);
            return rths_cli_fail(cli, RTHS_EINPUT, &err);
        }
        char *w = args->io_set + sprintf(args->io_set, "io.plugin='");
        for (const char *r = io_path; *r; r++) {
            if (*r == '\'') *w++ = '\'';
            *w++ = *r;
        }
        strcpy(w, "'");
        cli->sets[cli->n_sets++] = args->io_set;
    }
    return RTHS_OK;
}

int rths_cmd_controller(int argc, char **argv) {
    controller_args args = {0}; /* --site absent: 0, the whole test */
    int rc = parse_args(argc, argv, &args);
    if (rc || args.cli.help) return rc;
    rths_error err;
    rths_error_clear(&err);
    rths_api_controller_options o = {.config_path = args.config_path,
                                     .overrides = args.cli.sets,
                                     .n_overrides = args.cli.n_sets,
                                     .listen = args.listen,
                                     .site = args.site,
                                     .view_listen = args.view_listen,
                                     .duration_s = args.duration_s,
                                     .quiet = args.cli.quiet};
    if (args.latency_test_s > 0)
        rc = rths_api_controller_latency_test(&o, args.latency_test_s, &err);
    else
        rc = rths_api_controller_serve(&o, &err);
    if (rc) fprintf(stderr, "rths controller: %s\n", err.msg);
    return rc;
}
