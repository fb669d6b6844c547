/* results.mat: a run folder's data as one MAT 7.3 file (HDF5 underneath, written by libmatio), so
 * MATLAB loads it with `load`, Python with h5py and Julia with MAT.jl. The content is what the run
 * wrote as text (CSV tables, summary.json, config.yaml) plus tables that have no CSV; see
 * rths_report_write_mat in report.h for the layout. */
#include "rths/continuation.h"
#include "rths/report.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <json-c/json.h>
#include <math.h>
#include <hdf5.h>
#include <matio.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* MATLAB names: a letter first, then letters, digits, '_'; at most 63 characters. */
static void matlab_name(const char *in, char *out, size_t size) {
    size_t n = 0;
    if (!isalpha((unsigned char)in[0]) && size > 2) out[n++] = 'x';
    for (const char *p = in; *p && n + 1 < size && n < 63; p++)
        out[n++] = isalnum((unsigned char)*p) ? *p : '_';
    out[n] = 0;
}

static matvar_t *double_var(const char *name, size_t rows, size_t cols, const double *data) {
    size_t dims[2] = {rows, cols};
    /* matio copies the data (no MAT_F_DONT_COPY_DATA) */
    return Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, (void *)data, 0);
}

static matvar_t *text_var(const char *name, const char *text) {
    size_t dims[2] = {1, strlen(text)};
    return Mat_VarCreate(name, MAT_C_CHAR, MAT_T_UTF8, 2, dims, (void *)text, 0);
}

/* A struct with one field per column, each a rows x 1 double vector. */
static matvar_t *table_var(const rths_table *t) {
    char name[64];
    matlab_name(t->name, name, sizeof name);
    const char **fields = calloc((size_t)t->columns + 1, sizeof *fields);
    char(*names)[64] = calloc((size_t)t->columns + 1, sizeof *names);
    matvar_t *s = NULL;
    if (fields && names) {
        for (int c = 0; c < t->columns; c++) {
            matlab_name(t->column_names[c], names[c], sizeof names[c]);
            fields[c] = names[c];
        }
        size_t dims[2] = {1, 1};
        s = Mat_VarCreateStruct(name, 2, dims, fields, (unsigned)t->columns);
    }
    for (int c = 0; s && c < t->columns; c++) {
        matvar_t *v = double_var(NULL, (size_t)t->rows, 1, t->data[c]);
        if (!v) {
            Mat_VarFree(s);
            s = NULL;
            break;
        }
        Mat_VarSetStructFieldByName(s, names[c], 0, v);
    }
    free(fields);
    free(names);
    return s;
}

static matvar_t *json_var(const char *name, json_object *o);

static int is_number(json_object *o) {
    return json_object_is_type(o, json_type_double) || json_object_is_type(o, json_type_int) ||
           json_object_is_type(o, json_type_boolean) || json_object_is_type(o, json_type_null);
}

static double number_of(json_object *o) {
    return json_object_is_type(o, json_type_null) ? NAN : json_object_get_double(o);
}

/* A list of numbers -> 1 x n; a list of equal-length lists of numbers -> n x m; anything else
 * -> a 1 x n cell of converted elements. */
static matvar_t *json_array_var(const char *name, json_object *a) {
    size_t n = json_object_array_length(a), m = 0;
    int numbers = 1, rows_of_numbers = n > 0;
    for (size_t i = 0; i < n; i++) {
        json_object *e = json_object_array_get_idx(a, i);
        numbers &= is_number(e);
        int row = json_object_is_type(e, json_type_array);
        size_t len = row ? json_object_array_length(e) : 0;
        if (i == 0) m = len;
        for (size_t j = 0; row && j < len; j++)
            row &= is_number(json_object_array_get_idx(e, j));
        rows_of_numbers &= row && len == m && m > 0;
    }
    if (numbers || rows_of_numbers) {
        size_t cols = numbers ? 1 : m;
        double *v = calloc(n * cols + 1, sizeof *v);
        if (!v) return NULL;
        for (size_t i = 0; i < n; i++) {
            json_object *e = json_object_array_get_idx(a, i);
            for (size_t j = 0; j < cols; j++) /* column-major n x cols */
                v[i + j * n] = numbers ? number_of(e) : number_of(json_object_array_get_idx(e, j));
        }
        matvar_t *var = numbers ? double_var(name, 1, n, v) : double_var(name, n, m, v);
        free(v);
        return var;
    }
    size_t dims[2] = {1, n};
    matvar_t *cell = Mat_VarCreate(name, MAT_C_CELL, MAT_T_CELL, 2, dims, NULL, 0);
    for (size_t i = 0; cell && i < n; i++) {
        matvar_t *e = json_var(NULL, json_object_array_get_idx(a, i));
        if (!e) {
            Mat_VarFree(cell);
            return NULL;
        }
        Mat_VarSetCell(cell, (int)i, e);
    }
    return cell;
}

