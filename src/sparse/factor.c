/* MUMPS wrapper (see sparse.h): linear combinations of symmetric terms on the union of their
 * patterns; one MUMPS instance per arithmetic (dmumps for real LDL^T, zmumps for complex
 * symmetric), each analysed once (the fill-reducing ordering and symbolic factorisation depend on
 * the pattern only) and refactorised numerically per shift or frequency. Debian's sequential
 * MUMPS needs no MPI_Init: its libmpiseq stands in for MPI. */
#include "rths/sparse.h"

#include <dmumps_c.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zmumps_c.h>

#define MUMPS_JOB_INIT -1
#define MUMPS_JOB_END -2
#define MUMPS_USE_COMM_WORLD -987654
/* MUMPS's 1-based parameter arrays, as its manual numbers them */
#define ICNTL(id, k) ((id).icntl[(k)-1])
#define INFOG(id, k) ((id).infog[(k)-1])

struct rths_sparse_factor {
    int n, count;
    /* the caller's term pointers, copied (the terms themselves are referenced): a factor may
     * outlive the array it was created from (rths_sparse_eigs_keep hands its factor out) */
    const rths_sparse_sym **terms;
    rths_sparse_ordering ordering;
    long nnz;       /* union pattern, lower triangle */
    int *irn, *jcn; /* 1-based */
    long **where;   /* where[k][e]: position of terms[k]'s entry e in the union */
    double *a_real;
    ZMUMPS_COMPLEX *a_complex;
    DMUMPS_STRUC_C dm;
    ZMUMPS_STRUC_C zm;
    int dm_init, zm_init, dm_analysed, zm_analysed, dm_factored, zm_factored;
    rths_sparse_factor_stats stats;
};

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

const char *rths_sparse_ordering_name(rths_sparse_ordering ordering) {
    switch (ordering) {
    case RTHS_SPARSE_ORDER_AUTO:
    case RTHS_SPARSE_ORDER_SCOTCH:
        return "SCOTCH";
    case RTHS_SPARSE_ORDER_PORD:
        return "PORD";
    case RTHS_SPARSE_ORDER_AMD:
        return "AMD";
    }
    return "?";
}

/* The ordering MUMPS reports it used (INFOG(7)): it may fall back when one is not built in. */
static rths_sparse_ordering ordering_from_infog7(int infog7, rths_sparse_ordering asked) {
    switch (infog7) {
    case 0:
        return RTHS_SPARSE_ORDER_AMD;
    case 3:
        return RTHS_SPARSE_ORDER_SCOTCH;
    case 4:
        return RTHS_SPARSE_ORDER_PORD;
    default:
        return asked;
    }
}

static int icntl7(rths_sparse_ordering ordering) {
    switch (ordering) {
    case RTHS_SPARSE_ORDER_PORD:
        return 4;
    case RTHS_SPARSE_ORDER_AMD:
        return 0;
    default:
        return 3; /* SCOTCH */
    }
}

