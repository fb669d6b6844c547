/* rths campaign PLAN.yaml --out DIR: many `rths frf` runs of one configuration over a grid of
 * --set values and noise seeds, serially, with --jobs J worker processes, or shared between the
 * ranks of an MPI job (docs/campaign.md). Every run is exactly `rths frf CONFIG --set ... --seed S
 * --out DIR/run_K --quiet`: this binary executed again, so a run cannot differ from one started
 * by hand, and a crash in one run cannot take the campaign with it. One writer (this process, or
 * rank 0) records each run's exit status and rewrites campaign.csv atomically after every run. */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <inttypes.h>
#include <json-c/json.h>
#include <libfyaml.h>
#include <libgen.h>
#include <limits.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#ifdef RTHS_HAVE_MPI
#include <mpi.h>
#endif

static const char usage[] =
    "Usage: rths campaign PLAN.yaml --out DIR [--jobs J] [--set key=value]... [--quiet]\n"
    "       mpirun -n N rths campaign PLAN.yaml --out DIR [--set key=value]...\n"
    "\n"
    "Runs one `rths frf` test per combination of a grid of configuration values and noise\n"
    "seeds. PLAN.yaml (docs/campaign.md):\n"
    "  config: four_storey_linear.yaml     # the configuration, relative to the plan\n"
    "  set: {continuation.end_hz: 6}       # optional overrides for every run\n"
    "  grid: {split.mass_ratio: [0.3, 0.5], controller.kp_v_per_m: [2000, 4000]}\n"
    "  seeds: [1, 2, 3]                    # optional: --seed of each run\n"
    "Runs are numbered in plan order, the last grid key varying fastest and the seed fastest\n"
    "of all; run K is `rths frf CONFIG --set ... --seed S --out DIR/run_K --quiet` (the grid's\n"
    "values after the plan's set: and this command's --set).\n"
    "\n"
    "Options:\n"
    "  --out DIR    the campaign folder (created; see below for an existing one)\n"
    "  --jobs J     J runs at a time, each in its own process (default 1); a run starts as\n"
    "               soon as one ends, so runs of different length keep every process busy\n"
    "  --set k=v    an override for every run, after the plan's set: (repeatable)\n"
    "  --quiet      no progress lines\n"
    "\n"
    "Under mpirun (when rths is built with MPI: see rths --version) rank 0 hands out the runs\n"
    "one at a time to the other ranks as they finish, and writes campaign.csv; --jobs is not\n"
    "used there. With one rank the campaign runs as without MPI.\n"
    "\n"
    "Writes into DIR: plan.txt (the plan as resolved), runs.csv (the index: run, the grid\n"
    "values, seed), run_K/ (each run's folder, as rths frf writes it), logs/run_K.log (its\n"
    "messages), logs/run_K.status (its exit status, once it ended), campaign.csv (one row\n"
    "per run: the grid values, seed,\n"
    "exit_status, points, converged_points, evaluations, rig_time_s,\n"
    "max_relative_error_vs_truth, share_within_3_standard_errors; empty for runs not yet\n"
    "finished), rewritten atomically after every run.\n"
    "\n"
    "Resuming is the default: if DIR holds a campaign of the same plan (plan.txt: the same\n"
    "configuration file, overrides and runs), its finished runs (a run_K/summary.json and a\n"
    "recorded exit status) are kept untouched and the others run again, each unfinished folder\n"
    "replaced; this is said on stderr. DIR holding anything else, or a campaign of another\n"
    "plan, is refused.\n"
    "\n"
    "Ctrl-C (SIGINT) or SIGTERM: the runs in progress are stopped and left unfinished (they run\n"
    "again on resume), everything finished is recorded (exit 130).\n"
    "\n"
    "Before anything is written, every grid value is read by a run's own readers (run 0 and\n"
    "each other grid value in run 0's combination, started and cancelled before their first\n"
    "point in a scratch folder): a key no reader asks for (a typo) or a value a reader\n"
    "refuses is named at its FILE:LINE:COLUMN in the plan.\n"
    "\n"
    "rths view DIR shows the campaign: campaign.csv as a table, each run's own page, any\n"
    "result plotted against a grid value, updated after every run.\n"
    "\n"
    "Exit status: 0 every run exited 0; 1 some run failed (its exit status is in\n"
    "campaign.csv); 2 bad usage, plan or configuration (named FILE:LINE:COLUMN and key; nothing\n"
    "written), or DIR in use or holding something else; 130 interrupted.\n";

enum { MAX_AXES = 16 };

typedef struct {
    char *key;            /* dotted configuration key */
    char **values;        /* scalar texts as written in the plan */
    int *lines, *columns; /* each value's position in the plan */
    int n_values;
    int key_line, key_column; /* the key's position in the plan */
} grid_axis;

typedef struct {
    char *config_path; /* as the runs get it: relative to the plan's folder resolved */
    char **sets;       /* "key=value": plan's set:, then the command line's --set */
    int n_sets;
    int n_plan_sets;              /* the first n_plan_sets of sets are the plan's set: */
    int *set_lines, *set_columns; /* their keys' positions in the plan */
    grid_axis axes[MAX_AXES];
    int n_axes;
    char **seeds; /* decimal texts; n_seeds 0: runs take no --seed */
    int n_seeds;
    int n_runs;
} plan;

static void plan_free(plan *p) {
    free(p->config_path);
    for (int i = 0; i < p->n_sets; i++)
        free(p->sets[i]);
    free(p->sets);
    free(p->set_lines);
    free(p->set_columns);
    for (int a = 0; a < p->n_axes; a++) {
        free(p->axes[a].key);
        for (int i = 0; i < p->axes[a].n_values; i++)
            free(p->axes[a].values[i]);
        free(p->axes[a].values);
        free(p->axes[a].lines);
        free(p->axes[a].columns);
    }
    for (int i = 0; i < p->n_seeds; i++)
        free(p->seeds[i]);
    free(p->seeds);
    memset(p, 0, sizeof *p);
}

/* ---- the plan (libfyaml directly: the configuration reader refuses dotted keys, which the
 * grid's keys are; messages follow its form "FILE:LINE:COL: key 'a.b': what is wrong") ---- */

static void node_position(struct fy_node *n, int *line, int *column) {
    struct fy_token *t = n ? fy_node_get_scalar_token(n) : NULL;
    const struct fy_mark *m = t ? fy_token_start_mark(t) : NULL;
    *line = m ? m->line + 1 : 0;
    *column = m ? m->column + 1 : 0;
}

