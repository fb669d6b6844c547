/* What the view reads from a run folder: the accepted points (frf.csv, or journal.jsonl while the
 * run is in progress), the truth curve, the folder's state. Read only, never written. */
#include "view/view_internal.h"

#include "rths/continuation.h"
#include "rths/run.h"

#include <errno.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* frf.csv's columns and a journal point's row are the run's own (run.h), so the API and the
 * file never drift apart. */
#define frf_columns rths_run_frf_columns

char *view_join(const char *dir, const char *name) {
    size_t len = strlen(dir) + strlen(name) + 2;
    char *p = malloc(len);
    if (p) snprintf(p, len, "%s/%s", dir, name);
    return p;
}

int view_file_exists(const char *dir, const char *name) {
    char *p = view_join(dir, name);
    struct stat st;
    int ok = p && stat(p, &st) == 0 && S_ISREG(st.st_mode);
    free(p);
    return ok;
}

char *view_read_file(const char *path, size_t max_bytes, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 65536, n = 0;
    char *buf = malloc(cap + 1);
    while (buf) {
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (n < cap || got == 0) break;
        if (cap >= max_bytes) break;
        char *bigger = realloc(buf, 2 * cap + 1);
        if (!bigger) {
            free(buf);
            buf = NULL;
            break;
        }
        buf = bigger;
        cap *= 2;
    }
    int bad = ferror(f);
    fclose(f);
    if (!buf || bad) {
        free(buf);
        return NULL;
    }
    buf[n] = 0;
    if (len) *len = n;
    return buf;
}

int rths_view_check_run_dir(const char *dir, rths_error *err) {
    struct stat st;
    if (!dir || !dir[0]) return rths_error_set(err, RTHS_EINPUT, "no run folder given");
    if (stat(dir, &st) != 0)
        return rths_error_set(err, RTHS_EINPUT, "run folder %s: %s", dir, strerror(errno));
    if (!S_ISDIR(st.st_mode))
        return rths_error_set(err, RTHS_EINPUT, "%s is not a folder (give the folder of a run)",
                              dir);
    if (!view_file_exists(dir, "journal.jsonl") && !view_file_exists(dir, "frf.csv") &&
        !view_file_exists(dir, "live.json"))
        return rths_error_set(err, RTHS_EINPUT,
                              "%s is not a run folder: it holds no journal.jsonl, frf.csv or "
                              "live.json (the folder given to 'rths frf --out')",
                              dir);
    return RTHS_OK;
}

/* JSON has no NaN: a non-finite number is null. */
static json_object *number(double x) {
    return isfinite(x) ? json_object_new_double(x) : NULL;
}

static json_object *row_object(const char *const *columns, int n, const double *row) {
    json_object *o = json_object_new_object();
    for (int c = 0; c < n; c++)
        json_object_object_add(o, columns[c], number(row[c]));
    return o;
}

static json_object *columns_array(const char *const *columns, int n) {
    json_object *a = json_object_new_array();
    for (int c = 0; c < n; c++)
        json_object_array_add(a, json_object_new_string(columns[c]));
    return a;
}

