/* The structural part of a test configuration: structure, split, forcing, model.frf.
 * Every value is checked here, against the key it came from, so a user sees FILE:LINE:COL and the
 * key for each mistake before any work starts. */
#include "rths/setup.h"

#include "setup_internal.h"

#include "rths/beam.h"
#include "rths/mtx.h"
#include "rths/signals.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define K_STOREYS "structure.storeys"
#define K_MATRICES "structure.matrices"
/* Entries beyond this magnitude (kg, N s/m, N/m) are no structure, and K - w^2 M would overflow
 * (a 1e308 kg storey gave NaN rows). */
#define MAX_ENTRY 1e15
/* The smallest storey mass and leg stiffness taken (kg, N/m): below them a chain is no lab's
 * structure, and its modes leave every range the analysis resolves (a 1e-300 kg storey had a mode
 * at 5e151 Hz and NaN in the outputs). */
#define MIN_STOREY_MASS_KG 1e-6
#define MIN_STOREY_STIFFNESS_N_PER_M 1e-6
/* The smallest diagonal entry of a given mass matrix: kg on a displacement, kg m^2 on a rotation
 * (a millimetre beam element's rotary inertia is ~1e-10 kg m^2). */
#define MIN_DIAGONAL_MASS 1e-12
/* ... and of a given stiffness matrix (N/m, or N m/rad on a rotation): a 1e-300 N/m support makes
 * a mode at 1e-150 Hz and a static response of 1e300 m */
#define MIN_DIAGONAL_STIFFNESS 1e-12

static int read_chain(rths_config *cfg, rths_setup *s, rths_error *err) {
    static const char *const keys[3] = {K_STOREYS ".mass_kg", K_STOREYS ".damping_n_s_per_m",
                                        K_STOREYS ".stiffness_n_per_m"};
    /* damping may be zero (an undamped leg); mass and stiffness must be positive, and above a
     * floor a lab's structure is far from */
    static const int must_be_positive[3] = {1, 0, 1};
    static const double floor_of[3] = {MIN_STOREY_MASS_KG, 0, MIN_STOREY_STIFFNESS_N_PER_M};
    static const char *const unit_of[3] = {"kg", "N s/m", "N/m"};
    double *v[3] = {NULL, NULL, NULL};
    int count[3] = {0, 0, 0};
    int rc = RTHS_OK;
    for (int k = 0; k < 3 && !rc; k++)
        rc = rths_config_get_double_list(cfg, keys[k], 1, &v[k], &count[k], err);
    for (int k = 0; k < 3 && !rc; k++) {
        if (count[k] != count[0])
            rc = rths_config_error_at(cfg, keys[k], err,
                                      "has %d entries but %s has %d: one per storey", count[k],
                                      keys[0], count[0]);
        else if (count[k] < 1)
            rc = rths_config_error_at(cfg, keys[k], err, "needs at least one storey");
        for (int i = 0; i < count[k] && !rc; i++) {
            if ((must_be_positive[k] ? !(v[k][i] >= floor_of[k]) : !(v[k][i] >= 0)) ||
                !(v[k][i] <= MAX_ENTRY)) {
                char floor_text[48] = "";
                if (must_be_positive[k])
                    snprintf(floor_text, sizeof floor_text, ", at least %g %s", floor_of[k],
                             unit_of[k]);
                rc = rths_config_error_at(cfg, keys[k], err,
                                          "storey %d: must be %s and <= %g %s%s (got %g)", i + 1,
                                          must_be_positive[k] ? "> 0" : ">= 0", MAX_ENTRY,
                                          unit_of[k], floor_text, v[k][i]);
            }
        }
    }
    if (!rc) rc = rths_assembly_from_chain(count[0], v[0], v[1], v[2], &s->assembly, err);
    for (int k = 0; k < 3; k++)
        free(v[k]);
    s->chain = 1;
    return rc;
}

/* Path of a file named in the config: relative names are taken from the config file's folder. */
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

/* One matrix key: a list of rows, or a string naming a Matrix Market file (mtx_checks: what the
 * reader checks on the file's entries before it forms the dense matrix, rths_mtx_read_checked). */
static int read_matrix_key(rths_config *cfg, const char *key, int mtx_checks, double **m, int *rows,
                           int *cols, int *from_file, rths_error *err) {
    const char *name = NULL;
    rths_error local;
    *from_file = 0;
    if (rths_config_get_string(cfg, key, 1, NULL, &name, &local) != RTHS_OK || !name)
        return rths_config_get_matrix(cfg, key, 1, m, rows, cols, err);
    char *path = config_relative_path(cfg, name);
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = rths_mtx_read_checked(path, mtx_checks, m, rows, cols, &local);
    free(path);
    *from_file = 1;
    if (rc == RTHS_EINPUT) return rths_config_error_at(cfg, key, err, "%s", local.msg);
    if (rc) *err = local;
    return rc;
}

