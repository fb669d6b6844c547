/* rths_api_frf: the FRF test (rths frf) behind the C API, a thin layer over the run module's
 * rths_run_frf (include/rths/run.h), which holds the test's orchestration for the CLI and the API
 * alike. A library built without that module answers rths_api_frf_available() == 0. */
#include "api/api_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__has_include)
#if __has_include("rths/run.h")
#define RTHS_API_HAVE_RUN 1
#endif
#endif

void rths_api_frf_options_default(rths_api_frf_options *o) {
    memset(o, 0, sizeof *o);
    o->strategy = "default";
}

#ifndef RTHS_API_HAVE_RUN

int rths_api_frf_available(void) {
    return 0;
}

int rths_api_frf(const rths_api_config *cfg, const rths_api_frf_options *o, rths_result **out,
                 rths_error *err) {
    *out = NULL;
    if (!cfg || !o || !o->out_dir)
        return rths_error_set(err, RTHS_EINPUT, "rths_api_frf needs a configuration and out_dir");
    return rths_error_set(err, RTHS_EFAIL,
                          "this librths has no FRF run (the run module, include/rths/run.h, is "
                          "not built in)");
}

int rths_api_frf_run(rths_api_command_config *c, const rths_api_frf_run_options *o,
                     rths_api_frf_run_summary *r, rths_error *err) {
    (void)c, (void)o;
    memset(r, 0, sizeof *r);
    return rths_error_set(err, RTHS_EFAIL,
                          "this librths has no FRF run (the run module, include/rths/run.h, is "
                          "not built in)");
}

const char *const *rths_api_frf_paper_overrides(int *n) {
    *n = 0;
    return NULL;
}

#else

#include "rths/run.h"

#include <inttypes.h>

int rths_api_frf_available(void) {
    return 1;
}

_Static_assert(RTHS_API_FRF_MAX_HARMONICS == RTHS_MAX_MATCHED_HARMONICS,
               "rths.h's --harmonics limit is the matched harmonics'");
_Static_assert(RTHS_API_MAX_INTERFACE_DOFS == RTHS_MAX_INTERFACE_DOFS,
               "rths.h's interface DoF limit is the library's");

const char *const *rths_api_frf_paper_overrides(int *n) {
    *n = RTHS_RUN_PAPER_OVERRIDES;
    return rths_run_paper_overrides;
}

int rths_api_frf_run(rths_api_command_config *c, const rths_api_frf_run_options *o,
                     rths_api_frf_run_summary *r, rths_error *err) {
    memset(r, 0, sizeof *r);
    if (!c || !c->has_setup)
        return rths_error_set(err, RTHS_EINPUT, "rths_api_frf_run needs the setup read");
    rths_run_frf_options ro = {.cfg = c->config,
                               .setup = &c->setup,
                               .out_dir = o->out_dir,
                               .strategy = o->strategy,
                               .harmonics = o->harmonics,
                               .resume = o->resume,
                               .force = o->force,
                               .rig_uri = o->rig_uri,
                               .reset_fault = o->reset_fault,
                               .site_uris = o->site_uris,
                               .n_site_uris = o->n_site_uris,
                               .has_seed = o->has_seed,
                               .seed = o->seed,
                               .config_path = c->path,
                               .overrides = (const char *const *)c->overrides,
                               .n_overrides = c->n_overrides,
                               .argc = o->argc,
                               .argv = o->argv};
    rths_run_callbacks cb = {
        .on_progress = o->on_progress, .should_cancel = o->should_cancel, .user = o->user};
    rths_run_frf_result res;
    memset(&res, 0, sizeof res);
    int rc = rths_run_frf(&ro, &cb, &res, err);
    memset(r, 0, sizeof *r);
    r->cancelled = res.status == RTHS_RUN_CANCELLED;
    r->points = res.points;
    r->converged_points = res.converged_points;
    r->resumed_points = res.resumed_points;
    r->evaluations = res.evaluations;
    r->folds = res.folds;
    r->rig_time_s = res.rig_time_s;
    r->wall_time_s = res.wall_time_s;
    r->max_relative_error_vs_truth = res.max_relative_error_vs_truth;
    _Static_assert(sizeof r->stop_reason == sizeof res.stop_reason, "the same stop reason");
    memcpy(r->stop_reason, res.stop_reason, sizeof r->stop_reason);
    r->outputs_written = res.outputs_written;
    return rc;
}

typedef struct {
    const rths_api_frf_options *o;
    int stop;           /* the point callback asked to stop */
    int interface_dofs; /* the split's: frf.csv's columns depend on it */
} frf_context;

/* The caller's callback gets each accepted point once (a later fold-flag update is not repeated).
 * Its stop request ends the run through should_cancel, right after this point: a clean,
 * resumable end with everything saved, not a failure. */