static int points_from_journal(const char *dir, json_object *root, rths_error *err) {
    char *path = view_join(dir, "journal.jsonl");
    rths_point *pts = NULL;
    char *strategy = NULL;
    int n = 0;
    int rc = path ? rths_journal_read(path, &pts, &n, &strategy, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
    free(path);
    if (rc) return rc;
    json_object *arr = json_object_new_array();
    for (int i = 0; i < n; i++) {
        double row[VIEW_FRF_COLUMNS];
        rths_run_frf_row(&pts[i], row);
        json_object_array_add(arr, row_object(frf_columns, VIEW_FRF_COLUMNS, row));
    }
    json_object_object_add(root, "source", json_object_new_string("journal.jsonl"));
    json_object_object_add(root, "strategy", json_object_new_string(strategy ? strategy : ""));
    json_object_object_add(root, "columns", columns_array(frf_columns, VIEW_FRF_COLUMNS));
    json_object_object_add(root, "points", arr);
    free(strategy);
    free(pts);
    return RTHS_OK;
}

int view_csv_read(const char *path, view_csv *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    char *text = view_read_file(path, (size_t)64 << 20, NULL);
    if (!text) return rths_error_set(err, RTHS_EFAIL, "cannot read %s: %s", path, strerror(errno));
    char *save = NULL, *line = strtok_r(text, "\n", &save);
    for (char *h = line ? line : ""; h && out->n_columns < VIEW_CSV_MAX_COLUMNS;) {
        char *comma = strchr(h, ',');
        if (comma) *comma = 0;
        out->columns[out->n_columns++] = strdup(h);
        h = comma ? comma + 1 : NULL;
    }
    int rc = RTHS_OK;
    while (!rc && (line = strtok_r(NULL, "\n", &save))) {
        if (out->n_rows == out->cap) {
            int cap = out->cap ? 2 * out->cap : 256;
            double *v = realloc(out->values, (size_t)cap * (size_t)out->n_columns * sizeof *v);
            if (!v)
                rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
            else
                out->values = v, out->cap = cap;
        }
        double *row = rc ? NULL : out->values + (size_t)out->n_rows * (size_t)out->n_columns;
        char *p = line;
        for (int c = 0; !rc && c < out->n_columns; c++) {
            char *end;
            row[c] = strtod(p, &end); /* "nan" parses to NaN */
            if (end == p || (*end != ',' && *end != 0 && *end != '\r'))
                rc = rths_error_set(err, RTHS_EFAIL, "%s: row %d, column %d is not a number", path,
                                    out->n_rows + 1, c + 1);
            p = *end == ',' ? end + 1 : end;
        }
        if (!rc) out->n_rows++;
    }
    free(text);
    if (rc) view_csv_free(out);
    return rc;
}

void view_csv_free(view_csv *csv) {
    for (int c = 0; c < csv->n_columns; c++)
        free(csv->columns[c]);
    free(csv->values);
    memset(csv, 0, sizeof *csv);
}

static int points_from_csv(const char *dir, json_object *root, rths_error *err) {
    char *path = view_join(dir, "frf.csv");
    view_csv csv;
    int rc = path ? view_csv_read(path, &csv, err) : rths_error_set(err, RTHS_EFAIL, "no memory");
    free(path);
    if (rc) return rc;
    json_object *arr = json_object_new_array();
    for (int r = 0; r < csv.n_rows; r++)
        json_object_array_add(arr, row_object((const char *const *)csv.columns, csv.n_columns,
                                              csv.values + (size_t)r * (size_t)csv.n_columns));
    json_object_object_add(root, "source", json_object_new_string("frf.csv"));
    json_object_object_add(root, "columns",
                           columns_array((const char *const *)csv.columns, csv.n_columns));
    json_object_object_add(root, "points", arr);
    view_csv_free(&csv);
    return RTHS_OK;
}

char *view_json_text(json_object *obj) {
    /* %.17g round-trips every double: the page sees the numbers the run wrote */
    json_c_set_serialization_double_format("%.17g", JSON_C_OPTION_THREAD);
    const char *text = json_object_to_json_string_ext(obj, JSON_C_TO_STRING_PLAIN);
    char *copy = text ? strdup(text) : NULL;
    json_c_set_serialization_double_format(NULL, JSON_C_OPTION_THREAD);
    return copy;
}

int rths_view_points_json(const char *dir, char **json, rths_error *err) {
    *json = NULL;
    json_object *root = json_object_new_object();
    int rc;
    if (view_file_exists(dir, "frf.csv"))
        rc = points_from_csv(dir, root, err);
    else if (view_file_exists(dir, "journal.jsonl"))
        rc = points_from_journal(dir, root, err);
    else {
        /* a run that has not accepted anything yet */
        json_object_object_add(root, "source", json_object_new_string("none"));
        json_object_object_add(root, "columns", columns_array(frf_columns, VIEW_FRF_COLUMNS));
        json_object_object_add(root, "points", json_object_new_array());
        rc = RTHS_OK;
    }
    if (!rc && !(*json = view_json_text(root)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    json_object_put(root);
    return rc;
}

int view_truth_json(const char *dir, char **json, rths_error *err) {
    *json = NULL;
    char *path = view_join(dir, "truth.csv");
    view_csv csv;
    int rc = path ? view_csv_read(path, &csv, err) : rths_error_set(err, RTHS_EFAIL, "no memory");
    free(path);
    if (rc) return rc;
    json_object *root = json_object_new_object();
    for (int c = 0; c < csv.n_columns; c++) {
        json_object *col = json_object_new_array_ext(csv.n_rows);
        for (int r = 0; r < csv.n_rows; r++)
            json_object_array_add(col, number(csv.values[(size_t)r * (size_t)csv.n_columns + c]));
        json_object_object_add(root, csv.columns[c], col);
    }
    view_csv_free(&csv);
    if (!(*json = view_json_text(root))) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    json_object_put(root);
    return rc;
}

json_object *view_plan_object(const char *dir) {
    char *path = view_join(dir, "config.yaml");
    rths_config *cfg = NULL;
    rths_error err;
    rths_continuation_options cont;
    rths_continuation_defaults(&cont);
    json_object *plan = NULL;
    /* config.yaml is the configuration as the run resolved it: its continuation section says
     * what range the run covers */
    if (path && view_file_exists(dir, "config.yaml") &&
        !rths_config_load(path, NULL, 0, &cfg, &err) &&
        !rths_continuation_config_read(cfg, &cont, &err)) {
        plan = json_object_new_object();
        json_object_object_add(plan, "start_hz", json_object_new_double(cont.start_hz));
        json_object_object_add(plan, "end_hz", json_object_new_double(cont.end_hz));
        json_object_object_add(
            plan, "method",
            json_object_new_string(cont.method == RTHS_CONT_ARCLENGTH ? "arclength" : "natural"));
        json_object_object_add(plan, "max_points", json_object_new_int(cont.max_points));
    }
    rths_config_free(cfg);
    free(path);
    return plan;
}
