/* Symmetric CSC storage (see sparse.h): built from triplets by two counting sorts (by row, then
 * by column, which leaves the rows of each column in increasing order), duplicates then summed in
 * place. Memory and time are linear in the triplets plus n. */
#include "rths/sparse.h"

#include <stdlib.h>
#include <string.h>

void rths_sparse_free(rths_sparse_sym *a) {
    if (!a) return;
    free(a->colptr);
    free(a->rowidx);
    free(a->value);
    memset(a, 0, sizeof *a);
}

int rths_sparse_from_triplets(int n, long count, const int *row, const int *col,
                              const double *value, rths_sparse_sym *a, rths_error *err) {
    memset(a, 0, sizeof *a);
    if (n < 1 || n > RTHS_SPARSE_MAX_DIM)
        return rths_error_set(err, RTHS_EINPUT, "sparse matrix order %d is not in 1..%d", n,
                              RTHS_SPARSE_MAX_DIM);
    if (count < 0 || count > (long)0x7fffffff)
        return rths_error_set(err, RTHS_EINPUT, "sparse matrix entry count %ld is not in 0..%d",
                              count, 0x7fffffff);
    for (long e = 0; e < count; e++)
        if (row[e] < 0 || row[e] >= n || col[e] < 0 || col[e] >= n)
            return rths_error_set(err, RTHS_EINPUT,
                                  "sparse matrix entry %ld: index (%d,%d) is not in 0..%d", e,
                                  row[e], col[e], n - 1);
    size_t cnt = (size_t)count ? (size_t)count : 1;
    int *rowptr = calloc((size_t)n + 1, sizeof *rowptr);
    int *bycol = malloc(cnt * sizeof *bycol);
    double *byval = malloc(cnt * sizeof *byval);
    int *colptr = calloc((size_t)n + 1, sizeof *colptr);
    int *rowidx = malloc(cnt * sizeof *rowidx);
    double *val = malloc(cnt * sizeof *val);
    int *colfill = malloc((size_t)n * sizeof *colfill);
    if (!rowptr || !bycol || !byval || !colptr || !rowidx || !val || !colfill) {
        free(rowptr), free(bycol), free(byval), free(colptr), free(rowidx), free(val);
        free(colfill);
        return rths_error_set(err, RTHS_EFAIL, "out of memory for a sparse matrix of %ld entries",
                              count);
    }
    /* pass 1: bucket by (folded) row; the lower triangle holds (max, min) */
    for (long e = 0; e < count; e++) {
        int i = row[e] > col[e] ? row[e] : col[e];
        rowptr[i + 1]++;
    }
    for (int i = 0; i < n; i++)
        rowptr[i + 1] += rowptr[i];
    for (long e = 0; e < count; e++) {
        int i = row[e] > col[e] ? row[e] : col[e], j = row[e] > col[e] ? col[e] : row[e];
        int at = rowptr[i]++;
        bycol[at] = j;
        byval[at] = value[e];
    }
    /* rowptr[i] now holds the end of row i, the start of row i + 1 */
    /* pass 2: bucket by column, visiting rows in increasing order */
    for (long e = 0; e < count; e++)
        colptr[bycol[e] + 1]++;
    for (int j = 0; j < n; j++)
        colptr[j + 1] += colptr[j];
    memcpy(colfill, colptr, (size_t)n * sizeof *colfill);
    for (int i = 0, start = 0; i < n; start = rowptr[i], i++)
        for (int e = start; e < rowptr[i]; e++) {
            int at = colfill[bycol[e]]++;
            rowidx[at] = i;
            val[at] = byval[e];
        }
    free(colfill);
    free(rowptr);
    free(bycol);
    free(byval);
    /* sum duplicates in place (equal rows are adjacent within a column) */
    int out = 0;
    for (int j = 0; j < n; j++) {
        int start = colptr[j], end = colptr[j + 1];
        colptr[j] = out;
        for (int e = start; e < end; e++) {
            if (out > colptr[j] && rowidx[out - 1] == rowidx[e])
                val[out - 1] += val[e];
            else {
                rowidx[out] = rowidx[e];
                val[out] = val[e];
                out++;
            }
        }
    }
    colptr[n] = out;
    size_t keep = out ? (size_t)out : 1;
    int *ri = realloc(rowidx, keep * sizeof *ri);
    double *vv = realloc(val, keep * sizeof *vv);
    a->n = n;
    a->colptr = colptr;
    a->rowidx = ri ? ri : rowidx;
    a->value = vv ? vv : val;
    return RTHS_OK;
}

void rths_sparse_symv(const rths_sparse_sym *a, const double *x, double *y) {
    memset(y, 0, (size_t)a->n * sizeof *y);
    for (int j = 0; j < a->n; j++) {
        double xj = x[j], acc = 0;
        for (int e = a->colptr[j]; e < a->colptr[j + 1]; e++) {
            int i = a->rowidx[e];
            double v = a->value[e];
            y[i] += v * xj;
            if (i != j) acc += v * x[i];
        }
        y[j] += acc;
    }
}

double rths_sparse_get(const rths_sparse_sym *a, int i, int j) {
    if (i < j) {
        int t = i;
        i = j;
        j = t;
    }
    int lo = a->colptr[j], hi = a->colptr[j + 1] - 1;
    while (lo <= hi) {
        int mid = (lo + hi) / 2;
        if (a->rowidx[mid] == i) return a->value[mid];
        if (a->rowidx[mid] < i)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return 0;
}

double *rths_sparse_to_dense(const rths_sparse_sym *a) {
    double *d = rths_mat_new(a->n, a->n);
    if (!d) return NULL;
    for (int j = 0; j < a->n; j++)
        for (int e = a->colptr[j]; e < a->colptr[j + 1]; e++) {
            RTHS_AT(d, a->n, a->rowidx[e], j) = a->value[e];
            RTHS_AT(d, a->n, j, a->rowidx[e]) = a->value[e];
        }
    return d;
}
