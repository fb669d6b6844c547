/* Craig-Bampton reduction of a numerical substructure to its interface and the fixed-interface
 * modes below a cutoff (see include/rths/reduce.h for the method and the error bound). */
#include "rths/reduce.h"

#include "rths/model.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void rths_reduction_defaults(rths_reduction_options *opt) {
    opt->method = RTHS_REDUCTION_AUTO;
    opt->cutoff_hz = 0;
}

int rths_reduction_config_read(rths_config *cfg, rths_reduction_options *opt, rths_error *err) {
    static const char *const methods[] = {"auto", "none", "craig_bampton", NULL};
    int method = (int)opt->method, rc;
    if ((rc = rths_config_get_choice(cfg, "controller.reduction.method", 0, method, methods,
                                     &method, err)))
        return rc;
    opt->method = (rths_reduction_method)method;
    const char *text = NULL;
    const char *key = "controller.reduction.cutoff_hz";
    if (rths_config_has(cfg, key) && !rths_config_get_string(cfg, key, 0, NULL, &text, err) &&
        text && !strcmp(text, "auto")) {
        opt->cutoff_hz = 0;
        return RTHS_OK;
    }
    rths_error_clear(err);
    return rths_config_get_double_ex(cfg, key, 0, opt->cutoff_hz, 0, 1e7, RTHS_CONFIG_LO_OPEN,
                                     &opt->cutoff_hz, err);
}

double rths_reduction_cutoff_hz(const rths_reduction_options *opt, double sample_rate_hz) {
    return opt->cutoff_hz > 0 ? opt->cutoff_hz : sample_rate_hz / 20.0;
}

int rths_reduction_applies(const rths_reduction_options *opt, int n) {
    if (opt->method == RTHS_REDUCTION_AUTO) return n > RTHS_REDUCE_FULL_UP_TO;
    return opt->method == RTHS_REDUCTION_CRAIG_BAMPTON;
}

void rths_reduced_free(rths_reduced *r) {
    if (!r) return;
    free(r->transform);
    free(r->mass);
    free(r->damping);
    free(r->stiffness);
    free(r->mode_hz);
    memset(r, 0, sizeof *r);
}

/* rows/cols [r0, r0 + nr) x [c0, c0 + nc) of the n x n matrix a, as a new nr x nc matrix */
static double *block(const double *a, int n, int r0, int nr, int c0, int nc) {
    double *b = rths_mat_new(nr, nc);
    if (b)
        for (int j = 0; j < nc; j++)
            for (int i = 0; i < nr; i++)
                RTHS_AT(b, nr, i, j) = RTHS_AT(a, n, r0 + i, c0 + j);
    return b;
}

/* T^T A T (nr x nr) for the n x n matrix a. */
static double *project(const double *a, const double *t, int n, int nr) {
    double *at = rths_mat_new(n, nr), *out = rths_mat_new(nr, nr);
    if (at && out) {
        rths_mat_mul(n, nr, n, 1.0, a, 0, t, 0, 0.0, at);
        rths_mat_mul(nr, nr, n, 1.0, t, 1, at, 0, 0.0, out);
        /* symmetric by construction: remove the rounding asymmetry */
        for (int j = 0; j < nr; j++)
            for (int i = j + 1; i < nr; i++) {
                double s = 0.5 * (RTHS_AT(out, nr, i, j) + RTHS_AT(out, nr, j, i));
                RTHS_AT(out, nr, i, j) = RTHS_AT(out, nr, j, i) = s;
            }
    } else {
        free(out);
        out = NULL;
    }
    free(at);
    return out;
}

/* Static constraint modes Psi = -K_ii^{-1} K_ib (ni x nb). */
static int constraint_modes(const double *k, int n, int nb, double **psi_out, rths_error *err) {
    int ni = n - nb;
    double *kii = block(k, n, nb, ni, nb, ni), *psi = block(k, n, nb, ni, 0, nb);
    *psi_out = NULL;
    if (!kii || !psi) {
        free(kii), free(psi);
        return rths_error_set(err, RTHS_EFAIL, "out of memory in the reduction");
    }
    int info = rths_mat_solve(ni, nb, kii, psi);
    free(kii);
    if (info) {
        free(psi);
        return rths_error_set(err, RTHS_EINPUT,
                              "the numerical substructure with its interface held is not "
                              "restrained (K_ii singular, dgesv info %d): it cannot be reduced",
                              info);
    }
    for (int i = 0; i < ni * nb; i++)
        psi[i] = -psi[i];
    *psi_out = psi;
    return RTHS_OK;
}