typedef struct {
    char text[512];
} diag_capture;

static void capture_diag(struct fy_diag *diag, void *user, const char *buf, size_t len) {
    (void)diag;
    diag_capture *c = user;
    if (c->text[0] || !memmem(buf, len, ": error: ", 9)) return;
    while (len && (buf[len - 1] == '\n' || buf[len - 1] == ' '))
        len--;
    if (len >= sizeof c->text) len = sizeof c->text - 1;
    memcpy(c->text, buf, len);
    c->text[len] = 0;
}

/* A scalar's text (NUL-terminated copy) or NULL when the node is not a plain scalar. */
static char *scalar_copy(struct fy_node *n) {
    if (!n || !fy_node_is_scalar(n) || fy_node_is_alias(n)) return NULL;
    size_t len = 0;
    const char *s = fy_node_get_scalar(n, &len);
    return s ? strndup(s, len) : NULL;
}

/* at: the key node the message is about (its position), key: the dotted key named. */
static int plan_error(rths_error *err, const char *file, struct fy_node *at, const char *key,
                      const char *what) {
    int line, column;
    node_position(at, &line, &column);
    return rths_error_set(err, RTHS_EINPUT, "%s:%d:%d: key '%s': %s", file, line, column, key,
                          what);
}

static int valid_dotted_key(const char *k) {
    if (!*k || *k == '.' || k[strlen(k) - 1] == '.' || strstr(k, "..")) return 0;
    for (const char *c = k; *c; c++)
        if (*c == '=' || *c == ' ') return 0;
    return 1;
}

static int read_sets(struct fy_node *map, struct fy_node *keynode, const char *file, plan *p,
                     rths_error *err) {
    if (!fy_node_is_mapping(map))
        return plan_error(err, file, keynode, "set",
                          "must be a mapping of configuration keys to values");
    void *it = NULL;
    struct fy_node_pair *pair;
    int n = fy_node_mapping_item_count(map);
    p->sets = calloc((size_t)n + RTHS_CLI_MAX_SETS + 1, sizeof *p->sets);
    p->set_lines = calloc((size_t)n + 1, sizeof *p->set_lines);
    p->set_columns = calloc((size_t)n + 1, sizeof *p->set_columns);
    if (!p->sets || !p->set_lines || !p->set_columns)
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    while ((pair = fy_node_mapping_iterate(map, &it))) {
        struct fy_node *k = fy_node_pair_key(pair), *v = fy_node_pair_value(pair);
        char *key = scalar_copy(k);
        if (!key || !valid_dotted_key(key)) {
            free(key);
            return plan_error(err, file, k, "set", "keys must be dotted configuration keys");
        }
        char *val = scalar_copy(v);
        if (!val) {
            char name[300];
            snprintf(name, sizeof name, "set.%s", key);
            free(key);
            return plan_error(err, file, k, name, "must be a single value");
        }
        if (asprintf(&p->sets[p->n_sets], "%s=%s", key, val) < 0) p->sets[p->n_sets] = NULL;
        free(key);
        free(val);
        if (!p->sets[p->n_sets]) return rths_error_set(err, RTHS_EFAIL, "out of memory");
        node_position(k, &p->set_lines[p->n_sets], &p->set_columns[p->n_sets]);
        p->n_sets++;
        p->n_plan_sets++;
    }
    return RTHS_OK;
}

static int read_grid(struct fy_node *map, struct fy_node *keynode, const char *file, plan *p,
                     rths_error *err) {
    if (!fy_node_is_mapping(map))
        return plan_error(err, file, keynode, "grid",
                          "must be a mapping of configuration keys to lists of values");
    void *it = NULL;
    struct fy_node_pair *pair;
    while ((pair = fy_node_mapping_iterate(map, &it))) {
        struct fy_node *k = fy_node_pair_key(pair), *v = fy_node_pair_value(pair);
        char *key = scalar_copy(k);
        if (!key || !valid_dotted_key(key)) {
            free(key);
            return plan_error(err, file, k, "grid", "keys must be dotted configuration keys");
        }
        char name[300];
        snprintf(name, sizeof name, "grid.%s", key);
        for (int a = 0; a < p->n_axes; a++)
            if (!strcmp(p->axes[a].key, key)) {
                free(key);
                return plan_error(err, file, k, name, "given twice");
            }
        if (p->n_axes == MAX_AXES) {
            free(key);
            return plan_error(err, file, k, name, "more than 16 grid keys");
        }
        grid_axis *ax = &p->axes[p->n_axes++];
        ax->key = key;
        node_position(k, &ax->key_line, &ax->key_column);
        int n = fy_node_is_sequence(v) ? fy_node_sequence_item_count(v) : 0;
        if (n < 1) return plan_error(err, file, k, name, "must be a non-empty list of values");
        ax->values = calloc((size_t)n, sizeof *ax->values);
        ax->lines = calloc((size_t)n, sizeof *ax->lines);
        ax->columns = calloc((size_t)n, sizeof *ax->columns);
        if (!ax->values || !ax->lines || !ax->columns)
            return rths_error_set(err, RTHS_EFAIL, "out of memory");
        void *it2 = NULL;
        struct fy_node *item;
        while ((item = fy_node_sequence_iterate(v, &it2))) {
            char *val = scalar_copy(item);
            if (!val)
                return plan_error(err, file, k, name,
                                  "every entry must be a single value (no lists or mappings)");
            node_position(item, &ax->lines[ax->n_values], &ax->columns[ax->n_values]);
            ax->values[ax->n_values++] = val;
        }
    }
    return RTHS_OK;
}

