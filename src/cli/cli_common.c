/* Shared plumbing of the rths commands (see cli_common.h). */
#include "cli/cli_common.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int usage_error(const rths_cli *cli, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

static int usage_error(const rths_cli *cli, const char *fmt, ...) {
    va_list ap;
    fprintf(stderr, "rths %s: ", cli->command);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, " (see 'rths %s --help')\n", cli->command);
    return RTHS_EINPUT;
}

int rths_cli_fail(const rths_cli *cli, int rc, const rths_error *err) {
    fprintf(stderr, "rths %s: %s\n", cli->command,
            err && err->msg[0] ? err->msg : (rc == RTHS_EINPUT ? "bad input" : "failed"));
    return rc == RTHS_OK ? RTHS_EFAIL : rc;
}

void rths_cli_print(const rths_cli *cli, const char *fmt, ...) {
    if (cli->quiet) return;
    va_list ap;
    va_start(ap, fmt);
    vprintf(fmt, ap);
    va_end(ap);
    fflush(stdout);
}

/* "--name=value" or "--name value": returns the value or NULL (missing), advancing *i. */
static const char *option_value(int argc, char **argv, int *i, const char *name, int *matched) {
    const char *arg = argv[*i];
    size_t len = strlen(name);
    *matched = 0;
    if (strncmp(arg, name, len)) return NULL;
    if (arg[len] == '=') {
        *matched = 1;
        return arg + len + 1;
    }
    if (arg[len] != '\0') return NULL;
    *matched = 1;
    /* "--out --quiet" is a forgotten value, not a folder called --quiet */
    if (*i + 1 >= argc || !strncmp(argv[*i + 1], "--", 2)) return NULL;
    return argv[++*i];
}

/* A path the system would refuse only later, with a message of unbounded length (or after part of
 * the output was made): the whole path within PATH_MAX, each name within NAME_MAX. */
static int path_fits(const rths_cli *cli, const char *what, const char *path) {
    size_t len = strlen(path);
    if (len >= PATH_MAX) {
        usage_error(cli, "%s: the path is %zu bytes long; the system allows %d", what, len,
                    PATH_MAX - 1);
        return 0;
    }
    for (const char *p = path; *p;) {
        size_t name = strcspn(p, "/");
        if (name > NAME_MAX) {
            usage_error(cli, "%s: the name '%.40s...' is %zu bytes long; the system allows %d",
                        what, p, name, NAME_MAX);
            return 0;
        }
        p += name + (p[name] == '/');
    }
    return 1;
}

int rths_cli_parse(rths_cli *cli, int argc, char **argv, int flags, const char *usage,
                   rths_cli_opt *opts, int n_opts) {
    memset(cli, 0, sizeof *cli);
    cli->command = argc > 0 ? argv[0] : "?";
    for (int k = 0; k < n_opts; k++)
        opts[k].value = NULL;
    const char *seed_text = NULL;
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        int matched;
        const char *v;
        if (!strcmp(arg, "--help") || !strcmp(arg, "-h")) {
            fputs(usage, stdout);
            cli->help = 1;
            return RTHS_OK;
        }
        if (!strcmp(arg, "--quiet") || !strcmp(arg, "-q")) {
            cli->quiet = 1;
            continue;
        }
        if ((v = option_value(argc, argv, &i, "--set", &matched)) || matched) {
            if (!v) return usage_error(cli, "option --set needs a value KEY=VALUE");
            if (!strchr(v, '=') || v[0] == '=')
                return usage_error(
                    cli, "--set %s: expected KEY=VALUE (e.g. --set split.mass_ratio=0.33)", v);
            if (cli->n_sets >= RTHS_CLI_MAX_SETS)
                return usage_error(cli, "at most %d --set options", RTHS_CLI_MAX_SETS);
            cli->sets[cli->n_sets++] = v;
            continue;
        }
        if ((flags & RTHS_CLI_OUT) &&
            ((v = option_value(argc, argv, &i, "--out", &matched)) || matched)) {
            if (!v || !v[0]) return usage_error(cli, "option --out needs a directory");
            if (cli->out_dir) /* which one was meant? taking the last hid the first */
                return usage_error(cli, "option --out given twice ('%s' and '%s')", cli->out_dir,
                                   v);
            cli->out_dir = v;
            continue;
        }
        if ((flags & RTHS_CLI_SEED) &&
            ((v = option_value(argc, argv, &i, "--seed", &matched)) || matched)) {
            if (!v) return usage_error(cli, "option --seed needs a value");
            if (seed_text)
                return usage_error(cli, "option --seed given twice ('%s' and '%s')", seed_text, v);
            seed_text = v;
            continue;
        }
        int found = 0;
        for (int k = 0; k < n_opts && !found; k++) {
            if (!opts[k].metavar) {
                if (!strcmp(arg, opts[k].name)) opts[k].value = "1", found = 1;
                continue;
            }
            v = option_value(argc, argv, &i, opts[k].name, &matched);
            if (!matched) continue;
            if (!v)
                return usage_error(cli, "option %s needs a value %s", opts[k].name,
                                   opts[k].metavar);
            if (opts[k].value)
                return usage_error(cli, "option %s given twice ('%s' and '%s')", opts[k].name,
                                   opts[k].value, v);
            opts[k].value = v;
            found = 1;
        }
        if (found) continue;
        if (arg[0] == '-' && arg[1] != '\0') return usage_error(cli, "unknown option '%s'", arg);
        if (!(flags & RTHS_CLI_CONFIG) || cli->config_path)
            return usage_error(cli, "unexpected argument '%s'", arg);
        cli->config_path = arg;
    }
    if ((flags & RTHS_CLI_CONFIG) && !cli->config_path)
        return usage_error(cli, "missing CONFIG (a YAML test description, e.g. "
                                "examples/four_storey.yaml)");
    if ((flags & RTHS_CLI_OUT) && !cli->out_dir)
        return usage_error(cli, "missing --out DIR (the folder the results go to)");
    if (cli->out_dir && !path_fits(cli, "--out", cli->out_dir)) return RTHS_EINPUT;
    if (cli->config_path && !path_fits(cli, "CONFIG", cli->config_path)) return RTHS_EINPUT;
    if (seed_text) {
        char *end;
        errno = 0;
        unsigned long long s = strtoull(seed_text, &end, 0);
        if (errno || end == seed_text || *end != '\0' || seed_text[0] == '-')
            return usage_error(cli, "option --seed: '%s' is not a non-negative integer", seed_text);
        cli->seed = (uint64_t)s;
        cli->has_seed = 1;
    }
    return RTHS_OK;
}

