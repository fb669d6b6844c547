/* The view's HTTP side over civetweb: routes, error pages, server-sent events (see view.h). */
#include "view/view_internal.h"

#include <arpa/inet.h>
#include <civetweb.h>
#include <errno.h>
#include <json-c/json.h>
#include <limits.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

struct rths_view {
    struct mg_context *ctx;
    char *run_dir; /* realpath of the folder */
    int port;
    double poll_s;
    rths_view_snapshot_fn snapshot;
    void *snapshot_user;
    rths_view_process_fn process;
    void *process_user;
    const char *page; /* the asset served at / */
    int campaign;     /* run_dir is a campaign folder (docs/campaign.md) */
    atomic_int stopping;
    atomic_int event_streams; /* open /api/events streams, each holding a server thread */
};

/* Each live page holds one of the server's threads for as long as it is open: beyond this
 * many, a new stream is refused so the page's own requests are always served. */
enum { VIEW_MAX_EVENT_STREAMS = 8 };
/* civetweb's worker threads: every connection holds one from accept until it is closed, idle or
 * not. Streams take at most 8, the rest serve requests. */
#define VIEW_THREADS "32"
/* A connection that has not sent its request (or stops reading the answer) within this time is
 * closed (civetweb's request_timeout_ms, 30 s by default): idle connections cannot hold every
 * worker for long. A browser sends its request at once, even over a slow network. */
#define VIEW_REQUEST_TIMEOUT_MS "5000"

/* The files of a run whose changes the page hears about, and the API each one feeds. */
static const char *const run_watched[][2] = {
    {"journal.jsonl", "points"}, {"frf.csv", "points"},  {"live.json", "live"},
    {"summary.json", "summary"}, {"truth.csv", "truth"},
};
/* A campaign's: campaign.csv is rewritten after every run, runs.csv and plan.txt when it starts;
 * a run's own page is served under /runs/run_K/ and watches its run's files. */
static const char *const campaign_watched[][2] = {
    {"campaign.csv", "campaign"},
    {"runs.csv", "campaign"},
    {"plan.txt", "campaign"},
};
enum {
    N_RUN_WATCHED = sizeof run_watched / sizeof run_watched[0],
    N_CAMPAIGN_WATCHED = sizeof campaign_watched / sizeof campaign_watched[0],
    N_WATCHED = N_RUN_WATCHED /* the longer list */
};

/* The files watched in a folder served as a run (campaign 0) or as a campaign. */
static int watched_files(int campaign, const char *const (**list)[2]) {
    *list = campaign ? campaign_watched : run_watched;
    return campaign ? N_CAMPAIGN_WATCHED : N_RUN_WATCHED;
}

void rths_view_options_defaults(rths_view_options *opt) {
    memset(opt, 0, sizeof *opt);
    snprintf(opt->host, sizeof opt->host, "127.0.0.1");
    opt->port = 8080;
    opt->poll_s = 0.25;
}

int rths_view_host_is_loopback(const char *host) {
    struct in_addr a4;
    struct in6_addr a6;
    if (!strcmp(host, "localhost")) return 1;
    if (inet_pton(AF_INET, host, &a4) == 1) return (ntohl(a4.s_addr) >> 24) == 127;
    if (inet_pton(AF_INET6, host, &a6) == 1) return IN6_IS_ADDR_LOOPBACK(&a6);
    return 0;
}

