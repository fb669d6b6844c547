/* True assembly, substructure split, modal analysis and analytic FRF. */
#include "rths/model.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static int all_finite(const double *a, size_t count) {
    for (size_t i = 0; i < count; i++)
        if (!isfinite(a[i])) return 0;
    return 1;
}

static int assembly_alloc(int n, rths_assembly *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    out->n = n;
    out->mass = rths_mat_new(n, n);
    out->damping = rths_mat_new(n, n);
    out->stiffness = rths_mat_new(n, n);
    if (!out->mass || !out->damping || !out->stiffness) {
        rths_assembly_free(out);
        return rths_error_set(err, RTHS_EFAIL, "out of memory building a %d-DoF assembly", n);
    }
    return RTHS_OK;
}

void rths_assembly_free(rths_assembly *a) {
    if (!a) return;
    rths_mat_free(a->mass);
    rths_mat_free(a->damping);
    rths_mat_free(a->stiffness);
    memset(a, 0, sizeof *a);
}

int rths_assembly_from_chain(int n, const double *masses, const double *dampings,
                             const double *stiffnesses, rths_assembly *out, rths_error *err) {
    if (n < 1) return rths_error_set(err, RTHS_EINPUT, "a storey chain needs at least one storey");
    for (int i = 0; i < n; i++) {
        if (!(isfinite(masses[i]) && masses[i] > 0))
            return rths_error_set(err, RTHS_EINPUT, "storey %d: mass must be positive, got %g kg",
                                  i + 1, masses[i]);
        if (!(isfinite(dampings[i]) && dampings[i] >= 0))
            return rths_error_set(err, RTHS_EINPUT,
                                  "storey %d: leg damping must be >= 0, got %g N s/m", i + 1,
                                  dampings[i]);
        if (!(isfinite(stiffnesses[i]) && stiffnesses[i] > 0))
            return rths_error_set(err, RTHS_EINPUT,
                                  "storey %d: leg stiffness must be positive, got %g N/m", i + 1,
                                  stiffnesses[i]);
    }
    int rc = assembly_alloc(n, out, err);
    if (rc) return rc;
    for (int i = 0; i < n; i++) {
        RTHS_AT(out->mass, n, i, i) = masses[i];
        /* leg i joins storey i-1 (or the ground) to storey i */
        RTHS_AT(out->damping, n, i, i) += dampings[i];
        RTHS_AT(out->stiffness, n, i, i) += stiffnesses[i];
        if (i > 0) {
            RTHS_AT(out->damping, n, i - 1, i - 1) += dampings[i];
            RTHS_AT(out->damping, n, i - 1, i) -= dampings[i];
            RTHS_AT(out->damping, n, i, i - 1) -= dampings[i];
            RTHS_AT(out->stiffness, n, i - 1, i - 1) += stiffnesses[i];
            RTHS_AT(out->stiffness, n, i - 1, i) -= stiffnesses[i];
            RTHS_AT(out->stiffness, n, i, i - 1) -= stiffnesses[i];
        }
    }
    return RTHS_OK;
}

int rths_assembly_from_matrices(int n, const double *mass, const double *damping,
                                const double *stiffness, rths_assembly *out, rths_error *err) {
    if (n < 1) return rths_error_set(err, RTHS_EINPUT, "an assembly needs at least one DoF");
    const double *mats[3] = {mass, damping, stiffness};
    const char *names[3] = {"mass", "damping", "stiffness"};
    for (int m = 0; m < 3; m++) {
        if (!all_finite(mats[m], (size_t)n * (size_t)n))
            return rths_error_set(err, RTHS_EINPUT, "%s matrix has a non-finite entry", names[m]);
        if (!rths_mat_is_symmetric(mats[m], n, 1e-12))
            return rths_error_set(err, RTHS_EINPUT, "%s matrix is not symmetric", names[m]);
    }
    if (!rths_mat_is_spd(mass, n))
        return rths_error_set(err, RTHS_EINPUT, "mass matrix is not positive definite");
    int rc = assembly_alloc(n, out, err);
    if (rc) return rc;
    size_t bytes = (size_t)n * (size_t)n * sizeof(double);
    memcpy(out->mass, mass, bytes);
    memcpy(out->damping, damping, bytes);
    memcpy(out->stiffness, stiffness, bytes);
    return RTHS_OK;
}