/* tr(G^T M_ii^{-1} G) - sum over the kept modes of |phi_j^T G|^2 with G = M_ib + M_ii Psi: the
 * apparent interface mass of the dropped modes. */
static double dropped_mass(const double *m, int n, int nb, const double *psi,
                           const rths_modes *modes, int kept) {
    int ni = n - nb;
    double *mii = block(m, n, nb, ni, nb, ni), *g = block(m, n, nb, ni, 0, nb);
    double *x = rths_mat_new(ni, nb);
    double total = NAN;
    if (mii && g && x) {
        rths_mat_mul(ni, nb, ni, 1.0, mii, 0, psi, 0, 1.0, g);
        memcpy(x, g, sizeof(double) * (size_t)ni * (size_t)nb);
        if (!rths_mat_solve(ni, nb, mii, x)) {
            total = 0;
            for (int c = 0; c < nb; c++) {
                for (int i = 0; i < ni; i++)
                    total += RTHS_AT(g, ni, i, c) * RTHS_AT(x, ni, i, c);
                for (int j = 0; j < kept; j++) {
                    double mj = 0;
                    for (int i = 0; i < ni; i++)
                        mj += RTHS_AT(modes->shapes, ni, i, j) * RTHS_AT(g, ni, i, c);
                    total -= mj * mj;
                }
            }
            total = fmax(total, 0.0); /* rounding when nothing is dropped */
        }
    }
    free(mii), free(g), free(x);
    return total;
}

/* The modes of a diagonal pencil: unit vectors scaled to unit modal mass, ascending. */
static int diagonal_modes(const rths_assembly *a, rths_modes *out, rths_error *err) {
    int n = a->n;
    memset(out, 0, sizeof *out);
    out->n = n;
    out->omega_rad_s = calloc((size_t)n, sizeof(double));
    out->frequency_hz = calloc((size_t)n, sizeof(double));
    out->damping_ratio = calloc((size_t)n, sizeof(double));
    out->shapes = rths_mat_new(n, n);
    if (!out->omega_rad_s || !out->frequency_hz || !out->damping_ratio || !out->shapes) {
        rths_modes_free(out);
        return rths_error_set(err, RTHS_EFAIL, "out of memory in the reduction");
    }
    for (int r = 0; r < n; r++) {
        /* insertion by ascending k/m */
        int best = -1;
        double best_w2 = INFINITY;
        for (int i = 0; i < n; i++) {
            double w2 = RTHS_AT(a->stiffness, n, i, i) / RTHS_AT(a->mass, n, i, i);
            int used = 0;
            for (int q = 0; q < r && !used; q++)
                used = RTHS_AT(out->shapes, n, i, q) != 0;
            if (!used && (best < 0 || w2 < best_w2)) best = i, best_w2 = w2;
        }
        out->omega_rad_s[r] = sqrt(fmax(best_w2, 0.0));
        out->frequency_hz[r] = out->omega_rad_s[r] / (2 * M_PI);
        RTHS_AT(out->shapes, n, best, r) = 1.0 / sqrt(RTHS_AT(a->mass, n, best, best));
    }
    return RTHS_OK;
}

/* Fixed-interface modes of the interior (M_ii, K_ii); damping is not needed for the shapes. */
static int interior_modes(int n, int nb, const double *m, const double *k, rths_modes *modes,
                          rths_error *err) {
    int ni = n - nb;
    rths_assembly interior = {.n = ni,
                              .mass = block(m, n, nb, ni, nb, ni),
                              .damping = rths_mat_new(ni, ni),
                              .stiffness = block(k, n, nb, ni, nb, ni)};
    int rc = interior.mass && interior.damping && interior.stiffness
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory in the reduction");
    /* a diagonal pencil (one interior DoF, or uncoupled ones) goes to the dense solver: dsbgvd
     * with half-bandwidth 0 returns zero shapes here */
    if (!rc && rths_assembly_half_bandwidth(&interior) == 0) {
        rc = diagonal_modes(&interior, modes, err);
    } else if (!rc) {
        rc = rths_modal_analysis(&interior, modes, err);
    }
    free(interior.mass), free(interior.damping), free(interior.stiffness);
    return rc;
}

