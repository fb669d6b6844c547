/* The output folder of a run: atomic files, CSV, JSON summary, gnuplot figures, run.log. */
#include "rths/report.h"

#include <errno.h>
#include <fcntl.h>
#include <json-c/json.h>
#include <locale.h>
#include <spawn.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

struct rths_report {
    char *dir;
    FILE *log;
};

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

int rths_report_open(const char *dir, const char *command, int argc, char **argv, rths_report **out,
                     rths_error *err) {
    *out = NULL;
    int rc = mkdir_p(dir, err);
    if (rc) return rc;
    rths_report *rep = calloc(1, sizeof *rep);
    if (!rep || !(rep->dir = strdup(dir))) {
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

void rths_report_close(rths_report *rep) {
    if (!rep) return;
    if (rep->log) fclose(rep->log);
    free(rep->dir);
    free(rep);
}

const char *rths_report_dir(const rths_report *rep) {
    return rep->dir;
}

char *rths_report_path(const rths_report *rep, const char *name) {
    size_t len = strlen(rep->dir) + strlen(name) + 2;
    char *p = malloc(len);
    if (p) snprintf(p, len, "%s/%s", rep->dir, name);
    return p;
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
    rths_atomic_file *a;
    FILE *f;
    int rc = rths_atomic_open(gp, &a, &f, err);
    if (rc) {
        free(gp);
        return rc;
    }
    /* The same body twice: a PNG for viewing, an SVG for papers. Paths are relative to dir, so
     * the script reruns anywhere the data are (cd DIR && gnuplot NAME.gp). */
    fprintf(f,
            "# rths figure: run 'gnuplot %s.gp' in this folder to remake %s.png and %s.svg\n"
            "set terminal pngcairo size %d,%d font 'DejaVu Sans,14' enhanced\n"
            "set output '%s.png'\n%s\n"
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

int rths_progress_enabled(int quiet) {
    return !quiet && isatty(2);
}