static int read_seeds(struct fy_node *seq, struct fy_node *keynode, const char *file, plan *p,
                      rths_error *err) {
    int n = fy_node_is_sequence(seq) ? fy_node_sequence_item_count(seq) : 0;
    if (n < 1)
        return plan_error(err, file, keynode, "seeds", "must be a non-empty list of integers");
    p->seeds = calloc((size_t)n, sizeof *p->seeds);
    if (!p->seeds) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    void *it = NULL;
    struct fy_node *item;
    while ((item = fy_node_sequence_iterate(seq, &it))) {
        char *s = scalar_copy(item), *end = NULL;
        errno = 0;
        unsigned long long v = s && *s && *s != '-' ? strtoull(s, &end, 10) : 0;
        if (!s || !end || *end || errno) {
            char what[300];
            snprintf(what, sizeof what, "'%s' is not an unsigned 64-bit integer",
                     s ? s : "(a list or mapping)");
            free(s);
            return plan_error(err, file, item && s ? item : keynode, "seeds", what);
        }
        free(s);
        if (asprintf(&p->seeds[p->n_seeds], "%llu", v) < 0) p->seeds[p->n_seeds] = NULL;
        if (!p->seeds[p->n_seeds++]) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    return RTHS_OK;
}

static int plan_read(const char *file, const rths_cli *cli, plan *p, rths_error *err) {
    memset(p, 0, sizeof *p);
    diag_capture cap = {{0}};
    struct fy_diag_cfg dcfg;
    fy_diag_cfg_default(&dcfg);
    dcfg.fp = NULL;
    dcfg.output_fn = capture_diag;
    dcfg.user = &cap;
    dcfg.colorize = false;
    struct fy_diag *diag = fy_diag_create(&dcfg);
    if (!diag) return rths_error_set(err, RTHS_EFAIL, "out of memory creating the YAML parser");
    struct fy_parse_cfg pcfg = {.flags = FYPCF_QUIET, .diag = diag};
    if (access(file, R_OK)) {
        fy_diag_destroy(diag);
        return rths_error_set(err, RTHS_EINPUT, "%s: cannot read: %s", file, strerror(errno));
    }
    struct fy_document *doc = fy_document_build_from_file(&pcfg, file);
    int rc = RTHS_OK;
    struct fy_node *root = doc ? fy_document_root(doc) : NULL;
    if (!doc) {
        /* libfyaml's "FILE:LINE:COL: error: what" */
        const char *sep = strstr(cap.text, ": error: ");
        if (sep)
            rc = rths_error_set(err, RTHS_EINPUT, "%.*s: not valid YAML: %s", (int)(sep - cap.text),
                                cap.text, sep + 9);
        else
            rc = rths_error_set(err, RTHS_EINPUT, "%s: not valid YAML", file);
        goto done;
    }
    if (!root || !fy_node_is_mapping(root)) {
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s: a plan is a mapping with config, grid, seeds and set", file);
        goto done;
    }
    struct fy_node *config_key = NULL;
    void *it = NULL;
    struct fy_node_pair *pair;
    while ((pair = fy_node_mapping_iterate(root, &it))) {
        struct fy_node *k = fy_node_pair_key(pair), *v = fy_node_pair_value(pair);
        char *key = scalar_copy(k);
        if (!key) {
            rc = plan_error(err, file, k, "?", "keys must be plain names");
            goto done;
        }
        if (!strcmp(key, "config")) {
            config_key = k;
            char *c = scalar_copy(v);
            if (!c || !*c) {
                free(c);
                rc = plan_error(err, file, k, "config", "must be the configuration's file name");
            } else if (c[0] == '/') {
                p->config_path = c;
            } else {
                char *copy = strdup(file);
                const char *dir = copy ? dirname(copy) : ".";
                if (asprintf(&p->config_path, "%s/%s", dir, c) < 0) p->config_path = NULL;
                free(copy);
                free(c);
                if (!p->config_path) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
            }
        } else if (!strcmp(key, "set")) {
            rc = read_sets(v, k, file, p, err);
        } else if (!strcmp(key, "grid")) {
            rc = read_grid(v, k, file, p, err);
        } else if (!strcmp(key, "seeds")) {
            rc = read_seeds(v, k, file, p, err);
        } else {
            rc = plan_error(err, file, k, key,
                            "unknown key (a plan has config, set, grid and seeds)");
        }
        free(key);
        if (rc) goto done;
    }
    if (!config_key) {
        rc = rths_error_set(err, RTHS_EINPUT, "%s: key 'config' (the configuration) is missing",
                            file);
        goto done;
    }
    if (!p->sets && !(p->sets = calloc(RTHS_CLI_MAX_SETS + 1, sizeof *p->sets))) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    for (int i = 0; i < cli->n_sets; i++)
        if (!(p->sets[p->n_sets++] = strdup(cli->sets[i]))) {
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
            goto done;
        }
    if (p->n_sets + p->n_axes > RTHS_CLI_MAX_SETS) {
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s: %d overrides (set:, --set and grid keys) per run, at most %d",
                            file, p->n_sets + p->n_axes, RTHS_CLI_MAX_SETS);
        goto done;
    }
    long runs = p->n_seeds ? p->n_seeds : 1;
    for (int a = 0; a < p->n_axes && runs <= 1000000; a++)
        runs *= p->axes[a].n_values;
    if (runs > 1000000) {
        rc = rths_error_set(err, RTHS_EINPUT, "%s: the grid and seeds make more than 1000000 runs",
                            file);
        goto done;
    }
    p->n_runs = (int)runs;
done:
    if (doc) fy_document_destroy(doc);
    fy_diag_destroy(diag);
    if (rc) plan_free(p);
    return rc;
}

/* Run k's grid value indices (last axis fastest) and seed index (fastest of all). */
static void run_indices(const plan *p, int k, int *value_index, int *seed_index) {
    int per_seed = p->n_seeds ? p->n_seeds : 1;
    *seed_index = k % per_seed;
    int c = k / per_seed;
    for (int a = p->n_axes - 1; a >= 0; a--) {
        value_index[a] = c % p->axes[a].n_values;
        c /= p->axes[a].n_values;
    }
}

/* Run k's overrides ("key=value", malloc'ed each, *n of them): the plan's and the grid's. */
static int run_overrides(const plan *p, int k, char **out, int *n) {
    int vi[MAX_AXES], si;
    run_indices(p, k, vi, &si);
    *n = 0;
    for (int i = 0; i < p->n_sets; i++)
        if (!(out[(*n)++] = strdup(p->sets[i]))) return -1;
    for (int a = 0; a < p->n_axes; a++)
        if (asprintf(&out[(*n)++], "%s=%s", p->axes[a].key, p->axes[a].values[vi[a]]) < 0)
            return out[*n - 1] = NULL, -1;
    return 0;
}

static void free_strings(char **s, int n) {
    for (int i = 0; i < n; i++)
        free(s[i]);
}

/* Every grid value, then every grid combination, is loaded with the configuration and its
 * structure read before anything is written, so a bad value is refused naming its place in the
 * plan (or its run) and key instead of failing run by run. */
