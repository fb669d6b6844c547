/* Matrix Market reader (see mtx.h): strict about everything that could silently change a matrix
 * (counts, indices, triangles, trailing text, non-finite values), each problem located by line. */
#include "rths/mtx.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

typedef struct {
    const char *path;
    FILE *f;
    char *line;
    size_t cap;
    ssize_t len; /* bytes getline read: a NUL byte before them would hide the rest of the line */
    long lineno;
} mtx_reader;

static int bad(const mtx_reader *r, rths_error *err, const char *what) {
    return rths_error_set(err, RTHS_EINPUT, "%s:%ld: %s", r->path, r->lineno, what);
}

/* Next line that is neither a comment nor blank; 0 at end of file. */
static int next_data_line(mtx_reader *r) {
    for (;;) {
        if ((r->len = getline(&r->line, &r->cap, r->f)) < 0) return 0;
        r->lineno++;
        const char *p = r->line + strspn(r->line, " \t\r\n");
        if (*p && *p != '%') return 1;
    }
}

/* Parses exactly `count` whitespace-separated fields of the current line as numbers. */
static int parse_fields(mtx_reader *r, int count, double *v, rths_error *err) {
    char *p = r->line, msg[160];
    if ((ssize_t)strlen(r->line) != r->len) return bad(r, err, "the line holds a NUL byte");
    for (int k = 0; k < count; k++) {
        char *end;
        errno = 0;
        p += strspn(p, " \t");
        /* strtod also reads C99 hexadecimal floats ("0x1p3"), which no FE code writes: a value
         * like that is a corrupt or foreign file, not a number to trust */
        size_t token = strcspn(p, " \t\r\n");
        if (memchr(p, 'x', token) || memchr(p, 'X', token)) {
            snprintf(msg, sizeof msg, "'%.*s' is not a decimal number",
                     token < 40 ? (int)token : 40, p);
            return bad(r, err, msg);
        }
        v[k] = strtod(p, &end);
        if (end == p) {
            snprintf(msg, sizeof msg, "expected %d number%s on this line, found %d", count,
                     count > 1 ? "s" : "", k);
            return bad(r, err, msg);
        }
        if (!isfinite(v[k])) return bad(r, err, "value is not a finite number");
        p = end;
    }
    p += strspn(p, " \t\r\n");
    if (*p) {
        int len = (int)strcspn(p, "\r\n");
        while (len > 0 && (p[len - 1] == ' ' || p[len - 1] == '\t'))
            len--;
        snprintf(msg, sizeof msg, "unexpected text '%.*s' after %d number%s", len < 40 ? len : 40,
                 p, count, count > 1 ? "s" : "");
        return bad(r, err, msg);
    }
    return RTHS_OK;
}

static int parse_index(mtx_reader *r, double v, int dim, const char *what, int *out,
                       rths_error *err) {
    char msg[128];
    if (v != floor(v) || v < 1 || v > dim) {
        snprintf(msg, sizeof msg, "%s index %.17g is not a whole number in 1..%d", what, v, dim);
        return bad(r, err, msg);
    }
    *out = (int)v - 1;
    return RTHS_OK;
}

typedef struct {
    int coordinate, symmetric;
} mtx_kind;

static int parse_header(mtx_reader *r, mtx_kind *kind, rths_error *err) {
    if (getline(&r->line, &r->cap, r->f) < 0) {
        r->lineno = 1;
        return bad(r, err, "empty file: expected a '%%MatrixMarket matrix ...' header");
    }
    r->lineno = 1;
    char banner[32] = "", object[32] = "", format[32] = "", field[32] = "", symmetry[32] = "";
    char extra[32] = "";
    int got = sscanf(r->line, "%31s %31s %31s %31s %31s %31s", banner, object, format, field,
                     symmetry, extra);
    if (got < 1 || strcasecmp(banner, "%%MatrixMarket"))
        return bad(r, err,
                   "not a Matrix Market file: the first line must start with "
                   "'%%MatrixMarket'");
    if (got < 5)
        return bad(r, err,
                   "incomplete header: expected '%%MatrixMarket matrix FORMAT FIELD "
                   "SYMMETRY'");
    if (strcasecmp(object, "matrix")) return bad(r, err, "object must be 'matrix'");
    if (!strcasecmp(format, "coordinate"))
        kind->coordinate = 1;
    else if (!strcasecmp(format, "array"))
        kind->coordinate = 0;
    else
        return bad(r, err, "format must be 'coordinate' or 'array'");
    if (strcasecmp(field, "real") && strcasecmp(field, "double") && strcasecmp(field, "integer"))
        return bad(r, err,
                   "field must be 'real' (or 'integer'): a structural matrix has real "
                   "entries (complex and pattern files are not accepted)");
    if (!strcasecmp(symmetry, "general"))
        kind->symmetric = 0;
    else if (!strcasecmp(symmetry, "symmetric"))
        kind->symmetric = 1;
    else
        return bad(r, err, "symmetry must be 'general' or 'symmetric'");
    if (got > 5) return bad(r, err, "unexpected words after the header's SYMMETRY");
    return RTHS_OK;
}

