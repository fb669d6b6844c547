/* The rths command's side of the C API (rths.h, "the rths command's own entry points"): the
 * configuration a command reads once, its run folder, and the small services the command line
 * needs (progress lines, the wording of a range). The commands (src/cli) include nothing of the
 * library but rths.h (docs/architecture.md, "One front door"). */
#include "api/api_internal.h"

#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

_Static_assert((int)RTHS_API_RANGE_LO_OPEN == (int)RTHS_CONFIG_LO_OPEN &&
                   (int)RTHS_API_RANGE_HI_OPEN == (int)RTHS_CONFIG_HI_OPEN,
               "rths.h's range flags are the configuration's");

void rths_api_command_config_free(rths_api_command_config *c) {
    if (!c) return;
    rths_api_unload(c->config, c->has_setup ? &c->setup : NULL);
    for (int i = 0; i < c->n_overrides; i++)
        free(c->overrides[i]);
    free(c->overrides);
    free(c->path);
    free(c);
}

int rths_api_command_config_load(const char *path, const char *const *overrides, int n_overrides,
                                 unsigned flags, rths_api_command_config **out, rths_error *err) {
    *out = NULL;
    if (n_overrides < 0 || (n_overrides > 0 && !overrides))
        return rths_error_set(err, RTHS_EINPUT, "overrides: %d given without a list", n_overrides);
    rths_api_command_config *c = calloc(1, sizeof *c);
    int ok = c && (!path || (c->path = strdup(path))) &&
             (c->overrides = calloc((size_t)n_overrides + 1, sizeof *c->overrides));
    for (int i = 0; ok && i < n_overrides; i++)
        ok = (c->overrides[c->n_overrides++] = strdup(overrides[i])) != NULL;
    if (!ok) {
        rths_api_command_config_free(c);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    int rc;
    if (flags & RTHS_API_READ_SETUP) {
        /* the configuration and the setup as the operations read them (rths_api_load) */
        rths_api_config as_read = {
            .path = c->path, .overrides = c->overrides, .n_overrides = c->n_overrides};
        rc = rths_api_load(&as_read, &c->config, &c->setup, err);
        c->has_setup = rc == RTHS_OK;
    } else {
        rc = rths_config_load(c->path, (const char *const *)c->overrides, c->n_overrides,
                              &c->config, err);
        if (rc) c->config = NULL;
    }
    if (rc) {
        rths_api_command_config_free(c);
        return rc;
    }
    *out = c;
    return RTHS_OK;
}

int rths_api_run_folder_open(const char *dir, const char *command, int argc, char **argv,
                             const rths_api_command_config *c, rths_api_run_folder **out,
                             rths_error *err) {
    *out = NULL;
    if (!dir || !command || !c) return rths_error_set(err, RTHS_EINPUT, "no folder given");
    rths_api_run_folder *f = calloc(1, sizeof *f);
    if (!f) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = rths_report_open(dir, command, argc, argv, &f->report, err);
    if (rc) {
        free(f);
        return rc;
    }
    char *path = rths_report_path(f->report, "config.yaml");
    rc = path ? rths_config_write(c->config, path, err)
              : rths_error_set(err, RTHS_EFAIL, "out of memory");
    free(path);
    if (rc) {
        rths_api_run_folder_close(f);
        return rc;
    }
    *out = f;
    return RTHS_OK;
}

void rths_api_run_folder_log(rths_api_run_folder *f, const char *fmt, ...) {
    if (!f) return;
    char line[RTHS_ERROR_MSG_LEN + 512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    rths_report_log(f->report, "%s", line);
}

int rths_api_run_folder_write_mat(rths_api_run_folder *f, rths_error *err) {
    return rths_report_write_mat(f->report, err);
}

void rths_api_run_folder_close(rths_api_run_folder *f) {
    if (!f) return;
    rths_report_close(f->report);
    free(f);
}

int rths_api_result_write(const rths_result *r, rths_api_run_folder *f, rths_error *err) {
    return rths_result_write_report(r, f->report, err);
}

int rths_api_progress_enabled(int quiet) {
    return rths_progress_enabled(quiet);
}

const char *rths_api_range_text(double lo, double hi, unsigned flags, char *buf, size_t size) {
    return rths_config_range_text(lo, hi, flags, buf, size);
}

/* ---- the commands' computations on the configuration they hold ---- */

int rths_api_tune_run(rths_api_command_config *c, double delay_s, rths_result **out,
                      rths_error *err) {
    *out = NULL;
    if (!c || !c->has_setup)
        return rths_error_set(err, RTHS_EINPUT, "rths_api_tune_run needs the setup read");
    return rths_api_tune_compute(c->config, &c->setup, delay_s, c->path,
                                 (const char *const *)c->overrides, c->n_overrides, out, err);
}

int rths_api_fidelity_run(rths_api_command_config *c, rths_result **out, rths_error *err) {
    *out = NULL;
    if (!c || !c->has_setup)
        return rths_error_set(err, RTHS_EINPUT, "rths_api_fidelity_run needs the setup read");
    return rths_api_fidelity_compute(c->config, &c->setup, c->path,
                                     (const char *const *)c->overrides, c->n_overrides, out, err);
}

int rths_api_simulate_prepare(rths_api_command_config *c, const rths_api_simulate_options *o,
                              rths_api_simulation **out, rths_error *err) {
    *out = NULL;
    if (!c || !c->has_setup || !o)
        return rths_error_set(err, RTHS_EINPUT,
                              "rths_api_simulate_prepare needs the setup read and the options");
    return rths_api_simulation_prepare(c->config, &c->setup, o, c->path,
                                       (const char *const *)c->overrides, c->n_overrides, out, err);
}

int rths_api_simulate_run(rths_api_simulation *s, rths_api_run_folder *f, rths_result **out,
                          rths_error *err) {
    return rths_api_simulation_run(s, f ? f->report : NULL, out, err);
}