/* ---- split ---- */

void rths_split_free(rths_split *s) {
    if (!s) return;
    free(s->phys_dofs);
    free(s->int_dofs);
    free(s->num_dofs);
    free(s->mass_ratios);
    rths_mat_free(s->mass_phys);
    rths_mat_free(s->damping_phys);
    rths_mat_free(s->stiffness_phys);
    rths_mat_free(s->mass_num);
    rths_mat_free(s->damping_num);
    rths_mat_free(s->stiffness_num);
    memset(s, 0, sizeof *s);
}

/* Numerical share of the interface block of a (damping or stiffness): the elements joining each
 * interface DoF to internal numerical DoFs; the ground, physical and interface-interface couplings
 * stay physical, which for a storey chain is exactly "leg below the interface is physical". */
static void coupling_rule_num_share(const rths_split *s, const double *a, double *num_block) {
    int n = s->n, ni = s->n_int;
    memset(num_block, 0, (size_t)ni * (size_t)ni * sizeof(double));
    for (int i = 0; i < ni; i++) {
        double sum = 0.0;
        for (int j = 0; j < s->n_num; j++)
            sum += RTHS_AT(a, n, s->int_dofs[i], s->num_dofs[j]);
        RTHS_AT(num_block, ni, i, i) = -sum;
    }
}

static void fill_substructure(const rths_split *s, const double *a, const double *int_phys,
                              const double *int_num, double *phys, double *num) {
    int n = s->n, np = s->np, nn = s->nn, ni = s->n_int;
    /* physical ordering (phys..., int...), numerical ordering (int..., num...) */
    for (int i = 0; i < s->n_phys; i++) {
        for (int j = 0; j < s->n_phys; j++)
            RTHS_AT(phys, np, i, j) = RTHS_AT(a, n, s->phys_dofs[i], s->phys_dofs[j]);
        for (int j = 0; j < ni; j++) {
            RTHS_AT(phys, np, i, s->n_phys + j) = RTHS_AT(a, n, s->phys_dofs[i], s->int_dofs[j]);
            RTHS_AT(phys, np, s->n_phys + j, i) = RTHS_AT(a, n, s->int_dofs[j], s->phys_dofs[i]);
        }
    }
    for (int i = 0; i < ni; i++)
        for (int j = 0; j < ni; j++) {
            RTHS_AT(phys, np, s->n_phys + i, s->n_phys + j) = RTHS_AT(int_phys, ni, i, j);
            RTHS_AT(num, nn, i, j) = RTHS_AT(int_num, ni, i, j);
        }
    for (int i = 0; i < s->n_num; i++) {
        for (int j = 0; j < s->n_num; j++)
            RTHS_AT(num, nn, ni + i, ni + j) = RTHS_AT(a, n, s->num_dofs[i], s->num_dofs[j]);
        for (int j = 0; j < ni; j++) {
            RTHS_AT(num, nn, ni + i, j) = RTHS_AT(a, n, s->num_dofs[i], s->int_dofs[j]);
            RTHS_AT(num, nn, j, ni + i) = RTHS_AT(a, n, s->int_dofs[j], s->num_dofs[i]);
        }
    }
}

int rths_split_create(const rths_assembly *a, const rths_dof_role *role, double mass_ratio,
                      const double *damping_int_phys, const double *stiffness_int_phys,
                      rths_split *out, rths_error *err) {
    return rths_split_create_ratios(a, role, 1, &mass_ratio, damping_int_phys, stiffness_int_phys,
                                    out, err);
}

