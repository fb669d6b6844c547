/* The output folder of a run: atomic files, CSV, JSON summary, gnuplot figures, run.log. */
#include "rths/report.h"

#include <errno.h>
#include <fcntl.h>
#include <json-c/json.h>
#include <locale.h>
#include <math.h>
#include <spawn.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

/* The names of the files a run wrote (rths_report_path, rths_plot), in order, without repeats. */
typedef struct {
    char **names;
    int n, cap;
    int changed; /* since results.mat was last written */
} name_list;

struct rths_report {
    char *dir;
    FILE *log;
    name_list *files; /* behind a pointer: rths_report_path takes a const report */
    rths_table *extra;
    int n_extra;
};

static void names_add(name_list *l, const char *name) {
    for (int i = 0; i < l->n; i++)
        if (!strcmp(l->names[i], name)) {
            l->changed = 1;
            return;
        }
    if (l->n == l->cap) {
        int cap = l->cap ? 2 * l->cap : 16;
        char **p = realloc(l->names, (size_t)cap * sizeof *p);
        if (!p) return;
        l->names = p;
        l->cap = cap;
    }
    if ((l->names[l->n] = strdup(name))) l->n++;
    l->changed = 1;
}

static void names_free(name_list *l) {
    if (!l) return;
    for (int i = 0; i < l->n; i++)
        free(l->names[i]);
    free(l->names);
    free(l);
}

static int mkdir_p(const char *dir, rths_error *err) {
    char *path = strdup(dir);
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (char *p = path + 1;; p++) {
        if (*p == '/' || !*p) {
            char saved = *p;
            *p = 0;
            if (mkdir(path, 0777) != 0 && errno != EEXIST) {
                int e = errno;
                int rc = rths_error_set(err, RTHS_EFAIL, "cannot create folder %s: %s", path,
                                        strerror(e));
                free(path);
                return rc;
            }
            *p = saved;
            if (!saved) break;
        }
    }
    struct stat st;
    int ok = stat(dir, &st) == 0 && S_ISDIR(st.st_mode);
    free(path);
    return ok ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "%s is not a folder", dir);
}

static void utc_now(char *buf, size_t size) {
    time_t t = time(NULL);
    struct tm tm;
    gmtime_r(&t, &tm);
    strftime(buf, size, "%Y-%m-%dT%H:%M:%SZ", &tm);
}

/* The command named by the first line of dir/run.log ("<time> rths <version> <command>:"), into
 * buf; 0 when there is no such line. */
static int earlier_command(const char *dir, char *buf, size_t size) {
    char path[4096], line[512];
    snprintf(path, sizeof path, "%s/run.log", dir);
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    int found = 0;
    char version[64], name[512];
    if (fgets(line, sizeof line, f) && sscanf(line, "%*s rths %63s %511[^:]", version, name) == 2 &&
        strlen(name) < size) {
        snprintf(buf, size, "%s", name);
        found = 1;
    }
    fclose(f);
    return found;
}

/* An earlier run of the same command is replaced: the files it listed in .rths-files go. */
static void remove_earlier_files(const char *dir) {
    char path[4096], name[1024];
    snprintf(path, sizeof path, "%s/.rths-files", dir);
    FILE *f = fopen(path, "r");
    if (!f) return;
    while (fgets(name, sizeof name, f)) {
        name[strcspn(name, "\n")] = 0;
        /* only plain names inside the folder */
        if (!name[0] || strchr(name, '/') || !strcmp(name, "run.log")) continue;
        char file[4096 + 1024 + 2];
        snprintf(file, sizeof file, "%s/%s", dir, name);
        remove(file);
    }
    fclose(f);
    remove(path);
}

static int check_folder(const char *dir, const char *command, int argc, char **argv,
                        rths_error *err) {
    char earlier[512];
    if (!earlier_command(dir, earlier, sizeof earlier)) return RTHS_OK;
    if (strcmp(earlier, command))
        return rths_error_set(err, RTHS_EINPUT,
                              "%s holds an earlier 'rths %s' run (run.log): a '%s' run would mix "
                              "its files with it; choose another folder",
                              dir, earlier, command);
    for (int i = 1; i < argc; i++)
        if (argv[i] && !strcmp(argv[i], "--resume")) return RTHS_OK;
    remove_earlier_files(dir);
    return RTHS_OK;
}

