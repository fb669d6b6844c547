/* Large sparse models for `rths model` (model.h, "large sparse models"; docs/architecture.md,
 * "Sparse algebra"): the choice of path, the model read from Matrix Market files without ever
 * forming a dense matrix, its lowest modes and its FRF. */
#include "rths/model.h"
#include "rths/mtx.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#define K_MATRICES "structure.matrices"

static const char *const matrix_keys[3] = {K_MATRICES ".mass_kg", K_MATRICES ".damping_n_s_per_m",
                                           K_MATRICES ".stiffness_n_per_m"};

const char *rths_model_solver_name(rths_model_solver s) {
    switch (s) {
    case RTHS_MODEL_SOLVER_DENSE:
        return "dense";
    case RTHS_MODEL_SOLVER_BANDED:
        return "banded";
    case RTHS_MODEL_SOLVER_SPARSE:
        return "sparse";
    }
    return "?";
}

double rths_peak_memory_mb(void) {
    struct rusage u;
    if (getrusage(RUSAGE_SELF, &u)) return 0;
    return (double)u.ru_maxrss / 1024.0; /* kB on Linux */
}

/* Path of a file named in the config, relative to the config file's folder (as setup.c reads
 * structure.matrices). */
static char *config_relative_path(const rths_config *cfg, const char *name) {
    const char *cfg_path = rths_config_path(cfg);
    const char *slash = cfg_path ? strrchr(cfg_path, '/') : NULL;
    size_t dir_len = (name[0] == '/' || !slash) ? 0 : (size_t)(slash - cfg_path) + 1;
    char *out = malloc(dir_len + strlen(name) + 1);
    if (!out) return NULL;
    memcpy(out, cfg_path, dir_len);
    strcpy(out + dir_len, name);
    return out;
}

/* The Matrix Market file a matrix key names, or NULL (absent, a list of rows, out of memory). */
static char *matrix_file(rths_config *cfg, const char *key) {
    const char *name = NULL;
    rths_error local;
    if (!rths_config_has(cfg, key)) return NULL;
    if (rths_config_get_string(cfg, key, 1, NULL, &name, &local) != RTHS_OK || !name) return NULL;
    return config_relative_path(cfg, name);
}

static int half_bandwidth(const rths_sparse_sym *a) {
    int b = 0;
    for (int j = 0; j < a->n; j++)
        for (int e = a->colptr[j]; e < a->colptr[j + 1]; e++)
            if (a->value[e] != 0 && a->rowidx[e] - j > b) b = a->rowidx[e] - j;
    return b;
}

void rths_model_choice_dense(const rths_assembly *a, const char *why, rths_model_choice *out) {
    int n = a->n, b = rths_assembly_half_bandwidth(a);
    out->n = n;
    out->half_bandwidth = b;
    /* the rule of rths_modal_analysis (dsbgvd is wrong for n = 1: dense there) */
    out->solver = n > 1 && b <= n / 8 ? RTHS_MODEL_SOLVER_BANDED : RTHS_MODEL_SOLVER_DENSE;
    if (out->solver == RTHS_MODEL_SOLVER_BANDED)
        snprintf(out->reason, sizeof out->reason, "%s; half-bandwidth %d <= n / 8 = %d: banded",
                 why, b, n / 8);
    else
        snprintf(out->reason, sizeof out->reason,
                 "%s; half-bandwidth %d, banded only when at most n / 8 = %d", why, b, n / 8);
}

void rths_model_choice_free(rths_model_choice *c) {
    if (c) rths_sparse_free(&c->stiffness);
}

int rths_model_choose_solver(rths_config *cfg, rths_model_choice *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    out->half_bandwidth = -1;
    static const char *const solvers[] = {"auto", "dense", "sparse", NULL};
    int asked = 0;
    int rc = rths_config_get_choice(cfg, "model.solver", 0, 0, solvers, &asked, err);
    if (rc) return rc;
    char *kpath = matrix_file(cfg, matrix_keys[2]);
    if (!kpath) {
        if (asked == 2)
            return rths_config_error_at(cfg, "model.solver", err,
                                        "sparse needs structure.matrices given as Matrix Market "
                                        "files (the stiffness is not one)");
        out->solver = RTHS_MODEL_SOLVER_DENSE;
        snprintf(out->reason, sizeof out->reason, "%s",
                 asked == 1 ? "model.solver: dense" : "structure not from Matrix Market files");
        return RTHS_OK;
    }
    rths_error local;
    int rows = 0, cols = 0;
    rc = rths_mtx_read_size(kpath, &rows, &cols, &local);
    if (rc) {
        free(kpath);
        return rths_config_error_at(cfg, matrix_keys[2], err, "%s", local.msg);
    }
    out->n = rows;
    if (asked == 1 || (asked == 0 && rows <= RTHS_MODEL_DENSE_UP_TO)) {
        free(kpath);
        out->solver = RTHS_MODEL_SOLVER_DENSE;
        if (asked == 1)
            snprintf(out->reason, sizeof out->reason, "model.solver: dense");
        else
            snprintf(out->reason, sizeof out->reason, "n = %d <= %d", rows, RTHS_MODEL_DENSE_UP_TO);
        return RTHS_OK;
    }
    rc = rths_mtx_read_sparse(kpath, RTHS_MTX_POSITIVE_DIAGONAL, &out->stiffness, &local);
    free(kpath);
    if (rc) return rths_config_error_at(cfg, matrix_keys[2], err, "%s", local.msg);
    int b = half_bandwidth(&out->stiffness);
    out->half_bandwidth = b;
    if (asked == 2) {
        out->solver = RTHS_MODEL_SOLVER_SPARSE;
        snprintf(out->reason, sizeof out->reason,
                 "model.solver: sparse (n = %d, half-bandwidth %d)", rows, b);
    } else if (rows > RTHS_MTX_MAX_DIM) {
        out->solver = RTHS_MODEL_SOLVER_SPARSE;
        snprintf(out->reason, sizeof out->reason,
                 "n = %d > %d: dense matrices of this order do not fit (half-bandwidth %d)", rows,
                 RTHS_MTX_MAX_DIM, b);
    } else if (b > rows / 8) {
        out->solver = RTHS_MODEL_SOLVER_SPARSE;
        snprintf(out->reason, sizeof out->reason,
                 "n = %d > %d and the pattern is not banded (half-bandwidth %d > n / 8 = %d)", rows,
                 RTHS_MODEL_DENSE_UP_TO, b, rows / 8);
    } else {
        out->solver = RTHS_MODEL_SOLVER_BANDED;
        snprintf(out->reason, sizeof out->reason, "banded pattern: half-bandwidth %d <= n / 8 = %d",
                 b, rows / 8);
    }
    if (out->solver != RTHS_MODEL_SOLVER_SPARSE) rths_sparse_free(&out->stiffness);
    return RTHS_OK;
}

