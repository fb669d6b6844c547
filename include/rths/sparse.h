/* rths sparse: sparse symmetric algebra for finite-element models of 1e4-1e6 DoFs (sparse module).
 *
 * Storage: a symmetric matrix in compressed sparse column (CSC) form, lower triangle and diagonal
 * stored, rows sorted and unique within each column. Factorisations: MUMPS sequential (LDL^T of
 * the real symmetric K - sigma M, and the complex symmetric K + i w C - w^2 M per frequency), one
 * symbolic analysis (fill-reducing ordering) reused by every numerical refactorisation. Modes:
 * ARPACK-ng shift-invert Lanczos. Why these libraries: docs/architecture.md, "Sparse algebra". */
#ifndef RTHS_SPARSE_H
#define RTHS_SPARSE_H

#include "rths/core.h"

#include <complex.h>

/* Largest order accepted (MUMPS's 32-bit indices; memory is bounded by the entries anyway). */
#define RTHS_SPARSE_MAX_DIM 100000000

typedef struct rths_sparse_sym {
    int n;
    int *colptr;   /* n + 1 */
    int *rowidx;   /* colptr[n]: row of each entry, >= its column, increasing within a column */
    double *value; /* colptr[n] */
} rths_sparse_sym;

/* A = the n x n symmetric matrix of the triplets (0-based): an entry of either triangle stands
 * for itself and its mirror (i < j is folded onto (j, i)), duplicates are summed as FE assembly
 * does. Memory: the triplets' count plus n + 1 column pointers. RTHS_EINPUT on an index out of
 * range, RTHS_EFAIL on allocation failure. */
int rths_sparse_from_triplets(int n, long count, const int *row, const int *col,
                              const double *value, rths_sparse_sym *a, rths_error *err);
void rths_sparse_free(rths_sparse_sym *a);
/* y = A x with the full symmetric A (both triangles). */
void rths_sparse_symv(const rths_sparse_sym *a, const double *x, double *y);
/* Entry (i, j) of the full symmetric matrix (0 when not stored); binary search. */
double rths_sparse_get(const rths_sparse_sym *a, int i, int j);
/* The dense column-major n x n matrix (both triangles), for small cases and tests. */
double *rths_sparse_to_dense(const rths_sparse_sym *a);

/* Fill-reducing orderings of the symbolic analysis (MUMPS ICNTL(7)). Debian's sequential MUMPS
 * is built with SCOTCH and PORD (no METIS). */
typedef enum {
    RTHS_SPARSE_ORDER_AUTO = 0, /* SCOTCH (nested dissection: least fill on FE meshes) */
    RTHS_SPARSE_ORDER_SCOTCH,
    RTHS_SPARSE_ORDER_PORD,
    RTHS_SPARSE_ORDER_AMD,
} rths_sparse_ordering;
const char *rths_sparse_ordering_name(rths_sparse_ordering ordering);

/* A factorisation of linear combinations of `count` symmetric terms of one order (K, M, C):
 * sum_k coef[k] * terms[k], on the union of their patterns. The symbolic analysis runs once per
 * arithmetic (at the first real, and the first complex, factorisation); every later factorisation
 * is numerical only. The terms are referenced, not copied: they must outlive the factor. */
typedef struct rths_sparse_factor rths_sparse_factor;
int rths_sparse_factor_create(int count, const rths_sparse_sym *const *terms,
                              rths_sparse_ordering ordering, rths_sparse_factor **out,
                              rths_error *err);
void rths_sparse_factor_destroy(rths_sparse_factor *f);
/* LDL^T of sum coef[k] terms[k] (real symmetric, indefinite allowed). RTHS_EFAIL names a
 * singular matrix. */
int rths_sparse_factor_real(rths_sparse_factor *f, const double *coef, rths_error *err);
/* Overwrites the n x nrhs column-major rhs with the solution of the last real factorisation. */
int rths_sparse_solve_real(rths_sparse_factor *f, double *rhs, int nrhs, rths_error *err);
/* LDL^T of the complex symmetric (not Hermitian) sum coef[k] terms[k]. */
int rths_sparse_factor_complex(rths_sparse_factor *f, const double complex *coef, rths_error *err);
int rths_sparse_solve_complex(rths_sparse_factor *f, double complex *rhs, int nrhs,
                              rths_error *err);
/* Negative pivots of the last real factorisation: by Sylvester's law of inertia, for K - s M with
 * M positive definite, the number of eigenvalues of K x = lambda M x below s. */
int rths_sparse_factor_negative_pivots(const rths_sparse_factor *f);
/* Seconds of the last analysis and numerical factorisation, the factor's entries (real), and
 * how many symbolic analyses and numerical factorisations ran (both arithmetics together). */
typedef struct {
    double analysis_s, factor_s;
    int analyses, factorisations;
    long factor_entries;
    rths_sparse_ordering ordering_used;
} rths_sparse_factor_stats;
rths_sparse_factor_stats rths_sparse_factor_get_stats(const rths_sparse_factor *f);

/* The lowest modes of K phi = lambda M phi (K symmetric, M symmetric positive definite) by
 * ARPACK's shift-invert Lanczos (dsaupd/dseupd mode 3) about `shift` over a MUMPS LDL^T of
 * K - shift M: the `count` lowest, or with lambda_max > 0 every mode with lambda < lambda_max
 * (their number from the inertia of K - lambda_max M; then count is the most accepted, an error
 * when more lie below the cut-off). */
typedef struct {
    int count;         /* modes wanted (or the most accepted with lambda_max) */
    double lambda_max; /* > 0: every eigenvalue below this instead, rad^2/s^2 */
    double shift;      /* sigma of the shift-invert: below the lowest eigenvalue wanted
                          (0 when K is nonsingular; negative for free-floating models) */
    double tolerance;  /* ARPACK's relative Ritz tolerance; 0: machine precision */
    rths_sparse_ordering ordering;
} rths_sparse_eigs_options;
rths_sparse_eigs_options rths_sparse_eigs_defaults(void);
/* What the eigensolver did: the last analysis and factorisation (of K - shift M), the Lanczos
 * iteration (solves included), how many times it applied (K - shift M)^-1 M. */
typedef struct {
    double analysis_s, factor_s, lanczos_s;
    long factor_entries;
    int operator_applications;
    rths_sparse_ordering ordering;
} rths_sparse_eigs_stats;
/* On success *found modes: lambda[found] ascending, phi n x found column-major (malloc'ed,
 * mass-normalised: phi^T M phi = I), *phi_out NULL when phi_out is NULL; stats (may be NULL)
 * filled. One call at a time per process: ARPACK's reverse communication keeps its state in
 * Fortran SAVE variables, so two threads must not run it together. */
int rths_sparse_eigs(const rths_sparse_sym *k, const rths_sparse_sym *m,
                     const rths_sparse_eigs_options *opt, double **lambda_out, double **phi_out,
                     int *found, rths_sparse_eigs_stats *stats, rths_error *err);
/* The same, handing out (when factor_out is not NULL and it succeeds) the factor it used: terms
 * (K, M), its last real factorisation K - shift M, so a caller can solve with K (shift 0) or
 * refactorise K - s M without a second symbolic analysis. Destroy it after use. */
int rths_sparse_eigs_keep(const rths_sparse_sym *k, const rths_sparse_sym *m,
                          const rths_sparse_eigs_options *opt, double **lambda_out,
                          double **phi_out, int *found, rths_sparse_eigs_stats *stats,
                          rths_sparse_factor **factor_out, rths_error *err);

#endif