int rths_split_create_ratios(const rths_assembly *a, const rths_dof_role *role, int n_ratios,
                             const double *mass_ratios, const double *damping_int_phys,
                             const double *stiffness_int_phys, rths_split *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    int n = a->n;
    for (int r = 0; r < n_ratios; r++)
        if (!(isfinite(mass_ratios[r]) && mass_ratios[r] > 0.0 && mass_ratios[r] < 1.0))
            return rths_error_set(err, RTHS_EINPUT,
                                  "mass ratio p must lie in the open interval (0, 1), got %g",
                                  mass_ratios[r]);
    if (n_ratios < 1) return rths_error_set(err, RTHS_EINPUT, "no mass ratio given");
    out->n = n;
    out->mass_ratio = mass_ratios[0];
    out->phys_dofs = calloc((size_t)n, sizeof(int));
    out->int_dofs = calloc((size_t)n, sizeof(int));
    out->num_dofs = calloc((size_t)n, sizeof(int));
    if (!out->phys_dofs || !out->int_dofs || !out->num_dofs) goto oom;
    for (int i = 0; i < n; i++) {
        switch (role[i]) {
        case RTHS_DOF_PHYSICAL:
            out->phys_dofs[out->n_phys++] = i;
            break;
        case RTHS_DOF_INTERFACE:
            out->int_dofs[out->n_int++] = i;
            break;
        case RTHS_DOF_NUMERICAL:
            out->num_dofs[out->n_num++] = i;
            break;
        default:
            rths_split_free(out);
            return rths_error_set(err, RTHS_EINPUT, "DoF %d has no valid role", i + 1);
        }
    }
    if (out->n_int == 0) {
        rths_split_free(out);
        return rths_error_set(err, RTHS_EINPUT, "the split needs at least one interface DoF");
    }
    if (n_ratios != 1 && n_ratios != out->n_int) {
        int ni = out->n_int;
        rths_split_free(out);
        return rths_error_set(err, RTHS_EINPUT,
                              "%d mass ratios for %d interface DoFs: give one p, or one per "
                              "interface DoF",
                              n_ratios, ni);
    }
    out->mass_ratios = malloc(sizeof(double) * (size_t)out->n_int);
    if (!out->mass_ratios) goto oom;
    for (int d = 0; d < out->n_int; d++)
        out->mass_ratios[d] = mass_ratios[n_ratios == 1 ? 0 : d];
    /* Separability: internal physical and internal numerical DoFs may meet only through the
     * interface, otherwise no force exchange at the interface can represent the assembly. */
    const double *mats[3] = {a->mass, a->damping, a->stiffness};
    const char *names[3] = {"mass", "damping", "stiffness"};
    for (int m = 0; m < 3; m++)
        for (int i = 0; i < out->n_phys; i++)
            for (int j = 0; j < out->n_num; j++)
                if (RTHS_AT(mats[m], n, out->phys_dofs[i], out->num_dofs[j]) != 0.0) {
                    int pi = out->phys_dofs[i] + 1, nj = out->num_dofs[j] + 1;
                    rths_split_free(out);
                    return rths_error_set(err, RTHS_EINPUT,
                                          "%s couples physical DoF %d directly to numerical DoF "
                                          "%d: substructures must meet only at the interface",
                                          names[m], pi, nj);
                }
    out->np = out->n_phys + out->n_int;
    out->nn = out->n_int + out->n_num;
    int ni = out->n_int;
    out->mass_phys = rths_mat_new(out->np, out->np);
    out->damping_phys = rths_mat_new(out->np, out->np);
    out->stiffness_phys = rths_mat_new(out->np, out->np);
    out->mass_num = rths_mat_new(out->nn, out->nn);
    out->damping_num = rths_mat_new(out->nn, out->nn);
    out->stiffness_num = rths_mat_new(out->nn, out->nn);
    double *blk = rths_mat_new(4 * ni, ni);
    if (!out->mass_phys || !out->damping_phys || !out->stiffness_phys || !out->mass_num ||
        !out->damping_num || !out->stiffness_num || !blk) {
        rths_mat_free(blk);
        goto oom;
    }
    double *full = blk, *phys = blk + ni * ni, *num = blk + 2 * ni * ni;
    const double *explicit_phys[3] = {NULL, damping_int_phys, stiffness_int_phys};
    double *outs_phys[3] = {out->mass_phys, out->damping_phys, out->stiffness_phys};
    double *outs_num[3] = {out->mass_num, out->damping_num, out->stiffness_num};
    for (int m = 0; m < 3; m++) {
        for (int i = 0; i < ni; i++)
            for (int j = 0; j < ni; j++)
                RTHS_AT(full, ni, i, j) = RTHS_AT(mats[m], n, out->int_dofs[i], out->int_dofs[j]);
        if (m == 0) {
            for (int i = 0; i < ni; i++)
                for (int j = 0; j < ni; j++) {
                    double pi = out->mass_ratios[i], pj = out->mass_ratios[j];
                    double pij = pi == pj ? pi : sqrt(pi * pj);
                    RTHS_AT(num, ni, i, j) = pij * RTHS_AT(full, ni, i, j);
                    RTHS_AT(phys, ni, i, j) = RTHS_AT(full, ni, i, j) - RTHS_AT(num, ni, i, j);
                }
        } else if (explicit_phys[m]) {
            for (int k = 0; k < ni * ni; k++) {
                phys[k] = explicit_phys[m][k];
                num[k] = full[k] - phys[k];
            }
        } else {
            coupling_rule_num_share(out, mats[m], num);
            for (int k = 0; k < ni * ni; k++)
                phys[k] = full[k] - num[k];
        }
        fill_substructure(out, mats[m], phys, num, outs_phys[m], outs_num[m]);
    }
    rths_mat_free(blk);
    return RTHS_OK;
oom:
    rths_split_free(out);
    return rths_error_set(err, RTHS_EFAIL, "out of memory splitting the assembly");
}