/* ---- the model ---- */

void rths_sparse_model_free(rths_sparse_model *m) {
    if (!m) return;
    rths_sparse_free(&m->mass);
    rths_sparse_free(&m->damping);
    rths_sparse_free(&m->stiffness);
    free(m->roles);
    free(m->int_dofs);
    free(m->force);
    free(m->interface_damping_phys);
    free(m->interface_stiffness_phys);
    memset(m, 0, sizeof *m);
}

static int assign(rths_config *cfg, const char *key, const int *dofs, int count, rths_dof_role role,
                  int *assigned, rths_sparse_model *m, rths_error *err) {
    for (int i = 0; i < count; i++) {
        if (dofs[i] < 1 || dofs[i] > m->n)
            return rths_config_error_at(cfg, key, err, "DoF %d is outside 1..%d", dofs[i], m->n);
        if (assigned[dofs[i] - 1])
            return rths_config_error_at(
                cfg, key, err, "DoF %d is listed twice (each DoF has exactly one side)", dofs[i]);
        assigned[dofs[i] - 1] = 1;
        m->roles[dofs[i] - 1] = role;
    }
    return RTHS_OK;
}

/* split.*: the same keys and rules as setup.c's read_split for matrices (the DoFs not listed
 * take the side of the absent list), and the same separability check as rths_split_create. */
static int read_split(rths_config *cfg, rths_sparse_model *m, rths_error *err) {
    int n = m->n, *iface = NULL, *phys = NULL, *num = NULL, n_iface = 0, n_phys = 0, n_num = 0;
    int *assigned = calloc((size_t)n, sizeof *assigned);
    m->roles = calloc((size_t)n, sizeof *m->roles);
    int rc = assigned && m->roles ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_config_get_int_list(cfg, "split.interface", 1, &iface, &n_iface, err);
    if (!rc && n_iface < 1)
        rc = rths_config_error_at(cfg, "split.interface", err, "needs at least one DoF");
    if (!rc)
        rc = assign(cfg, "split.interface", iface, n_iface, RTHS_DOF_INTERFACE, assigned, m, err);
    if (!rc) rc = rths_config_get_int_list(cfg, "split.physical", 0, &phys, &n_phys, err);
    if (!rc) rc = rths_config_get_int_list(cfg, "split.numerical", 0, &num, &n_num, err);
    if (!rc) rc = assign(cfg, "split.physical", phys, n_phys, RTHS_DOF_PHYSICAL, assigned, m, err);
    if (!rc) rc = assign(cfg, "split.numerical", num, n_num, RTHS_DOF_NUMERICAL, assigned, m, err);
    for (int i = 0; i < n && !rc; i++)
        if (!assigned[i]) {
            if (n_num == 0)
                m->roles[i] = RTHS_DOF_NUMERICAL;
            else if (n_phys == 0)
                m->roles[i] = RTHS_DOF_PHYSICAL;
            else
                rc = rths_config_error_at(cfg, "split", err,
                                          "DoF %d is on no side: list it in split.physical or "
                                          "split.numerical",
                                          i + 1);
        }
    /* split.mass_ratio: one p or one per interface DoF, each in (0, 1); the first is reported */
    double *ratios = NULL;
    int n_ratios = 0;
    rths_error local;
    if (!rc &&
        rths_config_get_double_list(cfg, "split.mass_ratio", 0, &ratios, &n_ratios, &local) ==
            RTHS_OK &&
        n_ratios > 0) {
        if (n_ratios != n_iface)
            rc = rths_config_error_at(cfg, "split.mass_ratio", err,
                                      "lists %d mass ratios for %d interface DoFs: give one p, or "
                                      "one per interface DoF",
                                      n_ratios, n_iface);
        for (int i = 0; i < n_ratios && !rc; i++)
            if (!(ratios[i] > 0 && ratios[i] < 1))
                rc = rths_config_error_at(cfg, "split.mass_ratio", err,
                                          "entry %d: must be in (0, 1) (got %g)", i + 1, ratios[i]);
        /* the split's first interface DoF is the lowest numbered */
        int lowest = 0;
        for (int i = 1; i < n_iface && !rc; i++)
            if (iface[i] < iface[lowest]) lowest = i;
        if (!rc) m->mass_ratio = ratios[lowest];
    } else if (!rc) {
        rc = rths_config_get_double_ex(cfg, "split.mass_ratio", 1, 0.5, 0, 1,
                                       RTHS_CONFIG_LO_OPEN | RTHS_CONFIG_HI_OPEN, &m->mass_ratio,
                                       err);
    }
    free(ratios);
    static const char *const share_keys[2] = {"split.interface_damping_physical_n_s_per_m",
                                              "split.interface_stiffness_physical_n_per_m"};
    double **shares[2] = {&m->interface_damping_phys, &m->interface_stiffness_phys};
    for (int k = 0; k < 2 && !rc; k++) {
        if (!rths_config_has(cfg, share_keys[k])) continue;
        int r = 0, c = 0;
        rc = rths_config_get_matrix(cfg, share_keys[k], 1, shares[k], &r, &c, err);
        if (!rc && (r != n_iface || c != n_iface))
            rc = rths_config_error_at(cfg, share_keys[k], err,
                                      "must be %d x %d (one row per interface DoF)", n_iface,
                                      n_iface);
        for (int e = 0; !rc && e < r * c; e++)
            if (!(fabs((*shares[k])[e]) <= 1e15))
                rc = rths_config_error_at(cfg, share_keys[k], err,
                                          "entry %d = %g is not a finite number of magnitude "
                                          "<= 1e15",
                                          e + 1, (*shares[k])[e]);
    }
    if (!rc) {
        m->int_dofs = malloc(sizeof(int) * (size_t)n_iface);
        if (!m->int_dofs) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        for (int i = 0; i < n && !rc; i++)
            if (m->roles[i] == RTHS_DOF_INTERFACE) m->int_dofs[m->n_int++] = i;
    }
    /* internal physical and internal numerical DoFs may meet only through the interface */
    const rths_sparse_sym *mats[3] = {&m->mass, &m->damping, &m->stiffness};
    static const char *const names[3] = {"mass", "damping", "stiffness"};
    for (int k = 0; k < 3 && !rc; k++)
        for (int j = 0; j < n && !rc; j++)
            for (int e = mats[k]->colptr[j]; e < mats[k]->colptr[j + 1] && !rc; e++) {
                int i = mats[k]->rowidx[e];
                rths_dof_role a = m->roles[i], b = m->roles[j];
                if (mats[k]->value[e] != 0 &&
                    ((a == RTHS_DOF_PHYSICAL && b == RTHS_DOF_NUMERICAL) ||
                     (a == RTHS_DOF_NUMERICAL && b == RTHS_DOF_PHYSICAL)))
                    rc = rths_config_error_at(cfg, "split", err,
                                              "%s couples physical DoF %d directly to numerical "
                                              "DoF %d: substructures must meet only at the "
                                              "interface",
                                              names[k], a == RTHS_DOF_PHYSICAL ? i + 1 : j + 1,
                                              a == RTHS_DOF_PHYSICAL ? j + 1 : i + 1);
            }
    free(assigned);
    free(iface);
    free(phys);
    free(num);
    return rc;
}