/* Physical sense of (M, C, K), checked before any work so nothing is written for a structure
 * that cannot be analysed: finite entries of plausible size, symmetric, M and K positive definite
 * (K singular means a rigid-body mode: no static position, an infinite response at 0 Hz), C
 * positive semi-definite (a negative eigenvalue feeds energy in). */
static int check_physical(rths_config *cfg, const char *const *keys, double *const *m, int n,
                          rths_error *err) {
    for (int k = 0; k < 3; k++) {
        for (size_t e = 0; e < (size_t)n * (size_t)n; e++)
            if (!(fabs(m[k][e]) <= MAX_ENTRY))
                return rths_config_error_at(cfg, keys[k], err,
                                            "entry (%zu, %zu) = %g is not a finite number of "
                                            "magnitude <= %g",
                                            e % (size_t)n + 1, e / (size_t)n + 1, m[k][e],
                                            MAX_ENTRY);
        if (!rths_mat_is_symmetric(m[k], n, 1e-12))
            return rths_config_error_at(cfg, keys[k], err, "must be symmetric");
    }
    for (int i = 0; i < n; i++)
        if (!(RTHS_AT(m[0], n, i, i) >= MIN_DIAGONAL_MASS))
            return rths_config_error_at(cfg, keys[0], err,
                                        "diagonal entry (%d, %d) = %g is below %g (kg, or kg m^2 "
                                        "on a rotation): no lab's structure is that light, and "
                                        "its modes would leave every frequency range analysed",
                                        i + 1, i + 1, RTHS_AT(m[0], n, i, i), MIN_DIAGONAL_MASS);
    for (int i = 0; i < n; i++)
        if (!(RTHS_AT(m[2], n, i, i) >= MIN_DIAGONAL_STIFFNESS))
            return rths_config_error_at(cfg, keys[2], err,
                                        "diagonal entry (%d, %d) = %g is below %g (N/m, or N m/rad "
                                        "on a rotation): a support that soft has a mode near 0 Hz "
                                        "and a static response beyond any rig",
                                        i + 1, i + 1, RTHS_AT(m[2], n, i, i),
                                        MIN_DIAGONAL_STIFFNESS);
    if (!rths_mat_is_spd(m[0], n))
        return rths_config_error_at(cfg, keys[0], err,
                                    "must be positive definite (a mass matrix with a zero or "
                                    "negative mode has no dynamics)");
    if (!rths_mat_is_spd(m[2], n))
        return rths_config_error_at(cfg, keys[2], err,
                                    "must be positive definite: a zero or negative stiffness mode "
                                    "(rigid-body motion, an unsupported structure) has no static "
                                    "position and an unbounded response at low frequency");
    /* C >= 0: Cholesky of C + delta I, delta far above rounding and far below any real damping */
    double cmax = rths_mat_max_abs(m[1], n, n);
    if (cmax > 0) {
        double *shifted = rths_mat_dup(m[1], n, n);
        if (!shifted) return rths_error_set(err, RTHS_EFAIL, "out of memory");
        for (int i = 0; i < n; i++)
            RTHS_AT(shifted, n, i, i) += 1e-9 * cmax;
        int psd = rths_mat_is_spd(shifted, n);
        rths_mat_free(shifted);
        if (!psd)
            return rths_config_error_at(cfg, keys[1], err,
                                        "must be positive semi-definite: a negative damping mode "
                                        "feeds energy into the structure");
    }
    return RTHS_OK;
}

int rths_setup_read_matrices(rths_config *cfg, rths_setup *s, rths_error *err) {
    static const char *const keys[3] = {K_MATRICES ".mass_kg", K_MATRICES ".damping_n_s_per_m",
                                        K_MATRICES ".stiffness_n_per_m"};
    double *m[3] = {NULL, NULL, NULL};
    int rows[3] = {0, 0, 0}, cols[3] = {0, 0, 0}, from_file = 0;
    /* a mass or stiffness file without a positive diagonal term is refused from its entries: a
     * few bytes declaring 12000 x 12000 cost 80 s and 4.5 GB before the dense check refused them */
    const int checks[3] = {RTHS_MTX_POSITIVE_DIAGONAL, 0, RTHS_MTX_POSITIVE_DIAGONAL};
    int rc = RTHS_OK;
    for (int k = 0; k < 3 && !rc; k++) {
        rc = read_matrix_key(cfg, keys[k], checks[k], &m[k], &rows[k], &cols[k], &from_file, err);
        if (rc) break;
        if (rows[k] != cols[k] || rows[k] < 1)
            rc = rths_config_error_at(cfg, keys[k], err, "must be square (got %d x %d)", rows[k],
                                      cols[k]);
        else if (rows[k] != rows[0])
            rc = rths_config_error_at(cfg, keys[k], err, "is %d x %d but %s is %d x %d", rows[k],
                                      cols[k], keys[0], rows[0], cols[0]);
    }
    if (!rc) rc = check_physical(cfg, keys, m, rows[0], err);
    if (!rc) rc = rths_assembly_from_matrices(rows[0], m[0], m[1], m[2], &s->assembly, err);
    for (int k = 0; k < 3; k++)
        free(m[k]);
    s->chain = 0;
    return rc;
}