static int check_overrides(const plan *p, char **sets, int n, rths_error *e) {
    rths_cli c = {.config_path = p->config_path};
    for (int i = 0; i < n; i++)
        c.sets[i] = sets[i];
    c.n_sets = n;
    rths_api_command_config *cfg = NULL;
    int rc = rths_cli_load(&c, RTHS_API_READ_SETUP, &cfg, e);
    rths_api_command_config_free(cfg);
    return rc;
}

static int plan_check_runs(const plan *p, const char *plan_file, rths_error *err) {
    char *sets[RTHS_CLI_MAX_SETS];
    rths_error e = {0};
    int rc = check_overrides(p, p->sets, p->n_sets, &e);
    if (rc)
        return rths_error_set(err, rc, "%s: config %s%s: %s", plan_file, p->config_path,
                              p->n_sets ? " with set: and --set" : "", e.msg);
    for (int a = 0; a < p->n_axes; a++)
        for (int v = 0; v < p->axes[a].n_values; v++) {
            int n = 0;
            for (; n < p->n_sets; n++)
                sets[n] = p->sets[n];
            char one[4096];
            snprintf(one, sizeof one, "%s=%s", p->axes[a].key, p->axes[a].values[v]);
            sets[n++] = one;
            if ((rc = check_overrides(p, sets, n, &e)))
                return rths_error_set(err, rc, "%s:%d:%d: key 'grid.%s': value '%s': %s", plan_file,
                                      p->axes[a].lines[v], p->axes[a].columns[v], p->axes[a].key,
                                      p->axes[a].values[v], e.msg);
        }
    int per_seed = p->n_seeds ? p->n_seeds : 1;
    for (int k = 0; k < p->n_runs; k += per_seed) {
        int n = 0;
        if (run_overrides(p, k, sets, &n)) {
            free_strings(sets, n);
            return rths_error_set(err, RTHS_EFAIL, "out of memory");
        }
        rc = check_overrides(p, sets, n, &e);
        free_strings(sets, n);
        if (rc)
            return rths_error_set(err, rc, "%s: run_%04d (config %s): %s", plan_file, k,
                                  p->config_path, e.msg);
    }
    return RTHS_OK;
}

/* ---- CSV ---- */

static void csv_field(FILE *f, const char *s) {
    if (!strpbrk(s, ",\"\n\r")) {
        fputs(s, f);
        return;
    }
    fputc('"', f);
    for (; *s; s++) {
        if (*s == '"') fputc('"', f);
        fputc(*s, f);
    }
    fputc('"', f);
}

/* The columns identifying run k: run, the grid values, seed. */
static void write_run_id(FILE *f, const plan *p, int k) {
    int vi[MAX_AXES], si;
    run_indices(p, k, vi, &si);
    fprintf(f, "run_%04d", k);
    for (int a = 0; a < p->n_axes; a++) {
        fputc(',', f);
        csv_field(f, p->axes[a].values[vi[a]]);
    }
    fprintf(f, ",%s", p->n_seeds ? p->seeds[si] : "");
}

static void write_id_header(FILE *f, const plan *p) {
    fputs("run", f);
    for (int a = 0; a < p->n_axes; a++) {
        fputc(',', f);
        csv_field(f, p->axes[a].key);
    }
    fputs(",seed", f);
}

/* runs.csv, the index, as text (malloc'ed). */
static char *runs_index_text(const plan *p) {
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (!f) return NULL;
    write_id_header(f, p);
    fputc('\n', f);
    for (int k = 0; k < p->n_runs; k++) {
        write_run_id(f, p, k);
        fputc('\n', f);
    }
    if (fclose(f)) {
        free(buf);
        return NULL;
    }
    return buf;
}

/* plan.txt: what makes the runs what they are (the configuration file, the overrides of every
 * run, the index), compared when a campaign is taken up again: a finished run is kept only for
 * the same plan. malloc'ed. */
static char *plan_identity_text(const plan *p, const char *index) {
    char *buf = NULL, *real = realpath(p->config_path, NULL);
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (f) {
        fprintf(f, "config: %s\n", real ? real : p->config_path);
        for (int i = 0; i < p->n_sets; i++)
            fprintf(f, "set: %s\n", p->sets[i]);
        fprintf(f, "runs:\n%s", index);
        if (fclose(f)) {
            free(buf);
            buf = NULL;
        }
    }
    free(real);
    return buf;
}

/* ---- the campaign folder ---- */

typedef struct {
    const char *dir;
    const plan *p;
    char **results; /* per run: the result columns of campaign.csv, NULL while unfinished */
    int finished, failed;
    int quiet;
} campaign;

static char *path_of(const char *dir, const char *fmt, int k) {
    char name[64], *out = NULL;
    snprintf(name, sizeof name, fmt, k);
    if (asprintf(&out, "%s/%s", dir, name) < 0) return NULL;
    return out;
}

static double json_number(json_object *root, const char *key, int *ok) {
    json_object *v;
    if (!json_object_object_get_ex(root, key, &v) ||
        !(json_object_is_type(v, json_type_double) || json_object_is_type(v, json_type_int))) {
        *ok = 0;
        return 0;
    }
    return json_object_get_double(v);
}

/* Run k's result columns from its exit status and summary.json; NULL when the run is not
 * finished (no summary.json). */
static char *result_columns(const char *dir, int k, int exit_status) {
    char *path = path_of(dir, "run_%04d/summary.json", k), *out = NULL;
    json_object *s = path ? json_object_from_file(path) : NULL;
    free(path);
    if (!s) return NULL;
    int ok = 1;
    double points = json_number(s, "points", &ok),
           converged = json_number(s, "converged_points", &ok),
           evaluations = json_number(s, "evaluations_total", &ok),
           rig_time = json_number(s, "rig_time_s", &ok);
    int ok_truth = 1;
    double worst = json_number(s, "max_relative_error_vs_truth", &ok_truth),
           compared = json_number(s, "points_compared_with_truth", &ok_truth),
           within3 = json_number(s, "points_within_3_standard_errors", &ok_truth);
    json_object_put(s);
    if (!ok) {
        if (asprintf(&out, "%d,,,,,,", exit_status) < 0) out = NULL;
        return out;
    }
    char truth[128] = ",";
    if (ok_truth && compared > 0)
        snprintf(truth, sizeof truth, "%.17g,%.17g", worst, within3 / compared);
    if (asprintf(&out, "%d,%.17g,%.17g,%.17g,%.17g,%s", exit_status, points, converged, evaluations,
                 rig_time, truth) < 0)
        out = NULL;
    return out;
}

