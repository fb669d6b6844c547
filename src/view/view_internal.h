/* Inside the view module: reading a run folder, the embedded assets. */
#ifndef RTHS_VIEW_INTERNAL_H
#define RTHS_VIEW_INTERNAL_H

#include "rths/report.h"
#include "rths/run.h"
#include "rths/view.h"

#include <stddef.h>

struct json_object;

enum { VIEW_FRF_COLUMNS = RTHS_RUN_FRF_COLUMNS };

/* rths_view_parse_listen with the option's name in its messages (--listen, --view). */
int view_parse_listen_as(const char *option, const char *text, char *host, size_t host_cap,
                         int *port, rths_error *err);

int view_file_exists(const char *dir, const char *name); /* a regular file */
char *view_json_text(struct json_object *obj);           /* %.17g numbers, malloc'ed */
/* truth.csv as {"column": [values...], ...} */
int view_truth_json(const char *dir, char **json, rths_error *err);

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