/* 1-based DoF list -> roles; refuses out-of-range and repeated DoFs. */
static int assign_roles(rths_config *cfg, const char *key, const int *dofs, int count,
                        rths_dof_role role, int *assigned, rths_setup *s, rths_error *err) {
    int n = s->assembly.n;
    for (int i = 0; i < count; i++) {
        if (dofs[i] < 1 || dofs[i] > n)
            return rths_config_error_at(cfg, key, err, "DoF %d is outside 1..%d", dofs[i], n);
        if (assigned[dofs[i] - 1])
            return rths_config_error_at(
                cfg, key, err, "DoF %d is listed twice (each DoF has exactly one side)", dofs[i]);
        assigned[dofs[i] - 1] = 1;
        s->roles[dofs[i] - 1] = role;
    }
    return RTHS_OK;
}

/* Sides of the DoFs not listed. A chain: below the interface physical, above it numerical (for
 * whichever list is absent). Matrices: every DoF neither physical nor interface is numerical when
 * split.numerical is absent, every DoF neither numerical nor interface physical when only
 * split.physical is. */
static int default_sides(rths_setup *s, const int *iface, int n_iface, int n_phys, int n_num,
                         int *assigned) {
    int n = s->assembly.n, lowest = n, highest = -1;
    for (int i = 0; i < n_iface; i++) {
        if (iface[i] - 1 < lowest) lowest = iface[i] - 1;
        if (iface[i] - 1 > highest) highest = iface[i] - 1;
    }
    for (int i = 0; i < n; i++) {
        if (assigned[i]) continue;
        if (!s->chain)
            s->roles[i] = n_num == 0 ? RTHS_DOF_NUMERICAL : RTHS_DOF_PHYSICAL;
        else if (i < lowest && n_phys == 0)
            s->roles[i] = RTHS_DOF_PHYSICAL;
        else if (i > highest && n_num == 0)
            s->roles[i] = RTHS_DOF_NUMERICAL;
        else
            continue;
        assigned[i] = 1;
    }
    return RTHS_OK;
}

static void sort_ints(int *v, int n) {
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && v[j - 1] > v[j]; j--) {
            int t = v[j];
            v[j] = v[j - 1];
            v[j - 1] = t;
        }
}

/* split.mass_ratio: one p in (0, 1) for every interface DoF, or a list of one p per interface
 * DoF (in the order of split.interface; *ratios then holds them in the split's ascending DoF
 * order). p is the numerical share of the interface mass: both sides must keep some of it. */
static int read_mass_ratios(rths_config *cfg, int n_iface, const int *iface, double *p,
                            double **ratios, int *n_ratios, rths_error *err) {
    static const char *const key = "split.mass_ratio";
    double *list = NULL;
    int count = 0;
    rths_error local;
    int lrc = rths_config_get_double_list(cfg, key, 0, &list, &count, &local);
    if (lrc != RTHS_OK || count == 0) {
        free(list);
        *n_ratios = 1;
        /* a list with a bad entry: its own message, not the scalar reader's "got a list" */
        if (lrc != RTHS_OK && !strstr(local.msg, "expected a list")) {
            *err = local;
            return lrc;
        }
        return rths_config_get_double_ex(cfg, key, 1, 0.5, 0, 1,
                                         RTHS_CONFIG_LO_OPEN | RTHS_CONFIG_HI_OPEN, p, err);
    }
    if (count != n_iface) {
        free(list);
        return rths_config_error_at(cfg, key, err,
                                    "lists %d mass ratios for %d interface DoFs: give one p, or "
                                    "one per interface DoF",
                                    count, n_iface);
    }
    for (int i = 0; i < count; i++)
        if (!(list[i] > 0 && list[i] < 1)) {
            double bad = list[i];
            free(list);
            return rths_config_error_at(cfg, key, err,
                                        "entry %d: must be in (0, 1), the numerical share of the "
                                        "interface DoF's mass (got %g)",
                                        i + 1, bad);
        }
    /* into the split's order: ascending DoF number */
    *ratios = malloc(sizeof(double) * (size_t)(count > 0 ? count : 1));
    if (!*ratios) {
        free(list);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int i = 0; i < count; i++) {
        int rank = 0;
        for (int j = 0; j < count; j++)
            rank += iface[j] < iface[i];
        (*ratios)[rank] = list[i];
    }
    *p = (*ratios)[0];
    *n_ratios = count;
    free(list);
    return RTHS_OK;
}