/* forcing: force (dof, amplitude_n) or base (amplitude_m_s2: -M 1 per m/s^2), as setup.c. */
static int read_forcing(rths_config *cfg, rths_sparse_model *m, rths_error *err) {
    static const char *const types[] = {"force", "base", NULL};
    int type = 0, n = m->n;
    int rc = rths_config_get_choice(cfg, "forcing.type", 0, 0, types, &type, err);
    if (rc) return rc;
    m->force = calloc((size_t)n, sizeof *m->force);
    if (!m->force) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (type == 1) {
        static const char *const force_keys[] = {"forcing.dof", "forcing.amplitude_n"};
        for (int i = 0; i < 2; i++)
            if (rths_config_has(cfg, force_keys[i]))
                return rths_config_error_at(cfg, force_keys[i], err,
                                            "applies to forcing.type: force only (base "
                                            "excitation takes forcing.amplitude_m_s2)");
        rc = rths_config_get_double_ex(cfg, "forcing.amplitude_m_s2", 0, 1.0, 0, 1e6,
                                       RTHS_CONFIG_LO_OPEN, &m->forcing_amplitude_n, err);
        if (rc) return rc;
        m->base_excitation = 1;
        m->forcing_dof = n - 1;
        double *ones = malloc(sizeof(double) * (size_t)n);
        if (!ones) return rths_error_set(err, RTHS_EFAIL, "out of memory");
        for (int i = 0; i < n; i++)
            ones[i] = 1.0;
        rths_sparse_symv(&m->mass, ones, m->force);
        free(ones);
        for (int i = 0; i < n; i++)
            m->force[i] *= -m->forcing_amplitude_n;
        return RTHS_OK;
    }
    if (rths_config_has(cfg, "forcing.amplitude_m_s2"))
        return rths_config_error_at(cfg, "forcing.amplitude_m_s2", err,
                                    "applies to forcing.type: base only");
    long dof = 0;
    rc = rths_config_get_int(cfg, "forcing.dof", 1, 0, 1, n, &dof, err);
    if (!rc)
        rc = rths_config_get_double(cfg, "forcing.amplitude_n", 0, 1.0, 0, 1e9,
                                    &m->forcing_amplitude_n, err);
    if (!rc && !(m->forcing_amplitude_n > 0))
        rc = rths_config_error_at(cfg, "forcing.amplitude_n", err, "must be > 0 (got %g)",
                                  m->forcing_amplitude_n);
    if (rc) return rc;
    m->forcing_dof = (int)dof - 1;
    m->force[m->forcing_dof] = m->forcing_amplitude_n;
    return RTHS_OK;
}

static int read_model_keys(rths_config *cfg, rths_sparse_model *m, rths_error *err) {
    long points = 0, modes = 0, checks = 0;
    static const char *const frf_solvers[] = {"modal", "direct", NULL};
    int direct = 0;
    int rc = rths_config_get_double(cfg, "model.frf.start_hz", 0, 0, 0, 1e6, &m->frf_start_hz, err);
    if (!rc)
        rc = rths_config_get_double(cfg, "model.frf.end_hz", 0, 0, 0, 1e6, &m->frf_end_hz, err);
    if (!rc) rc = rths_config_get_int(cfg, "model.frf.points", 0, 0, 0, 10000000, &points, err);
    if (!rc && rths_config_has(cfg, "model.frf.points") && points < 2)
        rc = rths_config_error_at(cfg, "model.frf.points", err, "must be at least 2 (got %ld)",
                                  points);
    if (!rc && m->frf_end_hz > 0 && m->frf_end_hz <= m->frf_start_hz)
        rc = rths_config_error_at(cfg, "model.frf.end_hz", err,
                                  "must be above model.frf.start_hz (%g Hz), got %g Hz",
                                  m->frf_start_hz, m->frf_end_hz);
    /* a mode count Lanczos can hold: fewer than the DoFs, and a basis that fits in memory */
    long max_modes =
        m->n - 1 < RTHS_SPARSE_MODEL_MAX_MODES ? m->n - 1 : RTHS_SPARSE_MODEL_MAX_MODES;
    if (!rc) rc = rths_config_get_int(cfg, "model.modes", 0, 20, 1, max_modes, &modes, err);
    if (!rc && m->frf_end_hz > 0 && !rths_config_has(cfg, "model.modes")) {
        m->modes_below_hz = RTHS_SPARSE_MODEL_MODES_MARGIN * m->frf_end_hz;
        modes = max_modes;
    }
    if (!rc) rc = rths_config_get_choice(cfg, "model.frf.solver", 0, 0, frf_solvers, &direct, err);
    /* one direct complex solve costs about a symbolic analysis and two real factorisations (20 s
     * at 60 000 DoFs on two loaded cores): by default only on models below this size */
    long default_checks = m->n <= RTHS_SPARSE_MODEL_CHECK_UP_TO ? 1 : 0;
    if (!rc)
        rc = rths_config_get_int(cfg, "model.frf.check_points", 0, default_checks, 0, 100, &checks,
                                 err);
    m->frf_points = (int)points;
    m->modes_wanted = (int)modes;
    m->frf_direct = direct;
    m->frf_check_points = (int)checks;
    return rc;
}