static matvar_t *json_object_var(const char *name, json_object *o) {
    int n = json_object_object_length(o), k = 0;
    const char **fields = calloc((size_t)n + 1, sizeof *fields);
    char(*names)[64] = calloc((size_t)n + 1, sizeof *names);
    matvar_t *s = NULL;
    if (fields && names) {
        json_object_object_foreach(o, key, val) {
            (void)val;
            matlab_name(key, names[k], sizeof names[k]);
            fields[k] = names[k];
            k++;
        }
        size_t dims[2] = {1, 1};
        s = Mat_VarCreateStruct(name, 2, dims, fields, (unsigned)n);
    }
    k = 0;
    json_object_object_foreach(o, key2, val2) {
        (void)key2;
        if (!s) break;
        matvar_t *v = json_var(NULL, val2);
        if (!v) {
            Mat_VarFree(s);
            s = NULL;
            break;
        }
        Mat_VarSetStructFieldByName(s, names[k++], 0, v);
    }
    free(fields);
    free(names);
    return s;
}

static matvar_t *json_var(const char *name, json_object *o) {
    if (json_object_is_type(o, json_type_object)) return json_object_var(name, o);
    if (json_object_is_type(o, json_type_array)) return json_array_var(name, o);
    if (json_object_is_type(o, json_type_string)) return text_var(name, json_object_get_string(o));
    if (json_object_is_type(o, json_type_null)) return double_var(name, 0, 0, NULL);
    double v = json_object_get_double(o);
    return double_var(name, 1, 1, &v);
}

static int write_var(mat_t *mat, matvar_t *v, const char *what, rths_error *err) {
    if (!v) return rths_error_set(err, RTHS_EFAIL, "results.mat: cannot build %s", what);
    int bad = Mat_VarWrite(mat, v, MAT_COMPRESSION_NONE);
    Mat_VarFree(v);
    return bad ? rths_error_set(err, RTHS_EFAIL, "results.mat: cannot write %s", what) : RTHS_OK;
}

/* summary.json as `summary` (struct) and `summary_json` (text); config.yaml as `config_yaml`. */
static int write_texts(mat_t *mat, const char *dir, rths_error *err) {
    char path[4096];
    snprintf(path, sizeof path, "%s/summary.json", dir);
    char *json = rths_read_file(path, SIZE_MAX, NULL);
    int rc = RTHS_OK;
    if (json) {
        json_object *o = json_tokener_parse(json);
        if (o) rc = write_var(mat, json_var("summary", o), "summary", err);
        json_object_put(o);
        if (!rc) rc = write_var(mat, text_var("summary_json", json), "summary_json", err);
        free(json);
    }
    snprintf(path, sizeof path, "%s/config.yaml", dir);
    char *yaml = rc ? NULL : rths_read_file(path, SIZE_MAX, NULL);
    if (yaml) rc = write_var(mat, text_var("config_yaml", yaml), "config_yaml", err);
    free(yaml);
    return rc;
}

static int is_csv(const char *name) {
    size_t len = strlen(name);
    return len > 4 && !strcmp(name + len - 4, ".csv");
}

static int write_tables(mat_t *mat, const char *dir, const char *const *csv_names, int n_csv,
                        rths_error *err) {
    DIR *d = csv_names ? NULL : opendir(dir);
    if (!csv_names && !d) return rths_error_set(err, RTHS_EFAIL, "cannot list %s", dir);
    int rc = RTHS_OK;
    for (int i = 0; !rc; i++) {
        const char *name;
        if (csv_names) {
            if (i >= n_csv) break;
            name = csv_names[i];
        } else {
            struct dirent *e = readdir(d);
            if (!e) break;
            name = e->d_name;
            if (!is_csv(name)) continue;
        }
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, name);
        rths_table t;
        rc = rths_csv_read(path, &t, err);
        if (!rc) rc = write_var(mat, table_var(&t), name, err);
        rths_table_free(&t);
    }
    if (d) closedir(d);
    return rc;
}