static int read_split(rths_config *cfg, rths_setup *s, rths_error *err) {
    int n = s->assembly.n;
    int *iface = NULL, *phys = NULL, *num = NULL, n_iface = 0, n_phys = 0, n_num = 0;
    int *assigned = calloc((size_t)n, sizeof *assigned);
    s->roles = calloc((size_t)n, sizeof *s->roles);
    double p = 0, *c_int = NULL, *k_int = NULL;
    int rc = (assigned && s->roles) ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) rc = rths_config_get_int_list(cfg, "split.interface", 1, &iface, &n_iface, err);
    if (!rc && n_iface < 1)
        rc = rths_config_error_at(cfg, "split.interface", err, "needs at least one DoF");
    if (!rc)
        rc = assign_roles(cfg, "split.interface", iface, n_iface, RTHS_DOF_INTERFACE, assigned, s,
                          err);
    double *ratios = NULL;
    int n_ratios = 1;
    if (!rc) rc = read_mass_ratios(cfg, n_iface, iface, &p, &ratios, &n_ratios, err);
    if (!rc) rc = rths_config_get_int_list(cfg, "split.physical", 0, &phys, &n_phys, err);
    if (!rc) rc = rths_config_get_int_list(cfg, "split.numerical", 0, &num, &n_num, err);
    if (!rc)
        rc = assign_roles(cfg, "split.physical", phys, n_phys, RTHS_DOF_PHYSICAL, assigned, s, err);
    if (!rc)
        rc = assign_roles(cfg, "split.numerical", num, n_num, RTHS_DOF_NUMERICAL, assigned, s, err);
    if (!rc && (n_phys == 0 || n_num == 0))
        rc = default_sides(s, iface, n_iface, n_phys, n_num, assigned);
    for (int i = 0; i < n && !rc; i++)
        if (!assigned[i])
            rc = rths_config_error_at(cfg, "split", err,
                                      "DoF %d is on no side: list it in split.physical or "
                                      "split.numerical",
                                      i + 1);
    int r = 0, c = 0;
    if (!rc && rths_config_has(cfg, "split.interface_damping_physical_n_s_per_m")) {
        rc = rths_config_get_matrix(cfg, "split.interface_damping_physical_n_s_per_m", 1, &c_int,
                                    &r, &c, err);
        if (!rc && (r != n_iface || c != n_iface))
            rc = rths_config_error_at(cfg, "split.interface_damping_physical_n_s_per_m", err,
                                      "must be %d x %d (one row per interface DoF)", n_iface,
                                      n_iface);
    }
    if (!rc && rths_config_has(cfg, "split.interface_stiffness_physical_n_per_m")) {
        rc = rths_config_get_matrix(cfg, "split.interface_stiffness_physical_n_per_m", 1, &k_int,
                                    &r, &c, err);
        if (!rc && (r != n_iface || c != n_iface))
            rc = rths_config_error_at(cfg, "split.interface_stiffness_physical_n_per_m", err,
                                      "must be %d x %d (one row per interface DoF)", n_iface,
                                      n_iface);
    }
    /* a beam splits element by element unless the interface blocks are given */
    if (!rc && s->beam && !k_int && !c_int) {
        size_t ni = (size_t)(n_iface > 0 ? n_iface : 1);
        k_int = malloc(sizeof(double) * ni * ni);
        c_int = malloc(sizeof(double) * ni * ni);
        if (!k_int || !c_int) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        int *iface0 = rc ? NULL : malloc(sizeof(int) * ni);
        if (!rc && !iface0) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        for (int i = 0; !rc && i < n_iface; i++)
            iface0[i] = iface[i] - 1;
        /* the split orders the interface by DoF number: so do the shares */
        if (!rc) sort_ints(iface0, n_iface);
        if (!rc && !rths_beam_interface_shares(s->beam, s->roles, n_iface, iface0, c_int, k_int)) {
            free(c_int); /* modal damping: no element owns C (the split refuses its coupling) */
            c_int = NULL;
        }
        free(iface0);
    }
    if (!rc) {
        rths_error local;
        rc = rths_split_create_ratios(&s->assembly, s->roles, n_ratios, ratios ? ratios : &p, c_int,
                                      k_int, &s->split, &local);
        if (rc) rc = rths_config_error_at(cfg, "split", err, "%s", local.msg);
    }
    free(ratios);
    free(assigned);
    free(iface);
    free(phys);
    free(num);
    free(c_int);
    free(k_int);
    return rc;
}

