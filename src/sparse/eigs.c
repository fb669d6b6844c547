/* Lowest modes by shift-invert Lanczos (see sparse.h): ARPACK's dsaupd in mode 3 (generalised,
 * B = M) with OP = (K - sigma M)^-1 M through one MUMPS LDL^T; dseupd maps the Ritz values back
 * to lambda and returns M-orthonormal vectors. A frequency cut-off is turned into a count by the
 * inertia of K - lambda_max M (Sylvester: its negative pivots are the eigenvalues below). */
#include "rths/sparse.h"

#include <arpack.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

rths_sparse_eigs_options rths_sparse_eigs_defaults(void) {
    return (rths_sparse_eigs_options){.count = 20,
                                      .lambda_max = 0,
                                      .shift = 0,
                                      .tolerance = 0,
                                      .ordering = RTHS_SPARSE_ORDER_AUTO};
}

/* ARPACK's info codes worth a sentence; the rest are named by number. */
static int arpack_failed(const char *where, int info, rths_error *err) {
    if (info == 1)
        return rths_error_set(err, RTHS_EFAIL,
                              "sparse eigensolver (%s): ARPACK reached its iteration limit before "
                              "every wanted mode converged",
                              where);
    if (info == -9999 || info == 3)
        return rths_error_set(err, RTHS_EFAIL,
                              "sparse eigensolver (%s): ARPACK could not build a Lanczos "
                              "factorisation (info %d): too few Lanczos vectors for the modes "
                              "wanted",
                              where, info);
    return rths_error_set(err, RTHS_EFAIL, "sparse eigensolver (%s): ARPACK info %d", where, info);
}

/* Sorts the modes by lambda, ascending (few modes: insertion sort, moving columns). */
static void sort_modes(int n, int count, double *lambda, double *phi, double *tmp) {
    for (int a = 1; a < count; a++) {
        double key = lambda[a];
        if (phi) memcpy(tmp, phi + (size_t)a * n, (size_t)n * sizeof *tmp);
        int b = a - 1;
        while (b >= 0 && lambda[b] > key) {
            lambda[b + 1] = lambda[b];
            if (phi)
                memcpy(phi + (size_t)(b + 1) * n, phi + (size_t)b * n, (size_t)n * sizeof *phi);
            b--;
        }
        lambda[b + 1] = key;
        if (phi) memcpy(phi + (size_t)(b + 1) * n, tmp, (size_t)n * sizeof *tmp);
    }
}

int rths_sparse_eigs(const rths_sparse_sym *k, const rths_sparse_sym *m,
                     const rths_sparse_eigs_options *opt, double **lambda_out, double **phi_out,
                     int *found, rths_sparse_eigs_stats *stats, rths_error *err) {
    return rths_sparse_eigs_keep(k, m, opt, lambda_out, phi_out, found, stats, NULL, err);
}