int view_parse_listen_as(const char *option, const char *text, char *host, size_t host_cap,
                         int *port, rths_error *err) {
    const char *colon = strrchr(text, ':');
    const char *port_text = colon ? colon + 1 : text;
    size_t hlen = colon ? (size_t)(colon - text) : 0;
    const char *h = text;
    if (hlen >= 2 && text[0] == '[' && text[hlen - 1] == ']') h++, hlen -= 2;
    char *end;
    errno = 0;
    long p = strtol(port_text, &end, 10);
    if (!*port_text || *end || errno || p < 0 || p > 65535)
        return rths_error_set(err, RTHS_EINPUT,
                              "%s '%s': expected HOST:PORT with a port 0..65535 (0: a free "
                              "one), e.g. 127.0.0.1:8080",
                              option, text);
    if (colon && hlen == 0)
        return rths_error_set(err, RTHS_EINPUT, "%s '%s': empty host", option, text);
    if (hlen >= host_cap) return rths_error_set(err, RTHS_EINPUT, "%s: host too long", option);
    if (colon) {
        memcpy(host, h, hlen);
        host[hlen] = 0;
    } else {
        snprintf(host, host_cap, "127.0.0.1");
    }
    struct in_addr a4;
    struct in6_addr a6;
    if (strcmp(host, "localhost") && inet_pton(AF_INET, host, &a4) != 1 &&
        inet_pton(AF_INET6, host, &a6) != 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "%s '%s': '%s' is not a numeric IPv4/IPv6 address or "
                              "localhost",
                              option, text, host);
    *port = (int)p;
    return RTHS_OK;
}

int rths_view_parse_listen(const char *text, char *host, size_t host_cap, int *port,
                           rths_error *err) {
    return view_parse_listen_as("--listen", text, host, host_cap, port, err);
}

/* ---- responses ---- */

static const char *reason_phrase(int status) {
    switch (status) {
    case 200:
        return "OK";
    case 301:
        return "Moved Permanently";
    case 400:
        return "Bad Request";
    case 403:
        return "Forbidden";
    case 404:
        return "Not Found";
    case 405:
        return "Method Not Allowed";
    case 414:
        return "URI Too Long";
    case 503:
        return "Service Unavailable";
    default:
        return "Internal Server Error";
    }
}

static int is_head(struct mg_connection *c) {
    return !strcmp(mg_get_request_info(c)->request_method, "HEAD");
}

static void send_head(struct mg_connection *c, int status, const char *mime, size_t len) {
    mg_printf(c,
              "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\n"
              "Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n"
              "Connection: close\r\n\r\n",
              status, reason_phrase(status), mime, len);
}

static int send_body(struct mg_connection *c, int status, const char *mime, const void *body,
                     size_t len) {
    send_head(c, status, mime, len);
    if (len && !is_head(c)) mg_write(c, body, len);
    return status;
}

/* An open run file, whole, whatever its size (never truncated): Content-Length is its size when
 * opened; the run only appends to or atomically replaces its files, so that many bytes are
 * there. Should it shrink, the connection closes short of Content-Length and the client sees an
 * incomplete answer, not a complete wrong one. */
static int send_file(struct mg_connection *c, const view_file *f, const char *mime) {
    size_t left = (size_t)f->st.st_size;
    send_head(c, 200, mime, left);
    if (is_head(c)) return 200;
    char buf[65536];
    while (left > 0) {
        ssize_t n = read(f->fd, buf, left < sizeof buf ? left : sizeof buf);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0 || mg_write(c, buf, (size_t)n) <= 0) break;
        left -= (size_t)n;
    }
    return 200;
}

static int send_json_error(struct mg_connection *c, int status, const char *msg) {
    json_object *o = json_object_new_object();
    json_object_object_add(o, "error", json_object_new_string(msg));
    const char *text = json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN);
    send_body(c, status, "application/json", text, strlen(text));
    json_object_put(o);
    return status;
}

/* text (malloc'ed, freed here) with 200, or err's message with status when text is NULL. */
static int send_owned_json(struct mg_connection *c, int status, char *text, const rths_error *err) {
    if (!text) return send_json_error(c, status == 200 ? 500 : status, err->msg);
    send_body(c, 200, "application/json", text, strlen(text));
    free(text);
    return 200;
}

static int send_html_error(struct mg_connection *c, int status, const char *msg) {
    char page[2048];
    int n = snprintf(page, sizeof page,
                     "<!doctype html><html><head><meta charset=\"utf-8\"><title>rths view: "
                     "%d</title></head><body style=\"font-family:sans-serif\"><h1>%d</h1>"
                     "<p>%s</p><p>The view serves <a href=\"/\">the page</a>, /api/points, "
                     "/api/truth, /api/live, /api/summary, /api/status, /api/events and the run "
                     "folder's own files as /run/NAME (a live process: /api/process)."
                     "</p></body></html>",
                     status, status, msg);
    return send_body(c, status, "text/html; charset=utf-8", page, (size_t)n);
}