/* forcing.type: base. In coordinates relative to the ground, a ground acceleration a_g drives
 * every DoF through its inertia: M x'' + C x' + K x = -M 1 a_g (the damping and stiffness act on
 * relative motion), so the forcing is distributed as -M 1 per m/s^2. */
static int read_base_forcing(rths_config *cfg, rths_setup *s, rths_error *err) {
    static const char *const force_keys[] = {"forcing.dof", "forcing.amplitude_n"};
    for (int i = 0; i < 2; i++)
        if (rths_config_has(cfg, force_keys[i]))
            return rths_config_error_at(cfg, force_keys[i], err,
                                        "applies to forcing.type: force only (base excitation "
                                        "takes forcing.amplitude_m_s2)");
    int n = s->assembly.n;
    int rc = rths_config_get_double_ex(cfg, "forcing.amplitude_m_s2", 0, 1.0, 0, 1e6,
                                       RTHS_CONFIG_LO_OPEN, &s->forcing_amplitude_n, err);
    if (rc) return rc;
    s->base_excitation = 1;
    s->forcing_dof = n - 1;
    s->force = calloc((size_t)n, sizeof *s->force);
    s->forcing_shape = calloc((size_t)n, sizeof *s->forcing_shape);
    if (!s->force || !s->forcing_shape) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < n; i++) {
        double row = 0;
        for (int j = 0; j < n; j++)
            row += RTHS_AT(s->assembly.mass, n, i, j);
        s->forcing_shape[i] = -row;
        s->force[i] = s->forcing_amplitude_n * s->forcing_shape[i];
    }
    return RTHS_OK;
}

static int read_forcing(rths_config *cfg, rths_setup *s, rths_error *err) {
    static const char *const types[] = {"force", "base", NULL};
    int type = 0;
    int rc = rths_config_get_choice(cfg, "forcing.type", 0, 0, types, &type, err);
    if (rc) return rc;
    if (type == 1) return read_base_forcing(cfg, s, err);
    if (rths_config_has(cfg, "forcing.amplitude_m_s2"))
        return rths_config_error_at(cfg, "forcing.amplitude_m_s2", err,
                                    "applies to forcing.type: base only");
    long dof = 0;
    int n = s->assembly.n;
    rc = rths_config_get_int(cfg, "forcing.dof", 1, 0, 1, n, &dof, err);
    if (!rc)
        rc = rths_config_get_double(cfg, "forcing.amplitude_n", 0, 1.0, 0, 1e9,
                                    &s->forcing_amplitude_n, err);
    if (!rc && !(s->forcing_amplitude_n > 0))
        rc = rths_config_error_at(cfg, "forcing.amplitude_n", err, "must be > 0 (got %g)",
                                  s->forcing_amplitude_n);
    if (rc) return rc;
    s->forcing_dof = (int)dof - 1;
    s->force = calloc((size_t)n, sizeof *s->force);
    s->forcing_shape = calloc((size_t)n, sizeof *s->forcing_shape);
    if (!s->force || !s->forcing_shape) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    s->force[s->forcing_dof] = s->forcing_amplitude_n;
    s->forcing_shape[s->forcing_dof] = 1.0;
    return RTHS_OK;
}

static int read_frf_range(rths_config *cfg, rths_setup *s, rths_error *err) {
    long points = 0;
    int rc = rths_config_get_double(cfg, "model.frf.start_hz", 0, 0, 0, 1e6, &s->frf_start_hz, err);
    if (!rc)
        rc = rths_config_get_double(cfg, "model.frf.end_hz", 0, 0, 0, 1e6, &s->frf_end_hz, err);
    if (!rc) rc = rths_config_get_int(cfg, "model.frf.points", 0, 0, 0, 10000000, &points, err);
    if (!rc && rths_config_has(cfg, "model.frf.points") && points < 2)
        rc = rths_config_error_at(cfg, "model.frf.points", err, "must be at least 2 (got %ld)",
                                  points);
    if (!rc && s->frf_end_hz > 0 && s->frf_end_hz <= s->frf_start_hz)
        rc = rths_config_error_at(cfg, "model.frf.end_hz", err,
                                  "must be above model.frf.start_hz (%g Hz), got %g Hz",
                                  s->frf_start_hz, s->frf_end_hz);
    s->frf_points = (int)points;
    return rc;
}