void rths_split_recombine(const rths_split *s, double *mass, double *damping, double *stiffness) {
    int n = s->n, np = s->np, nn = s->nn;
    double *outs[3] = {mass, damping, stiffness};
    const double *phys[3] = {s->mass_phys, s->damping_phys, s->stiffness_phys};
    const double *num[3] = {s->mass_num, s->damping_num, s->stiffness_num};
    for (int m = 0; m < 3; m++) {
        memset(outs[m], 0, (size_t)n * (size_t)n * sizeof(double));
        for (int i = 0; i < np; i++) {
            int gi = i < s->n_phys ? s->phys_dofs[i] : s->int_dofs[i - s->n_phys];
            for (int j = 0; j < np; j++) {
                int gj = j < s->n_phys ? s->phys_dofs[j] : s->int_dofs[j - s->n_phys];
                RTHS_AT(outs[m], n, gi, gj) += RTHS_AT(phys[m], np, i, j);
            }
        }
        for (int i = 0; i < nn; i++) {
            int gi = i < s->n_int ? s->int_dofs[i] : s->num_dofs[i - s->n_int];
            for (int j = 0; j < nn; j++) {
                int gj = j < s->n_int ? s->int_dofs[j] : s->num_dofs[j - s->n_int];
                RTHS_AT(outs[m], n, gi, gj) += RTHS_AT(num[m], nn, i, j);
            }
        }
    }
}

/* ---- modal analysis ---- */

void rths_modes_free(rths_modes *m) {
    if (!m) return;
    free(m->omega_rad_s);
    free(m->frequency_hz);
    free(m->damping_ratio);
    rths_mat_free(m->shapes);
    memset(m, 0, sizeof *m);
}

int rths_assembly_half_bandwidth(const rths_assembly *a) {
    int n = a->n, b = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++)
            if (abs(i - j) > b &&
                (RTHS_AT(a->mass, n, i, j) != 0 || RTHS_AT(a->damping, n, i, j) != 0 ||
                 RTHS_AT(a->stiffness, n, i, j) != 0))
                b = abs(i - j);
    return b;
}

/* diag(Phi^T A Phi) for A with half-bandwidth b: O(n^2 b) for a banded A instead of a full
 * matrix product. */
static void modal_diagonal(int n, int b, const double *a, const double *shapes, double *out) {
    for (int r = 0; r < n; r++) {
        const double *phi = shapes + (size_t)r * (size_t)n;
        double acc = 0.0;
        for (int i = 0; i < n; i++) {
            double row = 0.0;
            int lo = i - b < 0 ? 0 : i - b, hi = i + b >= n ? n - 1 : i + b;
            for (int j = lo; j <= hi; j++)
                row += RTHS_AT(a, n, i, j) * phi[j];
            acc += phi[i] * row;
        }
        out[r] = acc;
    }
}

