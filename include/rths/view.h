/* rths view: a web page that watches a run folder, finished or still being written (`rths view`).
 *
 * The view only reads what the run writes (journal.jsonl, frf.csv, truth.csv, summary.json,
 * live.json, see live.h); the test process serves nothing and is not slowed. HTTP by civetweb, on
 * loopback unless another address is asked for. Routes (docs/view.md):
 *   /                  the page (assets embedded in the binary at build time: no network needed)
 *   /assets/NAME       the page's scripts and styles (uPlot)
 *   /api/points        every accepted point with the fields of frf.csv: from frf.csv once the run
 *                      has written it, before that from journal.jsonl
 *   /api/truth         truth.csv as columns
 *   /api/live          live.json as written
 *   /api/summary       summary.json, once the run has ended (404 before)
 *   /api/status        what the folder holds now, and the process snapshot when one is served
 *   /api/events        server-sent events: "change" whenever a file of the run changes
 *   /run/NAME          a file directly inside the run folder (figures, CSV); nothing else
 *   /api/process       a live process's own data (the controller's scope and lateness), when
 *                      one is served
 * A campaign folder (`rths campaign --out`, docs/campaign.md) is served as its own page:
 *   /                  the campaign's table and a plot of any result column against a grid column
 *   /api/campaign      campaign.csv as JSON (rths_view_campaign_json)
 *   /api/status        the campaign's state (running, ended, stopped) and files
 *   /api/events        "change" whenever campaign.csv or runs.csv changes
 *   /run/NAME          a file directly inside the campaign folder (campaign.csv, plan.txt, ...)
 *   /runs/run_K/...    run K's own page and API, as above for a run folder
 * Requests naming anything outside the run folder (.., encoded or not, slashes) are refused with
 * 403, and so is every file of the folder that is a symlink, FIFO, device or folder (only regular
 * files are read, never through a link); an encoded NUL gets 400; unknown paths get 404; all
 * errors are short JSON or text naming the reason, never a file's content. Files are sent whole.
 * Idle connections are closed after 5 s; live pages take at most 8 of the 32 workers
 * (docs/view.md, "Safety"). */
#ifndef RTHS_VIEW_H
#define RTHS_VIEW_H

#include "rths/core.h"
#include "rths/server.h"

#include <stddef.h>

typedef struct rths_view rths_view;

/* A snapshot of a live process, e.g. the controller's status (signals, limits, watchdog,
 * lateness): fills buf with one JSON object (NUL-terminated) and returns its length, or -1.
 * Called from the server's threads: it must only read state the process publishes for it. */
typedef int (*rths_view_snapshot_fn)(void *user, char *buf, size_t cap);
/* A live process's own data for its page (e.g. the controller's oscilloscope samples and
 * lateness histogram): malloc'ed JSON text, served at /api/process; NULL gives a 500 error.
 * Called from the server's threads, possibly several at once. */
typedef char *(*rths_view_process_fn)(void *user);

typedef struct rths_view_options {
    const char *run_dir; /* the run folder served; NULL: only the snapshot (controller page) */
    char host[256];      /* listen address, default "127.0.0.1" */
    int port;            /* default 8080; 0: a free port (see rths_view_port) */
    double poll_s;       /* how often the folder is checked for changes, default 0.25 s */
    rths_view_snapshot_fn snapshot; /* optional, served at /api/status as "process" */
    void *snapshot_user;
    rths_view_process_fn process; /* optional, served at /api/process */
    void *process_user;
    const char *page; /* the page served at /: "index.html" (NULL, the run's page) or
                         "controller.html" (the controller process's page) */
} rths_view_options;

void rths_view_options_defaults(rths_view_options *opt);

/* "HOST:PORT", "[IPv6]:PORT" or "PORT" (loopback). RTHS_EINPUT when malformed. */
int rths_view_parse_listen(const char *text, char *host, size_t host_cap, int *port,
                           rths_error *err);
/* 1 for 127.0.0.0/8, ::1 and "localhost". */
int rths_view_host_is_loopback(const char *host);

/* RTHS_OK when dir is a folder holding a run (journal.jsonl, frf.csv or live.json), else
 * RTHS_EINPUT with the reason (missing, not a folder, not a run). */
int rths_view_check_run_dir(const char *dir, rths_error *err);
/* RTHS_OK when dir holds a run (as above) or a campaign (`rths campaign --out`: campaign.csv, or
 * runs.csv and plan.txt), what rths_view_start serves; else RTHS_EINPUT with the reason. */
int rths_view_check_folder(const char *dir, rths_error *err);

/* A campaign folder's table as JSON {"kind": "campaign", "source": "campaign.csv"|"runs.csv"|
 * "none", "columns": [...], "grid": [the grid keys], "outputs": [the result columns],
 * "runs": [{column: value, ...}, ...] (empty fields null, numbers as numbers, other text as
 * text), "run_folders": [whether run K's folder holds a run yet], "total", "finished", "failed"}
 * (malloc'ed text, caller frees). */
int rths_view_campaign_json(const char *dir, char **json, rths_error *err);

/* The run's accepted points as JSON {"source": "frf.csv"|"journal.jsonl", "columns": [...],
 * "points": [{column: value, ...}, ...]} (malloc'ed text, caller frees). NaN becomes null. */
int rths_view_points_json(const char *dir, char **json, rths_error *err);

/* Binds and starts serving in background threads. */
int rths_view_start(const rths_view_options *opt, rths_view **out, rths_error *err);
int rths_view_port(const rths_view *v); /* the bound port */
void rths_view_stop(rths_view *v);      /* closes every connection; v may be NULL */

/* The controller process's page (`rths controller --view ADDR:PORT`): the interface signals as
 * an oscilloscope (physical and numerical interface displacement, target, force; the loop's
 * samples decimated to about 1 kHz), the limit state, the watchdog, the loop's lateness histogram
 * and overruns. It reads only what the loop publishes lock-free (server.h: the scope ring, the
 * histogram bins, atomics); a collector thread of its own is the scope ring's one consumer, so
 * the paced loop never waits for a browser. listen: "HOST:PORT" as for --listen (loopback by
 * default; the caller warns about any other address, rths_view_host_is_loopback). May start
 * before or after rths_server_start; stop it before rths_server_destroy. RTHS_EINPUT for a bad
 * listen text (naming --view), RTHS_EFAIL when it cannot listen. */
typedef struct rths_server_view rths_server_view;
int rths_server_view_start(rths_server *server, const char *listen, rths_server_view **out,
                           rths_error *err);
int rths_server_view_port(const rths_server_view *sv);         /* the bound port (listen port 0) */
const char *rths_server_view_host(const rths_server_view *sv); /* the address served on */
void rths_server_view_stop(rths_server_view *sv);              /* sv may be NULL */
/* The JSON of /api/process and of /api/status's "process" (tests, and a page elsewhere). */
char *rths_server_view_process_json(rths_server_view *sv);

#endif