/* structure.beam: Euler-Bernoulli beam elements assembled into matrices (beam.h). The beam is
 * kept: its elements decide the split (rths_beam_interface_shares) and its nodes place the
 * actuators and lasers (rig.actuators.offset_m). */
static int read_beam(rths_config *cfg, rths_setup *s, rths_error *err) {
    s->beam = calloc(1, sizeof *s->beam);
    if (!s->beam) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = rths_beam_config_read(cfg, "structure.beam", s->beam, err);
    if (rc) return rc;
    rths_error local;
    rc = rths_beam_to_assembly(s->beam, &s->assembly, &local);
    if (rc) rc = rths_config_error_at(cfg, "structure.beam", err, "%s", local.msg);
    s->chain = 0;
    return rc;
}

/* Exactly one of structure.storeys, structure.matrices and structure.beam. */
static int read_structure(rths_config *cfg, rths_setup *s, rths_error *err) {
    static const char *const forms[3] = {K_STOREYS, K_MATRICES, "structure.beam"};
    int given = -1;
    for (int f = 0; f < 3; f++) {
        if (!rths_config_has(cfg, forms[f])) continue;
        if (given >= 0)
            return rths_config_error_at(cfg, forms[f], err,
                                        "%s and %s both given: give the structure as one of "
                                        "structure.storeys, structure.matrices or "
                                        "structure.beam, not both",
                                        forms[given], forms[f]);
        given = f;
    }
    if (given < 0)
        return rths_config_error_at(cfg, "structure", err,
                                    "%s: give structure.storeys (mass_kg, damping_n_s_per_m, "
                                    "stiffness_n_per_m lists), structure.matrices or "
                                    "structure.beam",
                                    rths_config_has(cfg, "structure") ? "must be a mapping"
                                                                      : "missing");
    return given == 0   ? read_chain(cfg, s, err)
           : given == 1 ? rths_setup_read_matrices_or_sparse(cfg, s, err)
                        : read_beam(cfg, s, err);
}

int rths_setup_read_numerical_solver(rths_config *cfg, rths_setup *s, rths_error *err) {
    static const char *const solvers[] = {"realtime", "frequency", NULL};
    int solver = RTHS_NUMERICAL_REALTIME;
    int rc =
        rths_config_get_choice(cfg, "split.numerical_solver", 0, solver, solvers, &solver, err);
    s->numerical_solver = (rths_numerical_solver)solver;
    return rc;
}

/* ---- rig.actuators, rig.lasers: actuator and sensor transforms ---- */

/* Direction from the cut into the physical part of a beam cut at one node whose interface is its
 * (w, theta): +1 when the physical elements lie at larger x, -1 at smaller x; 0 when the
 * interface is not one node's w and theta (offsets do not apply). */
static int beam_cut_direction(const rths_setup *s) {
    const rths_split *sp = &s->split;
    if (!s->beam || sp->n_int != 2) return 0;
    const rths_beam_dof *a = &s->beam->dofs[sp->int_dofs[0]], *b = &s->beam->dofs[sp->int_dofs[1]];
    if (a->node != b->node || a->kind != RTHS_BEAM_W || b->kind != RTHS_BEAM_THETA) return 0;
    for (int i = 0; i < s->assembly.n; i++)
        if (s->roles[i] == RTHS_DOF_PHYSICAL) return s->beam->dofs[i].node > a->node ? 1 : -1;
    return 1; /* no internal physical DoF: the fixture alone, x grows into it */
}

/* offset_m -> the n_int x n_int transform: actuators (column a = (1, dir d_a), the force and
 * moment at the cut of 1 N at offset d_a) or lasers (row s = (1, dir d_s), the displacement at
 * offset d_s of the rigid fixture). A negative offset lies on the numerical side. */