int rths_report_open(const char *dir, const char *command, int argc, char **argv, rths_report **out,
                     rths_error *err) {
    *out = NULL;
    int rc = check_folder(dir, command, argc, argv, err);
    if (!rc) rc = mkdir_p(dir, err);
    if (rc) return rc;
    rths_report *rep = calloc(1, sizeof *rep);
    if (!rep || !(rep->dir = strdup(dir)) || !(rep->files = calloc(1, sizeof *rep->files))) {
        if (rep) free(rep->dir);
        free(rep);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    char *log_path = rths_report_path(rep, "run.log");
    rep->log = log_path ? fopen(log_path, "a") : NULL;
    if (!rep->log) {
        int e = errno;
        rc = rths_error_set(err, RTHS_EFAIL, "cannot open %s: %s", log_path ? log_path : dir,
                            strerror(e));
        free(log_path);
        rths_report_close(rep);
        return rc;
    }
    free(log_path);
    char when[32];
    utc_now(when, sizeof when);
    fprintf(rep->log, "%s rths %s %s:", when, RTHS_VERSION, command);
    for (int i = 1; i < argc; i++)
        fprintf(rep->log, " %s", argv[i]);
    fputc('\n', rep->log);
    fflush(rep->log);
    *out = rep;
    return RTHS_OK;
}

/* .rths-files: this run's files, one name a line, for the next run of the same command. */
static void write_file_list(const rths_report *rep) {
    if (!rep->files->n) return;
    size_t len = 1;
    for (int i = 0; i < rep->files->n; i++)
        len += strlen(rep->files->names[i]) + 1;
    char *text = malloc(len), *p = text;
    char *path = rths_report_path(rep, ".rths-files");
    if (text && path) {
        for (int i = 0; i < rep->files->n; i++)
            p += sprintf(p, "%s\n", rep->files->names[i]);
        rths_error err;
        (void)rths_write_file_atomic(path, text, (size_t)(p - text), &err);
    }
    free(text);
    free(path);
}

void rths_report_close(rths_report *rep) {
    if (!rep) return;
    if (rep->files && rep->files->changed) {
        rths_error err;
        rths_error_clear(&err);
        if (rths_report_write_mat(rep, &err)) {
            fprintf(stderr, "rths: warning: no results.mat: %s\n", err.msg);
            rths_report_log(rep, "warning: no results.mat: %s", err.msg);
        }
    }
    if (rep->files) write_file_list(rep);
    if (rep->log) fclose(rep->log);
    for (int i = 0; i < rep->n_extra; i++)
        rths_table_free(&rep->extra[i]);
    free(rep->extra);
    names_free(rep->files);
    free(rep->dir);
    free(rep);
}

const char *rths_report_dir(const rths_report *rep) {
    return rep->dir;
}

char *rths_path_join(const char *dir, const char *name) {
    size_t len = strlen(dir) + strlen(name) + 2;
    char *p = malloc(len);
    if (p) snprintf(p, len, "%s/%s", dir, name);
    return p;
}

char *rths_read_file(const char *path, size_t max_bytes, size_t *len) {
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

char *rths_report_path(const rths_report *rep, const char *name) {
    char *p = rths_path_join(rep->dir, name);
    if (rep->files && strcmp(name, ".rths-files") && strcmp(name, "results.mat"))
        names_add(rep->files, name);
    return p;
}

int rths_report_add_table(rths_report *rep, const rths_table *table, rths_error *err) {
    rths_table *p = realloc(rep->extra, (size_t)(rep->n_extra + 1) * sizeof *p);
    if (!p) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    rep->extra = p;
    int rc = rths_table_create(table->name, table->rows, table->columns,
                               (const char *const *)table->column_names, &p[rep->n_extra], err);
    if (rc) return rc;
    for (int c = 0; c < table->columns; c++)
        memcpy(p[rep->n_extra].data[c], table->data[c], (size_t)table->rows * sizeof(double));
    rep->n_extra++;
    rep->files->changed = 1;
    return RTHS_OK;
}

int rths_report_write_mat(rths_report *rep, rths_error *err) {
    int n_csv = 0, has_summary = 0;
    const char **csv = calloc((size_t)rep->files->n + 1, sizeof *csv);
    if (!csv) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < rep->files->n; i++) {
        const char *name = rep->files->names[i];
        size_t len = strlen(name);
        struct stat st;
        char *path = rths_report_path(rep, name);
        /* a name handed out but never written (a failed step) is not part of the run */
        int exists = path && stat(path, &st) == 0 && S_ISREG(st.st_mode);
        free(path);
        if (exists && len > 4 && !strcmp(name + len - 4, ".csv")) csv[n_csv++] = name;
        has_summary |= exists && !strcmp(name, "summary.json");
    }
    int rc = RTHS_OK, wanted = n_csv || has_summary || rep->n_extra;
    if (wanted) rc = rths_matfile_write(rep->dir, csv, n_csv, rep->extra, rep->n_extra, err);
    free(csv);
    if (!rc && wanted) {
        names_add(rep->files, "results.mat"); /* for .rths-files */
        rths_report_log(rep, "wrote results.mat");
    }
    /* a failed write was reported to the caller: the close does not retry it (a second message),
     * only a folder that changed since */
    rep->files->changed = 0;
    return rc;
}

void rths_report_log(rths_report *rep, const char *fmt, ...) {
    if (!rep || !rep->log) return;
    char when[32];
    utc_now(when, sizeof when);
    fprintf(rep->log, "%s ", when);
    va_list ap;
    va_start(ap, fmt);
    vfprintf(rep->log, fmt, ap);
    va_end(ap);
    fputc('\n', rep->log);
    fflush(rep->log);
}

/* ---- atomic files ---- */

struct rths_atomic_file {
    char *path, *tmp;
    FILE *f;
};

int rths_atomic_open(const char *path, rths_atomic_file **out, FILE **stream, rths_error *err) {
    *out = NULL;
    rths_atomic_file *a = calloc(1, sizeof *a);
    size_t len = strlen(path) + 32;
    if (!a || !(a->path = strdup(path)) || !(a->tmp = malloc(len))) {
        if (a) free(a->path);
        free(a);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    snprintf(a->tmp, len, "%s.tmp.%ld", path, (long)getpid());
    a->f = fopen(a->tmp, "w");
    if (!a->f) {
        int e = errno;
        int rc = rths_error_set(err, RTHS_EFAIL, "cannot write %s: %s", a->tmp, strerror(e));
        free(a->path);
        free(a->tmp);
        free(a);
        return rc;
    }
    *out = a;
    *stream = a->f;
    return RTHS_OK;
}

static void atomic_free(rths_atomic_file *a) {
    free(a->path);
    free(a->tmp);
    free(a);
}

/* After a rename the new directory entry itself must reach the disk, or a crash can bring back
 * the old file (or none) although the data were synced. Best effort: some filesystems refuse. */
static void sync_parent_dir(const char *path) {
    const char *slash = strrchr(path, '/');
    char *dir = slash ? strndup(path, (size_t)(slash - path)) : strdup(".");
    if (!dir) return;
    int fd = open(*dir ? dir : "/", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        (void)fsync(fd);
        close(fd);
    }
    free(dir);
}

int rths_atomic_commit(rths_atomic_file *a, rths_error *err) {
    int bad = ferror(a->f) || fflush(a->f) != 0 || fsync(fileno(a->f)) != 0;
    int e = errno;
    bad |= fclose(a->f) != 0;
    if (!bad && rename(a->tmp, a->path) != 0) {
        bad = 1;
        e = errno;
    }
    int rc = RTHS_OK;
    if (bad) {
        remove(a->tmp);
        rc = rths_error_set(err, RTHS_EFAIL, "cannot write %s: %s", a->path, strerror(e));
    } else {
        sync_parent_dir(a->path);
    }
    atomic_free(a);
    return rc;
}

void rths_atomic_abort(rths_atomic_file *a) {
    if (!a) return;
    fclose(a->f);
    remove(a->tmp);
    atomic_free(a);
}

int rths_write_file_atomic(const char *path, const char *data, size_t len, rths_error *err) {
    rths_atomic_file *a;
    FILE *f;
    int rc = rths_atomic_open(path, &a, &f, err);
    if (rc) return rc;
    if (len && fwrite(data, 1, len, f) != len) {
        rths_atomic_abort(a);
        return rths_error_set(err, RTHS_EFAIL, "cannot write %s", path);
    }
    return rths_atomic_commit(a, err);
}

/* ---- CSV ---- */

struct rths_csv {
    rths_atomic_file *file;
    FILE *f;
    int columns;
    locale_t c_locale;
};

int rths_csv_open(const char *path, int n_columns, const char *const *header, rths_csv **out,
                  rths_error *err) {
    *out = NULL;
    rths_csv *csv = calloc(1, sizeof *csv);
    if (!csv) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    /* numbers always with '.', whatever locale the process runs in */
    csv->c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
    if (!csv->c_locale) {
        free(csv);
        return rths_error_set(err, RTHS_EFAIL, "cannot create the C locale");
    }
    int rc = rths_atomic_open(path, &csv->file, &csv->f, err);
    if (rc) {
        freelocale(csv->c_locale);
        free(csv);
        return rc;
    }
    csv->columns = n_columns;
    for (int i = 0; i < n_columns; i++)
        fprintf(csv->f, "%s%s", i ? "," : "", header[i]);
    fputc('\n', csv->f);
    *out = csv;
    return RTHS_OK;
}

int rths_csv_row(rths_csv *csv, const double *values) {
    locale_t previous = uselocale(csv->c_locale);
    for (int i = 0; i < csv->columns; i++) {
        if (i) fputc(',', csv->f);
        if (values[i] != values[i])
            fputs("nan", csv->f);
        else
            fprintf(csv->f, "%.17g", values[i]);
    }
    fputc('\n', csv->f);
    uselocale(previous);
    return ferror(csv->f) ? RTHS_EFAIL : RTHS_OK;
}

int rths_csv_close(rths_csv *csv, rths_error *err) {
    int rc = rths_atomic_commit(csv->file, err);
    freelocale(csv->c_locale);
    free(csv);
    return rc;
}

void rths_csv_abort(rths_csv *csv) {
    if (!csv) return;
    rths_atomic_abort(csv->file);
    freelocale(csv->c_locale);
    free(csv);
}

int rths_csv_finish(rths_csv *csv, int rc, rths_error *err) {
    if (!csv) return rc;
    if (rc) {
        rths_csv_abort(csv);
        return rc;
    }
    return rths_csv_close(csv, err);
}

/* ---- tables read back ---- */

void rths_table_free(rths_table *t) {
    if (!t) return;
    for (int c = 0; c < t->columns; c++) {
        if (t->column_names) free(t->column_names[c]);
        if (t->data) free(t->data[c]);
    }
    free(t->column_names);
    free(t->data);
    free(t->name);
    memset(t, 0, sizeof *t);
}

int rths_table_create(const char *name, int rows, int columns, const char *const *column_names,
                      rths_table *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    out->name = strdup(name);
    out->column_names = calloc((size_t)columns + 1, sizeof *out->column_names);
    out->data = calloc((size_t)columns + 1, sizeof *out->data);
    int ok = out->name && out->column_names && out->data;
    out->columns = ok ? columns : 0;
    out->rows = rows;
    for (int c = 0; c < out->columns && ok; c++) {
        out->column_names[c] = strdup(column_names[c]);
        out->data[c] = calloc((size_t)rows + 1, sizeof(double));
        ok = out->column_names[c] && out->data[c];
    }
    if (ok) return RTHS_OK;
    rths_table_free(out);
    return rths_error_set(err, RTHS_EFAIL, "out of memory");
}

/* Splits line at commas in place (no quoting: rths never writes commas inside a field). */
static int split_fields(char *line, char **fields, int max) {
    int n = 0;
    line[strcspn(line, "\r\n")] = 0;
    for (char *p = line;; p++) {
        if (n < max) fields[n] = p;
        n++;
        p += strcspn(p, ",");
        if (!*p) break;
        *p = 0;
    }
    return n;
}

static int table_grow(rths_table *t, int *cap, rths_error *err) {
    int want = *cap ? 2 * *cap : 256;
    for (int c = 0; c < t->columns; c++) {
        double *p = realloc(t->data[c], (size_t)want * sizeof *p);
        if (!p) return rths_error_set(err, RTHS_EFAIL, "out of memory");
        t->data[c] = p;
    }
    *cap = want;
    return RTHS_OK;
}

static int read_rows(FILE *f, const char *path, rths_table *t, char **fields, rths_error *err) {
    char *line = NULL;
    size_t size = 0;
    int cap = 0, rc = RTHS_OK, line_no = 1;
    locale_t c_locale = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
    locale_t previous = c_locale ? uselocale(c_locale) : (locale_t)0;
    while (!rc && getline(&line, &size, f) > 0) {
        line_no++;
        if (line[0] == '\n' || line[0] == '\r') continue;
        int n = split_fields(line, fields, t->columns);
        if (n != t->columns) {
            rc = rths_error_set(err, RTHS_EINPUT, "%s:%d: %d fields, the header has %d", path,
                                line_no, n, t->columns);
            break;
        }
        if (t->rows == cap && (rc = table_grow(t, &cap, err))) break;
        for (int c = 0; c < n && !rc; c++) {
            char *end;
            double v = strtod(fields[c], &end);
            if (end == fields[c] || *end)
                rc = rths_error_set(err, RTHS_EINPUT, "%s:%d: column %s: '%s' is not a number",
                                    path, line_no, t->column_names[c], fields[c]);
            else
                t->data[c][t->rows] = v;
        }
        if (!rc) t->rows++;
    }
    if (c_locale) {
        uselocale(previous);
        freelocale(c_locale);
    }
    free(line);
    return rc;
}

int rths_csv_read(const char *path, rths_table *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    FILE *f = fopen(path, "r");
    if (!f) return rths_error_set(err, RTHS_EFAIL, "cannot read %s: %s", path, strerror(errno));
    char *header = NULL, **fields = NULL;
    size_t size = 0;
    int rc = RTHS_OK;
    if (getline(&header, &size, f) <= 0) {
        rc = rths_error_set(err, RTHS_EINPUT, "%s is empty (no header line)", path);
    } else {
        int n = split_fields(header, NULL, 0);
        fields = calloc((size_t)n, sizeof *fields);
        /* the header was cut in place: rebuild the field pointers */
        char *p = header;
        for (int c = 0; fields && c < n; c++, p += strlen(p) + 1)
            fields[c] = p;
        const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
        char *stem = strndup(base, strlen(base) > 4 && !strcmp(base + strlen(base) - 4, ".csv")
                                       ? strlen(base) - 4
                                       : strlen(base));
        rc = fields && stem ? rths_table_create(stem, 0, n, (const char *const *)fields, out, err)
                            : rths_error_set(err, RTHS_EFAIL, "out of memory");
        free(stem);
        if (!rc) rc = read_rows(f, path, out, fields, err);
    }
    free(fields);
    free(header);
    fclose(f);
    if (rc) rths_table_free(out);
    return rc;
}

/* ---- JSON ---- */

int rths_json_write(const char *path, struct json_object *obj, rths_error *err) {
    json_c_set_serialization_double_format("%.17g", JSON_C_OPTION_THREAD);
    const char *text = json_object_to_json_string_ext(
        obj, JSON_C_TO_STRING_PRETTY | JSON_C_TO_STRING_SPACED | JSON_C_TO_STRING_NOSLASHESCAPE);
    json_c_set_serialization_double_format(NULL, JSON_C_OPTION_THREAD);
    if (!text) return rths_error_set(err, RTHS_EFAIL, "cannot serialise %s", path);
    size_t len = strlen(text);
    char *data = malloc(len + 2);
    if (!data) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    memcpy(data, text, len);
    data[len] = '\n';
    data[len + 1] = 0;
    int rc = rths_write_file_atomic(path, data, len + 1, err);
    free(data);
    return rc;
}

struct json_object *rths_json_summary_new(const char *command) {
    json_object *o = json_object_new_object();
    if (!o) return NULL;
    char when[32];
    utc_now(when, sizeof when);
    json_object_object_add(o, "rths_version", json_object_new_string(RTHS_VERSION));
    json_object_object_add(o, "command", json_object_new_string(command));
    json_object_object_add(o, "created_utc", json_object_new_string(when));
    return o;
}

/* ---- figures ---- */

static void plot_warning(rths_report *rep, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
static void plot_warning(rths_report *rep, const char *fmt, ...) {
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    fprintf(stderr, "rths: warning: %s\n", msg);
    if (rep) rths_report_log(rep, "warning: %s", msg);
}

int rths_plot(rths_report *rep, const char *dir, const char *basename, int width_px, int height_px,
              const char *body, rths_error *err) {
    size_t len = strlen(dir) + strlen(basename) + 8;
    char *gp = malloc(len);
    if (!gp) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    snprintf(gp, len, "%s/%s.gp", dir, basename);
    if (rep && rep->files && !strcmp(dir, rep->dir)) {
        static const char *const ext[] = {".gp", ".png", ".svg"};
        for (int i = 0; i < 3; i++) {
            char name[512];
            snprintf(name, sizeof name, "%s%s", basename, ext[i]);
            names_add(rep->files, name);
        }
    }
    rths_atomic_file *a;
    FILE *f;
    int rc = rths_atomic_open(gp, &a, &f, err);
    if (rc) {
        free(gp);
        return rc;
    }
    /* The same body twice: a PNG for viewing, an SVG for papers. Paths are relative to dir, so
     * the script reruns anywhere the data are (cd DIR && gnuplot NAME.gp). */
    fprintf(
        f,
        "# rths figure: run 'gnuplot %s.gp' in this folder to remake %s.png and %s.svg\n"
        "set terminal pngcairo size %d,%d font 'DejaVu Sans,14' enhanced\n"
        "set output '%s.png'\n%s\n"
        "reset\n" /* the SVG starts from the state the PNG started from (no log scale left over) */
        "set terminal svg size %d,%d font 'DejaVu Sans,14' enhanced background rgb 'white'\n"
        "set output '%s.svg'\n%s\nunset output\n",
        basename, basename, basename, width_px, height_px, basename, body, width_px, height_px,
        basename, body);
    rc = rths_atomic_commit(a, err);
    if (rc) {
        free(gp);
        return rc;
    }
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    /* gnuplot's chatter goes to /dev/null on stdout; its errors still reach stderr */
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    char script[512];
    snprintf(script, sizeof script, "%s.gp", basename);
    char *args[] = {"gnuplot", script, NULL};
    /* the child runs in dir (glibc >= 2.29), so the script's relative paths resolve */
    posix_spawn_file_actions_addchdir_np(&actions, dir);
    pid_t pid;
    int spawn_rc = posix_spawnp(&pid, "gnuplot", &actions, NULL, args, environ);
    posix_spawn_file_actions_destroy(&actions);
    if (spawn_rc != 0) {
        plot_warning(rep, "gnuplot is not available (%s): %s kept, no %s.png/.svg",
                     strerror(spawn_rc), gp, basename);
        free(gp);
        return RTHS_OK;
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        plot_warning(rep, "gnuplot failed on %s (status %d): figure not made", gp,
                     WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    free(gp);
    return RTHS_OK;
}

double rths_plot_unit(double max_abs, const char *si, char *label, size_t size) {
    static const char *const prefix[] = {"", "m", "µ", "n", "p"};
    int k = 0;
    if (isfinite(max_abs) && max_abs > 0)
        while (k < 4 && max_abs * pow(1e3, k) < 1)
            k++;
    /* "m" with the milli prefix reads "mm"; an SI unit that starts with a prefix letter of its own
     * ("m/N") still takes it in front: "mm/N", "µm/N" */
    snprintf(label, size, "%s%s", prefix[k], si);
    return pow(1e3, k);
}

const char *rths_plot_colour(int d) {
    static const char *const colour[] = {"#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"};
    return colour[(d < 0 ? 0 : d) % 5];
}

int rths_progress_enabled(int quiet) {
    return !quiet && isatty(2);
}