int rths_sparse_model_read(rths_config *cfg, rths_model_choice *choice, rths_sparse_model *out,
                           rths_error *err) {
    memset(out, 0, sizeof *out);
    double t0 = rths_monotonic_s();
    out->stiffness = choice->stiffness;
    memset(&choice->stiffness, 0, sizeof choice->stiffness);
    out->n = out->stiffness.n;
    rths_sparse_sym *into[2] = {&out->mass, &out->damping};
    const int checks[2] = {RTHS_MTX_POSITIVE_DIAGONAL, 0};
    int rc = RTHS_OK;
    for (int k = 0; k < 2 && !rc; k++) {
        char *path = matrix_file(cfg, matrix_keys[k]);
        if (!path) {
            rc = rths_config_error_at(cfg, matrix_keys[k], err,
                                      "must name a Matrix Market file like %s on the sparse path",
                                      matrix_keys[2]);
            break;
        }
        rths_error local;
        rc = rths_mtx_read_sparse(path, checks[k], into[k], &local);
        free(path);
        if (rc) {
            rc = rths_config_error_at(cfg, matrix_keys[k], err, "%s", local.msg);
            break;
        }
        if (into[k]->n != out->n)
            rc = rths_config_error_at(cfg, matrix_keys[k], err, "is %d x %d but %s is %d x %d",
                                      into[k]->n, into[k]->n, matrix_keys[2], out->n, out->n);
    }
    out->read_matrices_s = rths_monotonic_s() - t0;
    if (!rc) rc = read_split(cfg, out, err);
    if (!rc) rc = read_forcing(cfg, out, err);
    if (!rc) rc = read_model_keys(cfg, out, err);
    if (rc) rths_sparse_model_free(out);
    return rc;
}

int *rths_sparse_model_output_dofs(const rths_sparse_model *m, int *count) {
    int n = m->n, k = 0;
    int *dofs = malloc((size_t)n * sizeof *dofs);
    if (!dofs) return NULL;
    for (int i = 0; i < n; i++)
        if (n <= 64 || m->roles[i] != RTHS_DOF_NUMERICAL ||
            (!m->base_excitation && i == m->forcing_dof))
            dofs[k++] = i;
    *count = k;
    return dofs;
}

void rths_sparse_model_forcing_text(const rths_sparse_model *m, char *buf, size_t size) {
    if (m->base_excitation)
        snprintf(buf, size, "ground acceleration %g m/s^2", m->forcing_amplitude_n);
    else
        snprintf(buf, size, "%g N on DoF %d", m->forcing_amplitude_n, m->forcing_dof + 1);
}

/* ---- modes ---- */

void rths_sparse_modes_free(rths_sparse_modes *m) {
    if (!m) return;
    free(m->omega_rad_s);
    free(m->frequency_hz);
    free(m->damping_ratio);
    free(m->shapes);
    free(m->static_x);
    free(m->static_y);
    memset(m, 0, sizeof *m);
}