static int offsets_transform(rths_config *cfg, const rths_setup *s, const char *key, int actuators,
                             double *t, rths_error *err) {
    double *d = NULL;
    int count = 0, dir = beam_cut_direction(s);
    int rc = rths_config_get_double_list(cfg, key, 1, &d, &count, err);
    if (!rc && dir == 0)
        rc =
            rths_config_error_at(cfg, key, err,
                                 "offsets need a structure.beam cut at one node with the interface "
                                 "(w, theta) of that node; give %s.transform instead",
                                 actuators ? "rig.actuators" : "rig.lasers");
    if (!rc && count != s->split.n_int)
        rc = rths_config_error_at(cfg, key, err,
                                  "lists %d offsets for %d interface DoFs: one %s per interface "
                                  "DoF",
                                  count, s->split.n_int, actuators ? "actuator" : "laser");
    for (int i = 0; !rc && i < count; i++) {
        if (!(fabs(d[i]) <= 10))
            rc = rths_config_error_at(cfg, key, err,
                                      "entry %d: must be a finite offset within "
                                      "10 m of the cut (got %g)",
                                      i + 1, d[i]);
        else if (d[i] < 0)
            rc =
                rths_config_error_at(cfg, key, err,
                                     "entry %d: offset %g m lies on the numerical side of the cut: "
                                     "%s acts on the physical substructure only (offsets count "
                                     "from the cut into the physical part)",
                                     i + 1, d[i], actuators ? "an actuator" : "a laser");
    }
    for (int i = 0; !rc && i < count; i++) {
        /* actuators: column i; lasers: row i */
        int r0 = actuators ? 0 : i, c0 = actuators ? i : 0, r1 = actuators ? 1 : i,
            c1 = actuators ? i : 1;
        RTHS_AT(t, 2, r0, c0) = 1.0;
        RTHS_AT(t, 2, r1, c1) = dir * d[i];
    }
    free(d);
    return rc;
}

/* One transform (rig.actuators or rig.lasers): offsets or a matrix, n_int x n_int, invertible. */
static int read_transform(rths_config *cfg, rths_setup *s, const char *section, int actuators,
                          double **out, rths_error *err) {
    char k_off[64], k_mat[64];
    snprintf(k_off, sizeof k_off, "%s.offset_m", section);
    snprintf(k_mat, sizeof k_mat, "%s.transform", section);
    int has_off = rths_config_has(cfg, k_off), has_mat = rths_config_has(cfg, k_mat);
    if (!has_off && !has_mat) {
        if (rths_config_has(cfg, section))
            return rths_config_error_at(cfg, section, err, "give offset_m or transform");
        return RTHS_OK;
    }
    if (has_off && has_mat)
        return rths_config_error_at(cfg, k_mat, err, "give %s or %s, not both", k_off, k_mat);
    int ni = s->split.n_int, rows = 0, cols = 0;
    const char *key = has_off ? k_off : k_mat;
    double *t = NULL;
    int rc = RTHS_OK;
    if (has_off) {
        t = rths_mat_new(ni, ni);
        rc = t ? offsets_transform(cfg, s, k_off, actuators, t, err)
               : rths_error_set(err, RTHS_EFAIL, "out of memory");
    } else {
        rc = rths_config_get_matrix(cfg, k_mat, 1, &t, &rows, &cols, err);
        if (!rc && (rows != ni || cols != ni))
            rc = rths_config_error_at(cfg, k_mat, err,
                                      "is %d x %d; the split has %d interface DoFs, so it must be "
                                      "%d x %d (%s)",
                                      rows, cols, ni, ni, ni,
                                      actuators ? "a row per interface DoF, a column per actuator"
                                                : "a row per laser, a column per interface DoF");
        for (int i = 0; !rc && i < ni * ni; i++)
            if (!(fabs(t[i]) <= 1e6))
                rc = rths_config_error_at(cfg, k_mat, err,
                                          "entry (%d, %d) = %g is not a finite "
                                          "number of magnitude <= 1e6",
                                          i % ni + 1, i / ni + 1, t[i]);
    }
    /* singular: the actuators cannot drive (or the lasers cannot tell apart) every interface DoF */
    double *inv = rc ? NULL : rths_mat_new(ni, ni);
    if (!rc && !inv) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc) {
        int info = rths_mat_inverse(ni, t, inv);
        double cond = info ? INFINITY : rths_mat_norm1(t, ni) * rths_mat_norm1(inv, ni);
        if (!(cond < 1e10))
            rc = rths_config_error_at(cfg, key, err,
                                      "the transform is singular (condition number %.3g): %s", cond,
                                      actuators ? "these actuators cannot drive every interface "
                                                  "DoF independently (two at the same offset?)"
                                                : "these lasers cannot tell every interface DoF "
                                                  "apart (two at the same offset?)");
    }
    rths_mat_free(inv);
    if (rc) {
        rths_mat_free(t);
        return rc;
    }
    *out = t;
    return RTHS_OK;
}

static int read_transforms(rths_config *cfg, rths_setup *s, rths_error *err) {
    int rc = read_transform(cfg, s, "rig.actuators", 1, &s->actuator_transform, err);
    if (!rc) rc = read_transform(cfg, s, "rig.lasers", 0, &s->sensor_transform, err);
    return rc;
}