/* Eigenvalues as the Rayleigh quotients phi^T K phi / phi^T M phi of the computed shapes: the
 * dense solver's eigenvalues are accurate to eps times the LARGEST one, which for a finely meshed
 * model (w_max^2 / w_1^2 ~ 1e10) leaves 1e-8 .. 1e-6 relative error on the lowest mode; the
 * quotient's error is quadratic in the shape's (itself eps w_max^2 / gap), far below. */
static int refine_and_normalise(const rths_assembly *a, rths_modes *out) {
    int n = a->n, b = rths_assembly_half_bandwidth(a);
    double *kd = calloc((size_t)n, sizeof(double)), *md = calloc((size_t)n, sizeof(double)),
           *cd = calloc((size_t)n, sizeof(double));
    int rc = kd && md && cd ? 0 : -1;
    if (!rc) {
        modal_diagonal(n, b, a->stiffness, out->shapes, kd);
        modal_diagonal(n, b, a->mass, out->shapes, md);
        modal_diagonal(n, b, a->damping, out->shapes, cd);
    }
    for (int r = 0; r < n && !rc; r++) {
        double w2 = kd[r] / md[r];
        double w = w2 > 0 ? sqrt(w2) : 0.0;
        out->omega_rad_s[r] = w;
        out->frequency_hz[r] = w / (2.0 * M_PI);
        out->damping_ratio[r] = w > 0 ? cd[r] / (2.0 * w) : 0.0;
        double *phi = out->shapes + (size_t)r * (size_t)n;
        /* Sign convention: largest-magnitude component positive, so shapes are reproducible. */
        int imax = 0;
        for (int i = 1; i < n; i++)
            if (fabs(phi[i]) > fabs(phi[imax])) imax = i;
        if (phi[imax] < 0)
            for (int i = 0; i < n; i++)
                phi[i] = -phi[i];
    }
    free(kd), free(md), free(cd);
    return rc;
}

/* The same pencil in LAPACK's band storage (dsbgvd: split Cholesky of M, reduction to
 * tridiagonal form in O(n^2 b), divide and conquer): a banded model's eigenproblem without the
 * dense reduction's n^3 / 3 x several. */
static lapack_int banded_eigen(const rths_assembly *a, int b, double *shapes, double *w2) {
    int n = a->n, ld = b + 1;
    double *kb = calloc((size_t)ld * (size_t)n, sizeof(double)),
           *mb = calloc((size_t)ld * (size_t)n, sizeof(double));
    lapack_int info = -1;
    if (kb && mb) {
        /* lower band: element (i, j), i >= j, at row i - j of column j */
        for (int j = 0; j < n; j++)
            for (int i = j; i <= j + b && i < n; i++) {
                kb[(size_t)(i - j) + (size_t)j * ld] = RTHS_AT(a->stiffness, n, i, j);
                mb[(size_t)(i - j) + (size_t)j * ld] = RTHS_AT(a->mass, n, i, j);
            }
        info = LAPACKE_dsbgvd(LAPACK_COL_MAJOR, 'V', 'L', n, b, b, kb, ld, mb, ld, w2, shapes, n);
    }
    free(kb), free(mb);
    return info;
}