/* Per-point harmonic coefficients of an FRF run, from its journal (the record of every accepted
 * point): one row per point; the measured Fourier coefficients a<k>, b<k> (k = 0..5; b0 is always
 * 0) of the physical and numerical interface displacements with their standard errors, and the
 * control target's a<k>, b<k> (k = 1..harmonics matched; 0 beyond). */
enum { H = RTHS_MAX_HARMONICS, HARMONIC_COLUMNS = 4 + 8 * (H + 1) + 2 * H };

static void harmonic_names(char (*names)[40]) {
    static const char *const sides[4] = {"phys", "num", "phys_se", "num_se"};
    int c = 0;
    snprintf(names[c++], 40, "point");
    snprintf(names[c++], 40, "frequency_hz");
    snprintf(names[c++], 40, "omega_rad_s");
    snprintf(names[c++], 40, "harmonics_matched");
    for (int s = 0; s < 4; s++)
        for (int k = 0; k <= H; k++) {
            snprintf(names[c++], 40, "%s_a%d_m", sides[s], k);
            snprintf(names[c++], 40, "%s_b%d_m", sides[s], k);
        }
    for (int k = 1; k <= H; k++) {
        snprintf(names[c++], 40, "target_a%d_m", k);
        snprintf(names[c++], 40, "target_b%d_m", k);
    }
}

static void harmonic_row(const rths_point *pt, rths_table *t, int i) {
    const rths_evaluation *e = &pt->sol.eval;
    const rths_fourier *sides[4] = {&e->phys, &e->num, &e->phys_se, &e->num_se};
    int c = 0;
    t->data[c++][i] = pt->index;
    t->data[c++][i] = pt->sol.frequency_hz;
    t->data[c++][i] = pt->sol.omega_rad_s;
    t->data[c++][i] = pt->sol.harmonics;
    for (int s = 0; s < 4; s++)
        for (int k = 0; k <= H; k++) {
            t->data[c++][i] = sides[s]->a[k];
            t->data[c++][i] = sides[s]->b[k];
        }
    for (int k = 0; k < H; k++) {
        t->data[c++][i] = k < pt->sol.harmonics ? pt->sol.target_a[k] : 0;
        t->data[c++][i] = k < pt->sol.harmonics ? pt->sol.target_b[k] : 0;
    }
}

static int harmonics_from_journal(const char *path, rths_table *t, rths_error *err) {
    rths_point *pts = NULL;
    char *strategy = NULL;
    int n = 0;
    int rc = rths_journal_read(path, &pts, &n, &strategy, err);
    free(strategy);
    char names[HARMONIC_COLUMNS][40];
    const char *ptrs[HARMONIC_COLUMNS];
    harmonic_names(names);
    for (int c = 0; c < HARMONIC_COLUMNS; c++)
        ptrs[c] = names[c];
    if (!rc) rc = rths_table_create("harmonics", n, HARMONIC_COLUMNS, ptrs, t, err);
    for (int i = 0; i < n && !rc; i++)
        harmonic_row(&pts[i], t, i);
    free(pts);
    return rc;
}

static int write_journal_harmonics(mat_t *mat, const char *dir, const rths_table *extra,
                                   int n_extra, rths_error *err) {
    for (int i = 0; i < n_extra; i++)
        if (!strcmp(extra[i].name, "harmonics")) return RTHS_OK; /* given by the run itself */
    char path[4096];
    snprintf(path, sizeof path, "%s/journal.jsonl", dir);
    if (access(path, R_OK)) return RTHS_OK;
    rths_table t;
    int rc = harmonics_from_journal(path, &t, err);
    if (!rc) rc = write_var(mat, table_var(&t), "harmonics", err);
    rths_table_free(&t);
    return rc;
}

/* HDF5's reason for a failed write, from its error stack: the operating system's message that its
 * low-level write quotes ("error message = 'No space left on device'"). HDF5 calls this instead of
 * printing its stack (H5Eset_auto2), so a failure costs one line of ours, not thousands of its. */
typedef struct {
    char reason[256];
} hdf5_failure;