int rths_cli_double_ex(const char *opt, const char *text, double lo, double hi, unsigned flags,
                       double *out, rths_error *err) {
    char *end;
    errno = 0;
    double v = strtod(text, &end);
    if (end == text || *end != '\0')
        return rths_error_set(err, RTHS_EINPUT, "option %s: '%s' is not a number", opt, text);
    if (!isfinite(v) || errno == ERANGE)
        return rths_error_set(err, RTHS_EINPUT, "option %s: '%s' is not a finite number", opt,
                              text);
    if (v < lo || v > hi || ((flags & RTHS_API_RANGE_LO_OPEN) && v == lo) ||
        ((flags & RTHS_API_RANGE_HI_OPEN) && v == hi)) {
        char range[128];
        return rths_error_set(err, RTHS_EINPUT, "option %s: must be %s (got %s)", opt,
                              rths_api_range_text(lo, hi, flags, range, sizeof range), text);
    }
    *out = v;
    return RTHS_OK;
}

int rths_cli_double(const char *opt, const char *text, double lo, double hi, double *out,
                    rths_error *err) {
    return rths_cli_double_ex(opt, text, lo, hi, 0, out, err);
}

int rths_cli_int(const char *opt, const char *text, long lo, long hi, long *out, rths_error *err) {
    char *end;
    errno = 0;
    long v = strtol(text, &end, 10);
    if (end == text || *end != '\0' || errno == ERANGE)
        return rths_error_set(err, RTHS_EINPUT, "option %s: '%s' is not an integer", opt, text);
    if (v < lo || v > hi) /* worded as the configuration's integer getter does */
        return rths_error_set(err, RTHS_EINPUT, "option %s: must be in [%ld, %ld] (got %ld)", opt,
                              lo, hi, v);
    *out = v;
    return RTHS_OK;
}

int rths_cli_double_list(const char *opt, const char *text, double *out, int max_count, int *count,
                         rths_error *err) {
    *count = 0;
    const char *p = text;
    for (;;) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        char item[64];
        if (len == 0 || len >= sizeof item)
            return rths_error_set(err, RTHS_EINPUT,
                                  "option %s: '%s' must be comma-separated numbers", opt, text);
        if (*count >= max_count)
            return rths_error_set(err, RTHS_EINPUT,
                                  "option %s: at most %d values (got more in '%s')", opt, max_count,
                                  text);
        memcpy(item, p, len);
        item[len] = '\0';
        char *end;
        double v = strtod(item, &end);
        if (end == item || *end != '\0' || !isfinite(v))
            return rths_error_set(err, RTHS_EINPUT, "option %s: '%s' is not a finite number", opt,
                                  item);
        out[(*count)++] = v;
        if (!comma) break;
        p = comma + 1;
    }
    return RTHS_OK;
}

int rths_cli_load(const rths_cli *cli, unsigned flags, rths_api_command_config **cfg,
                  rths_error *err) {
    return rths_api_command_config_load(cli->config_path, cli->sets, cli->n_sets, flags, cfg, err);
}

int rths_cli_open_folder(const rths_cli *cli, const rths_api_command_config *cfg, int argc,
                         char **argv, rths_api_run_folder **folder, rths_error *err) {
    return rths_api_run_folder_open(cli->out_dir, cli->command, argc, argv, cfg, folder, err);
}

int rths_cli_add_pace(rths_cli *cli, const char *value, int remote_rig, rths_error *err) {
    double pace;
    int rc = rths_cli_double("--pace", value, 1e-6, 1e6, &pace, err);
    if (rc) return rc;
    if (remote_rig)
        return rths_error_set(err, RTHS_EINPUT,
                              "option --pace paces the in-process virtual rig; a controller "
                              "process (--rig) runs at real time");
    if (cli->n_sets >= RTHS_CLI_MAX_SETS)
        return rths_error_set(err, RTHS_EINPUT, "too many --set (at most %d)", RTHS_CLI_MAX_SETS);
    snprintf(cli->pace_set, sizeof cli->pace_set, "rig.pace=%.17g", pace);
    cli->sets[cli->n_sets++] = cli->pace_set;
    return RTHS_OK;
}
