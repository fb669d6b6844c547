/* results.mat and the run folder's ownership (report module): what a run writes as CSV comes back
 * from the MAT file bit for bit (read with libmatio, independently of the writer's reader), tables
 * without a CSV are added, summary.json becomes a struct; a folder holding another command's run is
 * refused with nothing touched, an earlier run of the same command is replaced, a user's file is
 * kept. */
#include "testlib.h"

#include "rths/report.h"

#include <math.h>
#include <matio.h>
#include <stdio.h>
#include <stdlib.h>
#include <dirent.h>
#include <pthread.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[256];

static int setup_dir(void **state) {
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/rths_test_matfile_XXXXXX");
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown_dir(void **state) {
    (void)state;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

static int exists(const char *folder, const char *name) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", folder, name);
    struct stat st;
    return stat(path, &st) == 0;
}

static void write_text(const char *folder, const char *name, const char *text) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", folder, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

/* Values that a decimal round trip at fewer digits would change, and the specials. */
static const double values[5] = {0.1, 1.0 / 3.0, -2.2250738585072014e-308, 6.02214076e23, NAN};

static void write_run(const char *folder, const char *command) {
    char *argv[] = {(char *)command, NULL};
    rths_report *rep;
    rths_error err;
    assert_int_equal(rths_report_open(folder, command, 1, argv, &rep, &err), RTHS_OK);
    static const char *const header[2] = {"time_s", "x_m"};
    char *path = rths_report_path(rep, "trace.csv");
    rths_csv *csv;
    assert_int_equal(rths_csv_open(path, 2, header, &csv, &err), RTHS_OK);
    for (int i = 0; i < 5; i++) {
        double row[2] = {i * 1e-4, values[i]};
        assert_int_equal(rths_csv_row(csv, row), RTHS_OK);
    }
    assert_int_equal(rths_csv_close(csv, &err), RTHS_OK);
    free(path);
    path = rths_report_path(rep, "summary.json");
    static const char summary[] = "{\"points\": 5, \"stop_reason\": \"end\", \"seed\": [1, 2],"
                                  " \"fold\": {\"frequency_hz\": 12.5}}\n";
    assert_int_equal(rths_write_file_atomic(path, summary, strlen(summary), &err), RTHS_OK);
    free(path);
    /* a table without a CSV: 2 rows x 2 columns */
    rths_table extra;
    const char *names[2] = {"k", "phys_a_m"};
    assert_int_equal(rths_table_create("coefficients", 2, 2, names, &extra, &err), RTHS_OK);
    extra.data[0][0] = 1, extra.data[0][1] = 2;
    extra.data[1][0] = 1e-3, extra.data[1][1] = -2.5e-6;
    assert_int_equal(rths_report_add_table(rep, &extra, &err), RTHS_OK);
    rths_table_free(&extra);
    rths_report_close(rep);
}

static matvar_t *field(matvar_t *s, const char *name) {
    matvar_t *f = Mat_VarGetStructFieldByName(s, name, 0);
    assert_non_null(f);
    assert_int_equal(f->class_type, MAT_C_DOUBLE);
    return f;
}

static void test_mat_equals_csv(void **state) {
    (void)state;
    char run[300];
    snprintf(run, sizeof run, "%s/run", dir);
    write_run(run, "simulate");
    char path[400];
    snprintf(path, sizeof path, "%s/results.mat", run);
    mat_t *mat = Mat_Open(path, MAT_ACC_RDONLY);
    assert_non_null(mat);
    assert_int_equal(Mat_GetVersion(mat), MAT_FT_MAT73);
    matvar_t *trace = Mat_VarRead(mat, "trace");
    assert_non_null(trace);
    assert_int_equal(trace->class_type, MAT_C_STRUCT);
    matvar_t *x = field(trace, "x_m");
    assert_int_equal(x->dims[0], 5);
    assert_int_equal(x->dims[1], 1);
    const double *xd = x->data;
    for (int i = 0; i < 4; i++) /* bit for bit: %.17g round-trips every double */
        assert_memory_equal(&xd[i], &values[i], sizeof(double));
    assert_true(isnan(xd[4]));
    assert_true(((const double *)field(trace, "time_s")->data)[2] == 2e-4);
    Mat_VarFree(trace);
    matvar_t *coef = Mat_VarRead(mat, "coefficients");
    assert_non_null(coef);
    assert_true(((const double *)field(coef, "phys_a_m")->data)[1] == -2.5e-6);
    Mat_VarFree(coef);
    matvar_t *summary = Mat_VarRead(mat, "summary");
    assert_non_null(summary);
    assert_true(*(const double *)field(summary, "points")->data == 5);
    matvar_t *seed = field(summary, "seed");
    assert_int_equal(seed->dims[1], 2);
    assert_true(((const double *)seed->data)[1] == 2);
    matvar_t *reason = Mat_VarGetStructFieldByName(summary, "stop_reason", 0);
    assert_non_null(reason);
    assert_int_equal(reason->class_type, MAT_C_CHAR);
    matvar_t *fold = Mat_VarGetStructFieldByName(summary, "fold", 0);
    assert_non_null(fold);
    assert_true(*(const double *)field(fold, "frequency_hz")->data == 12.5);
    Mat_VarFree(summary);
    Mat_Close(mat);
}

static void test_csv_read_errors(void **state) {
    (void)state;
    write_text(dir, "ragged.csv", "a_m,b_m\n1,2\n3\n");
    char path[400];
    snprintf(path, sizeof path, "%s/ragged.csv", dir);
    rths_table t;
    rths_error err;
    assert_int_equal(rths_csv_read(path, &t, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "ragged.csv:3: 1 fields, the header has 2"));
    write_text(dir, "word.csv", "a_m\nabc\n");
    snprintf(path, sizeof path, "%s/word.csv", dir);
    assert_int_equal(rths_csv_read(path, &t, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "word.csv:2: column a_m: 'abc' is not a number"));
}

static void test_folder_ownership(void **state) {
    (void)state;
    char run[300];
    snprintf(run, sizeof run, "%s/owned", dir);
    write_run(run, "simulate");
    write_text(run, "notes.txt", "mine\n");
    /* another command: refused, nothing touched */
    rths_report *rep;
    rths_error err;
    char *argv[] = {"model", NULL};
    assert_int_equal(rths_report_open(run, "model", 1, argv, &rep, &err), RTHS_EINPUT);
    assert_null(rep);
    assert_non_null(strstr(err.msg, "earlier 'rths simulate' run"));
    assert_true(exists(run, "trace.csv") && exists(run, "results.mat"));
    /* the same command again: the earlier run's files go, the user's stays, run.log grows */
    char *again[] = {"simulate", NULL};
    assert_int_equal(rths_report_open(run, "simulate", 1, again, &rep, &err), RTHS_OK);
    assert_false(exists(run, "trace.csv"));
    assert_false(exists(run, "results.mat"));
    assert_false(exists(run, "summary.json"));
    assert_true(exists(run, "notes.txt"));
    assert_true(exists(run, "run.log"));
    rths_report_close(rep);
    /* nothing written: no results.mat appears */
    assert_false(exists(run, "results.mat"));
    /* --resume keeps the earlier files */
    write_run(run, "simulate");
    char *resume[] = {"simulate", "--resume", NULL};
    assert_int_equal(rths_report_open(run, "simulate", 2, resume, &rep, &err), RTHS_OK);
    assert_true(exists(run, "trace.csv"));
    rths_report_close(rep);
}

/* A folder with one CSV of rows x 3 numbers (about 60 bytes a row), nothing else. */
static void write_table_folder(const char *folder, int rows) {
    assert_int_equal(mkdir(folder, 0755), 0);
    char path[512];
    snprintf(path, sizeof path, "%s/table.csv", folder);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("time_s,x_m,f_n\n", f);
    for (int i = 0; i < rows; i++)
        fprintf(f, "%.17g,%.17g,%.17g\n", i * 1e-4, sin(i * 0.01), cos(i * 0.02));
    assert_int_equal(fclose(f), 0);
}

/* Whether folder holds a name containing part. */
static int has_name_with(const char *folder, const char *part) {
    DIR *d = opendir(folder);
    assert_non_null(d);
    struct dirent *e;
    int found = 0;
    while ((e = readdir(d)))
        found |= strstr(e->d_name, part) != NULL;
    closedir(d);
    return found;
}

/* A file size limit (`ulimit -f`) below results.mat's size: the write fails with the operating
 * system's reason, the process is not killed (SIGXFSZ killed it before) and no temporary file is
 * left; with the limit lifted the same folder is written. */
static void test_file_size_limit(void **state) {
    (void)state;
    char run[300];
    snprintf(run, sizeof run, "%s/limited", dir);
    write_table_folder(run, 400); /* about 24 kB of CSV, a MAT file of the same order */
    struct rlimit old;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &old), 0);
    struct rlimit low = {8192, old.rlim_max};
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &low), 0);
    rths_error err;
    rths_error_clear(&err);
    int rc = rths_matfile_write(run, NULL, 0, NULL, 0, &err);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &old), 0);
    assert_int_equal(rc, RTHS_EFAIL);
    char want[400];
    snprintf(want, sizeof want, "cannot write %s/results.mat: File too large", run);
    assert_string_equal(err.msg, want);
    assert_false(has_name_with(run, "results.mat"));
    assert_int_equal(rths_matfile_write(run, NULL, 0, NULL, 0, &err), RTHS_OK);
    assert_true(exists(run, "results.mat"));
    assert_false(has_name_with(run, ".tmp"));
}