int rths_sparse_eigs_keep(const rths_sparse_sym *k, const rths_sparse_sym *m,
                          const rths_sparse_eigs_options *opt, double **lambda_out,
                          double **phi_out, int *found, rths_sparse_eigs_stats *stats,
                          rths_sparse_factor **factor_out, rths_error *err) {
    if (factor_out) *factor_out = NULL;
    *lambda_out = NULL;
    if (stats) memset(stats, 0, sizeof *stats);
    if (phi_out) *phi_out = NULL;
    *found = 0;
    int n = k->n;
    if (m->n != n)
        return rths_error_set(err, RTHS_EINPUT, "sparse eigensolver: K is %d x %d but M is %d x %d",
                              n, n, m->n, m->n);
    if (opt->count < 1)
        return rths_error_set(err, RTHS_EINPUT, "sparse eigensolver: mode count %d is not >= 1",
                              opt->count);
    if (opt->lambda_max > 0 && !(opt->lambda_max > opt->shift))
        return rths_error_set(err, RTHS_EINPUT,
                              "sparse eigensolver: the cut-off %.17g rad^2/s^2 must lie above the "
                              "shift %.17g",
                              opt->lambda_max, opt->shift);
    const rths_sparse_sym *terms[2] = {k, m};
    rths_sparse_factor *f = NULL;
    int rc = rths_sparse_factor_create(2, terms, opt->ordering, &f, err);
    if (rc) return rc;
    int nev = opt->count;
    if (opt->lambda_max > 0) {
        double coef[2] = {1, -opt->lambda_max};
        rc = rths_sparse_factor_real(f, coef, err);
        if (rc) {
            rths_sparse_factor_destroy(f);
            return rc;
        }
        int below = rths_sparse_factor_negative_pivots(f);
        if (below > opt->count) {
            rths_sparse_factor_destroy(f);
            return rths_error_set(err, RTHS_EINPUT,
                                  "sparse eigensolver: %d modes lie below the cut-off %.6g Hz, "
                                  "more than the %d accepted",
                                  below, sqrt(opt->lambda_max) / (2 * M_PI), opt->count);
        }
        nev = below;
        if (nev == 0) {
            rths_sparse_factor_destroy(f);
            *lambda_out = malloc(sizeof **lambda_out);
            return *lambda_out
                       ? RTHS_OK
                       : rths_error_set(err, RTHS_EFAIL, "sparse eigensolver: out of memory");
        }
    }
    if (nev >= n) {
        rths_sparse_factor_destroy(f);
        return rths_error_set(err, RTHS_EINPUT,
                              "sparse eigensolver: %d modes wanted of a model of %d DoFs; Lanczos "
                              "needs fewer modes than DoFs (the dense solver suits this size)",
                              nev, n);
    }
    double coef[2] = {1, -opt->shift};
    rc = rths_sparse_factor_real(f, coef, err);
    if (rc) {
        rths_sparse_factor_destroy(f);
        return rc;
    }
    int ncv = 2 * nev + 1 > nev + 20 ? 2 * nev + 1 : nev + 20;
    if (ncv > n) ncv = n;
    int lworkl = ncv * (ncv + 8);
    double *resid = malloc((size_t)n * sizeof *resid);
    double *v = malloc((size_t)n * ncv * sizeof *v);
    double *workd = malloc(3 * (size_t)n * sizeof *workd);
    double *workl = malloc((size_t)lworkl * sizeof *workl);
    int *select = calloc((size_t)ncv, sizeof *select);
    double *d = malloc((size_t)nev * sizeof *d);
    double *z = malloc((size_t)n * nev * sizeof *z);
    double *tmp = malloc((size_t)n * sizeof *tmp);
    if (!resid || !v || !workd || !workl || !select || !d || !z || !tmp) {
        rc = rths_error_set(err, RTHS_EFAIL,
                            "sparse eigensolver: out of memory (n = %d, %d "
                            "Lanczos vectors)",
                            n, ncv);
        goto done;
    }
    /* a fixed start vector: the same modes (and signs) on every run */
    for (int i = 0; i < n; i++)
        resid[i] = 1.0 + 0.5 * sin(0.7 * i + 0.3);
    int iparam[11] = {0}, ipntr[14] = {0}, ido = 0, info = 1;
    iparam[0] = 1;    /* exact shifts */
    iparam[2] = 1000; /* restarts */
    iparam[6] = 3;    /* shift-invert, generalised */
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int applications = 0;
    for (;;) {
        dsaupd_c(&ido, "G", n, "LM", nev, opt->tolerance, resid, ncv, v, n, iparam, ipntr, workd,
                 workl, lworkl, &info);
        double *x = workd + ipntr[0] - 1, *y = workd + ipntr[1] - 1;
        if (ido == -1) { /* y = (K - sigma M)^-1 M x */
            applications++;
            rths_sparse_symv(m, x, y);
            if ((rc = rths_sparse_solve_real(f, y, 1, err))) goto done;
        } else if (ido == 1) { /* M x is already at ipntr[2] */
            applications++;
            memcpy(y, workd + ipntr[2] - 1, (size_t)n * sizeof *y);
            if ((rc = rths_sparse_solve_real(f, y, 1, err))) goto done;
        } else if (ido == 2) {
            rths_sparse_symv(m, x, y);
        } else
            break;
    }
    if (info < 0 || info == 1 || info == 3) {
        rc = arpack_failed("dsaupd", info, err);
        goto done;
    }
    dseupd_c(1, "A", select, d, z, n, opt->shift, "G", n, "LM", nev, opt->tolerance, resid, ncv, v,
             n, iparam, ipntr, workd, workl, lworkl, &info);
    if (info != 0) {
        rc = arpack_failed("dseupd", info, err);
        goto done;
    }
    if (stats) {
        struct timespec t1;
        clock_gettime(CLOCK_MONOTONIC, &t1);
        rths_sparse_factor_stats fs = rths_sparse_factor_get_stats(f);
        stats->analysis_s = fs.analysis_s;
        stats->factor_s = fs.factor_s;
        stats->factor_entries = fs.factor_entries;
        stats->ordering = fs.ordering_used;
        stats->operator_applications = applications;
        stats->lanczos_s =
            (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    }
    int converged = iparam[4];
    if (converged < nev) {
        rc = rths_error_set(err, RTHS_EFAIL,
                            "sparse eigensolver: %d of the %d modes wanted converged", converged,
                            nev);
        goto done;
    }
    /* mass-normalise exactly and fix each sign (largest component positive) */
    for (int c = 0; c < nev; c++) {
        double *phi = z + (size_t)c * n, mm = 0, big = 0;
        rths_sparse_symv(m, phi, tmp);
        for (int i = 0; i < n; i++) {
            mm += phi[i] * tmp[i];
            if (fabs(phi[i]) > fabs(big)) big = phi[i];
        }
        double scale = (big < 0 ? -1 : 1) / sqrt(mm);
        for (int i = 0; i < n; i++)
            phi[i] *= scale;
    }
    sort_modes(n, nev, d, z, tmp);
    *lambda_out = d;
    d = NULL;
    if (phi_out) {
        *phi_out = z;
        z = NULL;
    }
    *found = nev;
    if (factor_out) {
        *factor_out = f;
        f = NULL;
    }
done:
    free(resid);
    free(v);
    free(workd);
    free(workl);
    free(select);
    free(d);
    free(z);
    free(tmp);
    rths_sparse_factor_destroy(f);
    return rc;
}