/* ---- routes ---- */

/* Anything that could name a file outside the run folder: dot-dot (plain or percent-encoded),
 * backslashes, encoded slashes. Checked on the raw request (civetweb is told not to decode it)
 * and again on the path this server decodes itself. */
static int is_traversal(const char *raw) {
    return strstr(raw, "..") || strcasestr(raw, "%2e") || strcasestr(raw, "%2f") ||
           strcasestr(raw, "%5c") || strchr(raw, '\\');
}

static int serve_asset(struct mg_connection *c, const char *name) {
    for (int i = 0; i < view_asset_count; i++)
        if (!strcmp(view_assets[i].name, name))
            return send_body(c, 200, view_assets[i].mime, view_assets[i].data, view_assets[i].size);
    return send_html_error(c, 404, "No such asset.");
}

static const char *mime_of(const char *name) {
    const char *dot = strrchr(name, '.');
    static const char *const map[][2] = {
        {".png", "image/png"},
        {".svg", "image/svg+xml"},
        {".csv", "text/csv"},
        {".json", "application/json"},
        {".jsonl", "application/x-ndjson"},
        {".log", "text/plain; charset=utf-8"},
        {".gp", "text/plain; charset=utf-8"},
        {".yaml", "text/plain; charset=utf-8"},
    };
    for (size_t i = 0; dot && i < sizeof map / sizeof map[0]; i++)
        if (!strcmp(dot, map[i][0])) return map[i][1];
    return "application/octet-stream";
}

/* /run/NAME: a regular file directly inside the run folder, not a symlink (view_files.c),
 * served whole. */
static int serve_run_file(struct mg_connection *c, const char *dir, const char *name) {
    if (!*name || name[0] == '.' || strchr(name, '/'))
        return send_html_error(c, 403, "Refused: only files directly inside the run folder.");
    view_file f;
    rths_error err = {0};
    int status = view_file_open(dir, name, &f, &err);
    if (status == 200)
        status = send_file(c, &f, mime_of(name));
    else if (status == 404)
        status = send_html_error(c, 404, "The run folder holds no such file.");
    else if (status == 403)
        status = send_html_error(c, 403,
                                 "Refused: that name is a symbolic link or not a regular file; "
                                 "the view serves only the run folder's own files.");
    else
        status = send_html_error(c, 500, "Cannot read that file.");
    view_file_close(&f);
    return status;
}

/* /api/live, /api/summary: the file as the run wrote it, whole; `missing` when absent. */
static int serve_file_json(struct mg_connection *c, const char *dir, const char *name,
                           const char *missing) {
    view_file f;
    rths_error err = {0};
    int status = view_file_open(dir, name, &f, &err);
    status = status == 200   ? send_file(c, &f, "application/json")
             : status == 404 ? send_json_error(c, 404, missing)
                             : send_json_error(c, status, err.msg);
    view_file_close(&f);
    return status;
}

static json_object *files_object(const char *dir, int campaign) {
    json_object *files = json_object_new_object();
    const char *const(*watched)[2];
    int n_watched = watched_files(campaign, &watched);
    for (int i = 0; i < n_watched; i++) {
        char *path = rths_path_join(dir, watched[i][0]);
        struct stat st;
        if (path && lstat(path, &st) == 0 && S_ISREG(st.st_mode)) { /* the run's own files */
            json_object *f = json_object_new_object();
            json_object_object_add(f, "bytes", json_object_new_int64((int64_t)st.st_size));
            json_object_object_add(f, "modified_unix_s",
                                   json_object_new_double((double)st.st_mtim.tv_sec +
                                                          1e-9 * (double)st.st_mtim.tv_nsec));
            json_object_object_add(files, watched[i][0], f);
        }
        free(path);
    }
    return files;
}

