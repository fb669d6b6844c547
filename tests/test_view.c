/* The view module without a browser: the --listen parser, loopback detection, what counts as a
 * run folder, and /api/points built from frf.csv and from journal.jsonl against values computed
 * here from the point's coefficients (the HTTP side is tests/cli/view.sh); the controller
 * process's page (rths_server_view_start) on a running controller: its scope holds the loop's
 * decimated samples, its lateness histogram counts every sample, and the loop-side publishing
 * code calls nothing that allocates, locks or prints.
 *
 * `test_view --serve-controller CONFIG [key=value...]` is not a test: it runs a controller with
 * its page on free loopback ports for tests/cli/view.sh's browser test, until SIGTERM. */
#include "rths/continuation.h"
#include "rths/view.h"
#include "testlib.h"

#include <civetweb.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <pthread.h>
#include <signal.h>
#include <time.h>
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

/* ---- the controller process's page ---- */

static rths_server *start_controller(const char *config, const char *const *sets, int n_sets) {
    rths_config *cfg = NULL;
    rths_error err;
    if (rths_config_load(config, sets, n_sets, &cfg, &err)) fail_msg("%s", err.msg);
    rths_server_options opt;
    rths_server_options_defaults(&opt);
    opt.port = 0;
    opt.realtime = 0;
    opt.quiet = 1;
    rths_server *s = NULL;
    if (rths_server_create(cfg, &opt, &s, &err) || rths_server_start(s, &err))
        fail_msg("%s", err.msg);
    rths_config_free(cfg);
    return s;
}

/* GET path from the loopback server on port: the body (malloc'ed), NULL on failure. */
static char *http_get(int port, const char *path) {
    char ebuf[256] = "", request[256];
    snprintf(request, sizeof request, "GET %s HTTP/1.0\r\n\r\n", path);
    struct mg_connection *c = mg_download("127.0.0.1", port, 0, ebuf, sizeof ebuf, "%s", request);
    if (!c) return NULL;
    size_t cap = 1 << 16, n = 0;
    char *body = malloc(cap);
    int got;
    while (body && (got = mg_read(c, body + n, cap - 1 - n)) > 0) {
        n += (size_t)got;
        if (cap - 1 - n < 4096) body = realloc(body, cap *= 2);
    }
    mg_close_connection(c);
    if (body) body[n] = 0;
    return body;
}

static json_object *member(json_object *o, const char *key) {
    json_object *x = NULL;
    if (!json_object_object_get_ex(o, key, &x)) fail_msg("no '%s' in the JSON", key);
    return x;
}

static double sleep_poll_s(double s) {
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
    return s;
}

/* A running controller (disarmed: the loop runs, the plant rests) with its page: /api/process
 * holds the loop's samples decimated to 1 kHz (consecutive controller times exactly 10 samples
 * of 0.1 ms apart: nothing lost, nothing duplicated), the lateness histogram counts every
 * sample the loop ran (between the counts read before and after the request), the state says
 * disarmed with no fault; / is the controller's page; a bad --view text names --view. */
static void controller_page(void **state) {
    (void)state;
    const char *sets[] = {"rig.noise=false"};
    rths_server *srv =
        start_controller(rths_test_source_path("examples/four_storey.yaml"), sets, 1);
    rths_server_view *sv = NULL;
    rths_error err;
    assert_int_equal(rths_server_view_start(srv, "127.0.0.1", &sv, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "--view '127.0.0.1'"));
    assert_null(sv);
    assert_int_equal(rths_server_view_start(srv, "127.0.0.1:0", &sv, &err), RTHS_OK);
    int port = rths_server_view_port(sv);
    assert_true(port > 0);
    json_object *root = NULL, *scope = NULL;
    rths_server_stats before, after;
    for (double waited = 0; waited < 20; waited += sleep_poll_s(0.05)) {
        json_object_put(root);
        rths_server_get_stats(srv, &before);
        char *body = http_get(port, "/api/process");
        rths_server_get_stats(srv, &after);
        root = body ? json_tokener_parse(body) : NULL;
        free(body);
        scope = root ? member(root, "scope") : NULL;
        if (scope && json_object_array_length(member(scope, "time_s")) >= 200) break;
    }
    assert_non_null(scope);
    json_object *t = member(scope, "time_s");
    size_t n = json_object_array_length(t);
    assert_true(n >= 200);
    assert_int_equal(json_object_get_int(member(scope, "decimation")), 10);
    for (size_t i = 1; i < n; i++) /* %.9g of times below 1e3 s: 1e-6 s resolution at worst */
        assert_close(json_object_get_double(json_object_array_get_idx(t, i)) -
                         json_object_get_double(json_object_array_get_idx(t, i - 1)),
                     1e-3, 2e-6);
    assert_int_equal(json_object_array_length(member(scope, "x_phys_m")), n);
    assert_int_equal(json_object_array_length(member(scope, "force_n")), n);
    json_object *counts = member(member(root, "lateness"), "counts");
    uint64_t total = 0;
    for (size_t i = 0; i < json_object_array_length(counts); i++)
        total += (uint64_t)json_object_get_int64(json_object_array_get_idx(counts, i));
    /* the loop bins a wake-up just before it counts the sample */
    assert_true(total >= before.samples && total <= after.samples + 1);
    json_object *st = member(root, "state");
    assert_false(json_object_get_boolean(member(st, "armed")));
    assert_string_equal(json_object_get_string(member(st, "fault")), "no");
    assert_string_equal(json_object_get_string(member(st, "watchdog")), "idle (disarmed)");
    assert_close(json_object_get_double(member(st, "sample_period_s")), 1e-4, 1e-15);
    json_object_put(root);
    char *page = http_get(port, "/");
    assert_non_null(page);
    assert_non_null(strstr(page, "/assets/controller.js"));
    free(page);
    char *status = http_get(port, "/api/status");
    json_object *sj = status ? json_tokener_parse(status) : NULL;
    assert_non_null(sj);
    assert_true(json_object_get_int64(member(member(sj, "process"), "samples")) > 0);
    json_object_put(sj);
    free(status);
    rths_server_view_stop(sv);
    rths_server_watch w;
    rths_server_get_watch(srv, &w);
    assert_int_equal(w.scope_decimation, 0); /* nobody watches: the loop publishes nothing */
    /* a second page starts from the present: nothing the first one left in the ring */
    sleep_poll_s(0.2);
    rths_server_get_watch(srv, &w);
    assert_int_equal(rths_server_view_start(srv, "127.0.0.1:0", &sv, &err), RTHS_OK);
    double first = -1;
    for (double waited = 0; first < 0 && waited < 20; waited += sleep_poll_s(0.05)) {
        char *body = http_get(rths_server_view_port(sv), "/api/process");
        root = body ? json_tokener_parse(body) : NULL;
        free(body);
        t = root ? member(member(root, "scope"), "time_s") : NULL;
        if (t && json_object_array_length(t) > 0)
            first = json_object_get_double(json_object_array_get_idx(t, 0));
        json_object_put(root);
    }
    assert_true(first >= w.time_s);
    rths_server_view_stop(sv);
    rths_server_destroy(srv);
}