int rths_modal_analysis(const rths_assembly *a, rths_modes *out, rths_error *err) {
    int n = a->n;
    memset(out, 0, sizeof *out);
    out->n = n;
    out->omega_rad_s = calloc((size_t)n, sizeof(double));
    out->frequency_hz = calloc((size_t)n, sizeof(double));
    out->damping_ratio = calloc((size_t)n, sizeof(double));
    out->shapes = rths_mat_dup(a->stiffness, n, n);
    double *mass = rths_mat_dup(a->mass, n, n);
    if (!out->omega_rad_s || !out->frequency_hz || !out->damping_ratio || !out->shapes || !mass) {
        rths_mat_free(mass);
        rths_modes_free(out);
        return rths_error_set(err, RTHS_EFAIL, "out of memory in modal analysis");
    }
    /* K phi = w^2 M phi; dsygvd returns M-orthonormal eigenvectors with ascending eigenvalues
     * (the same reduction as dsygv, divide and conquer on the tridiagonal: several times faster
     * for large n) */
    int band = rths_assembly_half_bandwidth(a);
    /* dsbgvd returns a zero eigenvector for n = 1 (measured, OpenBLAS LAPACK): the dense path */
    lapack_int info = n > 1 && band <= n / 8
                          ? banded_eigen(a, band, out->shapes, out->omega_rad_s)
                          : LAPACKE_dsygvd(LAPACK_COL_MAJOR, 1, 'V', 'L', n, out->shapes, n, mass,
                                           n, out->omega_rad_s);
    rths_mat_free(mass);
    if (info != 0) {
        rths_modes_free(out);
        return rths_error_set(err, RTHS_EFAIL,
                              "modal analysis failed (LAPACK dsygvd/dsbgvd info %d): is M positive "
                              "definite and K symmetric?",
                              (int)info);
    }
    if (refine_and_normalise(a, out)) {
        rths_modes_free(out);
        return rths_error_set(err, RTHS_EFAIL, "out of memory in modal analysis");
    }
    /* a mode no frequency range can hold (entries of wildly different scales): refused here, so
     * no NaN or overflowing grid reaches an output */
    for (int r = 0; r < n; r++)
        if (!(isfinite(out->frequency_hz[r]) && out->frequency_hz[r] < 1e12)) {
            double f = out->frequency_hz[r];
            rths_modes_free(out);
            return rths_error_set(err, RTHS_EINPUT,
                                  "mode %d's natural frequency is %g Hz (at most 1e12 Hz is "
                                  "analysed): are the masses and stiffnesses in kg and N/m?",
                                  r + 1, f);
        }
    return RTHS_OK;
}

/* ---- analytic FRF ---- */

int rths_frf(int n, const double *mass, const double *damping, const double *stiffness,
             const double *force, double omega_rad_s, double complex *x_out, rths_error *err) {
    double complex *dyn = malloc((size_t)n * (size_t)n * sizeof *dyn);
    if (!dyn) return rths_error_set(err, RTHS_EFAIL, "out of memory in FRF");
    double w = omega_rad_s;
    for (size_t k = 0; k < (size_t)n * (size_t)n; k++)
        dyn[k] = stiffness[k] - w * w * mass[k] + I * w * damping[k];
    for (int i = 0; i < n; i++)
        x_out[i] = force[i];
    int info = rths_cmat_solve(n, 1, dyn, x_out);
    free(dyn);
    if (info != 0)
        return rths_error_set(err, RTHS_EFAIL,
                              "dynamic stiffness is singular at %g rad/s (zgesv info %d)",
                              omega_rad_s, info);
    return RTHS_OK;
}

static int compare_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int rths_frf_grid(const rths_modes *modes, double start_hz, double end_hz, int points,
                  double **freqs_hz, int *count, rths_error *err) {
    *freqs_hz = NULL;
    *count = 0;
    if (end_hz <= 0) end_hz = 1.25 * modes->frequency_hz[modes->n - 1];
    if (!(end_hz > start_hz) || start_hz < 0)
        return rths_error_set(err, RTHS_EINPUT, "FRF range [%g, %g] Hz is empty", start_hz, end_hz);
    enum { BACKGROUND = 400, PER_MODE = 81 };
    int cap = points > 1 ? points : BACKGROUND + PER_MODE * modes->n;
    double *f = malloc((size_t)cap * sizeof *f);
    if (!f) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int m = 0;
    int uniform = points > 1 ? points : BACKGROUND;
    for (int i = 0; i < uniform; i++)
        f[m++] = start_hz + (end_hz - start_hz) * i / (uniform - 1);
    if (points <= 1) {
        for (int r = 0; r < modes->n; r++) {
            double fr = modes->frequency_hz[r];
            /* half-power bandwidth 2 zeta f; zero damping still gets a narrow cluster */
            double half_bw = fmax(modes->damping_ratio[r], 1e-4) * fr;
            for (int i = 0; i < PER_MODE; i++) {
                double x = fr + 8.0 * half_bw * (2.0 * i / (PER_MODE - 1) - 1.0);
                if (x > start_hz && x < end_hz) f[m++] = x;
            }
        }
        qsort(f, (size_t)m, sizeof *f, compare_double);
    }
    *freqs_hz = f;
    *count = m;
    return RTHS_OK;
}