static int serve_status(rths_view *v, struct mg_connection *c, const char *dir, int campaign) {
    json_object *o = json_object_new_object();
    json_object_object_add(o, "rths_version", json_object_new_string(RTHS_VERSION));
    if (dir) {
        struct stat st;
        int present = stat(dir, &st) == 0;
        json_object_object_add(o, "kind", json_object_new_string(campaign ? "campaign" : "run"));
        json_object_object_add(o, "run_dir", json_object_new_string(dir));
        json_object_object_add(o, "run_dir_present", json_object_new_boolean(present));
        json_object *cs = campaign && present ? view_campaign_state(dir) : NULL, *state = NULL;
        if (cs && json_object_object_get_ex(cs, "state", &state)) json_object_get(state);
        json_object_object_add(
            o, "state",
            !present ? json_object_new_string("gone")
            : state  ? state
                     : json_object_new_string(view_file_exists(dir, "summary.json") ? "ended"
                                                                                    : "running"));
        json_object_object_add(o, "files", files_object(dir, campaign));
        if (campaign)
            json_object_object_add(o, "campaign", cs);
        else
            json_object_object_add(o, "plan", view_plan_object(dir));
        /* a run of a campaign: the link back to the campaign's page */
        if (!campaign && v->campaign)
            json_object_object_add(o, "campaign_page", json_object_new_string("/"));
    }
    if (v->snapshot) {
        char buf[16384];
        int n = v->snapshot(v->snapshot_user, buf, sizeof buf);
        json_object *p = n > 0 && (size_t)n < sizeof buf ? json_tokener_parse(buf) : NULL;
        json_object_object_add(o, "process", p);
    }
    char *text = view_json_text(o);
    json_object_put(o);
    rths_error err = {.msg = "out of memory"};
    return send_owned_json(c, 500, text, &err);
}

/* A signature of the watched files: any change of size, time or inode (rename) shows. */
static void signature(const char *dir, int campaign, long long sig[N_WATCHED][3]) {
    const char *const(*watched)[2];
    int n_watched = watched_files(campaign, &watched);
    for (int i = 0; i < N_WATCHED; i++)
        sig[i][0] = sig[i][1] = sig[i][2] = -1;
    for (int i = 0; i < n_watched; i++) {
        char *path = rths_path_join(dir, watched[i][0]);
        struct stat st;
        if (path && lstat(path, &st) == 0) {
            sig[i][0] = (long long)st.st_size;
            sig[i][1] = (long long)st.st_mtim.tv_sec * 1000000000LL + st.st_mtim.tv_nsec;
            sig[i][2] = (long long)st.st_ino;
        } else {
            sig[i][0] = sig[i][1] = sig[i][2] = -1;
        }
        free(path);
    }
}