static int read_size(mtx_reader *r, const mtx_kind *kind, int max_dim, int *rows, int *cols,
                     long *entries, rths_error *err) {
    if (!next_data_line(r)) return bad(r, err, "missing size line");
    double v[3];
    int rc = parse_fields(r, kind->coordinate ? 3 : 2, v, err);
    if (rc) return rc;
    char msg[160];
    for (int k = 0; k < 2; k++)
        if (v[k] != floor(v[k]) || v[k] < 1 || v[k] > max_dim) {
            snprintf(msg, sizeof msg, "size %.17g is not a whole number in 1..%d", v[k], max_dim);
            return bad(r, err, msg);
        }
    *rows = (int)v[0];
    *cols = (int)v[1];
    if (kind->symmetric && *rows != *cols) return bad(r, err, "a symmetric matrix must be square");
    long full = (long)*rows * *cols;
    if (kind->coordinate) {
        if (v[2] != floor(v[2]) || v[2] < 0 || v[2] > 4.0 * (double)full) {
            snprintf(msg, sizeof msg, "entry count %.17g is not a whole number in 0..%ld", v[2],
                     4 * full);
            return bad(r, err, msg);
        }
        *entries = (long)v[2];
    } else {
        *entries = kind->symmetric ? (long)*rows * (*rows + 1) / 2 : full;
    }
    return RTHS_OK;
}

/* The entries as the file lists them, held until the whole file has been checked: memory grows
 * with the entries present, never with the size line's promise (a few bytes declaring
 * 12000 x 12000 must be refused before a dense matrix of that size exists). */
typedef struct {
    int *i, *j;
    double *v;
    long n, cap;
} mtx_entries;

static int push_entry(mtx_entries *t, int i, int j, double v) {
    if (t->n == t->cap) {
        long cap = t->cap ? 2 * t->cap : 1024;
        int *ni = realloc(t->i, (size_t)cap * sizeof *ni);
        if (ni) t->i = ni;
        int *nj = realloc(t->j, (size_t)cap * sizeof *nj);
        if (nj) t->j = nj;
        double *nv = realloc(t->v, (size_t)cap * sizeof *nv);
        if (nv) t->v = nv;
        if (!ni || !nj || !nv) return -1;
        t->cap = cap;
    }
    t->i[t->n] = i;
    t->j[t->n] = j;
    t->v[t->n] = v;
    t->n++;
    return 0;
}

static int out_of_memory(const mtx_reader *r, rths_error *err) {
    return rths_error_set(err, RTHS_EFAIL, "%s: out of memory after %ld lines", r->path, r->lineno);
}

/* Coordinate entries; a symmetric file may use either triangle, not both. */
static int read_coordinate(mtx_reader *r, const mtx_kind *kind, int rows, int cols, long entries,
                           mtx_entries *t, rths_error *err) {
    int lower = 0, upper = 0;
    for (long e = 0; e < entries; e++) {
        if (!next_data_line(r)) {
            char msg[128];
            snprintf(msg, sizeof msg,
                     "file ends after %ld of the %ld entries the size line "
                     "announces",
                     e, entries);
            return bad(r, err, msg);
        }
        double v[3];
        int i, j, rc = parse_fields(r, 3, v, err);
        if (!rc) rc = parse_index(r, v[0], rows, "row", &i, err);
        if (!rc) rc = parse_index(r, v[1], cols, "column", &j, err);
        if (rc) return rc;
        lower |= i > j;
        upper |= i < j;
        if (kind->symmetric && lower && upper)
            return bad(r, err,
                       "a symmetric file stores one triangle only, this entry is in the "
                       "other one");
        if (push_entry(t, i, j, v[2])) return out_of_memory(r, err);
    }
    return RTHS_OK;
}

/* Array entries: column by column; symmetric: the lower triangle only. */
static int read_array(mtx_reader *r, const mtx_kind *kind, int rows, long entries, mtx_entries *t,
                      rths_error *err) {
    int i = 0, j = 0;
    for (long e = 0; e < entries; e++) {
        if (!next_data_line(r)) {
            char msg[128];
            snprintf(msg, sizeof msg,
                     "file ends after %ld of the %ld values the size line "
                     "announces",
                     e, entries);
            return bad(r, err, msg);
        }
        double v;
        int rc = parse_fields(r, 1, &v, err);
        if (rc) return rc;
        if (push_entry(t, i, j, v)) return out_of_memory(r, err);
        if (++i == rows) {
            j++;
            i = kind->symmetric ? j : 0;
        }
    }
    return RTHS_OK;
}

