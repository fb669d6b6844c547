/* Reading the structural part of a configuration: the seed example gives the seed's matrices and
 * split (interface mass divided by p, leg below the interface physical, leg above numerical),
 * defaults follow the chain rule, the bilinear preload points toward the stiff side, and
 * the FRF grid resolves every peak; a beam splits element by element (the follow-up's cantilever:
 * both substructures' stiffness positive definite, the cut's blocks the two elements' own), with
 * one p per interface DoF. */
#include "testlib.h"

#include "rths/setup.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void load_seed(const char *const *overrides, int n, rths_config **cfg, rths_setup *s) {
    rths_error err;
    int rc = rths_config_load(rths_test_source_path("examples/four_storey.yaml"), overrides, n, cfg,
                              &err);
    if (rc) fail_msg("%s", err.msg);
    rc = rths_setup_read(*cfg, s, &err);
    if (rc) fail_msg("%s", err.msg);
    rc = rths_config_check_unknown(*cfg, &err);
    if (rc) fail_msg("%s", err.msg);
}

static void test_seed_example(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load_seed(NULL, 0, &cfg, &s);
    assert_int_equal(s.assembly.n, 4);
    assert_int_equal(s.chain, 1);
    assert_int_equal(s.split.n_phys, 2);
    assert_int_equal(s.split.n_int, 1);
    assert_int_equal(s.split.n_num, 1);
    assert_int_equal(s.split.int_dofs[0], 2);
    assert_int_equal(s.forcing_dof, 3);
    assert_close(s.force[3], 1.0, 0);
    /* p = 0.5 of 5.37 kg on each side; interface row of the physical stiffness holds the leg
     * below storey 3 only (45052), the numerical side the leg above (45052) */
    int np = s.split.np, nn = s.split.nn;
    assert_close(RTHS_AT(s.split.mass_phys, np, 2, 2), 0.5 * 5.37, 1e-12);
    assert_close(RTHS_AT(s.split.mass_num, nn, 0, 0), 0.5 * 5.37, 1e-12);
    assert_close(RTHS_AT(s.split.stiffness_phys, np, 2, 2), 45052, 1e-9);
    assert_close(RTHS_AT(s.split.stiffness_num, nn, 0, 0), 45052, 1e-9);
    assert_close(RTHS_AT(s.split.mass_num, nn, 1, 1), 10.74, 1e-12);
    assert_int_equal(s.has_bilinear, 0);
    assert_close(s.frf_start_hz, 0.5, 0);
    assert_close(s.frf_end_hz, 35.0, 0);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static void test_overrides_and_bilinear(void **state) {
    (void)state;
    const char *ov[] = {"split.mass_ratio=0.33", "structure.bilinear.enabled=true",
                        "forcing.amplitude_n=3"};
    rths_config *cfg;
    rths_setup s;
    load_seed(ov, 3, &cfg, &s);
    assert_close(s.split.mass_ratio, 0.33, 0);
    assert_close(RTHS_AT(s.split.mass_num, s.split.nn, 0, 0), 0.33 * 5.37, 1e-12);
    assert_close(s.force[3], 3.0, 0);
    assert_int_equal(s.has_bilinear, 1);
    /* seed: the leg between storeys 2 and 3, 45052 N/m in extension, twice that in compression */
    assert_int_equal(s.leg.lower_dof, 1);
    assert_int_equal(s.leg.upper_dof, 2);
    assert_close(s.leg.stiffness_n_per_m, 45052, 1e-9);
    assert_close(s.leg.ratio, 2.0, 0);
    /* compression is x3 - x2 < 0: the preload pushes storey 3 in the negative direction */
    assert_close(s.static_force[2], -26.68, 0);
    assert_close(s.static_force[0] + s.static_force[1] + s.static_force[3], 0, 0);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Ground leg as the bilinear one: its stiffness must be k1 alone, not the diagonal k1 + k2. */
static void test_bilinear_ground_leg(void **state) {
    (void)state;
    const char *ov[] = {"structure.bilinear.enabled=true", "structure.bilinear.storey=1",
                        "split.interface=[2]"};
    rths_config *cfg;
    rths_setup s;
    load_seed(ov, 3, &cfg, &s);
    assert_int_equal(s.leg.lower_dof, -1);
    assert_close(s.leg.stiffness_n_per_m, 53048, 1e-9);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* The default grid puts points within a tenth of a half-power bandwidth of every mode, so the
 * sampled peak is within 1 % of the true peak (|H| near resonance ~ 1/sqrt(1 + (2 df/bw)^2)). */
static void test_default_grid_resolves_peaks(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    load_seed(NULL, 0, &cfg, &s);
    rths_modes m;
    rths_error err;
    assert_int_equal(rths_modal_analysis(&s.assembly, &m, &err), RTHS_OK);
    double *f;
    int count;
    assert_int_equal(rths_frf_grid(&m, 0, 0, 0, &f, &count, &err), RTHS_OK);
    assert_close(f[count - 1], 1.25 * m.frequency_hz[3], 1e-9);
    for (int i = 1; i < count; i++)
        assert_true(f[i] >= f[i - 1]);
    for (int r = 0; r < 4; r++) {
        double half_bw = m.damping_ratio[r] * m.frequency_hz[r];
        double nearest = INFINITY;
        for (int i = 0; i < count; i++)
            nearest = fmin(nearest, fabs(f[i] - m.frequency_hz[r]));
        assert_true(nearest <= 0.2 * half_bw);
    }
    free(f);
    rths_modes_free(&m);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static int load_file(const char *rel, const char *const *ov, int n, rths_config **cfg,
                     rths_setup *s, rths_error *err) {
    int rc = rths_config_load(rths_test_source_path(rel), ov, n, cfg, err);
    if (rc) return rc;
    rc = rths_setup_read(*cfg, s, err);
    if (rc) rths_config_free(*cfg);
    return rc;
}

/* The seed as Matrix Market files (array general, coordinate symmetric, coordinate general),
 * paths relative to the config's folder: the very assembly the storey chain builds, and with
 * split.numerical left out every remaining DoF (4) is numerical. */
static void test_matrix_market_seed(void **state) {
    (void)state;
    rths_config *cfg, *chain_cfg;
    rths_setup s, chain;
    rths_error err;
    if (load_file("tests/data/mtx/seed_matrices.yaml", NULL, 0, &cfg, &s, &err))
        fail_msg("%s", err.msg);
    load_seed(NULL, 0, &chain_cfg, &chain);
    assert_int_equal(s.assembly.n, 4);
    assert_int_equal(s.chain, 0);
    assert_memory_equal(s.assembly.mass, chain.assembly.mass, 16 * sizeof(double));
    assert_memory_equal(s.assembly.stiffness, chain.assembly.stiffness, 16 * sizeof(double));
    for (int k = 0; k < 16; k++) /* the chain adds 4.4062 + 3.7979 in binary: last-bit rounding */
        assert_close(s.assembly.damping[k], chain.assembly.damping[k], 1e-14);
    assert_int_equal(s.roles[3], RTHS_DOF_NUMERICAL);
    assert_int_equal(s.split.n_num, 1);
    assert_int_equal(s.split.num_dofs[0], 3);
    assert_int_equal(s.split.n_phys, 2);
    rths_setup_free(&s);
    rths_setup_free(&chain);
    rths_config_free(cfg);
    rths_config_free(chain_cfg);
}

/* A bad .mtx named in the config: the key's location, then the file's line and the problem. */
static void test_matrix_market_bad_file(void **state) {
    (void)state;
    const char *ov[] = {"structure.matrices.damping_n_s_per_m=bad_too_few.mtx"};
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    assert_int_equal(load_file("tests/data/mtx/seed_matrices.yaml", ov, 1, &cfg, &s, &err),
                     RTHS_EINPUT);
    print_message("%s\n", err.msg);
    assert_non_null(strstr(err.msg, "structure.matrices.damping_n_s_per_m"));
    assert_non_null(strstr(err.msg, "tests/data/mtx/bad_too_few.mtx:4: file ends after 2 of"));
}

/* Structures without physical sense are refused before any work (issue: a 1e308 kg storey gave
 * NaN rows and exit 0, an indefinite K or negative-definite C passed, a singular K failed after
 * writing files), each at its key. */
static void expect_refused(const char *rel, const char *override, const char *fragment) {
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    const char *ov[] = {override};
    int rc = load_file(rel, ov, 1, &cfg, &s, &err);
    print_message("%s -> %s\n", override, err.msg);
    assert_int_equal(rc, RTHS_EINPUT);
    if (!strstr(err.msg, fragment)) fail_msg("'%s' not in '%s'", fragment, err.msg);
}

static void test_physical_sense(void **state) {
    (void)state;
    const char *seed = "examples/four_storey.yaml", *mtx = "tests/data/mtx/seed_matrices.yaml";
    expect_refused(seed, "structure.storeys.mass_kg=[5.37, 5.37, 1e308, 10.74]",
                   "storey 3: must be > 0 and <= 1e+15 kg, at least 1e-06 kg (got 1e+308)");
    /* lower bounds: a 1e-300 kg storey had a mode at 5e151 Hz and NaN output with exit 0 */
    expect_refused(seed, "structure.storeys.mass_kg=[1e-300, 5.37, 5.37, 10.74]",
                   "key 'structure.storeys.mass_kg': storey 1: must be > 0 and <= 1e+15 kg, at "
                   "least 1e-06 kg (got 1e-300)");
    expect_refused(seed, "structure.storeys.stiffness_n_per_m=[45052, 1e-300, 45052, 45052]",
                   "storey 2: must be > 0 and <= 1e+15 N/m, at least 1e-06 N/m (got 1e-300)");
    expect_refused(mtx,
                   "structure.matrices.mass_kg=[[1, 0, 0, 0], [0, 1e-300, 0, 0], [0, 0, 1, 0], "
                   "[0, 0, 0, 1]]",
                   "key 'structure.matrices.mass_kg': diagonal entry (2, 2) = 1e-300 is below "
                   "1e-12");
    expect_refused(mtx,
                   "structure.matrices.stiffness_n_per_m=[[1e-300, 0, 0, 0], [0, 1, 0, 0], [0, 0, "
                   "1, 0], [0, 0, 0, 1]]",
                   "key 'structure.matrices.stiffness_n_per_m': diagonal entry (1, 1) = 1e-300 is "
                   "below 1e-12");
    expect_refused(seed, "forcing.amplitude_n=1e300", "forcing.amplitude_n");
    /* eigenvalues 3 and -1 */
    expect_refused(mtx,
                   "structure.matrices.stiffness_n_per_m=[[1, 2, 0, 0], [2, 1, 0, 0], [0, 0, 1, "
                   "0], [0, 0, 0, 1]]",
                   "stiffness_n_per_m': must be positive definite");
    /* a free-floating pair: the rigid-body mode (1, 1) has zero stiffness */
    expect_refused(mtx,
                   "structure.matrices.stiffness_n_per_m=[[1, -1, 0, 0], [-1, 1, 0, 0], [0, 0, 1, "
                   "0], [0, 0, 0, 1]]",
                   "rigid-body motion");
    expect_refused(mtx,
                   "structure.matrices.damping_n_s_per_m=[[-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, "
                   "-1, 0], [0, 0, 0, -1]]",
                   "damping_n_s_per_m': must be positive semi-definite");
    expect_refused(mtx,
                   "structure.matrices.mass_kg=[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], "
                   "[0, 0, 0, 1e300]]",
                   "entry (4, 4) = 1e+300 is not a finite number of magnitude <= 1e+15");
    /* the limits themselves pass: zero damping, a semi-definite (rank-deficient) C */
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    const char *ok[] = {"structure.matrices.damping_n_s_per_m=[[1, -1, 0, 0], [-1, 1, 0, 0], [0, "
                        "0, 0, 0], [0, 0, 0, 0]]"};
    if (load_file(mtx, ok, 1, &cfg, &s, &err)) fail_msg("%s", err.msg);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* rig.interface_mass (issue 23.1). The hybrid test's steady state at a perfect match, in closed
 * form: the rig's physical substructure (its interface block carrying the rig's interface mass)
 * obeys Z_rig x_p = F_LC e_I + f_p, the numerical one Z_num x_n = -w^2 M_comp x_I - F_LC e_I + f_n
 * (the inertial compensation of the measured acceleration); with x_I shared, adding the interface
 * rows eliminates F_LC: (Z_rig + Z_num + w^2 M_comp) x = f, which must be the true assembly's
 * (K - w^2 M + i w C) x = f for both modes (full: rig M_II, compensation p M_II; physical_share:
 * rig (1 - p) M_II, none) at the p = 0.971, to rounding (1e-12). The unknown key value
 * is refused by name. */
static void hybrid_match_case(const char *mode, double p) {
    char ov_mode[64], ov_p[64];
    snprintf(ov_mode, sizeof ov_mode, "rig.interface_mass=%s", mode);
    snprintf(ov_p, sizeof ov_p, "split.mass_ratio=%g", p);
    const char *ov[] = {ov_mode, ov_p};
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (load_file("examples/four_storey_linear.yaml", ov, 2, &cfg, &s, &err))
        fail_msg("%s", err.msg);
    const rths_split *sp = &s.split;
    int n = s.assembly.n, np = sp->np, nn = sp->nn, ni = sp->n_int;
    double complex *z = calloc((size_t)(n * n), sizeof *z), *x = calloc((size_t)n, sizeof *x),
                   *truth = calloc((size_t)n, sizeof *truth);
    int phys_of[16], num_of[16];
    for (int i = 0; i < np; i++)
        phys_of[i] = i < sp->n_phys ? sp->phys_dofs[i] : sp->int_dofs[i - sp->n_phys];
    for (int i = 0; i < nn; i++)
        num_of[i] = i < ni ? sp->int_dofs[i] : sp->num_dofs[i - ni];
    for (double hz = 0.5; hz < 30; hz *= 1.37) {
        double w = 2 * M_PI * hz;
        memset(z, 0, sizeof *z * (size_t)(n * n));
        for (int i = 0; i < np; i++)
            for (int j = 0; j < np; j++) {
                double m = RTHS_AT(sp->mass_phys, np, i, j);
                if (i >= sp->n_phys && j >= sp->n_phys)
                    m = rths_setup_rig_interface_mass(&s, i - sp->n_phys, j - sp->n_phys);
                z[phys_of[i] + n * phys_of[j]] += RTHS_AT(sp->stiffness_phys, np, i, j) -
                                                  w * w * m +
                                                  I * w * RTHS_AT(sp->damping_phys, np, i, j);
            }
        for (int i = 0; i < nn; i++)
            for (int j = 0; j < nn; j++)
                z[num_of[i] + n * num_of[j]] += RTHS_AT(sp->stiffness_num, nn, i, j) -
                                                w * w * RTHS_AT(sp->mass_num, nn, i, j) +
                                                I * w * RTHS_AT(sp->damping_num, nn, i, j);
        for (int d = 0; d < ni; d++)
            for (int e = 0; e < ni; e++)
                z[sp->int_dofs[d] + n * sp->int_dofs[e]] +=
                    w * w * rths_setup_compensation_mass(&s, d, e);
        for (int i = 0; i < n; i++)
            x[i] = s.force[i];
        assert_int_equal(rths_cmat_solve(n, 1, z, x), 0);
        assert_int_equal(rths_frf(n, s.assembly.mass, s.assembly.damping, s.assembly.stiffness,
                                  s.force, w, truth, &err),
                         RTHS_OK);
        for (int i = 0; i < n; i++)
            if (cabs(x[i] - truth[i]) > 1e-12 * cabs(truth[i]))
                fail_msg("%s p %g, %g Hz, DoF %d: hybrid %g%+gi, truth %g%+gi", mode, p, hz, i + 1,
                         creal(x[i]), cimag(x[i]), creal(truth[i]), cimag(truth[i]));
    }
    /* what the rig carries: the whole block, or the physical share */
    double m_ii = RTHS_AT(s.assembly.mass, n, sp->int_dofs[0], sp->int_dofs[0]);
    int share = !strcmp(mode, "physical_share");
    assert_close(rths_setup_rig_interface_mass(&s, 0, 0), share ? (1 - p) * m_ii : m_ii,
                 1e-12 * m_ii);
    assert_close(rths_setup_compensation_mass(&s, 0, 0), share ? 0.0 : p * m_ii, 1e-12 * m_ii);
    free(z), free(x), free(truth);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

static void test_interface_mass_modes(void **state) {
    (void)state;
    hybrid_match_case("full", 0.971);
    hybrid_match_case("physical_share", 0.971);
    hybrid_match_case("physical_share", 0.33);
    rths_config *cfg;
    rths_setup s;
    load_seed(NULL, 0, &cfg, &s);
    assert_int_equal(s.interface_mass, RTHS_INTERFACE_MASS_FULL); /* the default: the seed's */
    rths_setup_free(&s);
    rths_config_free(cfg);
    expect_refused("examples/four_storey.yaml", "rig.interface_mass=half", "rig.interface_mass");
}

/* examples/cantilever_two_shakers.yaml with p = [0.3, 0.6]: the physical share of the cut's
 * (w, theta) stiffness block is the first tip element's start-node block EI/l^3 [12, 6l; 6l,
 * 4l^2] (l = 0.06 m), the numerical share the last root element's end-node block (l = 0.17/3 m,
 * [12, -6l; -6l, 4l^2]); damping is Rayleigh element by element; the interface mass splits by
 * each DoF's p; both substructures' stiffness is positive definite (the coupling rule of a chain
 * left the numerical one indefinite: eigenvalue -2.9e4 N/m). */
static void test_beam_element_split(void **state) {
    (void)state;
    const char *ov[] = {"split.mass_ratio=[0.3, 0.6]"};
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    if (load_file("examples/cantilever_two_shakers.yaml", ov, 1, &cfg, &s, &err))
        fail_msg("%s", err.msg);
    const rths_split *sp = &s.split;
    assert_int_equal(sp->n_int, 2);
    assert_int_equal(sp->int_dofs[0], 4);
    assert_int_equal(sp->int_dofs[1], 5);
    const double ei = 0.459317, lp = 0.06, ln = 0.17 / 3;
    const double kp[4] = {12, 6 * lp, 6 * lp, 4 * lp * lp},
                 kn[4] = {12, -6 * ln, -6 * ln, 4 * ln * ln};
    int np = sp->np, nn = sp->nn, o = sp->n_phys;
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 2; j++) {
            double phys = RTHS_AT(sp->stiffness_phys, np, o + i, o + j);
            double num = RTHS_AT(sp->stiffness_num, nn, i, j);
            assert_close(phys, ei / (lp * lp * lp) * kp[i + 2 * j], 1e-9 * fabs(phys));
            assert_close(num, ei / (ln * ln * ln) * kn[i + 2 * j], 1e-9 * fabs(num));
            /* Rayleigh element by element: alpha M_e + beta K_e of the first tip element */
            const double me[4] = {156, 22 * lp, 22 * lp, 4 * lp * lp};
            double c_phys = s.beam->rayleigh_alpha_per_s * 0.19939 * lp / 420 * me[i + 2 * j] +
                            s.beam->rayleigh_beta_s * ei / (lp * lp * lp) * kp[i + 2 * j];
            assert_close(RTHS_AT(sp->damping_phys, np, o + i, o + j), c_phys, 1e-9 * fabs(c_phys));
            double full_m = RTHS_AT(s.assembly.mass, s.assembly.n, 4 + i, 4 + j);
            double p_ij = i == j ? (i ? 0.6 : 0.3) : sqrt(0.3 * 0.6);
            assert_close(RTHS_AT(sp->mass_num, nn, i, j), p_ij * full_m, 1e-15);
        }
    /* the recombined halves are the assembly */
    double *m = rths_mat_new(s.assembly.n, s.assembly.n),
           *c = rths_mat_new(s.assembly.n, s.assembly.n),
           *k = rths_mat_new(s.assembly.n, s.assembly.n);
    rths_split_recombine(sp, m, c, k);
    for (int e = 0; e < s.assembly.n * s.assembly.n; e++) {
        assert_close(c[e], s.assembly.damping[e],
                     1e-12 * rths_mat_max_abs(c, s.assembly.n, s.assembly.n));
        assert_close(k[e], s.assembly.stiffness[e],
                     1e-9 * rths_mat_max_abs(k, s.assembly.n, s.assembly.n));
    }
    assert_true(rths_mat_is_spd(sp->stiffness_num, nn));
    /* the physical tip is held by its actuators only: free-free, two rigid-body modes, so its
     * stiffness is positive semi-definite (positive definite once shifted slightly) */
    assert_false(rths_mat_is_spd(sp->stiffness_phys, np));
    double *shifted = rths_mat_dup(sp->stiffness_phys, np, np);
    for (int i = 0; i < np; i++)
        RTHS_AT(shifted, np, i, i) += 1e-9 * rths_mat_max_abs(shifted, np, np);
    assert_true(rths_mat_is_spd(shifted, np));
    rths_mat_free(shifted), rths_mat_free(m), rths_mat_free(c), rths_mat_free(k);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

/* Issue 27: the seed's leg below storey 4 lies on the numerical side (it was refused: "must be on
 * the physical side"), its preload a static force on storey 4 toward the stiff side; the element
 * list reads every type with its side and parameters, and a bad element is refused at its key. */
static void test_nonlinear_elements(void **state) {
    (void)state;
    const char *ov[] = {"structure.bilinear.enabled=true", "structure.bilinear.storey=4"};
    rths_config *cfg;
    rths_setup s;
    load_seed(ov, 2, &cfg, &s);
    assert_int_equal(s.has_bilinear, 1);
    assert_int_equal(s.n_nonlinear, 1);
    assert_int_equal(s.nonlinear[0].numerical, 1);
    assert_int_equal(s.nonlinear[0].dof_i, 3);
    assert_int_equal(s.nonlinear[0].dof_j, 2);
    assert_close(s.nonlinear[0].k, 45052, 1e-9); /* (2 - 1) x the chain's leg */
    assert_close(s.static_force[3], -26.68, 0);
    assert_close(s.static_force[0] + s.static_force[1] + s.static_force[2], 0, 0);
    assert_int_equal(rths_setup_nonlinear_count(&s, 1), 1);
    assert_int_equal(rths_setup_nonlinear_count(&s, 0), 0);
    rths_setup_free(&s);
    rths_config_free(cfg);

    const char *list[] = {
        "structure.nonlinear=[{type: cubic, dofs: [4, 3], stiffness_n_per_m3: 2e12}, "
        "{type: gap, dofs: [2, 1], stiffness_n_per_m: 1e4, clearance_m: 1e-4}, "
        "{type: friction, dofs: [3, 0], side: numerical, slip_force_n: 0.5, "
        "regularisation_m_s: 2e-3}, {type: bilinear, dofs: [2, 1], compression_ratio: 3, "
        "preload_n: 10}]"};
    load_seed(list, 1, &cfg, &s);
    assert_int_equal(s.n_nonlinear, 4);
    assert_int_equal(s.nonlinear[0].type, RTHS_NL_CUBIC);
    assert_int_equal(s.nonlinear[0].numerical, 1);
    assert_close(s.nonlinear[0].k, 2e12, 0);
    assert_int_equal(s.nonlinear[1].type, RTHS_NL_GAP);
    assert_int_equal(s.nonlinear[1].numerical, 0);
    assert_close(s.nonlinear[1].clearance_m, 1e-4, 0);
    assert_int_equal(s.nonlinear[2].type, RTHS_NL_FRICTION);
    assert_int_equal(s.nonlinear[2].numerical, 1);
    assert_int_equal(s.nonlinear[2].dof_j, -1);
    assert_close(s.nonlinear[2].v_reg_m_s, 2e-3, 0);
    assert_int_equal(s.nonlinear[3].type, RTHS_NL_BILINEAR);
    assert_close(s.nonlinear[3].leg_stiffness_n_per_m, 45724, 1e-9); /* the chain's leg 1-2 */
    assert_close(s.nonlinear[3].k, 2 * 45724, 1e-9);
    /* the preload compresses the leg: storey 2 pushed down, storey 1 up */
    assert_close(s.static_force[1], -10, 0);
    assert_close(s.static_force[0], 10, 0);
    /* the friction element's regularisation: tanh(v / v_reg), slope F / v_reg at rest */
    double slope;
    assert_close(rths_nl_force(&s.nonlinear[2], 2e-3, &slope), 0.5 * tanh(1.0), 1e-15);
    assert_close(rths_nl_force(&s.nonlinear[2], 0, &slope), 0, 0);
    assert_close(slope, 0.5 / 2e-3, 1e-9);
    rths_setup_free(&s);
    rths_config_free(cfg);

    const char *seed = "examples/four_storey.yaml";
    expect_refused(seed, "structure.nonlinear=[{type: cubic, dofs: [2, 4], stiffness_n_per_m3: 1}]",
                   "key 'structure.nonlinear.0.dofs': joins physical DoF and numerical DoF");
    expect_refused(seed,
                   "structure.nonlinear=[{type: cubic, dofs: [4, 3], side: physical, "
                   "stiffness_n_per_m3: 1}]",
                   "key 'structure.nonlinear.0.side': the element touches a numerical DoF");
    expect_refused(seed, "structure.nonlinear=[{type: spring, dofs: [4, 3]}]",
                   "structure.nonlinear.0.type");
    expect_refused(seed, "structure.nonlinear=[{type: gap, dofs: [4], stiffness_n_per_m: 1}]",
                   "lists 1 DoFs: give two");
    expect_refused(seed, "structure.nonlinear=[{type: gap, dofs: [4, 3], clearance_m: 0}]",
                   "structure.nonlinear.0.stiffness_n_per_m");
    expect_refused(seed,
                   "structure.nonlinear=[{type: friction, dofs: [4, 3], slip_force_n: 1, "
                   "regularisation_m_s: 1e-300}]",
                   "key 'structure.nonlinear.0.regularisation_m_s': must be in [1e-09, 1000]");
    expect_refused(seed,
                   "structure.nonlinear=[{type: bilinear, dofs: [4, 0], compression_ratio: 2}]",
                   "needs stiffness_n_per_m");
}

/* A numerical-side element with split.numerical_solver: frequency is accepted (issue 27: the host
 * solves the substructure by harmonic balance; tests/cli/frf_nonlinear_frequency.sh runs it). */
static void test_nonlinear_frequency_solver_refused(void **state) {
    (void)state;
    rths_config *cfg;
    rths_setup s;
    rths_error err;
    const char *ov[] = {"structure.bilinear.enabled=true", "structure.bilinear.storey=4",
                        "split.numerical_solver=frequency"};
    assert_int_equal(
        rths_config_load(rths_test_source_path("examples/four_storey.yaml"), ov, 3, &cfg, &err),
        RTHS_OK);
    assert_int_equal(rths_setup_read(cfg, &s, &err), RTHS_OK);
    assert_int_equal(s.numerical_solver, RTHS_NUMERICAL_FREQUENCY);
    assert_int_equal(rths_setup_nonlinear_count(&s, 1), 1);
    rths_setup_free(&s);
    rths_config_free(cfg);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_seed_example),
        cmocka_unit_test(test_overrides_and_bilinear),
        cmocka_unit_test(test_bilinear_ground_leg),
        cmocka_unit_test(test_default_grid_resolves_peaks),
        cmocka_unit_test(test_matrix_market_seed),
        cmocka_unit_test(test_matrix_market_bad_file),
        cmocka_unit_test(test_physical_sense),
        cmocka_unit_test(test_beam_element_split),
        cmocka_unit_test(test_interface_mass_modes),
        cmocka_unit_test(test_nonlinear_elements),
        cmocka_unit_test(test_nonlinear_frequency_solver_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
