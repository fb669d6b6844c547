/* The view module without a browser: the --listen parser, loopback detection, what counts as a
 * run folder, and /api/points built from frf.csv and from journal.jsonl against values computed
 * here from the point's coefficients (the HTTP side is tests/cli/view.sh); the controller
 * process's page (rths_server_view_start) on a running controller: its scope holds the loop's
 * decimated samples, its lateness histogram counts every sample, and the loop-side publishing
 * code calls nothing that allocates, locks or prints.
 *
 *
 * The HTTP server's hardening, in process over raw loopback sockets (requests sent exactly as
 * written): files of the run folder that are symlinks or FIFOs are refused without a byte of
 * what they name, files over 16 MB are served whole, an encoded NUL is refused, HEAD of the event
 * stream ends, a busy server says 503 Service Unavailable, idle connections are closed and do
 * not starve the API. A campaign folder: campaign.csv as JSON (quoted and text grid values,
 * 64-bit seeds, every digit of the results, unfinished runs null), its state, its page, and each
 * run's page and API under /runs/run_K/ with the path rules (run_ and digits, a folder of the
 * campaign, not a link, that holds a run). Every server a test starts is stopped by its
 * teardown, whatever the test's outcome.
 *
 * `test_view --serve-controller CONFIG [key=value...]` is not a test: it runs a controller with
 * its page on free loopback ports for tests/cli/view.sh's browser test, until SIGTERM. */
#include "rths/continuation.h"
#include "rths/view.h"
#include "testlib.h"

#include <civetweb.h>
#include <json-c/json.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static char scratch[64];
static rths_view *served; /* the server a test started, stopped by its teardown */

static int setup(void **state) {
    (void)state;
    snprintf(scratch, sizeof scratch, "/tmp/rths-test-view-XXXXXX");
    return mkdtemp(scratch) ? 0 : -1;
}

