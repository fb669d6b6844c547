/* The frequency form's numerical substructure from a sparse model (reduce.h,
 * rths_sparse_receptance; model.h, rths_sparse_model_numerical_side) against the dense one the
 * split makes (rths_split_create + rths_numerical_receptance, itself checked against the
 * assembly in test_reduce.c): a 12-storey chain with a non-proportional damper and a cross
 * spring on the numerical side, storeys 1-3 physical, 4 the interface, forcing on storey 9. The
 * sparse numerical side must equal the dense split's matrices entry by entry (the same sums: to
 * 1e-15 relative), and the receptance and the forcing's interface response from one sparse
 * complex solve per frequency must equal the dense solves to 1e-10 relative (both are direct
 * solves of the same 9 x 9 system; LDL^T and LU round differently, ~1e-14 measured). */
#include "testlib.h"

#include "rths/model.h"
#include "rths/reduce.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { N = 12, IFACE = 3, FORCED = 8 };

static void chain(rths_assembly *a) {
    double m[N], c[N], k[N];
    for (int i = 0; i < N; i++)
        m[i] = 5.0 + 0.3 * i, c[i] = 2.0 + 0.1 * i, k[i] = 4e4 + 1e3 * i;
    rths_error err;
    assert_int_equal(rths_assembly_from_chain(N, m, c, k, a, &err), 0);
    /* a damper and a spring across storeys 6 and 10 (numerical side): C no longer proportional,
     * K no longer a chain */
    const int p = 5, q = 9;
    double add[2] = {3.0, 7e3};
    double *mats[2] = {a->damping, a->stiffness};
    for (int t = 0; t < 2; t++) {
        RTHS_AT(mats[t], N, p, p) += add[t], RTHS_AT(mats[t], N, q, q) += add[t];
        RTHS_AT(mats[t], N, p, q) -= add[t], RTHS_AT(mats[t], N, q, p) -= add[t];
    }
}

static void to_sparse(const double *a, rths_sparse_sym *out) {
    int ti[N * N], tj[N * N];
    double tv[N * N];
    long t = 0;
    for (int j = 0; j < N; j++)
        for (int i = j; i < N; i++)
            if (RTHS_AT(a, N, i, j) != 0) ti[t] = i, tj[t] = j, tv[t++] = RTHS_AT(a, N, i, j);
    rths_error err;
    assert_int_equal(rths_sparse_from_triplets(N, t, ti, tj, tv, out, &err), 0);
}

static void test_sparse_numerical_side_and_receptance(void **state) {
    (void)state;
    rths_assembly a;
    chain(&a);
    rths_dof_role roles[N];
    for (int i = 0; i < N; i++)
        roles[i] = i < IFACE    ? RTHS_DOF_PHYSICAL
                   : i == IFACE ? RTHS_DOF_INTERFACE
                                : RTHS_DOF_NUMERICAL;
    const double p = 0.4;
    rths_split split;
    rths_error err;
    assert_int_equal(rths_split_create(&a, roles, p, NULL, NULL, &split, &err), 0);

    rths_sparse_model m = {0};
    m.n = N;
    to_sparse(a.mass, &m.mass);
    to_sparse(a.damping, &m.damping);
    to_sparse(a.stiffness, &m.stiffness);
    m.roles = roles;
    int iface = IFACE;
    m.n_int = 1;
    m.int_dofs = &iface;
    m.mass_ratio = p;

    rths_sparse_sym sm, sc, sk;
    int *dofs = NULL, nn = 0;
    assert_int_equal(rths_sparse_model_numerical_side(&m, &sm, &sc, &sk, &dofs, &nn, &err), 0);
    assert_int_equal(nn, split.nn);
    for (int i = 0; i < nn; i++)
        assert_int_equal(dofs[i], i == 0 ? split.int_dofs[0] : split.num_dofs[i - 1]);
    const rths_sparse_sym *sparse[3] = {&sm, &sc, &sk};
    const double *dense[3] = {split.mass_num, split.damping_num, split.stiffness_num};
    for (int t = 0; t < 3; t++)
        for (int i = 0; i < nn; i++)
            for (int j = 0; j < nn; j++) {
                double want = RTHS_AT(dense[t], nn, i, j), got = rths_sparse_get(sparse[t], i, j);
                assert_true(fabs(got - want) <= 1e-15 * fabs(want) + 1e-300);
            }

    rths_numerical_receptance *dense_r;
    rths_sparse_receptance *sparse_r;
    assert_int_equal(rths_numerical_receptance_create(&split, FORCED, &dense_r, &err), 0);
    int forced_at = -1;
    for (int i = 0; i < nn; i++)
        if (dofs[i] == FORCED) forced_at = i;
    assert_int_equal(rths_sparse_receptance_create(&sm, &sc, &sk, 0, forced_at, &sparse_r, &err),
                     0);
    const double omegas[5] = {3.0, 41.0, 77.7, 130.0, 400.0};
    for (int w = 0; w < 5; w++) {
        double complex hd, fd, hs, fs;
        assert_int_equal(rths_numerical_receptance_eval(dense_r, omegas[w], &hd, &fd, &err), 0);
        assert_int_equal(rths_sparse_receptance_eval(sparse_r, omegas[w], &hs, &fs, &err), 0);
        assert_true(cabs(hs - hd) <= 1e-10 * cabs(hd));
        assert_true(cabs(fs - fd) <= 1e-10 * cabs(fd));
        assert_true(cabs(fd) > 0);
    }
    rths_numerical_receptance_destroy(dense_r);
    rths_sparse_receptance_destroy(sparse_r);
    free(dofs);
    rths_sparse_free(&sm);
    rths_sparse_free(&sc);
    rths_sparse_free(&sk);
    rths_sparse_free(&m.mass);
    rths_sparse_free(&m.damping);
    rths_sparse_free(&m.stiffness);
    rths_split_free(&split);
    rths_assembly_free(&a);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sparse_numerical_side_and_receptance),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