static herr_t find_os_reason(unsigned n, const H5E_error2_t *e, void *data) {
    (void)n;
    hdf5_failure *f = data;
    const char *quote = e && e->desc ? strstr(e->desc, "error message = '") : NULL;
    if (!quote || f->reason[0]) return 0;
    quote += strlen("error message = '");
    size_t len = strcspn(quote, "'");
    if (len >= sizeof f->reason) len = sizeof f->reason - 1;
    memcpy(f->reason, quote, len);
    f->reason[len] = 0;
    return 0;
}

static herr_t on_hdf5_error(hid_t stack, void *data) {
    H5Ewalk2(stack, H5E_WALK_DOWNWARD, find_os_reason, data);
    return 0;
}

/* Writes the MAT file to tmp and checks that it reads back; runs in the writer's child process. */
static int write_tmp(const char *tmp, const char *dir, const char *const *csv_names, int n_csv,
                     const rths_table *extra, int n_extra, const hdf5_failure *hdf5,
                     rths_error *err) {
    mat_t *mat = Mat_CreateVer(tmp, NULL, MAT_FT_MAT73);
    if (!mat)
        return rths_error_set(err, RTHS_EFAIL, "cannot create %s: %s", tmp,
                              hdf5->reason[0] ? hdf5->reason
                                              : "libmatio without MAT 7.3 (HDF5) support?");
    int rc = write_tables(mat, dir, csv_names, n_csv, err);
    for (int i = 0; i < n_extra && !rc; i++)
        rc = write_var(mat, table_var(&extra[i]), extra[i].name, err);
    if (!rc) rc = write_journal_harmonics(mat, dir, extra, n_extra, err);
    if (!rc) rc = write_texts(mat, dir, err);
    /* HDF5 reports most failed writes (disk full, file size limit) only when the file closes */
    if (Mat_Close(mat) && !rc) rc = rths_error_set(err, RTHS_EFAIL, "closing it failed");
    if (!rc) {
        /* the data must be on disk, and readable, before the name points at them */
        int fd = open(tmp, O_RDONLY | O_CLOEXEC);
        if (fd < 0 || fsync(fd)) rc = rths_error_set(err, RTHS_EFAIL, "%s", strerror(errno));
        if (fd >= 0) close(fd);
        mat_t *check = rc ? NULL : Mat_Open(tmp, MAT_ACC_RDONLY);
        if (!rc && !check) rc = rths_error_set(err, RTHS_EFAIL, "it does not read back");
        if (check) Mat_Close(check);
    }
    /* the operating system's reason, when HDF5 met one, says more than matio's status */
    if (rc && hdf5->reason[0]) rths_error_set(err, RTHS_EFAIL, "%s", hdf5->reason);
    return rc;
}

/* One MAT writer at a time in a process: two threads in HDF5 at once (Python threads each running
 * rths.frf) failed intermittently with HDF5 lock errors. */
static pthread_mutex_t writer_lock = PTHREAD_MUTEX_INITIALIZER;

/* A results.mat of a long campaign is a few MB, written in well under a second; ten minutes is a
 * stall, not a slow disk. */
enum { WRITER_LIMIT_S = 600 };

/* The write runs in a child process. A write that fails inside HDF5 (disk full, `ulimit -f`) leaves
 * the library's open-file table in a state that crashes its own clean-up at exit (SIGSEGV in
 * H5F__close_cb, exit 139), and no HDF5 call can close that file again: the child takes that state
 * with it and leaves by _exit. In the child SIGXFSZ is ignored, so a file size limit turns into
 * EFBIG from write() (a failure) instead of killing the process; HDF5's own error printing is
 * replaced by on_hdf5_error. The child's message comes back through a pipe. */
