/* The C API (rths.h): configuration handles, results as named tables, reading a run folder. */
#include "api/api_internal.h"
#include "rths/continuation.h"
#include "rths/controller.h"
#include "rths/iterate.h"
#include "rths/plant.h"
#include "rths/run.h"
#include "rths/server.h"

#include <errno.h>
#include <json-c/json.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int rths_api_version(void) {
    return RTHS_API_VERSION;
}

const char *rths_api_release(void) {
    return RTHS_VERSION;
}

/* ---- the layout of the caller-allocated structs (rths.h) ---- */

typedef struct {
    const char *type, *field; /* field NULL: the type's own size in offset */
    size_t offset;
} layout_entry;

#define LAYOUT_TYPE(t)                                                                             \
    { #t, NULL, sizeof(t) }
#define LAYOUT_FIELD(t, f)                                                                         \
    { #t, #f, offsetof(t, f) }

static const layout_entry layout[] = {
    LAYOUT_TYPE(rths_error),
    LAYOUT_FIELD(rths_error, code),
    LAYOUT_FIELD(rths_error, msg),
    LAYOUT_TYPE(rths_api_frf_options),
    LAYOUT_FIELD(rths_api_frf_options, out_dir),
    LAYOUT_FIELD(rths_api_frf_options, strategy),
    LAYOUT_FIELD(rths_api_frf_options, harmonics),
    LAYOUT_FIELD(rths_api_frf_options, has_seed),
    LAYOUT_FIELD(rths_api_frf_options, seed),
    LAYOUT_FIELD(rths_api_frf_options, resume),
    LAYOUT_FIELD(rths_api_frf_options, rig_uri),
    LAYOUT_FIELD(rths_api_frf_options, on_point),
    LAYOUT_FIELD(rths_api_frf_options, should_cancel),
    LAYOUT_FIELD(rths_api_frf_options, user),
    LAYOUT_FIELD(rths_api_frf_options, force),
    LAYOUT_TYPE(rths_api_simulate_options),
    LAYOUT_FIELD(rths_api_simulate_options, out_dir),
    LAYOUT_FIELD(rths_api_simulate_options, frequency_hz),
    LAYOUT_FIELD(rths_api_simulate_options, periods),
    LAYOUT_FIELD(rths_api_simulate_options, feedback),
    LAYOUT_FIELD(rths_api_simulate_options, delay_s),
    LAYOUT_FIELD(rths_api_simulate_options, harmonics),
    LAYOUT_FIELD(rths_api_simulate_options, target_dofs),
    LAYOUT_FIELD(rths_api_simulate_options, target_a),
    LAYOUT_FIELD(rths_api_simulate_options, target_b),
    LAYOUT_FIELD(rths_api_simulate_options, trace_periods),
    LAYOUT_FIELD(rths_api_simulate_options, has_seed),
    LAYOUT_FIELD(rths_api_simulate_options, seed),
    LAYOUT_FIELD(rths_api_simulate_options, rig_uri),
    LAYOUT_FIELD(rths_api_simulate_options, reset_fault),
};

size_t rths_api_sizeof(const char *type) {
    for (size_t i = 0; type && i < sizeof layout / sizeof layout[0]; i++)
        if (!layout[i].field && !strcmp(layout[i].type, type)) return layout[i].offset;
    return 0;
}

long rths_api_offsetof(const char *type, const char *field) {
    for (size_t i = 0; type && field && i < sizeof layout / sizeof layout[0]; i++)
        if (layout[i].field && !strcmp(layout[i].type, type) && !strcmp(layout[i].field, field))
            return (long)layout[i].offset;
    return -1;
}

/* ---- configuration ---- */

void rths_api_config_free(rths_api_config *cfg) {
    if (!cfg) return;
    for (int i = 0; i < cfg->n_overrides; i++)
        free(cfg->overrides[i]);
    free(cfg->overrides);
    free(cfg->path);
    free(cfg);
}

int rths_api_load(const rths_api_config *cfg, rths_config **out, rths_setup *setup,
                  rths_error *err) {
    *out = NULL;
    memset(setup, 0, sizeof *setup);
    int rc = rths_config_load(cfg->path, (const char *const *)cfg->overrides, cfg->n_overrides, out,
                              err);
    if (rc) {
        *out = NULL;
        return rc;
    }
    rc = rths_setup_read(*out, setup, err);
    if (rc) {
        rths_api_unload(*out, setup);
        *out = NULL;
        memset(setup, 0, sizeof *setup);
    }
    return rc;
}

void rths_api_unload(rths_config *c, rths_setup *setup) {
    if (setup) rths_setup_free(setup);
    if (c) rths_config_free(c);
}

int rths_api_check_config(rths_config *c, const char *const *own, rths_error *err) {
    return rths_config_check_sections(c, own, err);
}

/* The sections a run reads (iteration, continuation, stability) and the controller process's
 * server section, read over their defaults as rths frf and rths controller read them, so a value
 * out of range or a misspelt key there is refused by the load rather than by the operation that
 * first reads it (fidelity and output are read with the structure they need, by their commands). */
static int read_run_sections(rths_config *c, rths_error *err) {
    rths_settle_options settle;
    rths_newton_options newton;
    rths_continuation_options cont;
    rths_floquet_measure_options floquet;
    rths_server_options server;
    int harmonics = 1;
    rths_settle_defaults(&settle, 0);
    rths_newton_defaults(&newton, 0);
    rths_continuation_defaults(&cont);
    rths_floquet_measure_defaults(&floquet);
    rths_server_options_defaults(&server);
    int rc = rths_iterate_config_read(c, &settle, &newton, &harmonics, err);
    if (!rc) rc = rths_continuation_config_read(c, &cont, err);
    if (!rc) rc = rths_floquet_measure_config_read(c, &floquet, err);
    if (!rc) rc = rths_server_config_read(c, &server, err);
    return rc;
}

int rths_api_config_load(const char *path, const char *const *overrides, int n_overrides,
                         rths_api_config **out, rths_error *err) {
    *out = NULL;
    if (n_overrides < 0 || (n_overrides > 0 && !overrides))
        return rths_error_set(err, RTHS_EINPUT, "overrides: %d given without a list", n_overrides);
    for (int i = 0; i < n_overrides; i++)
        if (!overrides[i] || !strchr(overrides[i], '=') || overrides[i][0] == '=')
            return rths_error_set(err, RTHS_EINPUT,
                                  "override '%s': expected KEY=VALUE (e.g. split.mass_ratio=0.33)",
                                  overrides[i] ? overrides[i] : "(null)");
    rths_api_config *cfg = calloc(1, sizeof *cfg);
    int ok = cfg && (!path || (cfg->path = strdup(path))) &&
             (cfg->overrides = calloc((size_t)n_overrides + 1, sizeof *cfg->overrides));
    for (int i = 0; ok && i < n_overrides; i++)
        ok = (cfg->overrides[cfg->n_overrides++] = strdup(overrides[i])) != NULL;
    if (!ok) {
        rths_api_config_free(cfg);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    /* read once now, so a bad file or key is reported by the load: the structural sections and
     * their keys, the rig and controller sections as the virtual rig reads them (every operation
     * that runs the hybrid loop does, and refuses there what it would refuse here), and the
     * top-level sections (a misspelt section, or key of structure, split, forcing, model, rig or
     * controller fails here, not in the operation that first reads it; read_run_sections for
     * the run's own sections) */
    rths_config *c;
    rths_setup setup;
    int rc = rths_api_load(cfg, &c, &setup, err);
    if (!rc) {
        static const char *const rig_sections[] = {
            "rig", "controller", "iteration", "continuation", "stability", "server", NULL};
        rths_controller_options copt;
        rths_plant_options popt;
        double pace;
        rths_controller_defaults(&copt);
        rths_plant_defaults(&popt);
        rc = rths_sample_loop_config_read(c, &copt, &popt, err);
        if (!rc) rc = rths_config_get_double(c, "rig.pace", 0, 0.0, 0.0, 1e6, &pace, err);
        rths_config_mark_known(c, "rig.sites"); /* the host's list of sites, read by a run */
        rths_config_mark_known(c, "output.trace_frequency_hz"); /* read by rths frf */
        if (!rc) rc = read_run_sections(c, err);
        if (!rc) rc = rths_config_check_sections(c, rig_sections, err);
        if (rc) rths_api_unload(c, &setup);
    }
    if (rc) {
        rths_api_config_free(cfg);
        return rc;
    }
    cfg->dofs = setup.assembly.n;
    rths_api_unload(c, &setup);
    *out = cfg;
    return RTHS_OK;
}

int rths_api_config_dofs(const rths_api_config *cfg) {
    return cfg ? cfg->dofs : 0;
}

int rths_api_write_file(const char *path, const char *data, size_t len, rths_error *err) {
    if (!path || (!data && len)) return rths_error_set(err, RTHS_EINPUT, "no path or data given");
    return rths_write_file_atomic(path, data ? data : "", len, err);
}

void rths_api_free(void *p) {
    free(p);
}

/* "[a, b, ...]" of n numbers at v[0], v[stride], ... (%.17g), appended to buf at *len. */
static void append_list(char *buf, size_t size, size_t *len, const double *v, int n,
                        size_t stride) {
    *len += (size_t)snprintf(buf + *len, size - *len, "[");
    for (int i = 0; i < n && *len < size; i++)
        *len += (size_t)snprintf(buf + *len, size - *len, "%s%.17g", i ? ", " : "",
                                 v[(size_t)i * stride]);
    if (*len < size) *len += (size_t)snprintf(buf + *len, size - *len, "]");
}

int rths_api_config_get(const rths_api_config *cfg, const char *key, char **text, rths_error *err) {
    *text = NULL;
    if (!cfg || !key) return rths_error_set(err, RTHS_EINPUT, "no configuration or key given");
    rths_config *c;
    int rc =
        rths_config_load(cfg->path, (const char *const *)cfg->overrides, cfg->n_overrides, &c, err);
    if (rc) return rc;
    rths_error ignored; /* each shape is tried in turn; the last failure is the message */
    const char *scalar = NULL;
    double *v = NULL;
    int rows = 0, cols = 0;
    if (!rths_config_has(c, key)) {
        rc = rths_error_set(err, RTHS_EINPUT,
                            "key '%s' is not set in the configuration (its default applies, "
                            "docs/config.md)",
                            key);
    } else if (!rths_config_get_string(c, key, 1, NULL, &scalar, &ignored) && scalar) {
        if (!(*text = strdup(scalar))) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    } else if (!rths_config_get_double_list(c, key, 1, &v, &cols, &ignored) ||
               !rths_config_get_matrix(c, key, 1, &v, &rows, &cols, &ignored)) {
        int matrix = rows > 0;
        size_t size = 32 + (size_t)(matrix ? rows : 1) * (size_t)(cols + 1) * 28;
        char *buf = malloc(size);
        size_t len = 0;
        if (!buf) {
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        } else if (!matrix) {
            append_list(buf, size, &len, v, cols, 1);
        } else {
            len += (size_t)snprintf(buf, size, "[");
            for (int r = 0; r < rows; r++) { /* column-major: row r is v[r], v[r + rows], ... */
                if (r) len += (size_t)snprintf(buf + len, size - len, ", ");
                append_list(buf, size, &len, v + r, cols, (size_t)rows);
            }
            len += (size_t)snprintf(buf + len, size - len, "]");
        }
        *text = buf;
    } else {
        rc = rths_error_set(err, RTHS_EINPUT,
                            "key '%s' holds a mapping or a list that is not numbers: ask for one "
                            "of its keys",
                            key);
    }
    free(v);
    rths_config_free(c);
    return rc;
}

/* ---- results ---- */

int rths_result_new(rths_result **out, rths_error *err) {
    rths_result *r = calloc(1, sizeof *r);
    if (r && (r->summary_json = strdup("")) && (r->config_yaml = strdup("")) &&
        (r->text = strdup(""))) {
        *out = r;
        return RTHS_OK;
    }
    rths_result_free(r);
    *out = NULL;
    return rths_error_set(err, RTHS_EFAIL, "out of memory");
}

void rths_result_free(rths_result *r) {
    if (!r) return;
    for (int t = 0; t < r->n_tables; t++)
        rths_table_free(&r->tables[t]);
    free(r->tables);
    for (int i = 0; i < r->n_log; i++)
        free(r->log[i]);
    free(r->log);
    for (int i = 0; i < r->n_figures; i++)
        free(r->figures[i].name), free(r->figures[i].body);
    free(r->figures);
    for (int i = 0; i < r->n_files; i++)
        free(r->file_names[i]), free(r->file_texts[i]);
    free(r->file_names);
    free(r->file_texts);
    free(r->text);
    free(r->summary_json);
    free(r->config_yaml);
    free(r->dir);
    free(r);
}

int rths_result_take_table(rths_result *r, rths_table *t, rths_error *err) {
    rths_table *p = realloc(r->tables, (size_t)(r->n_tables + 1) * sizeof *p);
    if (!p) {
        rths_table_free(t);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    r->tables = p;
    r->tables[r->n_tables++] = *t;
    memset(t, 0, sizeof *t);
    return RTHS_OK;
}

int rths_result_add_columns(rths_result *r, const char *name, int rows, int columns,
                            const char *const *names, const double *const *data, rths_error *err) {
    rths_table t;
    int rc = rths_table_create(name, rows, columns, names, &t, err);
    if (rc) return rc;
    for (int c = 0; c < columns; c++)
        if (rows) memcpy(t.data[c], data[c], (size_t)rows * sizeof(double));
    return rths_result_take_table(r, &t, err);
}

/* vsnprintf into a new string (NULL: out of memory) */
static char *vformat(const char *fmt, va_list ap) {
    va_list copy;
    va_copy(copy, ap);
    int len = vsnprintf(NULL, 0, fmt, copy);
    va_end(copy);
    char *s = len >= 0 ? malloc((size_t)len + 1) : NULL;
    if (s) vsnprintf(s, (size_t)len + 1, fmt, ap);
    return s;
}

void rths_result_printf(rths_result *r, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    char *s = vformat(fmt, ap);
    va_end(ap);
    size_t len = s ? strlen(s) : 0;
    char *grown = s ? realloc(r->text, r->text_len + len + 1) : NULL;
    if (!grown) {
        r->out_of_memory = 1;
    } else {
        memcpy(grown + r->text_len, s, len + 1);
        r->text = grown;
        r->text_len += len;
    }
    free(s);
}

void rths_result_log(rths_result *r, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    char *s = vformat(fmt, ap);
    va_end(ap);
    char **grown = s ? realloc(r->log, (size_t)(r->n_log + 1) * sizeof *grown) : NULL;
    if (!grown) {
        free(s);
        r->out_of_memory = 1;
        return;
    }
    r->log = grown;
    r->log[r->n_log++] = s;
}

int rths_result_add_figure(rths_result *r, const char *name, int width_px, int height_px,
                           const char *body, rths_error *err) {
    rths_api_figure *grown = realloc(r->figures, (size_t)(r->n_figures + 1) * sizeof *grown);
    if (!grown) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    r->figures = grown;
    rths_api_figure *f = &r->figures[r->n_figures];
    f->name = strdup(name);
    f->body = strdup(body);
    f->width_px = width_px, f->height_px = height_px;
    if (!f->name || !f->body) {
        free(f->name), free(f->body);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    r->n_figures++;
    return RTHS_OK;
}

int rths_result_add_file(rths_result *r, const char *name, const char *text, rths_error *err) {
    char **names = realloc(r->file_names, (size_t)(r->n_files + 1) * sizeof *names);
    if (names) r->file_names = names;
    char **texts = names ? realloc(r->file_texts, (size_t)(r->n_files + 1) * sizeof *texts) : NULL;
    if (texts) r->file_texts = texts;
    char *n = texts ? strdup(name) : NULL, *t = n ? strdup(text) : NULL;
    if (!t) {
        free(n);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    r->file_names[r->n_files] = n;
    r->file_texts[r->n_files++] = t;
    return RTHS_OK;
}

const char *rths_result_text(const rths_result *r) {
    return r ? r->text : NULL;
}

int rths_result_set_summary(rths_result *r, struct json_object *summary, rths_error *err) {
    if (!summary) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    json_c_set_serialization_double_format("%.17g", JSON_C_OPTION_THREAD);
    const char *text =
        json_object_to_json_string_ext(summary, JSON_C_TO_STRING_PRETTY | JSON_C_TO_STRING_SPACED |
                                                    JSON_C_TO_STRING_NOSLASHESCAPE);
    json_c_set_serialization_double_format(NULL, JSON_C_OPTION_THREAD);
    char *copy = text ? strdup(text) : NULL;
    json_object_put(summary);
    if (!copy) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    free(r->summary_json);
    r->summary_json = copy;
    return RTHS_OK;
}

int rths_result_table_count(const rths_result *r) {
    return r ? r->n_tables : 0;
}

static const rths_table *table_at(const rths_result *r, int t) {
    return r && t >= 0 && t < r->n_tables ? &r->tables[t] : NULL;
}

const char *rths_result_table_name(const rths_result *r, int t) {
    const rths_table *tab = table_at(r, t);
    return tab ? tab->name : NULL;
}

int rths_result_table_index(const rths_result *r, const char *name) {
    for (int t = 0; r && name && t < r->n_tables; t++)
        if (!strcmp(r->tables[t].name, name)) return t;
    return -1;
}

int rths_result_rows(const rths_result *r, int t) {
    const rths_table *tab = table_at(r, t);
    return tab ? tab->rows : 0;
}

int rths_result_columns(const rths_result *r, int t) {
    const rths_table *tab = table_at(r, t);
    return tab ? tab->columns : 0;
}

const char *rths_result_column_name(const rths_result *r, int t, int column) {
    const rths_table *tab = table_at(r, t);
    return tab && column >= 0 && column < tab->columns ? tab->column_names[column] : NULL;
}

const double *rths_result_column(const rths_result *r, int t, int column) {
    const rths_table *tab = table_at(r, t);
    return tab && column >= 0 && column < tab->columns ? tab->data[column] : NULL;
}

const char *rths_result_summary_json(const rths_result *r) {
    return r ? r->summary_json : NULL;
}

const char *rths_result_config_yaml(const rths_result *r) {
    return r ? r->config_yaml : NULL;
}

const char *rths_result_dir(const rths_result *r) {
    return r ? r->dir : NULL;
}

/* ---- run folders ---- */

static char *read_text(const char *dir, const char *name) {
    char *path = rths_path_join(dir, name);
    if (!path) return NULL;
    char *text = rths_read_file(path, SIZE_MAX, NULL);
    free(path);
    return text ? text : strdup(""); /* no such file: empty */
}

static int write_table_csv(rths_report *rep, const rths_table *t, rths_error *err) {
    size_t len = strlen(t->name) + 5;
    char *name = malloc(len);
    double *row = calloc((size_t)t->columns + 1, sizeof *row);
    char *path = NULL;
    rths_csv *csv = NULL;
    int rc = name && row ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        snprintf(name, len, "%s.csv", t->name);
        path = rths_report_path(rep, name);
        rc = path ? rths_csv_open(path, t->columns, (const char *const *)t->column_names, &csv, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int i = 0; i < t->rows && !rc; i++) {
        for (int c = 0; c < t->columns; c++)
            row[c] = t->data[c][i];
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing %s", path);
    }
    rc = rths_csv_finish(csv, rc, err);
    free(name);
    free(row);
    free(path);
    return rc;
}

int rths_result_write_report(const rths_result *r, rths_report *rep, rths_error *err) {
    int rc = RTHS_OK;
    for (int i = 0; i < r->n_files && !rc; i++) {
        char *path = rths_report_path(rep, r->file_names[i]);
        rc = path ? rths_write_file_atomic(path, r->file_texts[i], strlen(r->file_texts[i]), err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
        free(path);
    }
    if (!rc) rc = rths_result_write_tables(r, rep, err);
    if (!rc) rc = rths_result_write_log(r, rep, err);
    if (!rc) rc = rths_result_write_summary(r, rep, err);
    return rc ? rc : rths_result_write_figures(r, rep, err);
}

int rths_result_write_log(const rths_result *r, rths_report *rep, rths_error *err) {
    if (r->out_of_memory)
        return rths_error_set(err, RTHS_EFAIL, "out of memory (the result's text or log)");
    for (int i = 0; i < r->n_log; i++)
        rths_report_log(rep, "%s", r->log[i]);
    return RTHS_OK;
}

int rths_result_write_figures(const rths_result *r, rths_report *rep, rths_error *err) {
    int rc = RTHS_OK;
    for (int i = 0; i < r->n_figures && !rc; i++)
        rc = rths_plot(rep, rths_report_dir(rep), r->figures[i].name, r->figures[i].width_px,
                       r->figures[i].height_px, r->figures[i].body, err);
    return rc;
}

int rths_result_write_tables(const rths_result *r, rths_report *rep, rths_error *err) {
    int rc = RTHS_OK;
    for (int t = 0; t < r->n_tables && !rc; t++)
        rc = write_table_csv(rep, &r->tables[t], err);
    return rc;
}

int rths_result_write_summary(const rths_result *r, rths_report *rep, rths_error *err) {
    int rc = RTHS_OK;
    if (r->summary_json[0]) {
        /* as rths_json_write writes every summary: the text and a newline */
        size_t len = strlen(r->summary_json);
        char *text = malloc(len + 2);
        char *path = rths_report_path(rep, "summary.json");
        if (text && path) {
            memcpy(text, r->summary_json, len);
            text[len] = '\n';
            text[len + 1] = 0;
            rc = rths_write_file_atomic(path, text, len + 1, err);
            if (!rc) rths_report_log(rep, "wrote summary.json");
        } else {
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        }
        free(text);
        free(path);
    }
    return rc;
}

int rths_result_write_folder(rths_result *r, const rths_config *c, const char *dir,
                             const char *command, rths_error *caller_err) {
    rths_error local; /* the caller's err may be NULL; run.log still gets the reason */
    rths_error *err = caller_err ? caller_err : &local;
    rths_error_clear(err);
    char *argv[] = {(char *)command, "(C API)", NULL};
    rths_report *rep;
    int rc = rths_report_open(dir, command, 2, argv, &rep, err);
    if (rc) return rc;
    char *path = rths_report_path(rep, "config.yaml");
    rc = path ? rths_config_write(c, path, err) : rths_error_set(err, RTHS_EFAIL, "out of memory");
    free(path);
    if (!rc) rc = rths_result_write_report(r, rep, err);
    if (!rc) rc = rths_report_write_mat(rep, err); /* a failure fails the call */
    rths_report_log(rep, "finished with status %d%s%s", rc, rc ? ": " : "", rc ? err->msg : "");
    rths_report_close(rep);
    if (rc) return rc;
    char *yaml = read_text(dir, "config.yaml");
    free(r->dir);
    r->dir = strdup(dir);
    if (yaml) {
        free(r->config_yaml);
        r->config_yaml = yaml;
    }
    return r->dir && yaml ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
}

int rths_api_finish(rths_result *r, int rc, const rths_config *c, const char *out_dir,
                    const char *command, rths_result **out, rths_error *err) {
    if (!rc && out_dir) rc = rths_result_write_folder(r, c, out_dir, command, err);
    if (rc)
        rths_result_free(r);
    else
        *out = r;
    return rc;
}

static int compare_names(const void *a, const void *b) {
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* The CSV files the rths commands write (rths_report_path(rep, "NAME.csv") in src): what a folder
 * without .rths-files (a run killed before it closed its folder) is read for. A new output table
 * belongs here too. */
static const char *const rths_csv_files[] = {
    "absolute.csv", "boundary.csv",    "chart.csv",    "coefficients.csv",
    "critical.csv", "evaluations.csv", "fidelity.csv", "frf.csv",
    "modes.csv",    "trace.csv",       "true_frf.csv", "truth.csv",
};

static int is_regular_file(const char *dir, const char *name) {
    char *path = rths_path_join(dir, name);
    struct stat st;
    int yes = path && stat(path, &st) == 0 && S_ISREG(st.st_mode);
    free(path);
    return yes;
}

static int add_name(char ***names, int *n, int *cap, const char *name, rths_error *err) {
    for (int i = 0; i < *n; i++)
        if (!strcmp((*names)[i], name)) return RTHS_OK; /* listed twice */
    if (*n == *cap) {
        *cap = *cap ? 2 * *cap : 16;
        char **p = realloc(*names, (size_t)*cap * sizeof *p);
        if (!p) return rths_error_set(err, RTHS_EFAIL, "out of memory");
        *names = p;
    }
    if (!((*names)[*n] = strdup(name))) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    (*n)++;
    return RTHS_OK;
}

/* The CSV files rths wrote into dir, sorted (a stable table order): those its run listed in
 * .rths-files (written when a run closes its folder), or, without that list, those of the folder
 * named as an rths output. A user's own CSV file there is never read. */
static int list_csv(const char *dir, char ***names, int *n, rths_error *err) {
    *names = NULL;
    *n = 0;
    int cap = 0, rc = RTHS_OK;
    char *list_path = rths_path_join(dir, ".rths-files");
    char *list = list_path ? rths_read_file(list_path, SIZE_MAX, NULL) : NULL;
    free(list_path);
    if (list) {
        for (char *save = NULL, *line = strtok_r(list, "\n", &save); line && !rc;
             line = strtok_r(NULL, "\n", &save)) {
            size_t len = strlen(line);
            if (len > 4 && !strcmp(line + len - 4, ".csv") && !strchr(line, '/') &&
                is_regular_file(dir, line))
                rc = add_name(names, n, &cap, line, err);
        }
        free(list);
    } else {
        for (size_t i = 0; i < sizeof rths_csv_files / sizeof rths_csv_files[0] && !rc; i++)
            if (is_regular_file(dir, rths_csv_files[i]))
                rc = add_name(names, n, &cap, rths_csv_files[i], err);
    }
    if (*n) qsort(*names, (size_t)*n, sizeof **names, compare_names);
    return rc;
}

/* A folder an rths command wrote has its run.log (every command opens one), and an FRF run its
 * journal. */
static int check_run_folder(const char *dir, rths_error *err) {
    struct stat st;
    if (stat(dir, &st))
        return rths_error_set(err, RTHS_EINPUT, "cannot read run folder %s: %s", dir,
                              strerror(errno));
    if (!S_ISDIR(st.st_mode))
        return rths_error_set(err, RTHS_EINPUT, "%s is not a run folder: not a directory", dir);
    if (!is_regular_file(dir, "run.log") && !is_regular_file(dir, "summary.json") &&
        !is_regular_file(dir, "journal.jsonl"))
        return rths_error_set(err, RTHS_EINPUT,
                              "%s is not a run folder: no run.log, summary.json or journal.jsonl "
                              "in it",
                              dir);
    return RTHS_OK;
}

/* summary.json's text, checked: an rths run writes it atomically, so text that is not one JSON
 * object was damaged afterwards. */
static int check_summary(const char *dir, const char *text, rths_error *err) {
    if (!text[0]) return RTHS_OK; /* none: the run did not finish */
    enum json_tokener_error why = json_tokener_success;
    json_object *o = json_tokener_parse_verbose(text, &why);
    int ok = o && json_object_is_type(o, json_type_object);
    json_object_put(o);
    if (ok) return RTHS_OK;
    return rths_error_set(err, RTHS_EINPUT, "%s/summary.json: not a JSON object (%s)", dir,
                          o ? "another JSON value" : json_tokener_error_desc(why));
}

int rths_api_read_run(const char *dir, rths_result **out, rths_error *err) {
    *out = NULL;
    if (!dir) return rths_error_set(err, RTHS_EINPUT, "no run folder given");
    char **names = NULL;
    int n = 0;
    rths_result *r = NULL;
    int rc = check_run_folder(dir, err);
    if (!rc) rc = list_csv(dir, &names, &n, err);
    if (!rc) rc = rths_result_new(&r, err);
    for (int i = 0; i < n && !rc; i++) {
        char *path = rths_path_join(dir, names[i]);
        rths_table t;
        if (!path) {
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
            break;
        }
        rc = rths_csv_read(path, &t, err);
        free(path);
        if (!rc) rc = rths_result_take_table(r, &t, err);
    }
    for (int i = 0; i < n; i++)
        free(names[i]);
    free(names);
    if (!rc) {
        char *summary = read_text(dir, "summary.json"), *yaml = read_text(dir, "config.yaml");
        if (summary) free(r->summary_json), r->summary_json = summary;
        if (yaml) free(r->config_yaml), r->config_yaml = yaml;
        r->dir = strdup(dir);
        if (!summary || !yaml || !r->dir) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        if (!rc) rc = check_summary(dir, r->summary_json, err);
    }
    if (rc) {
        rths_result_free(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}

struct json_object *rths_api_summary_new(const char *command, const char *config_path,
                                         const char *const *overrides, int n_overrides) {
    json_object *root = rths_json_summary_new(command);
    if (!root) return NULL;
    if (config_path)
        json_object_object_add(root, "config_file", json_object_new_string(config_path));
    json_object *sets = json_object_new_array();
    for (int i = 0; i < n_overrides; i++)
        json_object_array_add(sets, json_object_new_string(overrides[i]));
    json_object_object_add(root, "overrides", sets);
    return root;
}