/* How many modes to keep under the cutoff and the size bound; -1 (err set) when refused. */
static int modes_to_keep(const rths_modes *modes, double *cutoff_hz, int max_modes, int clip,
                         rths_error *err) {
    int below = 0;
    while (below < modes->n && modes->frequency_hz[below] <= *cutoff_hz)
        below++;
    if (below <= max_modes) return below;
    if (!clip) {
        rths_error_set(err, RTHS_EINPUT,
                       "%d fixed-interface modes of the numerical substructure lie below the "
                       "reduction cutoff %g Hz; the real-time step takes at most %d: lower "
                       "controller.reduction.cutoff_hz (mode %d is at %g Hz)",
                       below, *cutoff_hz, max_modes, max_modes, modes->frequency_hz[max_modes - 1]);
        return -1;
    }
    *cutoff_hz = max_modes > 0 ? modes->frequency_hz[max_modes - 1] : 0.0;
    return max_modes;
}

static int build_transform(rths_reduced *r, const double *psi, const rths_modes *modes) {
    int n = r->n, nb = r->n_boundary, nr = r->nr, ni = n - nb;
    r->transform = rths_mat_new(n, nr);
    r->mode_hz = calloc((size_t)(r->n_modes > 0 ? r->n_modes : 1), sizeof(double));
    if (!r->transform || !r->mode_hz) return -1;
    for (int c = 0; c < nb; c++) {
        RTHS_AT(r->transform, n, c, c) = 1.0;
        for (int i = 0; i < ni; i++)
            RTHS_AT(r->transform, n, nb + i, c) = RTHS_AT(psi, ni, i, c);
    }
    for (int j = 0; j < r->n_modes; j++) {
        r->mode_hz[j] = modes->frequency_hz[j];
        for (int i = 0; i < ni; i++)
            RTHS_AT(r->transform, n, nb + i, nb + j) = RTHS_AT(modes->shapes, ni, i, j);
    }
    return 0;
}