/* The dense matrix of checked entries: coordinate duplicates summed (FE assembly writes element
 * contributions separately), symmetric files expanded to both triangles. */
static void assemble(const mtx_kind *kind, int rows, const mtx_entries *t, double *m) {
    for (long e = 0; e < t->n; e++) {
        int i = t->i[e], j = t->j[e];
        if (kind->coordinate) {
            RTHS_AT(m, rows, i, j) += t->v[e];
            if (kind->symmetric && i != j) RTHS_AT(m, rows, j, i) += t->v[e];
        } else {
            RTHS_AT(m, rows, i, j) = t->v[e];
            if (kind->symmetric) RTHS_AT(m, rows, j, i) = t->v[e];
        }
    }
}

/* Every diagonal term (duplicates summed) positive, checked on the entries before the dense
 * matrix exists: a mass or stiffness matrix without one is singular or indefinite anyway, and a
 * few-byte file declaring a large size must cost nothing to refuse. */
static int check_positive_diagonal(const mtx_reader *r, int n, const mtx_entries *t,
                                   rths_error *err) {
    double *diag = calloc((size_t)n, sizeof *diag);
    if (!diag) return out_of_memory(r, err);
    for (long e = 0; e < t->n; e++)
        if (t->i[e] == t->j[e]) diag[t->i[e]] += t->v[e];
    int rc = RTHS_OK;
    for (int i = 0; i < n && !rc; i++)
        if (!(diag[i] > 0))
            rc = rths_error_set(err, RTHS_EINPUT,
                                "%s: diagonal entry (%d,%d) is %s: a mass or stiffness matrix "
                                "needs a positive diagonal term on every DoF",
                                r->path, i + 1, i + 1,
                                diag[i] == 0 ? "zero or missing" : "negative");
    free(diag);
    return rc;
}

int rths_mtx_read(const char *path, double **out, int *rows, int *cols, rths_error *err) {
    return rths_mtx_read_checked(path, 0, out, rows, cols, err);
}

/* Reads the whole file into triplets (checked: header, size, every entry, the count), with
 * sizes up to max_dim; r->f is closed and r->line freed on return. */
static int read_entries(mtx_reader *r, int max_dim, mtx_kind *kind, int *rows, int *cols,
                        mtx_entries *t, rths_error *err) {
    r->f = fopen(r->path, "r");
    if (!r->f)
        return rths_error_set(err, RTHS_EINPUT, "%s: cannot open: %s", r->path, strerror(errno));
    long entries = 0;
    int rc = parse_header(r, kind, err);
    if (!rc) rc = read_size(r, kind, max_dim, rows, cols, &entries, err);
    if (!rc)
        rc = kind->coordinate ? read_coordinate(r, kind, *rows, *cols, entries, t, err)
                              : read_array(r, kind, *rows, entries, t, err);
    if (!rc && next_data_line(r)) rc = bad(r, err, "more entries than the size line announces");
    free(r->line);
    r->line = NULL;
    fclose(r->f);
    r->f = NULL;
    return rc;
}

static void free_entries(mtx_entries *t) {
    free(t->i);
    free(t->j);
    free(t->v);
    memset(t, 0, sizeof *t);
}

int rths_mtx_read_checked(const char *path, int flags, double **out, int *rows, int *cols,
                          rths_error *err) {
    *out = NULL;
    *rows = *cols = 0;
    mtx_reader r = {.path = path};
    mtx_kind kind = {0};
    mtx_entries t = {0};
    double *m = NULL;
    int rc = read_entries(&r, RTHS_MTX_MAX_DIM, &kind, rows, cols, &t, err);
    if (!rc && (flags & RTHS_MTX_POSITIVE_DIAGONAL)) {
        if (*rows != *cols)
            rc = rths_error_set(err, RTHS_EINPUT, "%s: must be square (is %d x %d)", path, *rows,
                                *cols);
        else
            rc = check_positive_diagonal(&r, *rows, &t, err);
    }
    if (!rc) {
        m = rths_mat_new(*rows, *cols);
        if (!m)
            rc = rths_error_set(err, RTHS_EFAIL, "%s: out of memory (%d x %d)", path, *rows, *cols);
        else
            assemble(&kind, *rows, &t, m);
    }
    free_entries(&t);
    if (rc) {
        rths_mat_free(m);
        *rows = *cols = 0;
        return rc;
    }
    *out = m;
    return RTHS_OK;
}

