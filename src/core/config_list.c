/* The configuration's getters for lists: lists of numbers and of integers, matrices (lists of
 * rows), and the count of items of a list. */
#include "core/config_internal.h"

#include <ctype.h>
#include <errno.h>
#include <libfyaml.h>
#include <limits.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static int number_list(rths_config *cfg, const char *key, cnode *n, int integers, double **dout,
                       int **iout, int *count, rths_error *err) {
    if (n->type != NODE_SEQUENCE)
        return config_key_error(cfg, key, n, err,
                                "expected a list of numbers like [1, 2], got %s%s%s",
                                config_describe(n), n->type == NODE_SCALAR ? " " : "",
                                n->type == NODE_SCALAR ? n->text : "");
    size_t m = (size_t)(n->count ? n->count : 1);
    double *d = integers ? NULL : calloc(m, sizeof *d);
    int *iv = integers ? calloc(m, sizeof *iv) : NULL;
    if (!d && !iv) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < n->count; i++) {
        cnode *item = n->items[i];
        int rc;
        if (integers) {
            long v = 0;
            rc = config_scalar_int(cfg, key, item, &v, err);
            if (!rc && (v < -2147483647L || v > 2147483647L))
                rc = config_key_error(cfg, key, item, err, "entry %d is out of range", i + 1);
            if (!rc) iv[i] = (int)v;
        } else {
            rc = config_scalar_number(cfg, key, item, &d[i], err);
        }
        if (rc) {
            free(d);
            free(iv);
            return rc;
        }
    }
    if (dout) *dout = d;
    if (iout) *iout = iv;
    *count = n->count;
    return RTHS_OK;
}

int rths_config_get_double_list(rths_config *cfg, const char *key, int required, double **out,
                                int *count, rths_error *err) {
    cnode *n;
    *out = NULL;
    *count = 0;
    int rc = config_get_node(cfg, key, required, &n, err);
    if (rc || !n) return rc;
    return number_list(cfg, key, n, 0, out, NULL, count, err);
}

int rths_config_get_int_list(rths_config *cfg, const char *key, int required, int **out, int *count,
                             rths_error *err) {
    cnode *n;
    *out = NULL;
    *count = 0;
    int rc = config_get_node(cfg, key, required, &n, err);
    if (rc || !n) return rc;
    return number_list(cfg, key, n, 1, NULL, out, count, err);
}

int rths_config_get_matrix(rths_config *cfg, const char *key, int required, double **out, int *rows,
                           int *cols, rths_error *err) {
    cnode *n;
    *out = NULL;
    *rows = *cols = 0;
    int rc = config_get_node(cfg, key, required, &n, err);
    if (rc || !n) return rc;
    if (n->type != NODE_SEQUENCE || n->count == 0)
        return config_key_error(cfg, key, n, err,
                                "expected a matrix as a list of rows, e.g. [[1, 0], [0, 1]]");
    int r = n->count, c = -1;
    for (int i = 0; i < r; i++) {
        cnode *row = n->items[i];
        if (row->type != NODE_SEQUENCE)
            return config_key_error(cfg, key, row, err, "row %d is not a list of numbers", i + 1);
        if (c < 0) c = row->count;
        if (row->count != c)
            return config_key_error(cfg, key, row, err, "row %d has %d entries, row 1 has %d",
                                    i + 1, row->count, c);
    }
    if (c < 1) return config_key_error(cfg, key, n, err, "the matrix has empty rows");
    double *m = calloc((size_t)r * (size_t)c, sizeof *m);
    if (!m) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < r; i++)
        for (int j = 0; j < c; j++) {
            rc = config_scalar_number(cfg, key, n->items[i]->items[j], &RTHS_AT(m, r, i, j), err);
            if (rc) {
                free(m);
                return rc;
            }
        }
    *out = m;
    *rows = r;
    *cols = c;
    return RTHS_OK;
}

int rths_config_get_count(rths_config *cfg, const char *key, int *count, rths_error *err) {
    *count = 0;
    cnode *n;
    int rc = config_get_node(cfg, key, 0, &n, err);
    if (rc || !n || config_is_empty(n)) return rc;
    if (n->type != NODE_SEQUENCE)
        return config_key_error(cfg, key, n, err, "must be a list ([...] or '- ' items), not %s",
                                config_describe(n));
    *count = n->count;
    return RTHS_OK;
}
