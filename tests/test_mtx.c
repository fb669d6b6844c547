/* The Matrix Market reader against matrices written out by hand in tests/data/mtx: every format
 * (coordinate / array), field (real / integer) and symmetry (general / symmetric, either
 * triangle) gives exactly the matrix in the file's comment, duplicates summed; every malformed
 * file is refused with RTHS_EINPUT, its path, the line at fault and what is wrong. */
#include "testlib.h"

#include "rths/mtx.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

static const char *data_path(const char *name) {
    static char path[1024];
    char rel[256];
    snprintf(rel, sizeof rel, "tests/data/mtx/%s", name);
    snprintf(path, sizeof path, "%s", rths_test_source_path(rel));
    return path;
}

static void expect_matrix(const char *name, int rows, int cols, const double *expect) {
    double *m;
    int r, c;
    rths_error err;
    if (rths_mtx_read(data_path(name), &m, &r, &c, &err)) fail_msg("%s: %s", name, err.msg);
    assert_int_equal(r, rows);
    assert_int_equal(c, cols);
    /* decimal values that are exact in binary, or read by strtod as the literal: bitwise equal */
    for (int k = 0; k < rows * cols; k++)
        assert_true(m[k] == expect[k]);
    free(m);
}

static const double sym3[9] = {4, -1, 0, -1, 4, -2, 0, -2, 5};

static void test_good_files(void **state) {
    (void)state;
    const double general[6] = {1.5, 2.25, 0, 0, 0, -4e3}; /* 3 x 2 column-major */
    expect_matrix("coord_general.mtx", 3, 2, general);
    expect_matrix("coord_symmetric.mtx", 3, 3, sym3);
    expect_matrix("coord_symmetric_upper.mtx", 3, 3, sym3);
    expect_matrix("array_symmetric.mtx", 3, 3, sym3);
    const double array[4] = {1, 2, 3, 4};
    expect_matrix("array_general.mtx", 2, 2, array);
}

/* Each bad file: the message names the file, the line and the problem. */
static void expect_refused(const char *name, int line, const char *fragment) {
    double *m = (double *)1;
    int r = 7, c = 7;
    rths_error err = {0};
    int rc = rths_mtx_read(data_path(name), &m, &r, &c, &err);
    print_message("%s -> %s\n", name, err.msg);
    assert_int_equal(rc, RTHS_EINPUT);
    assert_null(m);
    assert_int_equal(r, 0);
    char where[64];
    snprintf(where, sizeof where, "%s:%d: ", name, line);
    if (!strstr(err.msg, where)) fail_msg("%s: '%s' not in '%s'", name, where, err.msg);
    if (!strstr(err.msg, fragment)) fail_msg("%s: '%s' not in '%s'", name, fragment, err.msg);
}

static void test_bad_files(void **state) {
    (void)state;
    expect_refused("bad_empty.mtx", 1, "empty file");
    expect_refused("bad_banner.mtx", 1, "not a Matrix Market file");
    expect_refused("bad_complex.mtx", 1, "field must be 'real'");
    expect_refused("bad_pattern.mtx", 1, "field must be 'real'");
    expect_refused("bad_hermitian.mtx", 1, "symmetry must be");
    expect_refused("bad_symmetric_not_square.mtx", 2, "must be square");
    expect_refused("bad_size.mtx", 2, "size -2 is not a whole number");
    expect_refused("bad_size_fields.mtx", 2, "expected 3 numbers on this line, found 2");
    expect_refused("bad_row_index.mtx", 5, "row index 3 is not a whole number in 1..2");
    expect_refused("bad_fractional_index.mtx", 4, "column index 1.5");
    expect_refused("bad_too_few.mtx", 4, "file ends after 2 of the 3 entries");
    expect_refused("bad_too_many.mtx", 4, "more entries than the size line announces");
    expect_refused("bad_trailing.mtx", 3, "unexpected text 'extra'");
    expect_refused("bad_nan.mtx", 3, "not a finite number");
    expect_refused("bad_both_triangles.mtx", 4, "one triangle only");
    expect_refused("bad_array_short.mtx", 5, "file ends after 3 of the 4 values");
    /* what strtod and sscanf would let through: a NUL byte hiding the rest of the line, a
     * hexadecimal float, words after the header's SYMMETRY */
    expect_refused("bad_nul.mtx", 3, "NUL byte");
    expect_refused("bad_hex.mtx", 3, "'0x1.5p2' is not a decimal number");
    expect_refused("bad_header_words.mtx", 1, "unexpected words after the header");
}

/* A mass or stiffness matrix: a missing or negative diagonal term is refused from the entries,
 * before a dense matrix of the declared size exists. The 12000 x 12000 file is 70 bytes; under an
 * address-space limit of 512 MB (below the 1.15 GB its dense form needs) it must still be refused
 * for what it is, not for memory. */
static void test_positive_diagonal(void **state) {
    (void)state;
    double *m;
    int r, c;
    rths_error err;
    assert_int_equal(rths_mtx_read_checked(data_path("coord_symmetric.mtx"),
                                           RTHS_MTX_POSITIVE_DIAGONAL, &m, &r, &c, &err),
                     RTHS_OK);
    free(m);
    assert_int_equal(rths_mtx_read_checked(data_path("bad_negative_diagonal.mtx"),
                                           RTHS_MTX_POSITIVE_DIAGONAL, &m, &r, &c, &err),
                     RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "diagonal entry (2,2) is negative"));
    assert_int_equal(rths_mtx_read_checked(data_path("coord_general.mtx"),
                                           RTHS_MTX_POSITIVE_DIAGONAL, &m, &r, &c, &err),
                     RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "must be square (is 3 x 2)"));

    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
#if !defined(__SANITIZE_ADDRESS__)
        struct rlimit lim = {512ul << 20, 512ul << 20};
        if (setrlimit(RLIMIT_AS, &lim)) _exit(3);
#endif
        int rc = rths_mtx_read_checked(data_path("bad_missing_diagonal.mtx"),
                                       RTHS_MTX_POSITIVE_DIAGONAL, &m, &r, &c, &err);
        if (rc != RTHS_EINPUT) _exit(1);
        if (!strstr(err.msg, "diagonal entry (2,2) is zero or missing")) _exit(2);
        _exit(0);
    }
    int status;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 0);
}

static void test_missing_file(void **state) {
    (void)state;
    double *m;
    int r, c;
    rths_error err;
    assert_int_equal(rths_mtx_read(data_path("no_such_file.mtx"), &m, &r, &c, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "no_such_file.mtx: cannot open: No such file"));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_good_files),
        cmocka_unit_test(test_bad_files),
        cmocka_unit_test(test_missing_file),
        cmocka_unit_test(test_positive_diagonal),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
