/* rths_api_view_*: `rths view`, the live web page of a run or campaign folder (src/view/,
 * docs/view.md), behind the C API. */
#include "api/api_internal.h"
#include "rths/view.h"

#include <stdlib.h>
#include <string.h>

struct rths_api_view {
    rths_view_options options;
    char *dir;
    rths_view *view; /* NULL until served */
};

int rths_api_view_open(const char *dir, const char *listen, rths_api_view **out, rths_error *err) {
    *out = NULL;
    if (!dir) return rths_error_set(err, RTHS_EINPUT, "no folder given");
    rths_api_view *v = calloc(1, sizeof *v);
    if (!v || !(v->dir = strdup(dir))) {
        free(v);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    rths_view_options_defaults(&v->options);
    v->options.run_dir = v->dir;
    int rc = RTHS_OK;
    if (listen)
        rc = rths_view_parse_listen(listen, v->options.host, sizeof v->options.host,
                                    &v->options.port, err);
    if (!rc) rc = rths_view_check_folder(dir, err);
    if (rc) {
        rths_api_view_stop(v);
        return rc;
    }
    *out = v;
    return RTHS_OK;
}

const char *rths_api_view_host(const rths_api_view *v) {
    return v ? v->options.host : NULL;
}

int rths_api_view_host_is_loopback(const rths_api_view *v) {
    return v && rths_view_host_is_loopback(v->options.host);
}

int rths_api_view_serve(rths_api_view *v, rths_error *err) {
    if (!v) return rths_error_set(err, RTHS_EINPUT, "no view given");
    if (v->view) return RTHS_OK;
    return rths_view_start(&v->options, &v->view, err);
}

int rths_api_view_port(const rths_api_view *v) {
    return v && v->view ? rths_view_port(v->view) : -1;
}

void rths_api_view_stop(rths_api_view *v) {
    if (!v) return;
    rths_view_stop(v->view);
    free(v->dir);
    free(v);
}