static int point(void *user, const rths_point *pt, int is_update) {
    frf_context *c = user;
    if (is_update || !c->o->on_point || c->stop) return RTHS_OK;
    double row[RTHS_RUN_FRF_MAX_COLUMNS];
    const char *names[RTHS_RUN_FRF_MAX_COLUMNS];
    int columns = rths_run_frf_column_count(c->interface_dofs);
    for (int i = 0; i < columns; i++)
        names[i] = rths_run_frf_column_name(c->interface_dofs, i);
    rths_run_frf_row_dofs(pt, c->interface_dofs, row);
    c->stop = c->o->on_point(c->o->user, columns, names, row) != 0;
    return RTHS_OK;
}

static int cancel(void *user) {
    frf_context *c = user;
    return c->stop || (c->o->should_cancel && c->o->should_cancel(c->o->user));
}

/* The configuration with the paper strategy's overrides first (later ones still win), as
 * `rths frf --strategy paper` loads it. */
static int load_for_strategy(const rths_api_config *cfg, int paper, rths_config **c,
                             rths_setup *setup, rths_error *err) {
    if (!paper) return rths_api_load(cfg, c, setup, err);
    rths_api_config with = *cfg;
    with.n_overrides = RTHS_RUN_PAPER_OVERRIDES + cfg->n_overrides;
    with.overrides = calloc((size_t)with.n_overrides, sizeof *with.overrides);
    if (!with.overrides) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < RTHS_RUN_PAPER_OVERRIDES; i++)
        with.overrides[i] = (char *)rths_run_paper_overrides[i];
    for (int i = 0; i < cfg->n_overrides; i++)
        with.overrides[RTHS_RUN_PAPER_OVERRIDES + i] = cfg->overrides[i];
    int rc = rths_api_load(&with, c, setup, err);
    free(with.overrides);
    return rc;
}

/* The command line `rths frf` would have had, for run.log (and "--resume", which tells the report
 * module that the folder's earlier files belong to this run). */
static char **command_line(const rths_api_config *cfg, const rths_api_frf_options *o, int *argc,
                           char *seed_text, size_t seed_size) {
    char **argv = calloc((size_t)(12 + 2 * cfg->n_overrides), sizeof *argv);
    if (!argv) return NULL;
    int n = 0;
    argv[n++] = "frf";
    if (cfg->path) argv[n++] = cfg->path;
    argv[n++] = "--out";
    argv[n++] = (char *)o->out_dir;
    for (int i = 0; i < cfg->n_overrides; i++) {
        argv[n++] = "--set";
        argv[n++] = cfg->overrides[i];
    }
    if (o->has_seed) {
        snprintf(seed_text, seed_size, "%" PRIu64, o->seed);
        argv[n++] = "--seed";
        argv[n++] = seed_text;
    }
    if (o->resume) argv[n++] = "--resume";
    if (o->force) argv[n++] = "--force";
    argv[n++] = "(C API)";
    *argc = n;
    return argv;
}

int rths_api_frf(const rths_api_config *cfg, const rths_api_frf_options *o, rths_result **out,
                 rths_error *err) {
    *out = NULL;
    if (!cfg || !o || !o->out_dir)
        return rths_error_set(err, RTHS_EINPUT, "rths_api_frf needs a configuration and out_dir");
    const char *strategy = o->strategy ? o->strategy : "default";
    rths_config *c;
    rths_setup setup;
    int rc = load_for_strategy(cfg, !strcmp(strategy, "paper"), &c, &setup, err);
    if (rc) return rc;
    char seed_text[32];
    int argc = 0;
    char **argv = command_line(cfg, o, &argc, seed_text, sizeof seed_text);
    if (!argv) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    rths_run_frf_options ro = {.cfg = c,
                               .setup = &setup,
                               .out_dir = o->out_dir,
                               .strategy = strategy,
                               .harmonics = o->harmonics,
                               .resume = o->resume,
                               .force = o->force,
                               .rig_uri = o->rig_uri,
                               .has_seed = o->has_seed,
                               .seed = o->seed,
                               .config_path = cfg->path,
                               .overrides = (const char *const *)cfg->overrides,
                               .n_overrides = cfg->n_overrides,
                               .argc = argc,
                               .argv = argv};
    frf_context ctx = {o, 0, rc ? 1 : setup.split.n_int};
    rths_run_callbacks cb = {.on_point = point, .should_cancel = cancel, .user = &ctx};
    rths_run_frf_result result;
    if (!rc) rc = rths_run_frf(&ro, &cb, &result, err);
    free(argv);
    rths_api_unload(c, &setup);
    /* the folder as written, however the run ended (a failure still saved what was accepted,
     * but reports the failure) */
    if (!rc) rc = rths_api_read_run(o->out_dir, out, err);
    return rc;
}

#endif