/* The functions of server.c that run on the loop thread (the scope and histogram publishing
 * among them) call nothing that allocates, frees, locks, prints or does LAPACK (the per-sample
 * rule; step.c has its own scan in test_controller.c). Fails if one of them is not found. */
static void loop_side_source_is_clean(void **state) {
    (void)state;
    static const char *const loop_functions[] = {
        "static void apply_cmd(",  "static int64_t wait_next_sample(", "static void serve_host(",
        "static void timed_step(", "static void publish_scope(",       "static void publish_state(",
        "static void *loop_main("};
    enum { N_LOOP = sizeof loop_functions / sizeof loop_functions[0] };
    static const char *const forbidden[] = {"alloc(", "free(",  "printf", "puts",  "mutex",
                                            "lapack", "LAPACK", "cblas",  "send(", "write("};
    FILE *f = fopen(rths_test_source_path("src/controller/server.c"), "r");
    assert_non_null(f);
    char line[512];
    int inside = -1, seen[N_LOOP] = {0}, n = 0;
    while (fgets(line, sizeof line, f)) {
        n++;
        for (int i = 0; inside < 0 && i < N_LOOP; i++)
            if (!strncmp(line, loop_functions[i], strlen(loop_functions[i]))) inside = i;
        if (inside < 0) continue;
        seen[inside] = 1;
        for (size_t k = 0; k < sizeof forbidden / sizeof forbidden[0]; k++)
            if (strstr(line, forbidden[k]))
                fail_msg("server.c:%d (%s...): %s", n, loop_functions[inside], line);
        if (line[0] == '}') inside = -1;
    }
    fclose(f);
    for (int i = 0; i < N_LOOP; i++)
        if (!seen[i]) fail_msg("server.c has no '%s' to scan", loop_functions[i]);
}

/* test_view --serve-controller CONFIG [key=value...]: see the top of this file. */
static int serve_controller(int argc, char **argv) {
    sigset_t stop;
    sigemptyset(&stop);
    sigaddset(&stop, SIGINT);
    sigaddset(&stop, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop, NULL);
    rths_server *srv = start_controller(argv[2], (const char *const *)argv + 3, argc - 3);
    rths_server_view *sv;
    rths_error err;
    if (rths_server_view_start(srv, "127.0.0.1:0", &sv, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    printf("listening on 127.0.0.1:%d\nview at http://127.0.0.1:%d/\n", rths_server_port(srv),
           rths_server_view_port(sv));
    fflush(stdout);
    int sig;
    sigwait(&stop, &sig);
    rths_server_view_stop(sv);
    rths_server_destroy(srv);
    return 0;
}

int main(int argc, char **argv) {
    if (argc >= 3 && !strcmp(argv[1], "--serve-controller")) return serve_controller(argc, argv);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(listen_addresses),
        cmocka_unit_test_setup_teardown(run_folders, setup, teardown),
        cmocka_unit_test_setup_teardown(points_from_csv, setup, teardown),
        cmocka_unit_test_setup_teardown(points_from_journal, setup, teardown),
        cmocka_unit_test(process_snapshot),
        cmocka_unit_test(controller_page),
        cmocka_unit_test(loop_side_source_is_clean),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
