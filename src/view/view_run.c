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
    int ok = p && lstat(p, &st) == 0 && S_ISREG(st.st_mode); /* a symlink is not the run's */
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

/* The journal read through the view's own opening of it (view_files.c): returns the HTTP
 * status. A journal that cannot be read is a 500 naming it, the server keeps running. */
static int points_from_journal(const char *dir, json_object *root, rths_error *err) {
    rths_point *pts = NULL;
    char *strategy = NULL;
    int n = 0;
    view_file f;
    int status = view_file_open(dir, "journal.jsonl", &f, err);
    if (status == 200) status = view_file_parse_check(&f, "journal.jsonl", err);
    if (status == 200 && rths_journal_read(f.proc_path, &pts, &n, &strategy, err)) {
        view_error_rename(err, f.proc_path, "journal.jsonl");
        status = 500;
    }
    view_file_close(&f);
    if (status != 200) return status;
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
    return 200;
}

/* DIR/NAME read by the report module's CSV reader (the run's files: C locale, "nan" for NaN)
 * through the view's own opening of it (view_files.c): returns the HTTP status. */
static int read_run_csv(const char *dir, const char *name, rths_table *t, rths_error *err) {
    view_file f;
    int status = view_file_open(dir, name, &f, err);
    if (status == 200) status = view_file_parse_check(&f, name, err);
    if (status == 200 && rths_csv_read(f.proc_path, t, err)) {
        view_error_rename(err, f.proc_path, name);
        status = 500;
    }
    view_file_close(&f);
    return status;
}

static int points_from_csv(const char *dir, json_object *root, rths_error *err) {
    rths_table t;
    int status = read_run_csv(dir, "frf.csv", &t, err);
    if (status != 200) return status;
    double *row = malloc((size_t)(t.columns > 0 ? t.columns : 1) * sizeof *row);
    if (!row) {
        rths_table_free(&t);
        return rths_error_set(err, RTHS_EFAIL, "out of memory"), 500;
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
    return 200;
}

char *view_json_text(json_object *obj) {
    /* %.17g round-trips every double: the page sees the numbers the run wrote */
    json_c_set_serialization_double_format("%.17g", JSON_C_OPTION_THREAD);
    const char *text = json_object_to_json_string_ext(obj, JSON_C_TO_STRING_PLAIN);
    char *copy = text ? strdup(text) : NULL;
    json_c_set_serialization_double_format(NULL, JSON_C_OPTION_THREAD);
    return copy;
}

/* Whatever entry has the name decides (a symlinked frf.csv is refused, not skipped for the
 * journal): the page never shows points other than the run's own. */
int view_points_json(const char *dir, char **json, rths_error *err) {
    *json = NULL;
    json_object *root = json_object_new_object();
    int status;
    if (view_file_present(dir, "frf.csv"))
        status = points_from_csv(dir, root, err);
    else if (view_file_present(dir, "journal.jsonl"))
        status = points_from_journal(dir, root, err);
    else {
        /* a run that has not accepted anything yet */
        json_object_object_add(root, "source", json_object_new_string("none"));
        json_object_object_add(root, "columns", columns_array(frf_columns, VIEW_FRF_COLUMNS));
        json_object_object_add(root, "points", json_object_new_array());
        status = 200;
    }
    if (status == 200 && !(*json = view_json_text(root)))
        status = (rths_error_set(err, RTHS_EFAIL, "out of memory"), 500);
    json_object_put(root);
    return status;
}

int rths_view_points_json(const char *dir, char **json, rths_error *err) {
    int status = view_points_json(dir, json, err);
    return status == 200 ? RTHS_OK : err->code ? err->code : RTHS_EFAIL;
}

int view_truth_json(const char *dir, char **json, rths_error *err) {
    *json = NULL;
    rths_table t;
    int status = read_run_csv(dir, "truth.csv", &t, err);
    if (status != 200) return status;
    json_object *root = json_object_new_object();
    for (int c = 0; c < t.columns; c++) {
        json_object *col = json_object_new_array_ext(t.rows);
        for (int r = 0; r < t.rows; r++)
            json_object_array_add(col, number(t.data[c][r]));
        json_object_object_add(root, t.column_names[c], col);
    }
    rths_table_free(&t);
    if (!(*json = view_json_text(root)))
        status = (rths_error_set(err, RTHS_EFAIL, "out of memory"), 500);
    json_object_put(root);
    return status;
}

json_object *view_plan_object(const char *dir) {
    rths_config *cfg = NULL;
    rths_error err;
    rths_continuation_options cont;
    rths_continuation_defaults(&cont);
    json_object *plan = NULL;
    view_file f;
    /* config.yaml is the configuration as the run resolved it: its continuation section says
     * what range the run covers */
    if (view_file_open(dir, "config.yaml", &f, &err) == 200 &&
        view_file_parse_check(&f, "config.yaml", &err) == 200 &&
        !rths_config_load(f.proc_path, NULL, 0, &cfg, &err) &&
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
    view_file_close(&f);
    return plan;
}
