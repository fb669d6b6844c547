/* The output folder: CSV numbers survive a round trip bit for bit, files appear only when
 * complete, JSON is valid, a missing gnuplot costs the picture but not the run. */
#include "testlib.h"

#include "rths/report.h"

#include <dirent.h>
#include <json-c/json.h>
#include <locale.h>
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
    double values[][3] = {{0, 0.1, 1e-300},
                          {1, -0.0, 2.5e300},
                          {2, M_PI, -1.0 / 3.0},
                          {3, 4.9e-324, 13.47},
                          {4, NAN, 1e-17}};
    rths_csv *csv;
    rths_error err;
    assert_int_equal(rths_csv_open(path, 3, header, &csv, &err), RTHS_OK);
    for (int i = 0; i < 5; i++)
        assert_int_equal(rths_csv_row(csv, values[i]), RTHS_OK);
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

/* The whole of dir/name, NUL-terminated (binary files too: only the prefix is compared). */
static char *slurp(const char *name) {
    char path[300];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    rewind(f);
    char *buf = calloc((size_t)n + 1, 1);
    assert_non_null(buf);
    assert_int_equal(fread(buf, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    return buf;
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
    char *gp = slurp("sine.gp");
    assert_non_null(strstr(gp, "set terminal pngcairo size 400,300"));
    assert_non_null(strstr(gp, "set output 'sine.png'\nset xlabel 'x (m)'"));
    assert_non_null(strstr(gp, "set terminal svg size 400,300"));
    assert_non_null(strstr(gp, "set output 'sine.svg'\nset xlabel 'x (m)'"));
    assert_non_null(strstr(gp, "unset output"));
    free(gp);
    if (system("command -v gnuplot >/dev/null 2>&1") == 0) {
        assert_true(file_size("sine.png") > 1000);
        assert_true(file_size("sine.svg") > 1000);
        char *png = slurp("sine.png"), *svg = slurp("sine.svg");
        assert_memory_equal(png, "\x89PNG\r\n\x1a\n", 8);
        assert_non_null(strstr(svg, "<svg"));
        assert_non_null(strstr(svg, "sine"));
        free(png);
        free(svg);
    } else {
        print_message("(gnuplot not installed: figures not checked)\n");
    }
    /* gnuplot refusing the body (exit status 1): a warning, still OK */
    if (system("command -v gnuplot >/dev/null 2>&1") == 0) {
        assert_int_equal(rths_plot(rep, dir, "broken", 400, 300, "plot undefined_fn(x)\n", &err),
                         RTHS_OK);
        assert_true(file_size("broken.gp") > 0);
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
    char *log = slurp("run.log");
    assert_non_null(strstr(log, "warning: gnuplot is not available"));
    if (system("command -v gnuplot >/dev/null 2>&1") == 0)
        assert_non_null(strstr(log, "warning: gnuplot failed on"));
    free(log);
}

/* Random bit patterns cover every exponent, subnormals, both zeros and infinities: each value
 * written with %.17g must read back bit for bit (NaN as NaN). */
static void test_csv_random_bits(void **state) {
    (void)state;
    char path[300];
    snprintf(path, sizeof path, "%s/random.csv", dir);
    enum { ROWS = 500, COLS = 4 };
    static double v[ROWS][COLS];
    rths_rng rng;
    rths_rng_seed(&rng, 20261123);
    for (int i = 0; i < ROWS; i++)
        for (int j = 0; j < COLS; j++) {
            uint64_t bits = rths_rng_next(&rng);
            if (j == 3) bits >>= 12; /* subnormals: exponent field zero */
            memcpy(&v[i][j], &bits, sizeof bits);
        }
    v[0][0] = -0.0;
    v[0][1] = INFINITY;
    v[0][2] = -INFINITY;
    v[0][3] = NAN;
    const char *header[COLS] = {"a_m", "b_s", "c_N", "d_kg"};
    rths_csv *csv;
    rths_error err;
    assert_int_equal(rths_csv_open(path, COLS, header, &csv, &err), RTHS_OK);
    for (int i = 0; i < ROWS; i++)
        assert_int_equal(rths_csv_row(csv, v[i]), RTHS_OK);
    assert_int_equal(rths_csv_close(csv, &err), RTHS_OK);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[1024];
    assert_non_null(fgets(line, sizeof line, f));
    assert_string_equal(line, "a_m,b_s,c_N,d_kg\n");
    int nans = 0;
    for (int i = 0; i < ROWS; i++) {
        assert_non_null(fgets(line, sizeof line, f));
        char *p = line;
        for (int j = 0; j < COLS; j++) {
            char *end;
            double back = strtod(p, &end);
            assert_true(end > p);
            assert_true(*end == (j == COLS - 1 ? '\n' : ','));
            if (isnan(v[i][j])) {
                assert_true(isnan(back));
                assert_memory_equal(p, "nan", 3);
                nans++;
            } else {
                assert_memory_equal(&back, &v[i][j], sizeof back);
            }
            p = end + 1;
        }
    }
    assert_null(fgets(line, sizeof line, f));
    fclose(f);
    assert_true(nans >= 1);
}

/* The decimal point is '.' even when the process runs in a locale with ','. */
static void test_csv_locale(void **state) {
    (void)state;
    const char *locales[] = {"de_DE.UTF-8", "de_DE.utf8", "fr_FR.UTF-8", NULL};
    int switched = 0;
    for (int k = 0; locales[k] && !switched; k++)
        switched = setlocale(LC_NUMERIC, locales[k]) != NULL;
    char path[300];
    snprintf(path, sizeof path, "%s/locale.csv", dir);
    const char *header[2] = {"t_s", "x_m"};
    double row[2] = {0.5, -1234.125}; /* exact binary fractions: %.17g prints them as written */
    rths_csv *csv;
    rths_error err;
    assert_int_equal(rths_csv_open(path, 2, header, &csv, &err), RTHS_OK);
    assert_int_equal(rths_csv_row(csv, row), RTHS_OK);
    assert_int_equal(rths_csv_close(csv, &err), RTHS_OK);
    setlocale(LC_NUMERIC, "C");
    FILE *f = fopen(path, "r");
    char line[256];
    assert_non_null(fgets(line, sizeof line, f));
    assert_non_null(fgets(line, sizeof line, f));
    fclose(f);
    assert_string_equal(line, "0.5,-1234.125\n");
    if (!switched) print_message("(no comma locale installed: checked in the C locale only)\n");
}

/* An aborted CSV leaves nothing; a file being rewritten keeps its old content until the commit. */
static void test_atomic_commit_only(void **state) {
    (void)state;
    char path[300];
    snprintf(path, sizeof path, "%s/aborted.csv", dir);
    const char *header[1] = {"x_m"};
    double x = 1;
    rths_csv *csv;
    rths_error err;
    assert_int_equal(rths_csv_open(path, 1, header, &csv, &err), RTHS_OK);
    assert_int_equal(rths_csv_row(csv, &x), RTHS_OK);
    assert_int_equal(count_temporaries(), 1);
    rths_csv_abort(csv);
    assert_int_equal(access(path, F_OK), -1);
    assert_int_equal(count_temporaries(), 0);

    snprintf(path, sizeof path, "%s/replaced.txt", dir);
    assert_int_equal(rths_write_file_atomic(path, "old\n", 4, &err), RTHS_OK);
    rths_atomic_file *a;
    FILE *f;
    assert_int_equal(rths_atomic_open(path, &a, &f, &err), RTHS_OK);
    fputs("new\n", f);
    fflush(f);
    FILE *r = fopen(path, "r");
    char buf[16] = "";
    assert_non_null(fgets(buf, sizeof buf, r));
    fclose(r);
    assert_string_equal(buf, "old\n"); /* still the old file while the new one is written */
    assert_int_equal(rths_atomic_commit(a, &err), RTHS_OK);
    r = fopen(path, "r");
    assert_non_null(fgets(buf, sizeof buf, r));
    fclose(r);
    assert_string_equal(buf, "new\n");
    assert_int_equal(count_temporaries(), 0);
    /* a folder that cannot exist: a clear error, nothing left */
    snprintf(path, sizeof path, "%s/replaced.txt/inside.txt", dir);
    assert_int_equal(rths_write_file_atomic(path, "x", 1, &err), RTHS_EFAIL);
    assert_non_null(strstr(err.msg, "inside.txt"));
}

/* run.log: the command line first, appended on reopen (a resumed run keeps its history). */
static void test_report_folder(void **state) {
    (void)state;
    char sub[300];
    snprintf(sub, sizeof sub, "%s/a/b/run", dir);
    char *argv[] = {"rths", "frf", "test.yaml", "--set", "split.mass_ratio=0.3", NULL};
    rths_report *rep;
    rths_error err;
    assert_int_equal(rths_report_open(sub, "frf", 5, argv, &rep, &err), RTHS_OK);
    assert_string_equal(rths_report_dir(rep), sub);
    char *p = rths_report_path(rep, "summary.json");
    char want[400];
    snprintf(want, sizeof want, "%s/summary.json", sub);
    assert_string_equal(p, want);
    free(p);
    rths_report_log(rep, "iteration %d error %.3g m", 3, 1.5e-6);
    rths_report_close(rep);
    assert_int_equal(rths_report_open(sub, "frf", 5, argv, &rep, &err), RTHS_OK);
    rths_report_close(rep);
    snprintf(want, sizeof want, "%s/run.log", sub);
    FILE *f = fopen(want, "r");
    assert_non_null(f);
    char lines[3][512];
    for (int i = 0; i < 3; i++)
        assert_non_null(fgets(lines[i], sizeof lines[i], f));
    fclose(f);
    /* "YYYY-MM-DDTHH:MM:SSZ " then the command line */
    assert_int_equal(lines[0][4], '-');
    assert_int_equal(lines[0][10], 'T');
    assert_int_equal(lines[0][19], 'Z');
    assert_non_null(strstr(lines[0], "frf: frf test.yaml --set split.mass_ratio=0.3\n"));
    assert_non_null(strstr(lines[1], "iteration 3 error 1.5e-06 m\n"));
    assert_non_null(strstr(lines[2], "frf test.yaml"));
    /* a folder under a regular file cannot be made */
    snprintf(sub, sizeof sub, "%s/a/b/run/run.log/x", dir);
    assert_int_equal(rths_report_open(sub, "frf", 1, argv, &rep, &err), RTHS_EFAIL);
    assert_null(rep);
    assert_non_null(strstr(err.msg, "run.log"));
    assert_int_equal(rths_progress_enabled(1), 0);
    assert_int_equal(rths_progress_enabled(0), isatty(2) ? 1 : 0);
}

/* The figures' unit per magnitude (rths_plot_unit): the SI unit scaled by a power of 1000 so the
 * largest value reads between 1 and 1000; zero or non-finite magnitudes keep the SI unit. */
static void test_plot_unit(void **state) {
    (void)state;
    static const struct {
        double max_abs;
        const char *si, *label;
        double scale;
    } cases[] = {{3.4e-4, "m", "µm", 1e6},     {0.5, "m", "mm", 1e3},    {1.2, "m", "m", 1},
                 {2e-3, "m", "mm", 1e3},       {5e-10, "m", "pm", 1e12}, {3e-3, "rad", "mrad", 1e3},
                 {3.4e-4, "m/N", "µm/N", 1e6}, {0, "m", "m", 1},         {NAN, "s", "s", 1},
                 {1.5e-4, "s", "µs", 1e6},     {1e-20, "m", "pm", 1e12}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char label[24];
        double scale = rths_plot_unit(cases[i].max_abs, cases[i].si, label, sizeof label);
        assert_string_equal(label, cases[i].label);
        assert_rel(scale, cases[i].scale, 1e-12);
    }
    /* the palette cycles, and a negative index is the first colour */
    assert_string_equal(rths_plot_colour(0), rths_plot_colour(5));
    assert_string_equal(rths_plot_colour(-1), rths_plot_colour(0));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_plot_unit),
        cmocka_unit_test(test_csv_round_trip),
        cmocka_unit_test(test_atomic_abort_and_replace),
        cmocka_unit_test(test_json_summary),
        cmocka_unit_test(test_plot_with_and_without_gnuplot),
        cmocka_unit_test(test_csv_random_bits),
        cmocka_unit_test(test_csv_locale),
        cmocka_unit_test(test_atomic_commit_only),
        cmocka_unit_test(test_report_folder),
    };
    return cmocka_run_group_tests(tests, setup_dir, teardown_dir);
}