/* A writer that stalls is stopped and reported; the folder keeps no temporary file and the
 * results.mat already there is untouched. */
static void test_writer_stall(void **state) {
    (void)state;
    char run[300];
    snprintf(run, sizeof run, "%.256s/stall", dir);
    write_table_folder(run, 50);
    rths_error err;
    rths_error_clear(&err);
    assert_int_equal(rths_matfile_write(run, NULL, 0, NULL, 0, &err), RTHS_OK);
    setenv("RTHS_TEST_MAT_WRITER_STALL", "1", 1);
    int rc = rths_matfile_write(run, NULL, 0, NULL, 0, &err);
    unsetenv("RTHS_TEST_MAT_WRITER_STALL");
    assert_int_equal(rc, RTHS_EFAIL);
    char want[400];
    snprintf(want, sizeof want,
             "cannot write %s/results.mat: the writer did not finish within 1 s and was stopped",
             run);
    assert_string_equal(err.msg, want);
    assert_false(has_name_with(run, ".tmp"));
    char path[340];
    snprintf(path, sizeof path, "%s/results.mat", run);
    mat_t *mat = Mat_Open(path, MAT_ACC_RDONLY);
    assert_non_null(mat);
    Mat_Close(mat);
}

/* Threads writing results.mat at once (Python threads each running rths.frf) all succeed: the
 * writer is serialised (HDF5 lock errors before, intermittently). */