static int write_campaign_csv(const campaign *c, rths_error *err) {
    char *path;
    if (asprintf(&path, "%s/campaign.csv", c->dir) < 0)
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    /* built in memory, then written as every run folder's files are (rths_api_write_file) */
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    if (!f) {
        free(path);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    write_id_header(f, c->p);
    fputs(",exit_status,points,converged_points,evaluations,rig_time_s,"
          "max_relative_error_vs_truth,share_within_3_standard_errors\n",
          f);
    for (int k = 0; k < c->p->n_runs; k++) {
        write_run_id(f, c->p, k);
        fprintf(f, ",%s\n", c->results[k] ? c->results[k] : ",,,,,,");
    }
    int rc = fclose(f) || !text ? rths_error_set(err, RTHS_EFAIL, "out of memory")
                                : rths_api_write_file(path, text, len, err);
    free(text);
    free(path);
    return rc;
}

static int remove_entry(const char *path, const struct stat *st, int type, struct FTW *ftw) {
    (void)st;
    (void)type;
    (void)ftw;
    return remove(path);
}

/* ---- every grid value through the run's own readers ---- */

static int cancel_at_once(void *user) {
    (void)user;
    return 1;
}

/* The run of the combination vi (value index per grid axis) with the first seed. */
static int run_of(const plan *p, const int *vi) {
    int k = 0;
    for (int a = 0; a < p->n_axes; a++)
        k = k * p->axes[a].n_values + vi[a];
    return k * (p->n_seeds ? p->n_seeds : 1);
}

/* An error of the configuration reader about one of the overrides starts with "--set K=V:" (how
 * the reader locates a value given by --set): said again at its place in the plan, the key for
 * an unknown key, the value for a bad one. Anything else names the run. */
static int locate_in_plan(const plan *p, const char *plan_file, const int *vi, char *const *sets,
                          int n, const rths_error *e, rths_error *err) {
    for (int i = 0; i < n; i++) {
        size_t len = strlen(sets[i]);
        if (strncmp(e->msg, "--set ", 6) || strncmp(e->msg + 6, sets[i], len) ||
            e->msg[6 + len] != ':')
            continue;
        if (i < p->n_plan_sets) {
            const char *eq = strchr(sets[i], '=');
            return rths_error_set(err, e->code, "%s:%d:%d: key 'set.%.*s': %s", plan_file,
                                  p->set_lines[i], p->set_columns[i],
                                  (int)(eq ? eq - sets[i] : (ptrdiff_t)len), sets[i], e->msg);
        }
        if (i < p->n_sets) break; /* the command line's --set: the message says so */
        const grid_axis *ax = &p->axes[i - p->n_sets];
        if (strstr(e->msg, ": unknown key '"))
            return rths_error_set(err, e->code, "%s:%d:%d: key 'grid.%s': %s", plan_file,
                                  ax->key_line, ax->key_column, ax->key, e->msg);
        int v = vi[i - p->n_sets];
        return rths_error_set(err, e->code, "%s:%d:%d: key 'grid.%s': value '%s': %s", plan_file,
                              ax->lines[v], ax->columns[v], ax->key, ax->values[v], e->msg);
    }
    return rths_error_set(err, e->code, "%s: run_%04d (config %s): %s", plan_file, run_of(p, vi),
                          p->config_path, e->msg);
}

/* The combination vi started through the library's FRF test (rths_api_frf: the same readers and
 * checks as `rths frf`) in the scratch folder and cancelled before its first point. The run's
 * warnings (e.g. no mode in the sweep) go to stderr: held, and said unless quiet. */
static int check_combination(const plan *p, const char *plan_file, const int *vi,
                             const char *scratch, int quiet, rths_error *err) {
    char *sets[RTHS_CLI_MAX_SETS], *out = NULL;
    int n = 0;
    for (int i = 0; i < p->n_sets; i++)
        if (!(sets[n++] = strdup(p->sets[i]))) goto oom;
    for (int a = 0; a < p->n_axes; a++)
        if (asprintf(&sets[n++], "%s=%s", p->axes[a].key, p->axes[a].values[vi[a]]) < 0) {
            sets[n - 1] = NULL;
            goto oom;
        }
    if (asprintf(&out, "%s/run_%04d", scratch, run_of(p, vi)) < 0) goto oom;
    rths_error e = {0};
    rths_api_config *cfg = NULL;
    int rc = rths_api_config_load(p->config_path, (const char *const *)sets, n, &cfg, &e);
    if (!rc) {
        rths_api_frf_options o;
        rths_api_frf_options_default(&o);
        o.out_dir = out;
        o.should_cancel = cancel_at_once;
        if (p->n_seeds) {
            o.has_seed = 1;
            o.seed = strtoull(p->seeds[0], NULL, 10);
        }
        rths_result *r = NULL;
        fflush(stderr);
        FILE *held = tmpfile();
        int saved = held ? dup(STDERR_FILENO) : -1;
        if (saved >= 0) dup2(fileno(held), STDERR_FILENO);
        rc = rths_api_frf(cfg, &o, &r, &e);
        rths_result_free(r);
        fflush(stderr);
        if (saved >= 0) {
            dup2(saved, STDERR_FILENO);
            close(saved);
            char line[1024];
            rewind(held);
            while (!quiet && fgets(line, sizeof line, held))
                fprintf(stderr, "rths campaign: run_%04d (checked before the campaign): %s",
                        run_of(p, vi), line);
        }
        if (held) fclose(held);
    }
    rths_api_config_free(cfg);
    if (rc) rc = locate_in_plan(p, plan_file, vi, sets, n, &e, err);
    free_strings(sets, n);
    free(out);
    return rc;
oom:
    free_strings(sets, n);
    return rths_error_set(err, RTHS_EFAIL, "out of memory");
}

/* Before the campaign writes anything, every grid value is read by the run's own readers (every
 * section a run reads, key by key): run 0's combination, then each other value of each grid key
 * in run 0's combination. So a grid or set: key no reader asks for (a typo: split.mas_ratio,
 * controller.kp_v_per_mm) is refused with the reader's "did you mean", and so is any value a
 * run's reader refuses (not only the structure's, plan_check_runs), named at its place in the
 * plan. About 0.1-0.2 s per value (docs/campaign.md). */
static int plan_check_values(const plan *p, const char *plan_file, int quiet, rths_error *err) {
    if (!rths_api_frf_available()) return RTHS_OK;
    const char *tmp_root = getenv("TMPDIR");
    char *scratch = NULL;
    if (asprintf(&scratch, "%s/rths-campaign-check.XXXXXX",
                 tmp_root && *tmp_root ? tmp_root : "/tmp") < 0)
        scratch = NULL;
    if (!scratch || !mkdtemp(scratch)) {
        int e = errno;
        free(scratch);
        return rths_error_set(err, RTHS_EFAIL,
                              "cannot create a scratch folder to check the plan's values: %s",
                              strerror(e));
    }
    int vi0[MAX_AXES], vi[MAX_AXES], si;
    run_indices(p, 0, vi0, &si);
    int rc = check_combination(p, plan_file, vi0, scratch, quiet, err);
    for (int a = 0; a < p->n_axes && !rc; a++)
        for (int v = 0; v < p->axes[a].n_values && !rc; v++) {
            if (v == vi0[a]) continue;
            memcpy(vi, vi0, sizeof vi);
            vi[a] = v;
            rc = check_combination(p, plan_file, vi, scratch, 1, err);
        }
    nftw(scratch, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
    free(scratch);
    return rc;
}

/* Recorded exit status of run k, or -1. */
static int read_status(const char *dir, int k) {
    char *path = path_of(dir, "logs/run_%04d.status", k);
    FILE *f = path ? fopen(path, "r") : NULL;
    free(path);
    int status = -1;
    if (f) {
        if (fscanf(f, "exit %d", &status) != 1) status = -1;
        fclose(f);
    }
    return status;
}

/* Run k ended with exit status `status`: recorded, unless it was interrupted (it runs again). */
static int record_run(campaign *c, int k, int status, rths_error *err) {
    if (status == 130 || status >= 128 + 1) {
        if (!c->quiet)
            fprintf(stderr, "rths campaign: run_%04d interrupted (status %d): left unfinished\n", k,
                    status);
        return RTHS_OK;
    }
    char *path = path_of(c->dir, "logs/run_%04d.status", k), text[32];
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int n = snprintf(text, sizeof text, "exit %d\n", status);
    int rc = rths_api_write_file(path, text, (size_t)n, err);
    free(path);
    if (rc) return rc;
    free(c->results[k]);
    c->results[k] = result_columns(c->dir, k, status);
    if (!c->results[k] && asprintf(&c->results[k], "%d,,,,,,", status) < 0) c->results[k] = NULL;
    c->finished++;
    if (status) c->failed++;
    if (status) {
        /* a failure is said even with --quiet, with the run's first message */
        char *log = path_of(c->dir, "logs/run_%04d.log", k), line[512] = "";
        FILE *f = log ? fopen(log, "r") : NULL;
        if (f) {
            if (!fgets(line, sizeof line, f)) line[0] = 0;
            fclose(f);
        }
        free(log);
        line[strcspn(line, "\r\n")] = 0;
        fprintf(stderr, "rths campaign: run_%04d failed, exit %d%s%s (logs/run_%04d.log)\n", k,
                status, line[0] ? ": " : "", line, k);
    }
    if (!c->quiet)
        fprintf(stderr, "rths campaign: run_%04d exit %d (%d of %d finished)\n", k, status,
                c->finished, c->p->n_runs);
    return write_campaign_csv(c, err);
}

/* Creates DIR (or takes up the campaign in it), locks it, writes runs.csv, finds the finished
 * runs and lists the others in *todo (the unfinished folders and status files removed).
 * *lock_fd holds the lock for the campaign's life. */
static int campaign_open(campaign *c, int *todo, int *n_todo, int *lock_fd, rths_error *err) {
    const plan *p = c->p;
    *lock_fd = -1;
    char *index = runs_index_text(p), *path = NULL;
    char *identity = index ? plan_identity_text(p, index) : NULL;
    if (!identity) {
        free(index);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    int rc = RTHS_OK, existing = 0;
    struct stat st;
    if (!stat(c->dir, &st)) {
        if (!S_ISDIR(st.st_mode)) {
            rc = rths_error_set(err, RTHS_EINPUT, "--out %s: exists and is not a folder", c->dir);
            goto done;
        }
        if (asprintf(&path, "%s/plan.txt", c->dir) < 0) goto oom;
        FILE *f = fopen(path, "r");
        free(path);
        path = NULL;
        if (f) {
            char *old = NULL;
            size_t cap = 0;
            ssize_t len = getdelim(&old, &cap, '\0', f);
            fclose(f);
            int same =
                len >= 0 && (size_t)len == strlen(identity) && !memcmp(old, identity, (size_t)len);
            free(old);
            if (!same) {
                rc = rths_error_set(err, RTHS_EINPUT,
                                    "--out %s: holds a campaign of another plan (its plan.txt: "
                                    "configuration, overrides or runs differ); choose another "
                                    "folder",
                                    c->dir);
                goto done;
            }
            existing = 1;
        } else {
            /* an empty folder is taken; anything else is not a campaign */
            int entries = 0;
            DIR *d = opendir(c->dir);
            for (struct dirent *e; d && (e = readdir(d));)
                if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) entries++;
            if (d) closedir(d);
            if (entries) {
                rc = rths_error_set(err, RTHS_EINPUT,
                                    "--out %s: exists and holds no campaign (no plan.txt); "
                                    "choose another folder",
                                    c->dir);
                goto done;
            }
        }
    } else if (mkdir(c->dir, 0777)) {
        rc =
            rths_error_set(err, RTHS_EFAIL, "--out %s: cannot create: %s", c->dir, strerror(errno));
        goto done;
    }
    if (asprintf(&path, "%s/campaign.lock", c->dir) < 0) goto oom;
    *lock_fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    free(path);
    path = NULL;
    if (*lock_fd < 0 || flock(*lock_fd, LOCK_EX | LOCK_NB)) {
        rc =
            rths_error_set(err, RTHS_EINPUT, "--out %s: another campaign is running in it", c->dir);
        goto done;
    }
    if (asprintf(&path, "%s/logs", c->dir) < 0) goto oom;
    if (mkdir(path, 0777) && errno != EEXIST) {
        rc = rths_error_set(err, RTHS_EFAIL, "%s: cannot create: %s", path, strerror(errno));
        goto done;
    }
    free(path);
    if (asprintf(&path, "%s/runs.csv", c->dir) < 0) goto oom;
    if (!existing && (rc = rths_api_write_file(path, index, strlen(index), err))) goto done;
    free(path);
    /* written last: a folder with plan.txt has its index */
    if (asprintf(&path, "%s/plan.txt", c->dir) < 0) goto oom;
    if (!existing && (rc = rths_api_write_file(path, identity, strlen(identity), err))) goto done;
    *n_todo = 0;
    int kept = 0;
    for (int k = 0; k < p->n_runs; k++) {
        int status = read_status(c->dir, k);
        char *res = status >= 0 ? result_columns(c->dir, k, status) : NULL;
        if (res) {
            c->results[k] = res;
            c->finished++;
            if (status) c->failed++;
            kept++;
            continue;
        }
        todo[(*n_todo)++] = k;
        char *run = path_of(c->dir, "run_%04d", k),
             *st_path = path_of(c->dir, "logs/run_%04d.status", k);
        if (!run || !st_path) {
            free(run);
            free(st_path);
            goto oom;
        }
        if (!access(run, F_OK)) nftw(run, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
        unlink(st_path);
        free(run);
        free(st_path);
    }
    if (existing)
        fprintf(stderr,
                "rths campaign: resuming the campaign in %s: %d finished run(s) kept, %d to run\n",
                c->dir, kept, *n_todo);
    rc = write_campaign_csv(c, err);
    goto done;
oom:
    rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
done:
    free(path);
    free(index);
    free(identity);
    return rc;
}

/* ---- running ---- */

static volatile sig_atomic_t interrupted;

static void on_interrupt(int sig) {
    interrupted = sig;
}

/* Starts run k: this binary as `rths frf`, its messages in logs/run_K.log. The run dies with
 * this process (PR_SET_PDEATHSIG), so a killed campaign leaves no run holding its folder. */
static pid_t spawn_run(const char *self, const campaign *c, int k) {
    const plan *p = c->p;
    char *sets[RTHS_CLI_MAX_SETS];
    int n_sets = 0;
    char *out = path_of(c->dir, "run_%04d", k), *log = path_of(c->dir, "logs/run_%04d.log", k);
    int vi[MAX_AXES], si;
    run_indices(p, k, vi, &si);
    pid_t parent = getpid(), pid = -1;
    if (!out || !log || run_overrides(p, k, sets, &n_sets)) goto done;
    char *argv[8 + 2 * RTHS_CLI_MAX_SETS];
    int a = 0;
    argv[a++] = (char *)"rths";
    argv[a++] = (char *)"frf";
    argv[a++] = p->config_path;
    argv[a++] = (char *)"--out";
    argv[a++] = out;
    argv[a++] = (char *)"--quiet";
    if (p->n_seeds) {
        argv[a++] = (char *)"--seed";
        argv[a++] = p->seeds[si];
    }
    for (int i = 0; i < n_sets; i++) {
        argv[a++] = (char *)"--set";
        argv[a++] = sets[i];
    }
    argv[a] = NULL;
    fflush(NULL);
    pid = fork();
    if (pid == 0) {
        signal(SIGINT, SIG_DFL);
        signal(SIGTERM, SIG_DFL);
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (getppid() != parent) _exit(127);
        int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0666);
        if (fd >= 0) {
            dup2(fd, STDOUT_FILENO);
            dup2(fd, STDERR_FILENO);
            close(fd);
        }
        execv(self, argv);
        fprintf(stderr, "rths campaign: cannot execute %s: %s\n", self, strerror(errno));
        _exit(127);
    }
done:
    free_strings(sets, n_sets);
    free(out);
    free(log);
    return pid;
}

static int exit_status_of(int wstatus) {
    if (WIFEXITED(wstatus)) return WEXITSTATUS(wstatus);
    if (WIFSIGNALED(wstatus)) return 128 + WTERMSIG(wstatus);
    return 1;
}

/* The runs of todo, at most jobs at a time, the next started as soon as one ends. */
static int run_local(const char *self, campaign *c, const int *todo, int n_todo, int jobs,
                     rths_error *err) {
    pid_t *pids = calloc((size_t)jobs, sizeof *pids);
    int *runs = calloc((size_t)jobs, sizeof *runs), next = 0, running = 0, rc = RTHS_OK;
    if (!pids || !runs) {
        free(pids);
        free(runs);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    while (running || (next < n_todo && !interrupted && !rc)) {
        while (running < jobs && next < n_todo && !interrupted && !rc) {
            int slot = 0;
            while (pids[slot])
                slot++;
            int k = todo[next++];
            pid_t pid = spawn_run(self, c, k);
            if (pid < 0) {
                rc = rths_error_set(err, RTHS_EFAIL, "cannot start run_%04d: %s", k,
                                    strerror(errno));
                break;
            }
            pids[slot] = pid;
            runs[slot] = k;
            running++;
        }
        if (!running) break;
        int ws;
        pid_t pid = waitpid(-1, &ws, 0);
        if (pid < 0) {
            if (errno == EINTR) {
                /* the runs were sent the signal too when it came from the terminal; one sent
                 * to this process alone is passed on, so they save and stop */
                for (int s = 0; s < jobs; s++)
                    if (pids[s]) kill(pids[s], SIGTERM);
                continue;
            }
            rc = rths_error_set(err, RTHS_EFAIL, "waiting for the runs: %s", strerror(errno));
            break;
        }
        for (int s = 0; s < jobs; s++)
            if (pids[s] == pid) {
                pids[s] = 0;
                running--;
                int r = record_run(c, runs[s], exit_status_of(ws), err);
                if (r && !rc) rc = r;
            }
    }
    free(pids);
    free(runs);
    return rc;
}

#ifdef RTHS_HAVE_MPI
/* Runs one run to its end (a worker of the MPI job): its exit status. */
static int run_to_end(const char *self, const campaign *c, int k) {
    pid_t pid = spawn_run(self, c, k);
    if (pid < 0) return 1;
    int ws, told = 0;
    while (waitpid(pid, &ws, 0) < 0) {
        if (errno != EINTR) return 1;
        /* mpirun passes SIGINT/SIGTERM on to the ranks, not to their runs */
        if (interrupted && !told) told = !kill(pid, SIGTERM);
    }
    return exit_status_of(ws);
}

enum { TAG_RESULT = 1, TAG_WORK = 2 };

/* Rank 0: hands out todo's runs one at a time to the ranks that ask (a worker's first message
 * carries no result), records each result, tells every worker to stop when none is left. */
static int mpi_coordinate(campaign *c, const int *todo, int n_todo, int n_ranks, rths_error *err) {
    int next = 0, active = n_ranks - 1, rc = RTHS_OK;
    while (active) {
        int msg[2]; /* run, exit status; run -1: ready for the first */
        MPI_Status st;
        MPI_Recv(msg, 2, MPI_INT, MPI_ANY_SOURCE, TAG_RESULT, MPI_COMM_WORLD, &st);
        if (msg[0] >= 0) {
            int r = record_run(c, msg[0], msg[1], err);
            if (r && !rc) rc = r;
        }
        int work = (next < n_todo && !interrupted && !rc) ? todo[next++] : -1;
        if (work < 0) active--;
        MPI_Send(&work, 1, MPI_INT, st.MPI_SOURCE, TAG_WORK, MPI_COMM_WORLD);
    }
    return rc;
}

static void mpi_work(const char *self, const campaign *c) {
    int msg[2] = {-1, 0};
    for (;;) {
        MPI_Send(msg, 2, MPI_INT, 0, TAG_RESULT, MPI_COMM_WORLD);
        int work;
        MPI_Recv(&work, 1, MPI_INT, 0, TAG_WORK, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (work < 0) return;
        msg[0] = work;
        msg[1] = run_to_end(self, c, work);
    }
}
#endif

int rths_cmd_campaign(int argc, char **argv) {
    int rank = 0, n_ranks = 1;
#ifdef RTHS_HAVE_MPI
    /* only under a launcher: a plain `rths campaign` must not need MPI's runtime */
    int under_mpi = getenv("OMPI_COMM_WORLD_SIZE") || getenv("PMI_SIZE") || getenv("PMIX_RANK");
    if (under_mpi) {
        MPI_Init(&argc, &argv);
        MPI_Comm_rank(MPI_COMM_WORLD, &rank);
        MPI_Comm_size(MPI_COMM_WORLD, &n_ranks);
    }
#endif
    rths_cli cli;
    enum { OPT_JOBS, N_OPTS };
    rths_cli_opt opts[N_OPTS] = {[OPT_JOBS] = {"--jobs", "J", NULL}};
    rths_error err = {0};
    plan p = {0};
    campaign c = {0};
    int lock_fd = -1, *todo = NULL, n_todo = 0;
    long jobs = 1;
    int rc = rths_cli_parse(&cli, argc, argv, RTHS_CLI_CONFIG | RTHS_CLI_OUT, usage, opts, N_OPTS);
    if (rc || cli.help) goto end;
    if (cli.has_seed) {
        rc = rths_cli_fail(
            &cli,
            rths_error_set(&err, RTHS_EINPUT, "option --seed: the seeds are the plan's (seeds:)"),
            &err);
        goto end;
    }
    if (opts[OPT_JOBS].value &&
        (rc = rths_cli_int("--jobs", opts[OPT_JOBS].value, 1, 1024, &jobs, &err))) {
        rc = rths_cli_fail(&cli, rc, &err);
        goto end;
    }
    if ((rc = plan_read(cli.config_path, &cli, &p, &err))) {
        if (rank == 0) rths_cli_fail(&cli, rc, &err); /* every rank reads it: one says why */
        goto end;
    }
    char self[PATH_MAX];
    ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
    if (len <= 0) {
        rc = rths_cli_fail(&cli, rths_error_set(&err, RTHS_EFAIL, "cannot find the rths binary"),
                           &err);
        goto end;
    }
    self[len] = 0;
    c.dir = cli.out_dir;
    c.p = &p;
    c.quiet = cli.quiet;
    /* rank 0 alone checks the plan's runs and opens the folder; the others learn the outcome */
    if (rank == 0) {
        c.results = calloc((size_t)p.n_runs, sizeof *c.results);
        todo = calloc((size_t)p.n_runs, sizeof *todo);
        if (!c.results || !todo)
            rc = rths_error_set(&err, RTHS_EFAIL, "out of memory");
        else if (!(rc = plan_check_runs(&p, cli.config_path, &err)) &&
                 !(rc = plan_check_values(&p, cli.config_path, cli.quiet, &err)))
            rc = campaign_open(&c, todo, &n_todo, &lock_fd, &err);
        if (rc) rths_cli_fail(&cli, rc, &err);
    }
#ifdef RTHS_HAVE_MPI
    if (n_ranks > 1) MPI_Bcast(&rc, 1, MPI_INT, 0, MPI_COMM_WORLD);
#endif
    if (rc) goto end;
    /* without SA_RESTART, so that waitpid returns and the runs in progress are told */
    struct sigaction sa = {.sa_handler = on_interrupt};
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    if (rank == 0 && !cli.quiet)
        fprintf(stderr, "rths campaign: %d run(s) of %s, %d to run, %s\n", p.n_runs, p.config_path,
                n_todo,
                n_ranks > 1 ? "shared between the MPI ranks"
                            : (jobs > 1 ? "in parallel processes" : "one at a time"));
#ifdef RTHS_HAVE_MPI
    if (n_ranks > 1) {
        if (rank == 0)
            rc = mpi_coordinate(&c, todo, n_todo, n_ranks, &err);
        else
            mpi_work(self, &c);
    } else
#endif
        rc = run_local(self, &c, todo, n_todo, (int)jobs, &err);
    if (rank == 0) {
        if (rc)
            rths_cli_fail(&cli, rc, &err);
        else if (interrupted) {
            fprintf(stderr,
                    "rths campaign: interrupted; %d of %d runs finished, kept in %s (running the "
                    "same command again resumes)\n",
                    c.finished, p.n_runs, c.dir);
            rc = 130;
        } else {
            rths_cli_print(&cli, "%d runs, %d failed; campaign.csv in %s\n", p.n_runs, c.failed,
                           c.dir);
            rc = c.failed ? RTHS_EFAIL : RTHS_OK;
        }
    }
end:
#ifdef RTHS_HAVE_MPI
    if (under_mpi) {
        if (n_ranks > 1) MPI_Bcast(&rc, 1, MPI_INT, 0, MPI_COMM_WORLD);
        MPI_Finalize();
    }
#endif
    if (c.results)
        for (int k = 0; k < p.n_runs; k++)
            free(c.results[k]);
    free(c.results);
    free(todo);
    plan_free(&p);
    if (lock_fd >= 0) close(lock_fd);
    return rc;
}