static double dot(int n, const double *a, const double *b) {
    double s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

int rths_sparse_model_modes(const rths_sparse_model *m, rths_sparse_modes *out,
                            rths_sparse_factor **k_factor, rths_error *err) {
    memset(out, 0, sizeof *out);
    if (k_factor) *k_factor = NULL;
    int n = m->n;
    rths_sparse_eigs_options opt = rths_sparse_eigs_defaults();
    opt.count = m->modes_wanted;
    if (m->modes_below_hz > 0) opt.lambda_max = pow(2 * M_PI * m->modes_below_hz, 2);
    double *lambda = NULL, *phi = NULL;
    int found = 0;
    rths_sparse_factor *f = NULL;
    int rc = rths_sparse_eigs_keep(&m->stiffness, &m->mass, &opt, &lambda, &phi, &found,
                                   &out->stats, &f, err);
    if (rc == RTHS_EINPUT && m->modes_below_hz > 0) {
        rths_error why = *err; /* the message is formatted into err: a copy to read from */
        return rths_error_set(err, RTHS_EINPUT,
                              "%s: lower model.frf.end_hz (%g Hz; modes are computed up to %g x "
                              "it) or give model.modes",
                              why.msg, m->frf_end_hz, RTHS_SPARSE_MODEL_MODES_MARGIN);
    }
    if (rc) return rc;
    if (found == 0) {
        free(lambda);
        return rths_error_set(err, RTHS_EINPUT,
                              "no mode lies below %g Hz (%g x model.frf.end_hz): raise "
                              "model.frf.end_hz or give model.modes",
                              m->modes_below_hz, RTHS_SPARSE_MODEL_MODES_MARGIN);
    }
    double t0 = rths_monotonic_s();
    out->n = n;
    out->count = found;
    out->omega_rad_s = malloc(sizeof(double) * (size_t)found);
    out->frequency_hz = malloc(sizeof(double) * (size_t)found);
    out->damping_ratio = malloc(sizeof(double) * (size_t)found);
    double *cphi = malloc(sizeof(double) * (size_t)n * (size_t)found);
    double *kx = malloc(sizeof(double) * (size_t)n), *mx = malloc(sizeof(double) * (size_t)n);
    out->shapes = phi;
    if (!out->omega_rad_s || !out->frequency_hz || !out->damping_ratio || !cphi || !kx || !mx) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory after the sparse eigensolver");
        goto done;
    }
    for (int r = 0; r < found && !rc; r++) {
        double w2 = lambda[r], *p = phi + (size_t)r * n;
        if (!(w2 > 0)) {
            rc = rths_error_set(err, RTHS_EINPUT,
                                "mode %d's eigenvalue is %g rad^2/s^2: is K positive definite (no "
                                "rigid-body mode)?",
                                r + 1, w2);
            break;
        }
        out->omega_rad_s[r] = sqrt(w2);
        out->frequency_hz[r] = out->omega_rad_s[r] / (2 * M_PI);
        /* residual ||K phi - lambda M phi|| / ||K phi||: each mode checked on the matrices */
        rths_sparse_symv(&m->stiffness, p, kx);
        rths_sparse_symv(&m->mass, p, mx);
        double res = 0, norm = 0;
        for (int i = 0; i < n; i++) {
            double d = kx[i] - w2 * mx[i];
            res += d * d;
            norm += kx[i] * kx[i];
        }
        double rel = norm > 0 ? sqrt(res / norm) : INFINITY;
        if (rel > out->max_residual) out->max_residual = rel;
        double *c = cphi + (size_t)r * n;
        rths_sparse_symv(&m->damping, p, c);
        out->damping_ratio[r] = dot(n, p, c) / (2 * out->omega_rad_s[r]);
    }
    /* how far the modes are from decoupling C (0 for Rayleigh damping): the modal FRF's
     * assumption, checked */
    for (int r = 0; r < found && !rc; r++)
        for (int s = 0; s < r; s++) {
            double crs = dot(n, phi + (size_t)r * n, cphi + (size_t)s * n);
            double crr = 2 * out->omega_rad_s[r] * out->damping_ratio[r],
                   css = 2 * out->omega_rad_s[s] * out->damping_ratio[s];
            double scale = sqrt(fabs(crr * css));
            double coupling = scale > 0 ? fabs(crs) / scale : (crs != 0 ? INFINITY : 0);
            if (coupling > out->max_damping_coupling) out->max_damping_coupling = coupling;
        }
    /* The static response K^-1 f and its next moment K^-1 M K^-1 f (rths_sparse_frf_create),
     * while the factor is still that of K (shift 0) */
    out->static_x = malloc(sizeof(double) * (size_t)n);
    out->static_y = malloc(sizeof(double) * (size_t)n);
    if (!rc && (!out->static_x || !out->static_y))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory after the sparse eigensolver");
    if (!rc && opt.shift != 0) {
        double k_only[2] = {1, 0};
        rc = rths_sparse_factor_real(f, k_only, err);
    }
    if (!rc) {
        memcpy(out->static_x, m->force, sizeof(double) * (size_t)n);
        rc = rths_sparse_solve_real(f, out->static_x, 1, err);
    }
    if (!rc) {
        rths_sparse_symv(&m->mass, out->static_x, out->static_y);
        rc = rths_sparse_solve_real(f, out->static_y, 1, err);
    }
    /* Sturm count: the inertia of K - s M with s just above the last eigenvalue found is the
     * number of eigenvalues up to it: `count` when Lanczos missed none below (a larger count also
     * flags the partner of a double eigenvalue left out). One more numerical factorisation of the
     * kept factor (and one back to K when the caller keeps it). */
    if (!rc) {
        out->sturm_shift = lambda[found - 1] * (1 + 1e-7);
        double coef[2] = {1, -out->sturm_shift};
        rc = rths_sparse_factor_real(f, coef, err);
        if (!rc) out->sturm_below = rths_sparse_factor_negative_pivots(f);
        double k_only[2] = {1, 0};
        if (!rc && k_factor) rc = rths_sparse_factor_real(f, k_only, err);
    }
done:
    out->check_s = rths_monotonic_s() - t0;
    free(lambda);
    free(cphi);
    free(kx);
    free(mx);
    if (rc) {
        rths_sparse_factor_destroy(f);
        rths_sparse_modes_free(out);
        return rc;
    }
    if (k_factor)
        *k_factor = f;
    else
        rths_sparse_factor_destroy(f);
    return RTHS_OK;
}

/* ---- FRF ---- */

/* Frequencies whose sparse direct solves are kept. A complex LDL^T of a 60 000-DoF model takes
 * 16-25 s (docs/architecture.md, "Sparse algebra"), and the same frequencies come back: every
 * period of every evaluation at one forcing frequency converts the numerical side at its
 * RTHS_MAX_HARMONICS harmonics (the frequency form), and the truth is asked at each point by
 * frf.csv, the summary and the figures in turn. Exact equality of omega is the key: the callers
 * form the same product k * 2 pi f each time. */
#define DIRECT_CACHE 32

/* The slot holding omega in a cache of `count` frequencies, or -1. */
static int cache_find(const double *omegas, int count, double omega) {
    for (int i = 0; i < count; i++)
        if (omegas[i] == omega) return i;
    return -1;
}

struct rths_sparse_frf {
    const rths_sparse_model *model;
    int n_out, count;
    int *out_dofs;
    double *omega2, *two_zeta_omega; /* count */
    double *modal_out;               /* count x n_out: phi_r(out_o) p_r */
    double *residual_out;            /* n_out: static response of the modes not computed */
    double *residual2_out; /* n_out: their next moment, times w^2 (sparse_model.c, frf_create) */
    rths_sparse_factor *complex_factor;
    const rths_sparse_sym *terms[3];
    double complex *rhs;
    double direct_s;
    /* the direct solves of the last DIRECT_CACHE frequencies at out_dofs (cached_x: n_out each),
     * replaced round robin: a frequency asked again costs no factorisation (sparse_cache) */
    double cached_omega[DIRECT_CACHE];
    double complex *cached_x;
    int cached, cache_next;
};

