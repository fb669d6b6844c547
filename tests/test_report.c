/* The output folder: CSV numbers survive a round trip bit for bit, files appear only when
 * complete, JSON is valid, a missing gnuplot costs the picture but not the run. */
#include "testlib.h"

#include "rths/report.h"

#include <dirent.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[256];

static int setup_dir(void **state) {
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/rths_test_report_XXXXXX");
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown_dir(void **state) {
    (void)state;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

/* Files in dir whose name contains ".tmp." (left-over temporaries). */
static int count_temporaries(void) {
    DIR *d = opendir(dir);
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)))
        if (strstr(e->d_name, ".tmp.")) n++;
    if (d) closedir(d);
    return n;
}

static void test_csv_round_trip(void **state) {
    (void)state;
    char path[300];
    snprintf(path, sizeof path, "%s/numbers.csv", dir);
    const char *header[3] = {"index", "value_m", "other_s"};
    double values[][3] = {{0, 0.1, 1e-300},     {1, -0.0, 2.5e300}, {2, M_PI, -1.0 / 3.0},
                          {3, 4.9e-324, 13.47}, {4, NAN, 1e-17}};
    rths_csv *csv;
    rths_error err;
    assert_int_equal(rths_csv_open(path, 3, header, &csv, &err), RTHS_OK);
    for (int i = 0; i < 5; i++) assert_int_equal(rths_csv_row(csv, values[i]), RTHS_OK);
    /* nothing at the final name until the close */
    assert_int_equal(access(path, F_OK), -1);
    assert_int_equal(rths_csv_close(csv, &err), RTHS_OK);
    assert_int_equal(count_temporaries(), 0);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[512];
    assert_non_null(fgets(line, sizeof line, f));
    assert_string_equal(line, "index,value_m,other_s\n");
    for (int i = 0; i < 5; i++) {
        assert_non_null(fgets(line, sizeof line, f));
        char *p = line;
        for (int j = 0; j < 3; j++) {
            double v = strtod(p, &p);
            if (isnan(values[i][j]))
                assert_true(isnan(v));
            else
                assert_memory_equal(&v, &values[i][j], sizeof v); /* bit-identical, -0 too */
            p++;
        }
    }
    fclose(f);
}

static void test_atomic_abort_and_replace(void **state) {
    (void)state;
    char path[300];
    snprintf(path, sizeof path, "%s/result.txt", dir);
    rths_error err;
    assert_int_equal(rths_write_file_atomic(path, "old\n", 4, &err), RTHS_OK);
    rths_atomic_file *a;
    FILE *f;
    assert_int_equal(rths_atomic_open(path, &a, &f, &err), RTHS_OK);
    fputs("half-written new content", f);
    rths_atomic_abort(a);
    /* the old file is untouched and no temporary is left */
    f = fopen(path, "r");
    char buf[64] = "";
    assert_non_null(fgets(buf, sizeof buf, f));
    fclose(f);
    assert_string_equal(buf, "old\n");
    assert_int_equal(count_temporaries(), 0);
    assert_int_equal(rths_write_file_atomic(path, "new\n", 4, &err), RTHS_OK);
    f = fopen(path, "r");
    assert_non_null(fgets(buf, sizeof buf, f));
    fclose(f);
    assert_string_equal(buf, "new\n");
}

static void test_json_summary(void **state) {
    (void)state;
    char path[300];
    snprintf(path, sizeof path, "%s/summary.json", dir);
    json_object *o = rths_json_summary_new("frf");
    json_object_object_add(o, "amplitude_m", json_object_new_double(3.4199999999999998e-4));
    rths_error err;
    assert_int_equal(rths_json_write(path, o, &err), RTHS_OK);
    json_object_put(o);
    json_object *back = json_object_from_file(path);
    assert_non_null(back);
    json_object *v;
    assert_true(json_object_object_get_ex(back, "rths_version", &v));
    assert_string_equal(json_object_get_string(v), RTHS_VERSION);
    assert_true(json_object_object_get_ex(back, "command", &v));
    assert_string_equal(json_object_get_string(v), "frf");
    assert_true(json_object_object_get_ex(back, "amplitude_m", &v));
    assert_true(json_object_get_double(v) == 3.4199999999999998e-4);
    json_object_put(back);
}

static long file_size(const char *name) {
    char path[300];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

static void test_plot_with_and_without_gnuplot(void **state) {
    (void)state;
    rths_report *rep;
    rths_error err;
    char *argv[] = {"rths", "test", NULL};
    assert_int_equal(rths_report_open(dir, "test", 2, argv, &rep, &err), RTHS_OK);
    const char *body = "set xlabel 'x (m)'\nset ylabel 'y (m)'\nplot sin(x) title 'sine'\n";
    assert_int_equal(rths_plot(rep, dir, "sine", 400, 300, body, &err), RTHS_OK);
    assert_true(file_size("sine.gp") > 0);
    if (system("command -v gnuplot >/dev/null 2>&1") == 0) {
        assert_true(file_size("sine.png") > 1000);
        assert_true(file_size("sine.svg") > 1000);
    }
    /* no gnuplot on PATH: still OK, the script is kept, no picture */
    char *path = getenv("PATH") ? strdup(getenv("PATH")) : NULL;
    setenv("PATH", dir, 1);
    assert_int_equal(rths_plot(rep, dir, "nognuplot", 400, 300, body, &err), RTHS_OK);
    if (path) setenv("PATH", path, 1);
    free(path);
    assert_true(file_size("nognuplot.gp") > 0);
    assert_int_equal(file_size("nognuplot.png"), -1);
    rths_report_log(rep, "done");
    rths_report_close(rep);
    assert_true(file_size("run.log") > 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_csv_round_trip),
        cmocka_unit_test(test_atomic_abort_and_replace),
        cmocka_unit_test(test_json_summary),
        cmocka_unit_test(test_plot_with_and_without_gnuplot),
    };
    return cmocka_run_group_tests(tests, setup_dir, teardown_dir);
}