/* Position of row i in column j of the union pattern (present by construction). */
static long find_entry(const rths_sparse_sym *u, int i, int j) {
    int lo = u->colptr[j], hi = u->colptr[j + 1] - 1;
    while (lo <= hi) {
        int mid = (lo + hi) / 2;
        if (u->rowidx[mid] == i) return mid;
        if (u->rowidx[mid] < i)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

int rths_sparse_factor_create(int count, const rths_sparse_sym *const *terms,
                              rths_sparse_ordering ordering, rths_sparse_factor **out,
                              rths_error *err) {
    *out = NULL;
    if (count < 1) return rths_error_set(err, RTHS_EINPUT, "sparse factor: no terms");
    int n = terms[0]->n;
    long total = 0;
    for (int k = 0; k < count; k++) {
        if (terms[k]->n != n)
            return rths_error_set(err, RTHS_EINPUT,
                                  "sparse factor: term %d is of order %d, term 0 of order %d", k,
                                  terms[k]->n, n);
        total += terms[k]->colptr[n];
    }
    rths_sparse_factor *f = calloc(1, sizeof *f);
    if (!f) return rths_error_set(err, RTHS_EFAIL, "sparse factor: out of memory");
    f->n = n;
    f->count = count;
    f->terms = malloc((size_t)count * sizeof *f->terms);
    if (!f->terms) {
        free(f);
        return rths_error_set(err, RTHS_EFAIL, "sparse factor: out of memory");
    }
    for (int k = 0; k < count; k++)
        f->terms[k] = terms[k];
    f->ordering = ordering;
    f->stats.ordering_used =
        ordering == RTHS_SPARSE_ORDER_AUTO ? RTHS_SPARSE_ORDER_SCOTCH : ordering;
    /* the union pattern: every term's entries as zero-valued triplets */
    int *ti = malloc((size_t)(total ? total : 1) * sizeof *ti);
    int *tj = malloc((size_t)(total ? total : 1) * sizeof *tj);
    double *tv = calloc((size_t)(total ? total : 1), sizeof *tv);
    rths_sparse_sym u = {0};
    int rc = RTHS_OK;
    if (!ti || !tj || !tv)
        rc = rths_error_set(err, RTHS_EFAIL, "sparse factor: out of memory");
    else {
        long at = 0;
        for (int k = 0; k < count; k++)
            for (int j = 0; j < n; j++)
                for (int e = terms[k]->colptr[j]; e < terms[k]->colptr[j + 1]; e++) {
                    ti[at] = terms[k]->rowidx[e];
                    tj[at] = j;
                    at++;
                }
        rc = rths_sparse_from_triplets(n, total, ti, tj, tv, &u, err);
    }
    free(ti);
    free(tj);
    free(tv);
    if (!rc) {
        f->nnz = u.colptr[n];
        f->irn = malloc((size_t)(f->nnz ? f->nnz : 1) * sizeof *f->irn);
        f->jcn = malloc((size_t)(f->nnz ? f->nnz : 1) * sizeof *f->jcn);
        f->where = calloc((size_t)count, sizeof *f->where);
        if (!f->irn || !f->jcn || !f->where)
            rc = rths_error_set(err, RTHS_EFAIL, "sparse factor: out of memory");
    }
    if (!rc) {
        for (int j = 0; j < n; j++)
            for (int e = u.colptr[j]; e < u.colptr[j + 1]; e++) {
                f->irn[e] = u.rowidx[e] + 1;
                f->jcn[e] = j + 1;
            }
        for (int k = 0; k < count && !rc; k++) {
            long nk = terms[k]->colptr[n];
            f->where[k] = malloc((size_t)(nk ? nk : 1) * sizeof **f->where);
            if (!f->where[k]) {
                rc = rths_error_set(err, RTHS_EFAIL, "sparse factor: out of memory");
                break;
            }
            for (int j = 0; j < n; j++)
                for (int e = terms[k]->colptr[j]; e < terms[k]->colptr[j + 1]; e++)
                    f->where[k][e] = find_entry(&u, terms[k]->rowidx[e], j);
        }
    }
    rths_sparse_free(&u);
    if (rc) {
        rths_sparse_factor_destroy(f);
        return rc;
    }
    *out = f;
    return RTHS_OK;
}

void rths_sparse_factor_destroy(rths_sparse_factor *f) {
    if (!f) return;
    if (f->dm_init) {
        f->dm.job = MUMPS_JOB_END;
        dmumps_c(&f->dm);
    }
    if (f->zm_init) {
        f->zm.job = MUMPS_JOB_END;
        zmumps_c(&f->zm);
    }
    if (f->where)
        for (int k = 0; k < f->count; k++)
            free(f->where[k]);
    free(f->where);
    free(f->terms);
    free(f->irn);
    free(f->jcn);
    free(f->a_real);
    free(f->a_complex);
    free(f);
}

/* Silence MUMPS (it prints to stdout by default), choose the ordering, give the numerical phase
 * more workspace than the analysis estimates (pivoting in LDL^T of an indefinite shift), and have
 * it count null pivots: without ICNTL(24) an exactly singular K (a free-floating model at shift 0)
 * factorises "successfully" and the solves return garbage. The threshold (CNTL(3) = 0) is
 * 1e-5 eps ||A||: a shift close to an eigenvalue, which shift-invert needs to work, passes. */
#define CONFIGURE(id, f)                                                                           \
    do {                                                                                           \
        ICNTL(id, 1) = -1;                                                                         \
        ICNTL(id, 2) = -1;                                                                         \
        ICNTL(id, 3) = -1;                                                                         \
        ICNTL(id, 4) = 0;                                                                          \
        ICNTL(id, 7) = icntl7((f)->ordering);                                                      \
        ICNTL(id, 14) = 50;                                                                        \
        ICNTL(id, 24) = 1; /* count null pivots (INFOG(28)), do not divide by them */              \
        (id).n = (f)->n;                                                                           \
        (id).nnz = (f)->nnz;                                                                       \
        (id).irn = (f)->irn;                                                                       \
        (id).jcn = (f)->jcn;                                                                       \
    } while (0)

static int mumps_failed(const char *what, int infog1, int infog2, rths_error *err) {
    if (infog1 == -10)
        return rths_error_set(err, RTHS_EFAIL,
                              "sparse %s: the matrix is numerically singular (MUMPS INFOG(1) = "
                              "-10): a shift equal to an eigenvalue, or a free-floating model "
                              "factorised without a shift",
                              what);
    return rths_error_set(err, RTHS_EFAIL, "sparse %s: MUMPS error INFOG(1) = %d, INFOG(2) = %d",
                          what, infog1, infog2);
}

int rths_sparse_factor_real(rths_sparse_factor *f, const double *coef, rths_error *err) {
    if (!f->a_real) {
        f->a_real = malloc((size_t)(f->nnz ? f->nnz : 1) * sizeof *f->a_real);
        if (!f->a_real) return rths_error_set(err, RTHS_EFAIL, "sparse factor: out of memory");
    }
    memset(f->a_real, 0, (size_t)f->nnz * sizeof *f->a_real);
    for (int k = 0; k < f->count; k++) {
        const rths_sparse_sym *t = f->terms[k];
        if (coef[k] == 0) continue;
        for (int e = 0; e < t->colptr[f->n]; e++)
            f->a_real[f->where[k][e]] += coef[k] * t->value[e];
    }
    if (!f->dm_init) {
        memset(&f->dm, 0, sizeof f->dm);
        f->dm.comm_fortran = MUMPS_USE_COMM_WORLD;
        f->dm.par = 1;
        f->dm.sym = 2; /* general symmetric: LDL^T with pivoting, indefinite allowed */
        f->dm.job = MUMPS_JOB_INIT;
        dmumps_c(&f->dm);
        if (INFOG(f->dm, 1) < 0)
            return mumps_failed("initialisation", INFOG(f->dm, 1), INFOG(f->dm, 2), err);
        f->dm_init = 1;
    }
    CONFIGURE(f->dm, f);
    f->dm.a = f->a_real;
    if (!f->dm_analysed) {
        double t0 = now_s();
        f->dm.job = 1;
        dmumps_c(&f->dm);
        f->stats.analyses++;
        f->stats.analysis_s = now_s() - t0;
        if (INFOG(f->dm, 1) < 0)
            return mumps_failed("analysis", INFOG(f->dm, 1), INFOG(f->dm, 2), err);
        f->dm_analysed = 1;
        f->stats.ordering_used = ordering_from_infog7(INFOG(f->dm, 7), f->ordering);
    }
    double t0 = now_s();
    f->dm_factored = 0;
    f->dm.job = 2;
    dmumps_c(&f->dm);
    f->stats.factorisations++;
    f->stats.factor_s = now_s() - t0;
    if (INFOG(f->dm, 1) < 0)
        return mumps_failed("factorisation", INFOG(f->dm, 1), INFOG(f->dm, 2), err);
    if (INFOG(f->dm, 28) > 0)
        return rths_error_set(err, RTHS_EFAIL,
                              "sparse factorisation: the matrix is numerically singular (%d null "
                              "pivots of %d): a shift equal to an eigenvalue, or a free-floating "
                              "model factorised without a shift",
                              INFOG(f->dm, 28), f->n);
    /* INFOG(29): entries in the factors (negative: millions) */
    long fe = INFOG(f->dm, 29);
    f->stats.factor_entries = fe < 0 ? -fe * 1000000L : fe;
    f->dm_factored = 1;
    return RTHS_OK;
}

int rths_sparse_solve_real(rths_sparse_factor *f, double *rhs, int nrhs, rths_error *err) {
    if (!f->dm_factored) return rths_error_set(err, RTHS_EFAIL, "sparse solve: not factorised");
    f->dm.rhs = rhs;
    f->dm.nrhs = nrhs;
    f->dm.lrhs = f->n;
    f->dm.job = 3;
    dmumps_c(&f->dm);
    if (INFOG(f->dm, 1) < 0) return mumps_failed("solve", INFOG(f->dm, 1), INFOG(f->dm, 2), err);
    return RTHS_OK;
}

int rths_sparse_factor_negative_pivots(const rths_sparse_factor *f) {
    return f->dm_factored ? INFOG(f->dm, 12) : -1;
}

int rths_sparse_factor_complex(rths_sparse_factor *f, const double complex *coef, rths_error *err) {
    if (!f->a_complex) {
        f->a_complex = malloc((size_t)(f->nnz ? f->nnz : 1) * sizeof *f->a_complex);
        if (!f->a_complex) return rths_error_set(err, RTHS_EFAIL, "sparse factor: out of memory");
    }
    memset(f->a_complex, 0, (size_t)f->nnz * sizeof *f->a_complex);
    for (int k = 0; k < f->count; k++) {
        const rths_sparse_sym *t = f->terms[k];
        double cr = creal(coef[k]), ci = cimag(coef[k]);
        if (cr == 0 && ci == 0) continue;
        for (int e = 0; e < t->colptr[f->n]; e++) {
            ZMUMPS_COMPLEX *a = &f->a_complex[f->where[k][e]];
            a->r += cr * t->value[e];
            a->i += ci * t->value[e];
        }
    }
    if (!f->zm_init) {
        memset(&f->zm, 0, sizeof f->zm);
        f->zm.comm_fortran = MUMPS_USE_COMM_WORLD;
        f->zm.par = 1;
        f->zm.sym = 2; /* complex symmetric (A = A^T, not Hermitian) */
        f->zm.job = MUMPS_JOB_INIT;
        zmumps_c(&f->zm);
        if (INFOG(f->zm, 1) < 0)
            return mumps_failed("initialisation", INFOG(f->zm, 1), INFOG(f->zm, 2), err);
        f->zm_init = 1;
    }
    CONFIGURE(f->zm, f);
    f->zm.a = f->a_complex;
    if (!f->zm_analysed) {
        double t0 = now_s();
        f->zm.job = 1;
        zmumps_c(&f->zm);
        f->stats.analyses++;
        f->stats.analysis_s = now_s() - t0;
        if (INFOG(f->zm, 1) < 0)
            return mumps_failed("analysis", INFOG(f->zm, 1), INFOG(f->zm, 2), err);
        f->zm_analysed = 1;
    }
    double t0 = now_s();
    f->zm_factored = 0;
    f->zm.job = 2;
    zmumps_c(&f->zm);
    f->stats.factorisations++;
    f->stats.factor_s = now_s() - t0;
    if (INFOG(f->zm, 1) < 0)
        return mumps_failed("factorisation", INFOG(f->zm, 1), INFOG(f->zm, 2), err);
    if (INFOG(f->zm, 28) > 0)
        return rths_error_set(err, RTHS_EFAIL,
                              "sparse factorisation: the matrix is numerically singular (%d null "
                              "pivots of %d): a shift equal to an eigenvalue, or a free-floating "
                              "model factorised without a shift",
                              INFOG(f->zm, 28), f->n);
    f->zm_factored = 1;
    return RTHS_OK;
}

int rths_sparse_solve_complex(rths_sparse_factor *f, double complex *rhs, int nrhs,
                              rths_error *err) {
    if (!f->zm_factored) return rths_error_set(err, RTHS_EFAIL, "sparse solve: not factorised");
    size_t len = (size_t)f->n * (size_t)nrhs;
    ZMUMPS_COMPLEX *b = malloc(len * sizeof *b);
    if (!b) return rths_error_set(err, RTHS_EFAIL, "sparse solve: out of memory");
    for (size_t q = 0; q < len; q++) {
        b[q].r = creal(rhs[q]);
        b[q].i = cimag(rhs[q]);
    }
    f->zm.rhs = b;
    f->zm.nrhs = nrhs;
    f->zm.lrhs = f->n;
    f->zm.job = 3;
    zmumps_c(&f->zm);
    int rc = RTHS_OK;
    if (INFOG(f->zm, 1) < 0)
        rc = mumps_failed("solve", INFOG(f->zm, 1), INFOG(f->zm, 2), err);
    else
        for (size_t q = 0; q < len; q++)
            rhs[q] = b[q].r + I * b[q].i;
    free(b);
    f->zm.rhs = NULL;
    return rc;
}

rths_sparse_factor_stats rths_sparse_factor_get_stats(const rths_sparse_factor *f) {
    return f->stats;
}