void rths_sparse_frf_destroy(rths_sparse_frf *s) {
    if (!s) return;
    free(s->out_dofs);
    free(s->omega2);
    free(s->two_zeta_omega);
    free(s->modal_out);
    free(s->residual_out);
    free(s->residual2_out);
    free(s->rhs);
    free(s->cached_x);
    rths_sparse_factor_destroy(s->complex_factor);
    free(s);
}

int rths_sparse_frf_create(const rths_sparse_model *m, const rths_sparse_modes *modes, int n_out,
                           const int *out_dofs, rths_sparse_frf **out, rths_error *err) {
    *out = NULL;
    int n = m->n, count = modes ? modes->count : 0;
    rths_sparse_frf *s = calloc(1, sizeof *s);
    if (!s) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    s->model = m;
    s->n_out = n_out;
    s->count = count;
    s->out_dofs = malloc(sizeof(int) * (size_t)(n_out > 0 ? n_out : 1));
    s->omega2 = malloc(sizeof(double) * (size_t)(count + 1));
    s->two_zeta_omega = malloc(sizeof(double) * (size_t)(count + 1));
    s->modal_out = malloc(sizeof(double) * (size_t)(count + 1) * (size_t)(n_out + 1));
    s->residual_out = calloc((size_t)n_out + 1, sizeof(double));
    s->residual2_out = calloc((size_t)n_out + 1, sizeof(double));
    int rc = s->out_dofs && s->omega2 && s->two_zeta_omega && s->modal_out && s->residual_out &&
                     s->residual2_out
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) memcpy(s->out_dofs, out_dofs, sizeof(int) * (size_t)n_out);
    if (!rc && modes) {
        /* The modes not computed (j) respond with sum_j phi_j p_j / (w_j^2 - w^2), expanded in
         * w^2 / w_j^2 (undamped: their damping changes it by 2 z_j w / w_j, below the first
         * term's error): sum_j phi_j p_j / w_j^2 + w^2 sum_j phi_j p_j / w_j^4 + ...; the two
         * sums are the static response K^-1 f and its next moment K^-1 M K^-1 f
         * (rths_sparse_model_modes solved them), each less what the computed modes carry of
         * them. The error left is of order (w / w_first dropped)^4 of the dropped modes' static
         * share. */
        const double *x = modes->static_x, *y = modes->static_y;
        for (int o = 0; o < n_out && !rc; o++) {
            s->residual_out[o] = x[out_dofs[o]];
            s->residual2_out[o] = y[out_dofs[o]];
        }
        for (int r = 0; r < count && !rc; r++) {
            const double *phi = modes->shapes + (size_t)r * n;
            double p = dot(n, phi, m->force);
            s->omega2[r] = modes->omega_rad_s[r] * modes->omega_rad_s[r];
            s->two_zeta_omega[r] = 2 * modes->damping_ratio[r] * modes->omega_rad_s[r];
            for (int o = 0; o < n_out; o++) {
                double c = phi[out_dofs[o]] * p;
                s->modal_out[(size_t)r * n_out + o] = c;
                s->residual_out[o] -= c / s->omega2[r];
                s->residual2_out[o] -= c / (s->omega2[r] * s->omega2[r]);
            }
        }
    }
    if (rc) {
        rths_sparse_frf_destroy(s);
        return rc;
    }
    *out = s;
    return RTHS_OK;
}

int rths_sparse_frf_eval(rths_sparse_frf *s, double omega_rad_s, double complex *x_out,
                         rths_error *err) {
    if (s->model->frf_direct) return rths_sparse_frf_direct(s, omega_rad_s, x_out, err);
    double w = omega_rad_s;
    for (int o = 0; o < s->n_out; o++)
        x_out[o] = s->residual_out[o] + w * w * s->residual2_out[o];
    for (int r = 0; r < s->count; r++) {
        double complex h = 1.0 / (s->omega2[r] - w * w + I * s->two_zeta_omega[r] * w);
        const double *c = s->modal_out + (size_t)r * s->n_out;
        for (int o = 0; o < s->n_out; o++)
            x_out[o] += c[o] * h;
    }
    return RTHS_OK;
}

int rths_sparse_frf_direct(rths_sparse_frf *s, double omega_rad_s, double complex *x_out,
                           rths_error *err) {
    const rths_sparse_model *m = s->model;
    int hit = cache_find(s->cached_omega, s->cached, omega_rad_s);
    if (hit >= 0) {
        memcpy(x_out, s->cached_x + (size_t)hit * s->n_out, sizeof *x_out * (size_t)s->n_out);
        return RTHS_OK;
    }
    double t0 = rths_monotonic_s();
    int rc = RTHS_OK;
    if (!s->complex_factor) {
        s->terms[0] = &m->stiffness;
        s->terms[1] = &m->damping;
        s->terms[2] = &m->mass;
        /* each only once: a retry after a failure here must not leak the first */
        if (!s->rhs) s->rhs = malloc(sizeof(double complex) * (size_t)m->n);
        if (!s->cached_x)
            s->cached_x = malloc(sizeof(double complex) * (size_t)(s->n_out > 0 ? s->n_out : 1) *
                                 DIRECT_CACHE);
        if (!s->rhs || !s->cached_x) return rths_error_set(err, RTHS_EFAIL, "out of memory");
        rc =
            rths_sparse_factor_create(3, s->terms, RTHS_SPARSE_ORDER_AUTO, &s->complex_factor, err);
        if (rc) return rc;
    }
    double w = omega_rad_s;
    double complex coef[3] = {1, I * w, -w * w};
    rc = rths_sparse_factor_complex(s->complex_factor, coef, err);
    for (int i = 0; i < m->n && !rc; i++)
        s->rhs[i] = m->force[i];
    if (!rc) rc = rths_sparse_solve_complex(s->complex_factor, s->rhs, 1, err);
    for (int o = 0; o < s->n_out && !rc; o++)
        x_out[o] = s->rhs[s->out_dofs[o]];
    if (!rc) {
        int slot = s->cache_next;
        s->cache_next = (s->cache_next + 1) % DIRECT_CACHE;
        if (s->cached < DIRECT_CACHE) s->cached++;
        s->cached_omega[slot] = omega_rad_s;
        memcpy(s->cached_x + (size_t)slot * s->n_out, x_out, sizeof *x_out * (size_t)s->n_out);
    }
    s->direct_s += rths_monotonic_s() - t0;
    return rc;
}