int rths_reduce_craig_bampton(int n, int n_boundary, const double *mass, const double *damping,
                              const double *stiffness, double cutoff_hz, int max_modes, int clip,
                              rths_reduced *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    if (n_boundary < 1 || n_boundary >= n)
        return rths_error_set(err, RTHS_EINPUT,
                              "a reduction needs interior DoFs besides the %d interface ones of "
                              "a %d-DoF model",
                              n_boundary, n);
    double *psi = NULL;
    int rc = constraint_modes(stiffness, n, n_boundary, &psi, err);
    if (rc) return rc;
    rths_modes modes;
    rc = interior_modes(n, n_boundary, mass, stiffness, &modes, err);
    if (rc) {
        free(psi);
        return rc;
    }
    out->n = n;
    out->n_boundary = n_boundary;
    out->cutoff_hz = cutoff_hz;
    int kept = modes_to_keep(&modes, &out->cutoff_hz, max_modes, clip, err);
    if (kept < 0) {
        rc = RTHS_EINPUT;
        goto done;
    }
    out->n_modes = kept;
    out->nr = n_boundary + kept;
    out->first_dropped_hz = kept < modes.n ? modes.frequency_hz[kept] : INFINITY;
    out->dropped_mass_kg = dropped_mass(mass, n, n_boundary, psi, &modes, kept);
    if (build_transform(out, psi, &modes) ||
        !(out->mass = project(mass, out->transform, n, out->nr)) ||
        !(out->damping = project(damping, out->transform, n, out->nr)) ||
        !(out->stiffness = project(stiffness, out->transform, n, out->nr)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory in the reduction");
done:
    free(psi);
    rths_modes_free(&modes);
    if (rc) rths_reduced_free(out);
    return rc;
}

int rths_reduce_craig_bampton_keeping(int n, int n_interface, const double *mass,
                                      const double *damping, const double *stiffness, int n_keep,
                                      const int *keep, double cutoff_hz, int max_modes, int clip,
                                      rths_reduced *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    int *perm = malloc(sizeof(int) * (size_t)(n > 0 ? n : 1));
    int *seen = calloc((size_t)(n > 0 ? n : 1), sizeof(int));
    if (!perm || !seen) {
        free(perm), free(seen);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    int rc = RTHS_OK, nb = 0;
    for (int i = 0; i < n_interface && i < n; i++)
        perm[nb++] = i, seen[i] = 1;
    for (int m = 0; m < n_keep && !rc; m++) {
        if (keep[m] < n_interface || keep[m] >= n || seen[keep[m]])
            rc = rths_error_set(err, RTHS_EINPUT,
                                "a DoF to keep in the reduction, %d, is an interface DoF, repeated "
                                "or outside the substructure's %d DoFs",
                                keep[m] + 1, n);
        else
            perm[nb++] = keep[m], seen[keep[m]] = 1;
    }
    for (int i = 0; i < n && !rc; i++)
        if (!seen[i]) perm[nb++] = i;
    free(seen);
    double *pm = rc ? NULL : rths_mat_new(n, n), *pc = rc ? NULL : rths_mat_new(n, n);
    double *pk = rc ? NULL : rths_mat_new(n, n);
    if (!rc && (!pm || !pc || !pk)) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int c = 0; c < n && !rc; c++)
        for (int r = 0; r < n; r++) {
            size_t from = perm[r] + (size_t)perm[c] * n, to = r + (size_t)c * n;
            pm[to] = mass[from], pc[to] = damping[from], pk[to] = stiffness[from];
        }
    if (!rc)
        rc = rths_reduce_craig_bampton(n, n_interface + n_keep, pm, pc, pk, cutoff_hz, max_modes,
                                       clip, out, err);
    /* the transform back to the substructure's own DoF order: row perm[r] is the permuted row r */
    double *t = !rc ? rths_mat_new(n, out->nr) : NULL;
    if (!rc && !t) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        for (int c = 0; c < out->nr; c++)
            for (int r = 0; r < n; r++)
                t[perm[r] + (size_t)c * n] = out->transform[r + (size_t)c * n];
        free(out->transform);
        out->transform = t;
    } else if (out->transform) {
        rths_reduced_free(out);
    }
    free(perm), free(pm), free(pc), free(pk);
    return rc;
}

double rths_reduced_stiffness_error_bound(const rths_reduced *r, double omega_rad_s) {
    if (r->n_modes == r->n - r->n_boundary) return 0.0;
    double wc = 2 * M_PI * r->first_dropped_hz, w2 = omega_rad_s * omega_rad_s;
    if (!(w2 < wc * wc)) return INFINITY;
    return w2 * w2 * r->dropped_mass_kg / (wc * wc - w2);
}

int rths_interface_dynamic_stiffness(int n, int n_boundary, const double *mass,
                                     const double *damping, const double *stiffness,
                                     double omega_rad_s, double complex *s_out, rths_error *err) {
    int nb = n_boundary, ni = n - nb;
    double w = omega_rad_s;
    double complex *dii = malloc(sizeof *dii * (size_t)ni * (size_t)ni);
    double complex *dib = malloc(sizeof *dib * (size_t)(ni > 0 ? ni : 1) * (size_t)nb);
    if (!dii || !dib) {
        free(dii), free(dib);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
#define DYN(i, j)                                                                                  \
    (RTHS_AT(stiffness, n, i, j) - w * w * RTHS_AT(mass, n, i, j) +                                \
     I * w * RTHS_AT(damping, n, i, j))
    for (int j = 0; j < ni; j++)
        for (int i = 0; i < ni; i++)
            RTHS_AT(dii, ni, i, j) = DYN(nb + i, nb + j);
    for (int j = 0; j < nb; j++)
        for (int i = 0; i < ni; i++)
            RTHS_AT(dib, ni, i, j) = DYN(nb + i, j);
    int info = ni > 0 ? rths_cmat_solve(ni, nb, dii, dib) : 0;
    if (!info)
        for (int j = 0; j < nb; j++)
            for (int i = 0; i < nb; i++) {
                double complex s = DYN(i, j);
                for (int l = 0; l < ni; l++)
                    s -= DYN(i, nb + l) * RTHS_AT(dib, ni, l, j);
                RTHS_AT(s_out, nb, i, j) = s;
            }
#undef DYN
    free(dii), free(dib);
    if (info)
        return rths_error_set(err, RTHS_EFAIL,
                              "interior dynamic stiffness singular at %g rad/s (zgesv info %d)",
                              omega_rad_s, info);
    return RTHS_OK;
}
