/* The view module without a browser: the --listen parser, loopback detection, what counts as a
 * run folder, and /api/points built from frf.csv and from journal.jsonl against values computed
 * here from the point's coefficients (the HTTP side is tests/cli/view.sh). */
#include "rths/continuation.h"
#include "rths/view.h"
#include "testlib.h"

#include <civetweb.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char scratch[64];

static int setup(void **state) {
    (void)state;
    snprintf(scratch, sizeof scratch, "/tmp/rths-test-view-XXXXXX");
    return mkdtemp(scratch) ? 0 : -1;
}

static int teardown(void **state) {
    (void)state;
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", scratch);
    return system(cmd) == 0 ? 0 : -1;
}

static void write_text(const char *name, const char *text) {
    char path[128];
    snprintf(path, sizeof path, "%s/%s", scratch, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

static void listen_addresses(void **state) {
    (void)state;
    char host[64];
    int port = -1;
    rths_error err;
    assert_int_equal(rths_view_parse_listen("127.0.0.1:8080", host, sizeof host, &port, &err), 0);
    assert_string_equal(host, "127.0.0.1");
    assert_int_equal(port, 8080);
    assert_int_equal(rths_view_parse_listen("[::1]:0", host, sizeof host, &port, &err), 0);
    assert_string_equal(host, "::1");
    assert_int_equal(port, 0);
    assert_int_equal(rths_view_parse_listen("9000", host, sizeof host, &port, &err), 0);
    assert_string_equal(host, "127.0.0.1"); /* a bare port stays on loopback */
    assert_int_equal(port, 9000);
    const char *bad[] = {"",
                         "127.0.0.1",
                         "127.0.0.1:",
                         ":80",
                         "127.0.0.1:65536",
                         "127.0.0.1:-1",
                         "127.0.0.1:80x",
                         "example.com:80",
                         "1.2.3:80"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        assert_int_equal(rths_view_parse_listen(bad[i], host, sizeof host, &port, &err),
                         RTHS_EINPUT);
    assert_true(rths_view_host_is_loopback("127.0.0.1"));
    assert_true(rths_view_host_is_loopback("127.8.9.10"));
    assert_true(rths_view_host_is_loopback("::1"));
    assert_true(rths_view_host_is_loopback("localhost"));
    assert_false(rths_view_host_is_loopback("0.0.0.0"));
    assert_false(rths_view_host_is_loopback("10.1.2.3"));
    assert_false(rths_view_host_is_loopback("::"));
    assert_false(rths_view_host_is_loopback("128.0.0.1"));
}

static void run_folders(void **state) {
    (void)state;
    rths_error err;
    char path[128];
    snprintf(path, sizeof path, "%s/missing", scratch);
    assert_int_equal(rths_view_check_run_dir(path, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "No such file"));
    assert_int_equal(rths_view_check_run_dir(scratch, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "not a run folder"));
    write_text("notes.txt", "x\n");
    snprintf(path, sizeof path, "%s/notes.txt", scratch);
    assert_int_equal(rths_view_check_run_dir(path, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "not a folder"));
    write_text("live.json", "{}\n");
    assert_int_equal(rths_view_check_run_dir(scratch, &err), RTHS_OK);
    /* the server refuses a non-run folder before binding anything */
    rths_view_options opt;
    rths_view_options_defaults(&opt);
    assert_string_equal(opt.host, "127.0.0.1");
    snprintf(path, sizeof path, "%s/missing", scratch);
    opt.run_dir = path;
    opt.port = 0;
    rths_view *v = NULL;
    assert_int_equal(rths_view_start(&opt, &v, &err), RTHS_EINPUT);
    assert_null(v);
    opt.run_dir = scratch;
    assert_int_equal(rths_view_start(&opt, &v, &err), RTHS_OK);
    assert_true(rths_view_port(v) > 0); /* port 0: the system picked one */
    rths_view_stop(v);
}

static json_object *first_point(const char *json, const char *source) {
    json_object *root = json_tokener_parse(json);
    assert_non_null(root);
    json_object *v, *pts;
    assert_true(json_object_object_get_ex(root, "source", &v));
    assert_string_equal(json_object_get_string(v), source);
    assert_true(json_object_object_get_ex(root, "points", &pts));
    assert_int_equal((int)json_object_array_length(pts), 1);
    json_object *p = json_object_get(json_object_array_get_idx(pts, 0));
    json_object_put(root);
    return p;
}

static double field(json_object *p, const char *key) {
    json_object *v;
    assert_true(json_object_object_get_ex(p, key, &v));
    return json_object_get_double(v);
}

static void points_from_csv(void **state) {
    (void)state;
    write_text("frf.csv", "point,frequency_hz,amplitude_m\n0,12.5,nan\n");
    char *json = NULL;
    rths_error err;
    assert_int_equal(rths_view_points_json(scratch, &json, &err), RTHS_OK);
    json_object *p = first_point(json, "frf.csv");
    assert_close(field(p, "frequency_hz"), 12.5, 0);
    json_object *v;
    assert_true(json_object_object_get_ex(p, "amplitude_m", &v));
    assert_null(v); /* NaN is null: JSON has no NaN */
    json_object_put(p);
    free(json);
}

/* A journal point whose frf.csv row follows from its coefficients by hand. */
static void points_from_journal(void **state) {
    (void)state;
    char path[128];
    snprintf(path, sizeof path, "%s/journal.jsonl", scratch);
    rths_journal *j;
    rths_error err;
    assert_int_equal(rths_journal_open(path, "default", &j, &err), RTHS_OK);
    rths_point pt;
    memset(&pt, 0, sizeof pt);
    pt.sol.harmonics = pt.sol.eval.harmonics = 1;
    pt.sol.frequency_hz = pt.sol.eval.frequency_hz = 13;
    pt.sol.omega_rad_s = 2 * M_PI * 13;
    pt.sol.eval.phys.a[1] = 3e-6; /* measured amplitude 5e-6, phase atan2(4, 3) */
    pt.sol.eval.phys.b[1] = -4e-6;
    pt.sol.eval.num.a[1] = 3e-6 + 6e-9; /* mismatch (6, 8) nm: 10 nm */
    pt.sol.eval.num.b[1] = -4e-6 + 8e-9;
    pt.sol.eval.phys.a[2] = 5e-8; /* second harmonic 1.3e-7 */
    pt.sol.eval.phys.b[2] = 1.2e-7;
    pt.sol.amplitude_m = 5.001e-6;
    pt.sol.amplitude_se_m = 2e-9;
    pt.sol.target_a[0] = 1e-6;
    pt.sol.target_b[0] = -2e-6;
    pt.sol.residual_norm_m = 1e-8;
    pt.sol.tolerance_m = 2e-8;
    pt.sol.converged = 1;
    pt.evaluations = 3;
    pt.iterations = 2;
    pt.rig_time_s = 4.5;
    assert_int_equal(rths_journal_append(j, &pt, 0, &err), RTHS_OK);
    rths_journal_close(j);
    char *json = NULL;
    assert_int_equal(rths_view_points_json(scratch, &json, &err), RTHS_OK);
    json_object *p = first_point(json, "journal.jsonl");
    assert_close(field(p, "point"), 0, 0);
    assert_close(field(p, "frequency_hz"), 13, 0);
    assert_close(field(p, "amplitude_m"), 5.001e-6, 0);
    assert_rel(field(p, "measured_amplitude_m"), 5e-6, 1e-14);
    assert_rel(field(p, "phase_rad"), atan2(4, 3), 1e-14);
    assert_rel(field(p, "interface_error_m"), 1e-8, 1e-6); /* difference of 3e-6-sized numbers */
    assert_rel(field(p, "amplitude_h2_m"), 1.3e-7, 1e-14);
    assert_rel(field(p, "numerical_amplitude_m"), hypot(3.006e-6, 3.992e-6), 1e-14);
    assert_close(field(p, "target_b1_m"), -2e-6, 0);
    assert_close(field(p, "evaluations"), 3, 0);
    assert_close(field(p, "rig_time_s"), 4.5, 0);
    assert_close(field(p, "converged"), 1, 0);
    assert_close(field(p, "amplitude_se_m"), 2e-9, 0);
    json_object_put(p);
    free(json);
}

/* The controller's page: no run folder, a process snapshot served under /api/status "process". */
static int snapshot(void *user, char *buf, size_t cap) {
    return snprintf(buf, cap, "{\"overruns\": %d, \"armed\": true}", *(int *)user);
}

static void process_snapshot(void **state) {
    (void)state;
    int overruns = 17;
    rths_view_options opt;
    rths_view_options_defaults(&opt);
    opt.port = 0;
    opt.snapshot = snapshot;
    opt.snapshot_user = &overruns;
    rths_view *v;
    rths_error err;
    assert_int_equal(rths_view_start(&opt, &v, &err), RTHS_OK);
    char ebuf[256] = "", body[4096] = "";
    struct mg_connection *c = mg_download("127.0.0.1", rths_view_port(v), 0, ebuf, sizeof ebuf,
                                          "GET /api/status HTTP/1.0\r\n\r\n");
    assert_non_null(c);
    int n = 0, got;
    while ((got = mg_read(c, body + n, sizeof body - 1 - (size_t)n)) > 0)
        n += got;
    body[n] = 0;
    mg_close_connection(c);
    rths_view_stop(v);
    json_object *root = json_tokener_parse(body), *proc, *x;
    assert_non_null(root);
    assert_true(json_object_object_get_ex(root, "process", &proc));
    assert_true(json_object_object_get_ex(proc, "overruns", &x));
    assert_int_equal(json_object_get_int(x), 17);
    assert_false(json_object_object_get_ex(root, "run_dir", &x));
    json_object_put(root);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(listen_addresses),
        cmocka_unit_test_setup_teardown(run_folders, setup, teardown),
        cmocka_unit_test_setup_teardown(points_from_csv, setup, teardown),
        cmocka_unit_test_setup_teardown(points_from_journal, setup, teardown),
        cmocka_unit_test(process_snapshot),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