double rths_sparse_frf_direct_s(const rths_sparse_frf *s) {
    return s ? s->direct_s : 0;
}

/* ---- the numerical substructure ---- */

int rths_sparse_model_numerical_side(const rths_sparse_model *m, rths_sparse_sym *mass,
                                     rths_sparse_sym *damping, rths_sparse_sym *stiffness,
                                     int **dofs_out, int *nn_out, rths_error *err) {
    int n = m->n, nn = 0;
    memset(mass, 0, sizeof *mass);
    memset(damping, 0, sizeof *damping);
    memset(stiffness, 0, sizeof *stiffness);
    *dofs_out = NULL;
    *nn_out = 0;
    int *map = malloc(sizeof(int) * (size_t)n), *dofs = malloc(sizeof(int) * (size_t)n);
    double *diag = calloc((size_t)n, sizeof(double));
    const rths_sparse_sym *src[3] = {&m->mass, &m->damping, &m->stiffness};
    rths_sparse_sym *dst[3] = {mass, damping, stiffness};
    long cap = 0;
    for (int k = 0; k < 3; k++)
        if (src[k]->colptr[n] + n + m->n_int * m->n_int > cap)
            cap = src[k]->colptr[n] + n + m->n_int * m->n_int;
    int *ti = malloc(sizeof(int) * (size_t)cap), *tj = malloc(sizeof(int) * (size_t)cap);
    double *tv = malloc(sizeof(double) * (size_t)cap);
    int rc = map && dofs && diag && ti && tj && tv
                 ? RTHS_OK
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    /* the split's order: interface DoFs, then the internal numerical ones, each ascending */
    for (int pass = 0; pass < 2 && !rc; pass++)
        for (int i = 0; i < n; i++) {
            rths_dof_role want = pass == 0 ? RTHS_DOF_INTERFACE : RTHS_DOF_NUMERICAL;
            if (pass == 0) map[i] = -1;
            if (m->roles[i] == want) map[i] = nn, dofs[nn++] = i;
        }
    for (int k = 0; k < 3 && !rc; k++) {
        const rths_sparse_sym *a = src[k];
        /* given physical shares of C_II, K_II: the numerical side takes the rest of the block */
        const double *share = k == 1   ? m->interface_damping_phys
                              : k == 2 ? m->interface_stiffness_phys
                                       : NULL;
        long t = 0;
        memset(diag, 0, sizeof(double) * (size_t)n);
        for (int j = 0; j < n; j++)
            for (int e = a->colptr[j]; e < a->colptr[j + 1]; e++) {
                int i = a->rowidx[e];
                if (map[i] < 0 || map[j] < 0) continue;
                int ii = m->roles[i] == RTHS_DOF_INTERFACE, ij = m->roles[j] == RTHS_DOF_INTERFACE;
                double v = a->value[e];
                if (ii && ij && share) {
                    ti[t] = map[i], tj[t] = map[j], tv[t++] = v;
                    continue;
                }
                if (ii && ij) {
                    /* the interface block: p M_II of the mass (rths_split_create); of C and K
                     * only what joins the interface to numerical DoFs (the coupling rule,
                     * added below) */
                    if (k == 0) ti[t] = map[i], tj[t] = map[j], tv[t++] = m->mass_ratio * v;
                    continue;
                }
                if (k > 0 && !share && ii != ij) diag[ii ? i : j] -= v;
                ti[t] = map[i], tj[t] = map[j], tv[t++] = v;
            }
        if (k > 0 && !share)
            for (int d = 0; d < m->n_int; d++)
                ti[t] = tj[t] = map[m->int_dofs[d]], tv[t++] = diag[m->int_dofs[d]];
        for (int d = 0; share && d < m->n_int; d++) /* lower triangle: mirrored by the reader */
            for (int e = 0; e <= d; e++)
                ti[t] = map[m->int_dofs[d]], tj[t] = map[m->int_dofs[e]],
                tv[t++] = -share[d + e * m->n_int];
        rc = rths_sparse_from_triplets(nn, t, ti, tj, tv, dst[k], err);
    }
    free(map);
    free(diag);
    free(ti);
    free(tj);
    free(tv);
    if (rc) {
        free(dofs);
        for (int k = 0; k < 3; k++)
            rths_sparse_free(dst[k]);
        return rc;
    }
    *dofs_out = dofs;
    *nn_out = nn;
    return RTHS_OK;
}

/* ---- the frequency form's numerical substructure (model.h) ---- */

struct rths_sparse_model_receptance {
    rths_sparse_sym mass, damping, stiffness; /* the numerical side, interface first */
    const rths_sparse_sym *terms[3];
    rths_sparse_factor *factor;
    double *load;      /* nn: the numerical side's share of the forcing, per unit amplitude */
    double complex *x; /* nn */
    double solve_s;
    /* the last DIRECT_CACHE frequencies' results, replaced round robin (sparse_frf's cache) */
    double cached_omega[DIRECT_CACHE];
    double complex cached_h[DIRECT_CACHE], cached_forced[DIRECT_CACHE];
    int cached, cache_next;
};

void rths_sparse_model_receptance_destroy(rths_sparse_model_receptance *r) {
    if (!r) return;
    if (r->factor) rths_sparse_factor_destroy(r->factor);
    rths_sparse_free(&r->mass);
    rths_sparse_free(&r->damping);
    rths_sparse_free(&r->stiffness);
    free(r->load);
    free(r->x);
    free(r);
}