static int write_in_child(const char *tmp, const char *dir, const char *const *csv_names, int n_csv,
                          const rths_table *extra, int n_extra, rths_error *err) {
    /* test hook: a writer that never finishes, stopped after 1 s */
    const char *stall_env = getenv("RTHS_TEST_MAT_WRITER_STALL");
    int stall_for_test = stall_env && !strcmp(stall_env, "1");
    int fds[2];
    if (pipe2(fds, O_CLOEXEC))
        return rths_error_set(err, RTHS_EFAIL, "cannot start the writer: %s", strerror(errno));
    fflush(NULL); /* nothing buffered is written twice */
    pid_t pid = fork();
    if (pid < 0) {
        int e = errno;
        close(fds[0]);
        close(fds[1]);
        return rths_error_set(err, RTHS_EFAIL, "cannot start the writer: %s", strerror(e));
    }
    if (pid == 0) {
        close(fds[0]);
        signal(SIGXFSZ, SIG_IGN);
        int null = open("/dev/null", O_WRONLY | O_CLOEXEC);
        if (null >= 0) dup2(null, STDERR_FILENO); /* matio's own warnings: the message says it */
        static hdf5_failure hdf5;
        H5Eset_auto2(H5E_DEFAULT, on_hdf5_error, &hdf5);
        static rths_error child_err;
        rths_error_clear(&child_err);
        if (stall_for_test) pause(); /* stopped by the watchdog */
        int rc = write_tmp(tmp, dir, csv_names, n_csv, extra, n_extra, &hdf5, &child_err);
        if (rc) {
            size_t len = strlen(child_err.msg), done = 0;
            while (done < len) {
                ssize_t w = write(fds[1], child_err.msg + done, len - done);
                if (w <= 0) break;
                done += (size_t)w;
            }
        }
        _exit(rc ? RTHS_EFAIL : RTHS_OK);
    }
    close(fds[1]);
    /* The parent watches the child, not only the pipe: another thread of the caller forking at the
     * same time (Python running a subprocess) keeps a copy of the pipe's write end, so EOF may come
     * late; and a child that stalls (a lock held by another thread at fork time stays held in the
     * child) is killed after WRITER_LIMIT_S and reported, never waited for without end. */
    int limit_s = stall_for_test ? 1 : WRITER_LIMIT_S;
    char message[RTHS_ERROR_MSG_LEN];
    size_t got = 0;
    int status = 0, exited = 0, stalled = 0, eof = 0;
    struct timespec start;
    clock_gettime(CLOCK_MONOTONIC, &start);
    while (!exited) {
        pid_t w = waitpid(pid, &status, WNOHANG);
        if (w == pid || (w < 0 && errno != EINTR)) {
            exited = 1;
            fcntl(fds[0], F_SETFL, O_NONBLOCK); /* the rest of the message, without waiting */
        } else {
            struct timespec now;
            clock_gettime(CLOCK_MONOTONIC, &now);
            if ((double)(now.tv_sec - start.tv_sec) > limit_s) {
                kill(pid, SIGKILL);
                while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
                }
                stalled = 1;
                break;
            }
            struct pollfd readable = {.fd = fds[0], .events = POLLIN};
            if (eof || poll(&readable, 1, 100) <= 0) {
                if (eof) nanosleep(&(struct timespec){0, 10000000}, NULL); /* closing, exiting */
                continue;
            }
        }
        for (;;) {
            char chunk[512];
            ssize_t r = read(fds[0], chunk, sizeof chunk);
            if (r < 0 && errno == EINTR) continue;
            if (r == 0) eof = 1;
            if (r <= 0) break;
            size_t keep = sizeof message - 1 - got;
            if ((size_t)r < keep) keep = (size_t)r;
            memcpy(message + got, chunk, keep);
            got += keep;
            if (!exited) break; /* back to watching the child */
        }
    }
    close(fds[0]);
    message[got] = 0;
    if (stalled)
        return rths_error_set(err, RTHS_EFAIL,
                              "the writer did not finish within %d s and was stopped", limit_s);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return RTHS_OK;
    if (WIFSIGNALED(status))
        return rths_error_set(err, RTHS_EFAIL, "the writer died of signal %d (%s)",
                              WTERMSIG(status), strsignal(WTERMSIG(status)));
    return rths_error_set(err, RTHS_EFAIL, "%s", got ? message : "the writer failed");
}

int rths_matfile_write(const char *dir, const char *const *csv_names, int n_csv,
                       const rths_table *extra, int n_extra, rths_error *err) {
    char path[4096], tmp[4096 + 32];
    snprintf(path, sizeof path, "%s/results.mat", dir);
    snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
    pthread_mutex_lock(&writer_lock);
    remove(tmp);
    rths_error why;
    rths_error_clear(&why);
    int rc = write_in_child(tmp, dir, csv_names, n_csv, extra, n_extra, &why);
    if (!rc && rename(tmp, path)) rc = rths_error_set(&why, RTHS_EFAIL, "%s", strerror(errno));
    if (rc) {
        remove(tmp); /* whatever went wrong, no temporary file is left behind */
        rths_error_set(err, RTHS_EFAIL, "cannot write %s: %.3000s", path, why.msg);
    }
    pthread_mutex_unlock(&writer_lock);
    return rc;
}