enum { WRITERS = 4, WRITES = 3 };

/* All writers start together and leave together: no thread is being created or torn down while
 * another forks its writer child. GCC 12's AddressSanitizer does not lock its allocator around
 * fork, so a child forked while another thread is inside it can wait forever (the test's only
 * timeout in CI); the library's watchdog would end that, but it is not the property tested here. */
static pthread_barrier_t writers_start, writers_done;

static void *writer(void *arg) {
    const char *folder = arg;
    static int failures; /* only read after the joins */
    pthread_barrier_wait(&writers_start);
    for (int i = 0; i < WRITES; i++) {
        rths_error err;
        if (rths_matfile_write(folder, NULL, 0, NULL, 0, &err)) {
            fprintf(stderr, "%s: %s\n", folder, err.msg);
            __atomic_add_fetch(&failures, 1, __ATOMIC_SEQ_CST);
        }
    }
    pthread_barrier_wait(&writers_done);
    return &failures;
}

static void test_threads(void **state) {
    (void)state;
    char folders[WRITERS][280];
    pthread_t threads[WRITERS];
    for (int t = 0; t < WRITERS; t++) {
        snprintf(folders[t], sizeof folders[t], "%.256s/thread%d", dir, t);
        write_table_folder(folders[t], 200 + 50 * t);
    }
    assert_int_equal(pthread_barrier_init(&writers_start, NULL, WRITERS), 0);
    assert_int_equal(pthread_barrier_init(&writers_done, NULL, WRITERS), 0);
    for (int t = 0; t < WRITERS; t++)
        assert_int_equal(pthread_create(&threads[t], NULL, writer, folders[t]), 0);
    int *failures = NULL;
    for (int t = 0; t < WRITERS; t++)
        assert_int_equal(pthread_join(threads[t], (void **)&failures), 0);
    assert_int_equal(*failures, 0);
    pthread_barrier_destroy(&writers_start);
    pthread_barrier_destroy(&writers_done);
    for (int t = 0; t < WRITERS; t++) {
        char path[320];
        snprintf(path, sizeof path, "%.280s/results.mat", folders[t]);
        mat_t *mat = Mat_Open(path, MAT_ACC_RDONLY);
        assert_non_null(mat);
        matvar_t *table = Mat_VarRead(mat, "table");
        assert_non_null(table);
        matvar_t *x = field(table, "x_m");
        assert_int_equal(x->dims[0], 200 + 50 * t);
        assert_true(((const double *)x->data)[100] == sin(100 * 0.01));
        Mat_VarFree(table);
        Mat_Close(mat);
        assert_false(has_name_with(folders[t], ".tmp"));
    }
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mat_equals_csv),   cmocka_unit_test(test_csv_read_errors),
        cmocka_unit_test(test_folder_ownership), cmocka_unit_test(test_file_size_limit),
        cmocka_unit_test(test_writer_stall),     cmocka_unit_test(test_threads),
    };
    return cmocka_run_group_tests(tests, setup_dir, teardown_dir);
}