/* A general file read as symmetric: every off-diagonal entry (duplicates summed) must equal its
 * mirror, to rounding of the largest entry (an FE code writing both triangles prints the same
 * number twice); checked column by column on the two triangles folded onto the lower one. */
static int check_symmetric(const char *path, const rths_sparse_sym *lower,
                           const rths_sparse_sym *upper, rths_error *err) {
    double big = 0;
    for (int e = 0; e < lower->colptr[lower->n]; e++)
        big = fmax(big, fabs(lower->value[e]));
    for (int e = 0; e < upper->colptr[upper->n]; e++)
        big = fmax(big, fabs(upper->value[e]));
    double tol = 1e-12 * big;
    for (int j = 0; j < lower->n; j++) {
        int a = lower->colptr[j], ae = lower->colptr[j + 1];
        int b = upper->colptr[j], be = upper->colptr[j + 1];
        if (a < ae && lower->rowidx[a] == j) a++; /* the diagonal has no mirror */
        while (a < ae || b < be) {
            int ia = a < ae ? lower->rowidx[a] : lower->n,
                ib = b < be ? upper->rowidx[b] : upper->n;
            int i = ia < ib ? ia : ib;
            double va = ia == i ? lower->value[a++] : 0, vb = ib == i ? upper->value[b++] : 0;
            if (fabs(va - vb) > tol)
                return rths_error_set(err, RTHS_EINPUT,
                                      "%s: not symmetric: entry (%d,%d) is %.17g but (%d,%d) is "
                                      "%.17g",
                                      path, i + 1, j + 1, va, j + 1, i + 1, vb);
        }
    }
    return RTHS_OK;
}

int rths_mtx_read_sparse(const char *path, int flags, rths_sparse_sym *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    mtx_reader r = {.path = path};
    mtx_kind kind = {0};
    mtx_entries t = {0};
    int rows = 0, cols = 0;
    int rc = read_entries(&r, RTHS_MTX_MAX_SPARSE_DIM, &kind, &rows, &cols, &t, err);
    if (!rc && rows != cols)
        rc = rths_error_set(err, RTHS_EINPUT, "%s: must be square (is %d x %d)", path, rows, cols);
    /* a positive diagonal needs n entries: refused before anything of the declared size exists */
    if (!rc && (flags & RTHS_MTX_POSITIVE_DIAGONAL) && t.n < rows)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s: declares %d x %d but holds %ld entries: a mass or stiffness "
                            "matrix needs a positive diagonal term on every DoF",
                            path, rows, cols, t.n);
    if (!rc && (flags & RTHS_MTX_POSITIVE_DIAGONAL))
        rc = check_positive_diagonal(&r, rows, &t, err);
    if (!rc && kind.symmetric) {
        rc = rths_sparse_from_triplets(rows, t.n, t.i, t.j, t.v, out, err);
    } else if (!rc) {
        /* general: the lower entries (with the diagonal) and the upper ones, each folded onto the
         * lower triangle, must agree */
        long nl = 0;
        for (long e = 0; e < t.n; e++)
            if (t.i[e] >= t.j[e]) {
                int ti = t.i[e], tj = t.j[e];
                double tv = t.v[e];
                t.i[e] = t.i[nl], t.j[e] = t.j[nl], t.v[e] = t.v[nl];
                t.i[nl] = ti, t.j[nl] = tj, t.v[nl] = tv;
                nl++;
            }
        rths_sparse_sym upper = {0};
        rc = rths_sparse_from_triplets(rows, nl, t.i, t.j, t.v, out, err);
        if (!rc)
            rc = rths_sparse_from_triplets(rows, t.n - nl, t.i + nl, t.j + nl, t.v + nl, &upper,
                                           err);
        if (!rc) rc = check_symmetric(path, out, &upper, err);
        rths_sparse_free(&upper);
    }
    free_entries(&t);
    if (rc) rths_sparse_free(out);
    return rc;
}

int rths_mtx_read_size(const char *path, int *rows, int *cols, rths_error *err) {
    mtx_reader r = {.path = path};
    mtx_kind kind = {0};
    long entries = 0;
    *rows = *cols = 0;
    r.f = fopen(path, "r");
    if (!r.f) return rths_error_set(err, RTHS_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    int rc = parse_header(&r, &kind, err);
    if (!rc) rc = read_size(&r, &kind, RTHS_MTX_MAX_SPARSE_DIM, rows, cols, &entries, err);
    free(r.line);
    fclose(r.f);
    return rc;
}
