/* Inside the view module: reading a run folder, the embedded assets. */
#ifndef RTHS_VIEW_INTERNAL_H
#define RTHS_VIEW_INTERNAL_H

#include "rths/report.h"
#include "rths/run.h"
#include "rths/view.h"

#include <stddef.h>
#include <sys/stat.h>

struct json_object;

enum { VIEW_FRF_COLUMNS = RTHS_RUN_FRF_COLUMNS };

/* rths_view_parse_listen with the option's name in its messages (--listen, --view). */
int view_parse_listen_as(const char *option, const char *text, char *host, size_t host_cap,
                         int *port, rths_error *err);

int view_file_exists(const char *dir, const char *name); /* a regular file, not a symlink */

/* A file of the run folder, open for reading (view_files.c): a regular file in the folder itself,
 * never through a symbolic link, never a FIFO or device. */
typedef struct view_file {
    int fd;
    struct stat st;
    char proc_path[32]; /* /proc/self/fd/N: this open file for readers that take a path */
} view_file;
/* 200 with f open; 404 no such file; 403 refused (a symbolic link, FIFO, device, folder: never
 * read); 500 cannot open. err names NAME and the reason, never the file's content. */
int view_file_open(const char *dir, const char *name, view_file *f, rths_error *err);
void view_file_close(view_file *f);                       /* f->fd may be -1 */
int view_file_present(const char *dir, const char *name); /* any kind of entry, links too */
/* Files the view parses into memory (CSV, journal, config) up to this size; larger: 500 naming
 * the limit. Files it passes through (/run/NAME, /api/live, /api/summary) are streamed whole. */
#define VIEW_MAX_PARSED_BYTES ((size_t)256 << 20)
int view_file_parse_check(const view_file *f, const char *name, rths_error *err); /* 200 or 500 */
/* Replaces every `from` in err's message by `to` (a reader's /proc/self/fd/N by the file's name).
 */
void view_error_rename(rths_error *err, const char *from, const char *to);
char *view_json_text(struct json_object *obj); /* %.17g numbers, malloc'ed */
/* truth.csv as {"column": [values...], ...}; returns the HTTP status (200, 403, 404, 500). */
int view_truth_json(const char *dir, char **json, rths_error *err);
/* rths_view_points_json returning the HTTP status: 403 for a refused file. */
int view_points_json(const char *dir, char **json, rths_error *err);

/* A campaign folder (view_campaign.c, docs/campaign.md): campaign.csv, or runs.csv with plan.txt
 * (a campaign that has only started). */
int view_is_campaign_dir(const char *dir);
/* NAME is run_ and digits (never "..", a slash, a hidden name). */
int view_campaign_run_name(const char *name);
/* NAME is such a run folder directly inside the campaign folder, a folder and not a symlink. */
int view_campaign_run_dir(const char *campaign_dir, const char *name);
/* rths_view_campaign_json returning the HTTP status (403 for a refused file). */
int view_campaign_json(const char *dir, char **json, rths_error *err);
/* The campaign's state for /api/status: {state: running|ended|stopped, runs, finished, failed,
 * config}. */
struct json_object *view_campaign_state(const char *dir);

/* What the run's config.yaml plans: {start_hz, end_hz, method, max_points}, or NULL. */
struct json_object *view_plan_object(const char *dir);

/* The page and its libraries, compiled into the binary (web/assets.cmake generates the table). */
typedef struct view_asset {
    const char *name; /* "index.html", "uPlot.iife.min.js", ... */
    const char *mime;
    const unsigned char *data;
    size_t size;
} view_asset;
extern const view_asset view_assets[];
extern const int view_asset_count;

#endif
