/* Shared plumbing of the rths commands: argument parsing, loading the configuration, the output
 * folder, error reporting and exit status. A command looks like:
 *
 *   rths_cli_opt opts[] = {{"--frequency", "F", NULL}, {"--verbose", NULL, NULL}};
 *   rths_cli cli;
 *   int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT, usage, opts, 2);
 *   if (rc || cli.help) return rc;               // message or usage already printed
 *   ... validate opts[i].value with rths_cli_double() etc.; on error
 *       return rths_cli_fail(&cli, rc, &err);    // exit 2, nothing written
 *   rths_api_command_config *cfg; rths_error err;
 *   if ((rc = rths_cli_load(&cli, RTHS_API_READ_SETUP, &cfg, &err)))
 *       return rths_cli_fail(&cli, rc, &err);
 *   rths_result *result;
 *   rc = rths_api_COMMAND_run(cfg, ..., &result, &err);  // reads and checks its sections
 *   rths_api_run_folder *folder;
 *   if (!rc) rc = rths_cli_open_folder(&cli, cfg, argc, argv, &folder, &err);  // creates DIR
 *   ... print rths_result_text(result), rths_api_result_write(result, folder, &err),
 *       rths_api_run_folder_close(folder), rths_api_command_config_free(cfg) ...
 *
 * Everything that can refuse input runs before rths_cli_open_folder, so exit status 2 never
 * leaves files behind. Exit status: RTHS_OK 0, RTHS_EFAIL 1, RTHS_EINPUT 2 (the error codes).
 * The commands reach the library through the C API alone (rths/rths.h; tests/cli/layering.sh). */
#ifndef RTHS_CLI_COMMON_H
#define RTHS_CLI_COMMON_H

#include "rths/rths.h"

#include <stdint.h>

/* What a command takes besides --set, --quiet and --help (always accepted). */
enum {
    RTHS_CLI_CONFIG = 1, /* one positional CONFIG file, required */
    RTHS_CLI_OUT = 2,    /* --out DIR, required */
    RTHS_CLI_SEED = 4,   /* --seed S accepted (unsigned 64-bit) */
};

/* A command-specific option. metavar NULL: a flag (value becomes "1" when given). Otherwise it
 * takes a value ("--name V" or "--name=V"), at most once: an option given twice is refused (as
 * are --out and --seed), so the one the user meant is never silently dropped. value is NULL when
 * absent. */
typedef struct rths_cli_opt {
    const char *name;    /* with the dashes: "--frequency" */
    const char *metavar; /* "F", or NULL for a flag */
    const char *value;   /* filled by rths_cli_parse; points into argv */
} rths_cli_opt;

#define RTHS_CLI_MAX_SETS 64

typedef struct rths_cli {
    const char *command;                 /* argv[0], e.g. "fidelity" */
    const char *config_path;             /* CONFIG */
    const char *out_dir;                 /* --out */
    const char *sets[RTHS_CLI_MAX_SETS]; /* --set k=v, in order */
    int n_sets;
    int quiet;    /* --quiet: nothing on stdout except errors (stderr) */
    int has_seed; /* --seed given */
    uint64_t seed;
    int help;          /* --help was given and the usage printed: return 0 */
    char pace_set[48]; /* "rig.pace=F" when --pace F was given (one of sets) */
} rths_cli;

/* Parses argv (argv[0] = command name). usage is printed for --help (stdout, then cli->help = 1
 * and RTHS_OK). Any problem: "rths <cmd>: <message>" on stderr and RTHS_EINPUT. */
int rths_cli_parse(rths_cli *cli, int argc, char **argv, int flags, const char *usage,
                   rths_cli_opt *opts, int n_opts);

/* --pace F (F x real time): appends rig.pace = F (docs/config/rig.md) to the overrides, named
 * as the option when bad; refused with a controller process (remote_rig), which runs at real
 * time. Returns RTHS_OK or RTHS_EINPUT with err filled. */
int rths_cli_add_pace(rths_cli *cli, const char *value, int remote_rig, rths_error *err);

/* Prints "rths <cmd>: <err->msg>" on stderr and returns rc (the exit status). */
int rths_cli_fail(const rths_cli *cli, int rc, const rths_error *err);

/* printf to stdout unless --quiet. */
void rths_cli_print(const rths_cli *cli, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* Option value parsers: the whole text must be the number, finite, inside [lo, hi]; otherwise
 * RTHS_EINPUT with "option --name: ..." in err. */
int rths_cli_double(const char *opt, const char *text, double lo, double hi, double *out,
                    rths_error *err);
/* The same with open ends where flagged (RTHS_API_RANGE_LO_OPEN: lo < x), worded as the
 * configuration's getters word a range ("must be in (0, 100000] (got 0)"). */
int rths_cli_double_ex(const char *opt, const char *text, double lo, double hi, unsigned flags,
                       double *out, rths_error *err);
int rths_cli_int(const char *opt, const char *text, long lo, long hi, long *out, rths_error *err);
/* Comma-separated numbers "1e-4,0,-2e-5" (at most max_count); *count how many. */
int rths_cli_double_list(const char *opt, const char *text, double *out, int max_count, int *count,
                         rths_error *err);

/* Loads CONFIG with the --set overrides (rths_api_command_config_load; flags
 * RTHS_API_READ_SETUP also reads the structural setup: structure, split, forcing, model). On
 * failure nothing is left allocated. Free with rths_api_command_config_free. */
int rths_cli_load(const rths_cli *cli, unsigned flags, rths_api_command_config **cfg,
                  rths_error *err);

/* Creates the output folder --out, opens run.log (the command line as its first line), writes
 * config.yaml (as resolved). */
int rths_cli_open_folder(const rths_cli *cli, const rths_api_command_config *cfg, int argc,
                         char **argv, rths_api_run_folder **folder, rths_error *err);

#endif
