/* What the view reads from a run folder: the accepted points (frf.csv, or journal.jsonl while the
 * run is in progress), the truth curve, the folder's state. Read only, never written. */
#include "view/view_internal.h"

#include "rths/continuation.h"
#include "rths/report.h"
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

int view_file_exists(const char *dir, const char *name) {
    char *p = rths_path_join(dir, name);
    struct stat st;
    int ok = p && stat(p, &st) == 0 && S_ISREG(st.st_mode);
    free(p);
    return ok;
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
    char *path = rths_path_join(dir, "journal.jsonl");
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

/* DIR/NAME read by the report module's CSV reader (the run's files: C locale, "nan" for NaN) */
static int read_run_csv(const char *dir, const char *name, rths_table *t, rths_error *err) {
    char *path = rths_path_join(dir, name);
    int rc = path ? rths_csv_read(path, t, err) : rths_error_set(err, RTHS_EFAIL, "no memory");
    free(path);
    return rc;
}

static int points_from_csv(const char *dir, json_object *root, rths_error *err) {
    rths_table t;
    int rc = read_run_csv(dir, "frf.csv", &t, err);
    if (rc) return rc;
    double *row = malloc((size_t)(t.columns > 0 ? t.columns : 1) * sizeof *row);
    if (!row) {
        rths_table_free(&t);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    const char *const *names = (const char *const *)t.column_names;
    json_object *arr = json_object_new_array();
    for (int r = 0; r < t.rows; r++) { /* the table is by column, a point is a row */
        for (int c = 0; c < t.columns; c++)
            row[c] = t.data[c][r];
        json_object_array_add(arr, row_object(names, t.columns, row));
    }
    json_object_object_add(root, "source", json_object_new_string("frf.csv"));
    json_object_object_add(root, "columns", columns_array(names, t.columns));
    json_object_object_add(root, "points", arr);
    free(row);
    rths_table_free(&t);
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
    rths_table t;
    int rc = read_run_csv(dir, "truth.csv", &t, err);
    if (rc) return rc;
    json_object *root = json_object_new_object();
    for (int c = 0; c < t.columns; c++) {
        json_object *col = json_object_new_array_ext(t.rows);
        for (int r = 0; r < t.rows; r++)
            json_object_array_add(col, number(t.data[c][r]));
        json_object_object_add(root, t.column_names[c], col);
    }
    rths_table_free(&t);
    if (!(*json = view_json_text(root))) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    json_object_put(root);
    return rc;
}

json_object *view_plan_object(const char *dir) {
    char *path = rths_path_join(dir, "config.yaml");
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