int rths_sparse_model_receptance_create(const rths_sparse_model *m,
                                        rths_sparse_model_receptance **out, rths_error *err) {
    *out = NULL;
    if (m->n_int != 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "the host-side numerical substructure takes one interface DoF; this "
                              "split has %d (split.interface)",
                              m->n_int);
    rths_sparse_model_receptance *r = calloc(1, sizeof *r);
    if (!r) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int *dofs = NULL, nn = 0;
    int rc =
        rths_sparse_model_numerical_side(m, &r->mass, &r->damping, &r->stiffness, &dofs, &nn, err);
    if (!rc) {
        r->load = calloc((size_t)nn, sizeof(double));
        r->x = malloc(sizeof(double complex) * (size_t)nn);
        if (!r->load || !r->x) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    if (!rc && m->base_excitation) {
        double *ones = malloc(sizeof(double) * (size_t)nn);
        if (!ones) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        for (int i = 0; i < nn && !rc; i++)
            ones[i] = 1.0;
        if (!rc) rths_sparse_symv(&r->mass, ones, r->load);
        for (int i = 0; i < nn && !rc; i++)
            r->load[i] = -r->load[i];
        free(ones);
    } else if (!rc) {
        for (int i = 0; i < nn; i++)
            if (dofs[i] == m->forcing_dof) r->load[i] = 1.0;
    }
    free(dofs);
    r->terms[0] = &r->stiffness;
    r->terms[1] = &r->damping;
    r->terms[2] = &r->mass;
    if (!rc) rc = rths_sparse_factor_create(3, r->terms, RTHS_SPARSE_ORDER_AUTO, &r->factor, err);
    if (rc) {
        rths_sparse_model_receptance_destroy(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}

int rths_sparse_model_receptance_eval(void *ctx, double omega_rad_s,
                                      double complex *receptance_m_per_n,
                                      double complex *forced_m_per_n, rths_error *err) {
    rths_sparse_model_receptance *r = ctx;
    int hit = cache_find(r->cached_omega, r->cached, omega_rad_s);
    if (hit >= 0) {
        *receptance_m_per_n = r->cached_h[hit];
        *forced_m_per_n = r->cached_forced[hit];
        return RTHS_OK;
    }
    double t0 = rths_monotonic_s(), w = omega_rad_s;
    int nn = r->stiffness.n;
    double complex coef[3] = {1, I * w, -w * w};
    int rc = rths_sparse_factor_complex(r->factor, coef, err);
    if (!rc) {
        memset(r->x, 0, sizeof(double complex) * (size_t)nn);
        r->x[0] = 1; /* the interface: the numerical side's first DoF */
        rc = rths_sparse_solve_complex(r->factor, r->x, 1, err);
    }
    if (!rc) {
        double complex forced = 0;
        for (int i = 0; i < nn; i++)
            forced += r->x[i] * r->load[i];
        *receptance_m_per_n = r->x[0];
        *forced_m_per_n = forced;
        int slot = r->cache_next;
        r->cache_next = (r->cache_next + 1) % DIRECT_CACHE;
        if (r->cached < DIRECT_CACHE) r->cached++;
        r->cached_omega[slot] = omega_rad_s;
        r->cached_h[slot] = r->x[0];
        r->cached_forced[slot] = forced;
    }
    r->solve_s += rths_monotonic_s() - t0;
    return rc;
}

double rths_sparse_model_receptance_s(const rths_sparse_model_receptance *r, int *analyses) {
    if (analyses) *analyses = r->factor ? rths_sparse_factor_get_stats(r->factor).analyses : 0;
    return r->solve_s;
}

/* ---- the physical substructure (model.h) ---- */

int rths_sparse_model_physical_side(const rths_sparse_model *m, int max_np, double **mass,
                                    double **damping, double **stiffness, int *np_out,
                                    rths_error *err) {
    *mass = *damping = *stiffness = NULL;
    *np_out = 0;
    int n_phys = 0;
    for (int i = 0; i < m->n; i++)
        n_phys += m->roles[i] == RTHS_DOF_PHYSICAL;
    int np = n_phys + m->n_int;
    if (np > max_np)
        return rths_error_set(err, RTHS_EINPUT,
                              "the physical substructure has %d DoFs, more than the %d a rig's "
                              "dense model takes (split.physical)",
                              np, max_np);
    rths_sparse_sym num[3];
    int *dofs = NULL, nn = 0;
    int rc = rths_sparse_model_numerical_side(m, &num[0], &num[1], &num[2], &dofs, &nn, err);
    if (rc) return rc;
    free(dofs); /* the numerical side's first n_int DoFs are the interface, ascending */
    int *pd = malloc(sizeof(int) * (size_t)(np > 0 ? np : 1));
    double *out[3] = {rths_mat_new(np, np), rths_mat_new(np, np), rths_mat_new(np, np)};
    if (!pd || !out[0] || !out[1] || !out[2]) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    const rths_sparse_sym *full[3] = {&m->mass, &m->damping, &m->stiffness};
    for (int i = 0, q = 0; i < m->n && !rc; i++)
        if (m->roles[i] == RTHS_DOF_PHYSICAL) pd[q++] = i;
    for (int d = 0; d < m->n_int && !rc; d++)
        pd[n_phys + d] = m->int_dofs[d];
    for (int t = 0; t < 3 && !rc; t++)
        for (int j = 0; j < np; j++)
            for (int i = 0; i < np; i++) {
                double v = rths_sparse_get(full[t], pd[i], pd[j]);
                if (i >= n_phys && j >= n_phys)
                    v -= rths_sparse_get(&num[t], i - n_phys, j - n_phys);
                RTHS_AT(out[t], np, i, j) = v;
            }
    free(pd);
    for (int t = 0; t < 3; t++)
        rths_sparse_free(&num[t]);
    if (rc) {
        for (int t = 0; t < 3; t++)
            rths_mat_free(out[t]);
        return rc;
    }
    *mass = out[0], *damping = out[1], *stiffness = out[2];
    *np_out = np;
    return RTHS_OK;
}