static int read_interface_mass(rths_config *cfg, rths_setup *s, rths_error *err) {
    static const char *const modes[] = {"full", "physical_share", NULL};
    int mode = RTHS_INTERFACE_MASS_FULL;
    /* read only when given: a read key of `rig` makes a command the section's reader
     * (config_check.c, setup_subsections), and `rths model` ignores the rest of `rig` */
    s->interface_mass = RTHS_INTERFACE_MASS_FULL;
    if (!rths_config_has(cfg, "rig.interface_mass")) return RTHS_OK;
    int rc = rths_config_get_choice(cfg, "rig.interface_mass", 0, mode, modes, &mode, err);
    s->interface_mass = (rths_interface_mass)mode;
    return rc;
}

const char *rths_interface_mass_name(rths_interface_mass mode) {
    return mode == RTHS_INTERFACE_MASS_PHYSICAL_SHARE ? "physical_share" : "full";
}

double rths_setup_rig_interface_mass(const rths_setup *s, int d, int e) {
    const rths_split *sp = &s->split;
    if (s->interface_mass == RTHS_INTERFACE_MASS_PHYSICAL_SHARE)
        return RTHS_AT(sp->mass_phys, sp->np, sp->n_phys + d, sp->n_phys + e);
    if (s->sparse) return rths_sparse_get(&s->sparse->mass, sp->int_dofs[d], sp->int_dofs[e]);
    return RTHS_AT(s->assembly.mass, s->assembly.n, sp->int_dofs[d], sp->int_dofs[e]);
}

double rths_setup_compensation_mass(const rths_setup *s, int d, int e) {
    if (s->interface_mass == RTHS_INTERFACE_MASS_PHYSICAL_SHARE) return 0.0;
    /* the sparse split keeps no numerical side: its interface block is p M_II (one p) */
    if (s->sparse)
        return s->sparse->mass_ratio *
               rths_sparse_get(&s->sparse->mass, s->split.int_dofs[d], s->split.int_dofs[e]);
    return RTHS_AT(s->split.mass_num, s->split.nn, d, e);
}

int rths_setup_read(rths_config *cfg, rths_setup *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    int rc = read_structure(cfg, out, err);
    if (!rc && out->sparse) {
        rc = rths_setup_read_sparse_rest(cfg, out, err);
        if (!rc) rc = read_transforms(cfg, out, err);
        if (!rc) rc = read_interface_mass(cfg, out, err);
        if (rc) rths_setup_free(out);
        return rc;
    }
    if (!rc) rc = read_split(cfg, out, err);
    if (!rc) rc = read_forcing(cfg, out, err);
    if (!rc) rc = rths_setup_read_bilinear(cfg, out, err);
    if (!rc) rc = rths_setup_read_nonlinear(cfg, out, err);
    if (!rc) rc = read_frf_range(cfg, out, err);
    if (!rc) rc = rths_setup_read_numerical_solver(cfg, out, err);
    if (!rc) rc = rths_setup_check_solver_nonlinear(cfg, out, err);
    if (!rc) rc = read_transforms(cfg, out, err);
    if (!rc) rc = read_interface_mass(cfg, out, err);
    if (rc) rths_setup_free(out);
    return rc;
}

void rths_setup_free(rths_setup *s) {
    if (!s) return;
    rths_assembly_free(&s->assembly);
    rths_split_free(&s->split);
    free(s->roles);
    free(s->force);
    free(s->forcing_shape);
    free(s->static_force);
    if (s->beam) rths_beam_free(s->beam);
    free(s->beam);
    rths_mat_free(s->actuator_transform);
    rths_mat_free(s->sensor_transform);
    rths_sparse_truth_free(s->sparse_truth);
    if (s->sparse) rths_sparse_model_free(s->sparse);
    free(s->sparse);
    memset(s, 0, sizeof *s);
}

int *rths_setup_output_dofs(const rths_setup *s, int *count) {
    int n = s->assembly.n, m = 0;
    int *dofs = malloc((size_t)n * sizeof *dofs);
    if (!dofs) return NULL;
    for (int i = 0; i < n; i++)
        if (n <= RTHS_SETUP_ALL_DOFS_UP_TO || s->roles[i] != RTHS_DOF_NUMERICAL ||
            i == s->forcing_dof)
            dofs[m++] = i;
    *count = m;
    return dofs;
}

void rths_setup_forcing_text(const rths_setup *s, char *buf, size_t size) {
    if (s->base_excitation)
        snprintf(buf, size, "ground acceleration %g m/s^2", s->forcing_amplitude_n);
    else
        snprintf(buf, size, "%g N on DoF %d", s->forcing_amplitude_n, s->forcing_dof + 1);
}

int rths_setup_dof_is_rotation(const rths_setup *s, int dof) {
    return s->beam && dof >= 0 && dof < s->beam->n && s->beam->dofs[dof].kind == RTHS_BEAM_THETA;
}