static void sleep_s(double s) {
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

/* Server-sent events: "change" with the APIs to fetch again, a comment as keep-alive. Ends when
 * the browser goes (a write fails) or the view stops. */
static int serve_event_stream(rths_view *v, struct mg_connection *c, const char *dir, int campaign);

static const char event_stream_head[] =
    "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n"
    "Connection: close\r\n\r\n";

static int serve_events(rths_view *v, struct mg_connection *c, const char *dir, int campaign) {
    /* HEAD: the head a stream would have, and no stream (it would hold a thread for nothing) */
    if (is_head(c)) return mg_printf(c, "%s", event_stream_head), 200;
    if (atomic_fetch_add(&v->event_streams, 1) >= VIEW_MAX_EVENT_STREAMS) {
        atomic_fetch_sub(&v->event_streams, 1);
        return send_json_error(c, 503,
                               "too many live pages are open on this view (8): close one and "
                               "reload");
    }
    int status = serve_event_stream(v, c, dir, campaign);
    atomic_fetch_sub(&v->event_streams, 1);
    return status;
}

/* Polls the run folder and pushes a change event; a keep-alive every second otherwise, so a
 * page that went away frees its thread within a second. */
static int serve_event_stream(rths_view *v, struct mg_connection *c, const char *dir,
                              int campaign) {
    mg_printf(c, "%sretry: 1000\n\n", event_stream_head);
    const char *const(*watched)[2];
    int n_watched = watched_files(campaign, &watched);
    long long last[N_WATCHED][3], now[N_WATCHED][3];
    memset(last, 0xff, sizeof last);
    memset(now, 0xff, sizeof now);
    int first = 1;
    double idle = 0;
    while (!atomic_load(&v->stopping)) {
        if (dir) signature(dir, campaign, now);
        char list[256] = "";
        for (int i = 0; dir && i < n_watched; i++)
            if ((first || memcmp(now[i], last[i], sizeof now[i])) && !strstr(list, watched[i][1]))
                snprintf(list + strlen(list), sizeof list - strlen(list), "%s\"%s\"",
                         list[0] ? ", " : "", watched[i][1]);
        /* a process snapshot changes all the time: sent with every poll */
        if (list[0] || v->snapshot)
            snprintf(list + strlen(list), sizeof list - strlen(list), "%s\"status\"",
                     list[0] ? ", " : "");
        if (v->process)
            snprintf(list + strlen(list), sizeof list - strlen(list), "%s\"process\"",
                     list[0] ? ", " : "");
        char msg[512];
        if (list[0]) {
            int n = snprintf(msg, sizeof msg, "event: change\ndata: {\"changed\": [%s]}\n\n", list);
            if (mg_write(c, msg, (size_t)n) <= 0) break;
            idle = 0;
        } else if ((idle += v->poll_s) >= 1) {
            if (mg_write(c, ": keep-alive\n\n", 14) <= 0) break;
            idle = 0;
        }
        memcpy(last, now, sizeof last);
        first = 0;
        sleep_s(v->poll_s);
    }
    return 200;
}

static int route_api(rths_view *v, struct mg_connection *c, const char *dir, int campaign,
                     const char *what) {
    rths_error err = {0};
    char *text = NULL;
    if (!strcmp(what, "status")) return serve_status(v, c, dir, campaign);
    if (!strcmp(what, "events")) return serve_events(v, c, dir, campaign);
    if (!strcmp(what, "process")) {
        if (!v->process) return send_json_error(c, 404, "this view serves no live process");
        err.code = RTHS_EFAIL;
        snprintf(err.msg, sizeof err.msg, "the process gave no data");
        return send_owned_json(c, 500, v->process(v->process_user), &err);
    }
    if (!dir) return send_json_error(c, 404, "this view serves no run folder");
    struct stat st;
    if (stat(dir, &st) != 0) {
        char msg[PATH_MAX + 64];
        snprintf(msg, sizeof msg, "the %s folder %s is gone", campaign ? "campaign" : "run", dir);
        return send_json_error(c, 404, msg);
    }
    if (campaign) {
        if (!strcmp(what, "campaign")) {
            int status = view_campaign_json(dir, &text, &err);
            return send_owned_json(c, status, text, &err);
        }
        return send_json_error(c, 404,
                               "unknown API for a campaign folder: use campaign, status, events; "
                               "each run's own API is under /runs/run_K/api/");
    }
    if (!strcmp(what, "points")) {
        int status = view_points_json(dir, &text, &err);
        return send_owned_json(c, status, text, &err);
    }
    if (!strcmp(what, "truth")) {
        if (!view_file_present(dir, "truth.csv"))
            return send_json_error(c, 404, "no truth.csv in the run folder (yet)");
        int status = view_truth_json(dir, &text, &err);
        return send_owned_json(c, status, text, &err);
    }
    if (!strcmp(what, "live"))
        return serve_file_json(c, dir, "live.json",
                               "no live.json: this run has not written one (yet); runs write "
                               "it after every evaluation when they are watched");
    if (!strcmp(what, "summary"))
        return serve_file_json(c, dir, "summary.json",
                               "the run has not ended: no summary.json yet");
    return send_json_error(
        c, 404, "unknown API: use points, truth, live, summary, status, events, process");
}

/* The routes of one folder: the run folder (or campaign folder) served, or a run of the
 * campaign under /runs/run_K/ (uri is then the rest after it, from its slash). */
static int route_folder(rths_view *v, struct mg_connection *c, const char *uri, const char *dir,
                        int campaign) {
    if (!strcmp(uri, "/") || !strcmp(uri, "/index.html"))
        return serve_asset(c, campaign ? "campaign.html" : v->page);
    if (!strncmp(uri, "/assets/", 8)) return serve_asset(c, uri + 8);
    if (!strncmp(uri, "/api/", 5)) return route_api(v, c, dir, campaign, uri + 5);
    if (!strncmp(uri, "/run/", 5)) {
        if (!dir) return send_html_error(c, 404, "This view serves no run folder.");
        return serve_run_file(c, dir, uri + 5);
    }
    return send_html_error(c, 404, "Not found.");
}

/* /runs/run_K/...: run K of the campaign, its page and API as for a run folder. Only a folder
 * named run_ and digits directly inside the campaign folder, not a symbolic link, holding a run
 * (it has started). /runs/run_K without the slash is sent to /runs/run_K/ (the run's page asks
 * for its API relative to its own address). */
static int route_campaign_run(rths_view *v, struct mg_connection *c, const char *rest) {
    char name[32];
    size_t len = strcspn(rest, "/");
    if (len >= sizeof name)
        return send_html_error(c, 404, "No such run: runs are named run_ and digits.");
    memcpy(name, rest, len);
    name[len] = 0;
    if (!view_campaign_run_name(name))
        return send_html_error(c, 404, "No such run: runs are named run_ and digits.");
    if (!view_campaign_run_dir(v->run_dir, name))
        return send_html_error(c, 404,
                               "The campaign folder holds no such run folder (a symbolic link is "
                               "not followed).");
    if (!rest[len]) {
        mg_printf(c,
                  "HTTP/1.1 301 Moved Permanently\r\nLocation: /runs/%s/\r\n"
                  "Content-Length: 0\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
                  name);
        return 301;
    }
    char *dir = rths_path_join(v->run_dir, name);
    rths_error err = {0};
    int status;
    if (!dir)
        status = send_html_error(c, 500, "Out of memory.");
    else if (rths_view_check_run_dir(dir, &err))
        status = send_html_error(c, 404, "That run has not started yet: its folder holds no run.");
    else
        status = route_folder(v, c, rest + len, dir, 0);
    free(dir);
    return status;
}

/* civetweb hands the path over undecoded (decode_url=no, rths_view_start): decoding it itself
 * would cut it at an encoded NUL ("/run/frf.csv%00.png" served frf.csv), so %00 is refused
 * before this server decodes the path, and the decoded path is checked again. */
static int handle_request(rths_view *v, struct mg_connection *c) {
    const struct mg_request_info *ri = mg_get_request_info(c);
    const char *raw = ri->local_uri_raw ? ri->local_uri_raw : ri->local_uri ? ri->local_uri : "/";
    if (strcmp(ri->request_method, "GET") && strcmp(ri->request_method, "HEAD"))
        return send_html_error(c, 405, "Only GET and HEAD.");
    if (strstr(raw, "%00") || (ri->query_string && strstr(ri->query_string, "%00")))
        return send_html_error(c, 400, "Refused: the request holds an encoded NUL (%00).");
    if (is_traversal(raw))
        return send_html_error(c, 403, "Refused: the path leaves the run folder.");
    char uri[PATH_MAX];
    int n = mg_url_decode(raw, (int)strlen(raw), uri, (int)sizeof uri, 0);
    if (n < 0) return send_html_error(c, 414, "Refused: the path is too long.");
    if ((size_t)n != strlen(uri))
        return send_html_error(c, 400, "Refused: the request holds an encoded NUL (%00).");
    if (is_traversal(uri))
        return send_html_error(c, 403, "Refused: the path leaves the run folder.");
    if (v->campaign && !strncmp(uri, "/runs/", 6)) return route_campaign_run(v, c, uri + 6);
    return route_folder(v, c, uri, v->run_dir, v->campaign);
}

typedef struct {
    rths_view *v;
    struct mg_connection *c;
    int status;
} request_job;

static void *request_thread(void *arg) {
    request_job *job = arg;
    job->status = handle_request(job->v, job->c);
    return NULL;
}

/* civetweb's workers have 100 kB stacks (Debian's build), too little for json-c, the journal
 * reader and a sanitizer build: each request runs on a thread of ordinary size while the worker
 * waits, so only one thread ever uses the connection. */
static int handle(struct mg_connection *c, void *cbdata) {
    request_job job = {.v = cbdata, .c = c, .status = 500};
    pthread_attr_t attr;
    pthread_t thread;
    pthread_attr_init(&attr);
    pthread_attr_setstacksize(&attr, (size_t)8 << 20);
    int e = pthread_create(&thread, &attr, request_thread, &job);
    if (e == 0) {
        pthread_join(thread, NULL);
    } else { /* plain text: json-c is what this small stack cannot afford */
        char why[160];
        int n = snprintf(why, sizeof why,
                         "the view cannot start a thread for this request (%s): try again",
                         strerror(e));
        job.status = send_body(c, 503, "text/plain; charset=utf-8", why, (size_t)n);
    }
    pthread_attr_destroy(&attr);
    return job.status;
}

/* civetweb's own messages (bind failures) reach the caller through mg_start2's error text;
 * per-request chatter is not printed. */
static int quiet_log(const struct mg_connection *c, const char *message) {
    (void)c;
    (void)message;
    return 1;
}

int rths_view_start(const rths_view_options *opt, rths_view **out, rths_error *err) {
    *out = NULL;
    rths_view *v = calloc(1, sizeof *v);
    if (!v) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    v->poll_s = opt->poll_s > 0 ? opt->poll_s : 0.25;
    v->snapshot = opt->snapshot;
    v->snapshot_user = opt->snapshot_user;
    v->process = opt->process;
    v->process_user = opt->process_user;
    v->page = opt->page && opt->page[0] ? opt->page : "index.html";
    if (opt->run_dir) {
        int rc = rths_view_check_folder(opt->run_dir, err);
        if (!rc && !(v->run_dir = realpath(opt->run_dir, NULL)))
            rc = rths_error_set(err, RTHS_EINPUT, "run folder %s: %s", opt->run_dir,
                                strerror(errno));
        if (rc) {
            free(v);
            return rc;
        }
        v->campaign = view_is_campaign_dir(v->run_dir);
    }
    char ports[300];
    snprintf(ports, sizeof ports, strchr(opt->host, ':') ? "[%s]:%d" : "%s:%d", opt->host,
             opt->port);
    /* one request per connection (no keep-alive), idle connections closed after the request
     * timeout, the path left undecoded for handle_request */
    const char *options[] = {"listening_ports",
                             ports,
                             "num_threads",
                             VIEW_THREADS,
                             "request_timeout_ms",
                             VIEW_REQUEST_TIMEOUT_MS,
                             "enable_keep_alive",
                             "no",
                             "decode_url",
                             "no",
                             NULL};
    struct mg_callbacks callbacks = {.log_message = quiet_log};
    struct mg_init_data init = {
        .callbacks = &callbacks, .user_data = v, .configuration_options = options};
    char text[256] = "";
    unsigned code = 0;
    struct mg_error_data error = {.code = &code, .text = text, .text_buffer_size = sizeof text};
    mg_init_library(0);
    v->ctx = mg_start2(&init, &error);
    if (!v->ctx) {
        free(v->run_dir);
        free(v);
        mg_exit_library();
        return rths_error_set(err, RTHS_EFAIL, "cannot listen on %s: %s", ports,
                              text[0] ? text : "civetweb refused");
    }
    mg_set_request_handler(v->ctx, "/", handle, v);
    struct mg_server_port sp[4];
    int n = mg_get_server_ports(v->ctx, 4, sp);
    v->port = n > 0 ? sp[0].port : opt->port;
    *out = v;
    return RTHS_OK;
}

int rths_view_port(const rths_view *v) {
    return v->port;
}

void rths_view_stop(rths_view *v) {
    if (!v) return;
    atomic_store(&v->stopping, 1);
    if (v->ctx) mg_stop(v->ctx);
    mg_exit_library();
    free(v->run_dir);
    free(v);
}
