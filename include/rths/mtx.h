/* rths mtx: Matrix Market (.mtx) input for the structure's matrices (model module).
 *
 * The format finite-element codes export (NIST Matrix Market exchange format): a header line
 * "%%MatrixMarket matrix FORMAT FIELD SYMMETRY" with FORMAT coordinate or array, FIELD real,
 * double or integer, SYMMETRY general or symmetric; '%' comment lines; a size line; then the
 * entries (coordinate: "i j value", 1-based, duplicates summed as FE assembly does; array: values
 * column by column, for symmetric only the lower triangle). Values are decimal (no hexadecimal
 * floats, no NUL bytes, nothing after the header's five words). No Debian package with a permissive
 * licence reads it (SuiteSparse's reader sits in GPL-linked CHOLMOD), hence this small reader. */
#ifndef RTHS_MTX_H
#define RTHS_MTX_H

#include "rths/core.h"
#include "rths/sparse.h"

/* Largest dimension accepted: a dense n x n double matrix of this size is 1.3 GB. */
#define RTHS_MTX_MAX_DIM 12000

/* Reads path into a dense column-major rows x cols matrix (*out malloc'ed; symmetric files
 * expanded to both triangles). Every problem is RTHS_EINPUT with "PATH:LINE: what is wrong";
 * a file that cannot be opened names the system's reason. */
int rths_mtx_read(const char *path, double **out, int *rows, int *cols, rths_error *err);

/* Checks rths_mtx_read_checked can make on the entries before the dense matrix is formed. */
enum {
    /* square, every diagonal term (duplicates summed) > 0: a mass or stiffness matrix */
    RTHS_MTX_POSITIVE_DIAGONAL = 1,
};
/* rths_mtx_read with checks (flags: the enum above, or-ed). The file's entries are held as they
 * are read and checked before the dense matrix is allocated, so memory grows with the entries
 * present: a short file declaring a large size is refused without allocating it. */
int rths_mtx_read_checked(const char *path, int flags, double **out, int *rows, int *cols,
                          rths_error *err);

/* Largest order rths_mtx_read_sparse accepts. The only memory that follows the size line rather
 * than the entries is allocated after every entry has been read and checked: the column pointers
 * and two work arrays of the CSC build, 12 bytes per declared column (120 MB at this size, for a
 * file that holds the entries it declares; with RTHS_MTX_POSITIVE_DIAGONAL a file with fewer
 * entries than its order never gets that far). */
#define RTHS_MTX_MAX_SPARSE_DIM 10000000

/* Reads a square matrix file into symmetric CSC (lower triangle; a "symmetric" file's one
 * triangle, or a "general" file that must then be symmetric, checked), streaming: the entries are
 * held as triplets as they are read, so memory follows the entries present, not the declared
 * size; with RTHS_MTX_POSITIVE_DIAGONAL a file with fewer entries than its order is refused before
 * anything of that order is allocated. Errors as rths_mtx_read's. */
int rths_mtx_read_sparse(const char *path, int flags, rths_sparse_sym *out, rths_error *err);

/* The order a file declares (header and size line only, nothing else read): how `rths model`
 * chooses between the dense and the sparse path before reading a large file. */
int rths_mtx_read_size(const char *path, int *rows, int *cols, rths_error *err);

#endif