static int teardown(void **state) {
    (void)state;
    rths_view_stop(served);
    served = NULL;
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
    assert_int_equal(rths_view_start(&opt, &served, &err), RTHS_OK); /* stopped by teardown */
    assert_true(rths_view_port(served) > 0);                         /* port 0: picked */
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
    rths_error err;
    assert_int_equal(rths_view_start(&opt, &served, &err), RTHS_OK); /* stopped by teardown */
    char ebuf[256] = "", body[4096] = "";
    struct mg_connection *c = mg_download("127.0.0.1", rths_view_port(served), 0, ebuf, sizeof ebuf,
                                          "GET /api/status HTTP/1.0\r\n\r\n");
    assert_non_null(c);
    int n = 0, got;
    while ((got = mg_read(c, body + n, sizeof body - 1 - (size_t)n)) > 0)
        n += got;
    body[n] = 0;
    mg_close_connection(c);
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

/* ---- the HTTP server's hardening, over raw sockets ---- */

/* A TCP connection to the view on loopback whose reads give up after timeout_s; -1 on failure. */
static int connect_view(int port, double timeout_s) {
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) return -1;
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    struct timeval tv = {(time_t)timeout_s, (suseconds_t)((timeout_s - (time_t)timeout_s) * 1e6)};
    if (connect(fd, (struct sockaddr *)&a, sizeof a) != 0 ||
        setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

/* The request exactly as written (no encoding, unlike a client library), and the whole answer
 * until the server closes the connection: malloc'ed, NUL-terminated, its length in *len. NULL
 * when the answer had not ended within timeout_s (an answer that keeps coming, a stream, too). */
static char *raw_http(int port, const char *request, double timeout_s, size_t *len) {
    int fd = connect_view(port, timeout_s);
    if (fd < 0) return NULL;
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap + 1);
    double deadline = rths_monotonic_s() + timeout_s;
    ssize_t got = send(fd, request, strlen(request), MSG_NOSIGNAL);
    while (buf && got > 0) {
        if (n == cap && !(buf = realloc(buf, (cap *= 2) + 1))) break;
        double left = deadline - rths_monotonic_s();
        struct pollfd pfd = {.fd = fd, .events = POLLIN};
        if (left <= 0 || poll(&pfd, 1, (int)(left * 1e3) + 1) <= 0) {
            got = -1;
            break;
        }
        got = recv(fd, buf + n, cap - n, 0);
        if (got > 0) n += (size_t)got;
    }
    close(fd);
    if (!buf || got < 0) { /* the answer had not ended in time */
        free(buf);
        return NULL;
    }
    buf[n] = 0;
    if (len) *len = n;
    return buf;
}

static int status_of(const char *answer) {
    int status = -1;
    return answer && sscanf(answer, "HTTP/1.%*d %d", &status) == 1 ? status : -1;
}

static const char *body_of(const char *answer) {
    const char *end = strstr(answer, "\r\n\r\n");
    assert_non_null(end);
    return end + 4;
}

/* GET path: the answer, which must have come with status want and must not hold `never`. */
static char *expect_answer(int port, const char *path, int want, const char *never) {
    char request[512];
    snprintf(request, sizeof request, "GET %s HTTP/1.0\r\n\r\n", path);
    char *a = raw_http(port, request, 20, NULL);
    if (!a) fail_msg("GET %s: no complete answer within 20 s", path);
    if (status_of(a) != want) fail_msg("GET %s: %.120s, expected %d", path, a, want);
    if (never && strstr(a, never))
        fail_msg("GET %s: the answer holds '%s': %.300s", path, never, a);
    return a;
}

static char *scratch_path(const char *name) {
    static char path[4][256];
    static int next;
    char *p = path[next++ % 4];
    snprintf(p, sizeof path[0], "%s/%s", scratch, name);
    return p;
}

static int serve_scratch_run(void) {
    rths_view_options opt;
    rths_view_options_defaults(&opt);
    opt.port = 0;
    opt.run_dir = scratch_path("run");
    rths_error err;
    if (rths_view_start(&opt, &served, &err)) fail_msg("%s", err.msg);
    return rths_view_port(served);
}

/* Symlinks in the run folder pointing outside it (the probe: ln -s /etc/passwd RUN/live.json)
 * are refused by every route that reads a file, and no byte of the target is sent, not even in
 * an error message (/api/points echoed a field of a symlinked CSV). */
static void symlinks_refused(void **state) {
    (void)state;
    assert_int_equal(mkdir(scratch_path("run"), 0700), 0);
    write_text("secret.csv", "a,b\nSECRET-4711,1\n");
    write_text("run/journal.jsonl", "\n"); /* makes it a run folder */
    const char *links[] = {"live.json", "summary.json", "frf.csv",
                           "truth.csv", "config.yaml",  "figure.png"};
    for (size_t i = 0; i < sizeof links / sizeof links[0]; i++) {
        char link[128];
        snprintf(link, sizeof link, "run/%s", links[i]);
        assert_int_equal(symlink(scratch_path("secret.csv"), scratch_path(link)), 0);
    }
    int port = serve_scratch_run();
    const char *refused[] = {"/api/live",      "/api/summary",    "/api/points",      "/api/truth",
                             "/run/live.json", "/run/figure.png", "/run/summary.json"};
    for (size_t i = 0; i < sizeof refused / sizeof refused[0]; i++) {
        char *a = expect_answer(port, refused[i], 403, "SECRET");
        if (!strstr(a, "symbolic link")) fail_msg("GET %s: no reason: %s", refused[i], a);
        free(a);
    }
    /* the status lists the run's own files only, and the plan comes from none of the links */
    char *a = expect_answer(port, "/api/status", 200, "SECRET");
    json_object *st = json_tokener_parse(body_of(a)), *files, *x;
    assert_non_null(st);
    assert_true(json_object_object_get_ex(st, "files", &files));
    assert_true(json_object_object_get_ex(files, "journal.jsonl", &x));
    assert_false(json_object_object_get_ex(files, "live.json", &x));
    assert_false(json_object_object_get_ex(files, "frf.csv", &x));
    json_object_put(st);
    free(a);
}

/* A FIFO named live.json blocked a server thread for ever (reading waits for a writer): it is
 * refused at once. Should the server block anyway, the FIFO is opened for writing so that the
 * thread and the test can end. */
static void fifo_refused(void **state) {
    (void)state;
    assert_int_equal(mkdir(scratch_path("run"), 0700), 0);
    write_text("run/journal.jsonl", "\n");
    assert_int_equal(mkfifo(scratch_path("run/live.json"), 0600), 0);
    int port = serve_scratch_run();
    const char *paths[] = {"GET /api/live HTTP/1.0\r\n\r\n", "GET /run/live.json HTTP/1.0\r\n\r\n"};
    for (int i = 0; i < 2; i++) {
        char *a = raw_http(port, paths[i], 20, NULL);
        if (!a) {
            int unblock = open(scratch_path("run/live.json"), O_WRONLY | O_NONBLOCK);
            if (unblock >= 0) close(unblock);
            fail_msg("%.20s...: no answer within 20 s (blocked on the FIFO)", paths[i]);
        }
        if (status_of(a) != 403 || !strstr(a, i ? "not a regular file" : "a FIFO"))
            fail_msg("%.20s...: %s", paths[i], a);
        free(a);
    }
}

/* Files over 16 MB were cut to 16 MB with 200 (/api/live, /api/summary) and /run/ files to
 * 256 MB: they are sent whole, Content-Length their size. */
static void large_files_whole(void **state) {
    (void)state;
    assert_int_equal(mkdir(scratch_path("run"), 0700), 0);
    write_text("run/journal.jsonl", "\n");
    size_t size = ((size_t)17 << 20) + 7;
    char *data = malloc(size);
    assert_non_null(data);
    for (size_t i = 0; i < size; i++)
        data[i] = (char)('a' + (i * 7 + i / 4093) % 26);
    FILE *f = fopen(scratch_path("run/live.json"), "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, size, f), size);
    fclose(f);
    int port = serve_scratch_run();
    const char *requests[] = {"GET /api/live HTTP/1.0\r\n\r\n",
                              "GET /run/live.json HTTP/1.0\r\n\r\n"};
    for (int i = 0; i < 2; i++) {
        size_t len = 0;
        char *a = raw_http(port, requests[i], 20, &len);
        assert_non_null(a);
        assert_int_equal(status_of(a), 200);
        const char *body = body_of(a);
        unsigned long long declared = 0;
        const char *cl = strcasestr(a, "Content-Length:");
        assert_true(cl && cl < body && sscanf(cl + 15, "%llu", &declared) == 1);
        assert_int_equal(declared, size);
        assert_int_equal(len - (size_t)(body - a), size);
        assert_memory_equal(body, data, size);
        free(a);
    }
    free(data);
}

/* civetweb decodes the path before the handler sees it, which cut it at an encoded NUL:
 * /run/frf.csv%00.png served frf.csv. Refused with 400, in the path and in the query. */
static void encoded_nul_refused(void **state) {
    (void)state;
    assert_int_equal(mkdir(scratch_path("run"), 0700), 0);
    write_text("run/frf.csv", "point,frequency_hz\n0,12.5\n");
    int port = serve_scratch_run();
    const char *paths[] = {"/run/frf.csv%00.png", "/api/status%00", "/api/status?x=%00",
                           "/run/frf.csv?%00"};
    for (size_t i = 0; i < sizeof paths / sizeof paths[0]; i++) {
        char *a = expect_answer(port, paths[i], 400, "frequency_hz");
        if (!strstr(a, "400 Bad Request") || !strstr(a, "NUL")) fail_msg("%s: %s", paths[i], a);
        free(a);
    }
    /* the view decodes the rest itself: an encoded letter still names the file */
    char *a = expect_answer(port, "/run/fr%66.csv", 200, NULL);
    assert_non_null(strstr(body_of(a), "0,12.5"));
    free(a);
}

/* HEAD /api/events opened a stream that never ended: it answers the stream's head and closes.
 * With every event stream taken (8), a 9th is refused with "503 Service Unavailable" (it said
 * Internal Server Error) and the API still answers. */
static void events_head_and_busy(void **state) {
    (void)state;
    assert_int_equal(mkdir(scratch_path("run"), 0700), 0);
    write_text("run/journal.jsonl", "\n");
    int port = serve_scratch_run();
    char *a = raw_http(port, "HEAD /api/events HTTP/1.0\r\n\r\n", 10, NULL);
    if (!a) fail_msg("HEAD /api/events: the answer did not end within 10 s (a stream)");
    assert_int_equal(status_of(a), 200);
    assert_non_null(strstr(a, "Content-Type: text/event-stream"));
    assert_string_equal(body_of(a), "");
    free(a);
    enum { STREAMS = 8 };
    int streams[STREAMS];
    for (int i = 0; i < STREAMS; i++) {
        streams[i] = connect_view(port, 20);
        assert_true(streams[i] >= 0);
        const char *get = "GET /api/events HTTP/1.0\r\n\r\n";
        assert_int_equal(send(streams[i], get, strlen(get), MSG_NOSIGNAL), (ssize_t)strlen(get));
        char head[512] = "";
        size_t n = 0;
        ssize_t got;
        while (!strstr(head, "retry:") && n + 1 < sizeof head &&
               (got = recv(streams[i], head + n, sizeof head - 1 - n, 0)) > 0)
            head[n += (size_t)got] = 0;
        if (!strstr(head, "retry:")) fail_msg("event stream %d did not start: %s", i, head);
    }
    a = expect_answer(port, "/api/events", 503, NULL);
    if (!strstr(a, "503 Service Unavailable") || !strstr(a, "too many live pages"))
        fail_msg("9th stream: %s", a);
    free(a);
    free(expect_answer(port, "/api/status", 200, NULL));
    for (int i = 0; i < STREAMS; i++)
        close(streams[i]);
}

/* Connections that never send a request held the server's workers (16) for civetweb's default
 * 30 s, so 16 idle connections blocked every request. With more idle connections than workers
 * (40), a request is still answered and an idle connection is closed by the server, both well
 * within 20 s (the view closes them after 5 s; the bound leaves room for a loaded machine). */
static void idle_connections_closed(void **state) {
    (void)state;
    assert_int_equal(mkdir(scratch_path("run"), 0700), 0);
    write_text("run/journal.jsonl", "\n");
    int port = serve_scratch_run();
    enum { IDLE = 40 };
    int idle[IDLE];
    for (int i = 0; i < IDLE; i++)
        assert_true((idle[i] = connect_view(port, 20)) >= 0);
    char *a = expect_answer(port, "/api/status", 200, NULL);
    free(a);
    char byte;
    ssize_t got = recv(idle[0], &byte, 1, 0);
    int e = errno;
    for (int i = 0; i < IDLE; i++)
        close(idle[i]);
    if (got != 0)
        fail_msg("an idle connection was not closed within 20 s (recv %zd, %s)", got,
                 got < 0 ? strerror(e) : "data");
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

/* ---- a campaign folder (rths campaign --out, docs/campaign.md) ---- */

/* campaign.csv as the campaign writes it: a grid value quoted (it holds a comma), a text grid
 * value, a 64-bit seed, a failed run (no summary: results empty), an unfinished run. */
static const char campaign_csv[] =
    "run,split.mass_ratio,controller.scheme,seed,exit_status,points,converged_points,evaluations,"
    "rig_time_s,max_relative_error_vs_truth,share_within_3_standard_errors\n"
    "run_0000,0.4,\"a,b\",18446744073709551615,0,5,5,11,13.361799999982198,"
    "0.00030924030501774312,1\n"
    "run_0001,0.5,foe,2,1,,,,,,\n"
    "run_0002,0.6,foe,1,,,,,,,\n";

/* scratch as a campaign: campaign.csv, run_0000/ a run (frf.csv), run_0001/ not started (empty),
 * run_0002 a symbolic link to run_0000 (never followed). */
static void write_campaign(void) {
    write_text("runs.csv", "run,split.mass_ratio,controller.scheme,seed\n");
    write_text("plan.txt", "config: /somewhere/four_storey_linear.yaml\nruns:\n");
    write_text("campaign.csv", campaign_csv);
    assert_int_equal(mkdir(scratch_path("run_0000"), 0700), 0);
    write_text("run_0000/frf.csv", "point,frequency_hz,amplitude_m\n0,12,4.5e-05\n");
    assert_int_equal(mkdir(scratch_path("run_0001"), 0700), 0);
    assert_int_equal(symlink(scratch_path("run_0000"), scratch_path("run_0002")), 0);
}

static json_object *array_at(json_object *o, const char *key, size_t i) {
    json_object *a = member(o, key);
    assert_true(json_object_is_type(a, json_type_array));
    assert_true(i < json_object_array_length(a));
    return json_object_array_get_idx(a, i);
}

static void campaign_table(void **state) {
    (void)state;
    rths_error err;
    /* an empty folder is neither; runs.csv with plan.txt is a campaign that has just started */
    assert_int_equal(rths_view_check_folder(scratch, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "not a run folder"));
    assert_non_null(strstr(err.msg, "nor a campaign folder"));
    write_text("runs.csv", "run,split.mass_ratio,seed\nrun_0000,0.4,1\n");
    assert_int_equal(rths_view_check_folder(scratch, &err), RTHS_EINPUT);
    write_text("plan.txt", "config: x.yaml\n");
    assert_int_equal(rths_view_check_folder(scratch, &err), RTHS_OK);
    char *json = NULL;
    assert_int_equal(rths_view_campaign_json(scratch, &json, &err), RTHS_OK);
    json_object *root = json_tokener_parse(json);
    free(json);
    assert_string_equal(json_object_get_string(member(root, "source")), "runs.csv");
    assert_int_equal(json_object_get_int(member(root, "total")), 1);
    assert_int_equal(json_object_get_int(member(root, "finished")), 0);
    json_object_put(root);
    unlink(scratch_path("runs.csv"));
    unlink(scratch_path("plan.txt"));

    write_campaign();
    assert_int_equal(rths_view_check_folder(scratch, &err), RTHS_OK);
    assert_int_equal(rths_view_campaign_json(scratch, &json, &err), RTHS_OK);
    root = json_tokener_parse(json);
    free(json);
    assert_non_null(root);
    assert_string_equal(json_object_get_string(member(root, "source")), "campaign.csv");
    /* the grid keys are the columns between run and seed; the results follow seed */
    json_object *grid = member(root, "grid"), *outputs = member(root, "outputs");
    assert_int_equal(json_object_array_length(grid), 2);
    assert_string_equal(json_object_get_string(json_object_array_get_idx(grid, 0)),
                        "split.mass_ratio");
    assert_string_equal(json_object_get_string(json_object_array_get_idx(grid, 1)),
                        "controller.scheme");
    assert_int_equal(json_object_array_length(outputs), 7);
    assert_string_equal(json_object_get_string(json_object_array_get_idx(outputs, 0)),
                        "exit_status");
    json_object *r0 = array_at(root, "runs", 0), *r1 = array_at(root, "runs", 1);
    assert_string_equal(json_object_get_string(member(r0, "run")), "run_0000");
    assert_string_equal(json_object_get_string(member(r0, "controller.scheme")), "a,b");
    /* every digit the file holds: %.17g round-trips the double, the seed is an integer */
    assert_true(json_object_get_double(member(r0, "rig_time_s")) == 13.361799999982198);
    assert_true(json_object_get_double(member(r0, "max_relative_error_vs_truth")) ==
                0.00030924030501774312);
    assert_true(json_object_get_uint64(member(r0, "seed")) == UINT64_MAX);
    assert_int_equal(json_object_get_int(member(r0, "points")), 5);
    assert_true(json_object_is_type(member(r0, "points"), json_type_int));
    assert_int_equal(json_object_get_int(member(r1, "exit_status")), 1);
    json_object *x;
    assert_true(json_object_object_get_ex(r1, "points", &x) && x == NULL); /* empty: null */
    assert_int_equal(json_object_get_int(member(root, "total")), 3);
    assert_int_equal(json_object_get_int(member(root, "finished")), 2);
    assert_int_equal(json_object_get_int(member(root, "failed")), 1);
    /* a link only to a run that has started, in a folder of its own (not a symbolic link) */
    assert_true(json_object_get_boolean(array_at(root, "run_folders", 0)));
    assert_false(json_object_get_boolean(array_at(root, "run_folders", 1)));
    assert_false(json_object_get_boolean(array_at(root, "run_folders", 2)));
    json_object_put(root);
}

/* GET path's JSON body (status want). */
static json_object *expect_json(int port, const char *path, int want) {
    char *a = expect_answer(port, path, want, "SECRET");
    json_object *o = json_tokener_parse(body_of(a));
    if (!o) fail_msg("GET %s: not JSON: %.300s", path, a);
    free(a);
    return o;
}

/* The campaign's own routes, a run's page and API under /runs/run_K/, and the path rules: only
 * run_ and digits, a folder (not a link) of the campaign that holds a run. */
static void campaign_routes(void **state) {
    (void)state;
    write_campaign();
    rths_view_options opt;
    rths_view_options_defaults(&opt);
    opt.port = 0;
    opt.run_dir = scratch;
    rths_error err;
    if (rths_view_start(&opt, &served, &err)) fail_msg("%s", err.msg); /* stopped by teardown */
    int port = rths_view_port(served);
    char *a = expect_answer(port, "/", 200, NULL);
    assert_non_null(strstr(a, "campaign.js")); /* the campaign's page */
    free(a);
    a = expect_answer(port, "/assets/campaign.js", 200, NULL);
    free(a);
    json_object *o = expect_json(port, "/api/campaign", 200);
    assert_int_equal(json_object_get_int(member(o, "total")), 3);
    json_object_put(o);
    /* stopped: runs without an exit status and no campaign holding campaign.lock */
    o = expect_json(port, "/api/status", 200);
    assert_string_equal(json_object_get_string(member(o, "kind")), "campaign");
    assert_string_equal(json_object_get_string(member(o, "state")), "stopped");
    assert_string_equal(json_object_get_string(member(member(o, "campaign"), "config")),
                        "/somewhere/four_storey_linear.yaml");
    json_object_put(o);
    /* running while a process holds the lock (here, this one) */
    int lock = open(scratch_path("campaign.lock"), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    assert_true(lock >= 0);
    assert_int_equal(flock(lock, LOCK_EX | LOCK_NB), 0);
    o = expect_json(port, "/api/status", 200);
    assert_string_equal(json_object_get_string(member(o, "state")), "running");
    json_object_put(o);
    close(lock);
    a = expect_answer(port, "/run/campaign.csv", 200, NULL);
    assert_string_equal(body_of(a), campaign_csv);
    free(a);
    o = expect_json(port, "/api/points", 404); /* a campaign has no points of its own */
    json_object_put(o);

    /* run 0: its page and API, relative to /runs/run_0000/ */
    a = expect_answer(port, "/runs/run_0000", 301, NULL);
    assert_non_null(strstr(a, "\r\nLocation: /runs/run_0000/\r\n"));
    free(a);
    a = expect_answer(port, "/runs/run_0000/", 200, NULL);
    assert_non_null(strstr(a, "app.js")); /* the run's page */
    free(a);
    o = expect_json(port, "/runs/run_0000/api/points", 200);
    assert_string_equal(json_object_get_string(member(o, "source")), "frf.csv");
    assert_true(json_object_get_double(member(array_at(o, "points", 0), "amplitude_m")) == 4.5e-05);
    json_object_put(o);
    o = expect_json(port, "/runs/run_0000/api/status", 200);
    assert_string_equal(json_object_get_string(member(o, "kind")), "run");
    assert_string_equal(json_object_get_string(member(o, "campaign_page")), "/");
    json_object_put(o);
    a = expect_answer(port, "/runs/run_0000/run/frf.csv", 200, NULL);
    free(a);
    /* not started, a symbolic link, no such run, not a run's name, out of the folder */
    const char *missing[] = {"/runs/run_0001/api/points",
                             "/runs/run_0002/api/points",
                             "/runs/run_0002/run/frf.csv",
                             "/runs/run_0009/",
                             "/runs/logs/",
                             "/runs/run_0000x/api/points",
                             "/runs//api/points"};
    for (size_t i = 0; i < sizeof missing / sizeof missing[0]; i++)
        free(expect_answer(port, missing[i], 404, "4.5e-05"));
    const char *outside[] = {"/runs/../campaign.csv", "/runs/run_0000/../../etc/passwd",
                             "/runs/run_0000/run/..%2f..%2fcampaign.csv", "/runs/%2e%2e/"};
    for (size_t i = 0; i < sizeof outside / sizeof outside[0]; i++)
        free(expect_answer(port, outside[i], 403, "root:"));
    free(expect_answer(port, "/runs/run_0000/run/%00", 400, NULL));
}

int main(int argc, char **argv) {
    if (argc >= 3 && !strcmp(argv[1], "--serve-controller")) return serve_controller(argc, argv);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(listen_addresses),
        cmocka_unit_test_setup_teardown(run_folders, setup, teardown),
        cmocka_unit_test_setup_teardown(points_from_csv, setup, teardown),
        cmocka_unit_test_setup_teardown(points_from_journal, setup, teardown),
        cmocka_unit_test_setup_teardown(process_snapshot, setup, teardown),
        cmocka_unit_test_setup_teardown(symlinks_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(fifo_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(large_files_whole, setup, teardown),
        cmocka_unit_test_setup_teardown(encoded_nul_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(events_head_and_busy, setup, teardown),
        cmocka_unit_test_setup_teardown(idle_connections_closed, setup, teardown),
        cmocka_unit_test_setup_teardown(campaign_table, setup, teardown),
        cmocka_unit_test_setup_teardown(campaign_routes, setup, teardown),
        cmocka_unit_test(controller_page),
        cmocka_unit_test(loop_side_source_is_clean),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
