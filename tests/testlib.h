/* Shared test helpers (cmocka). */
#ifndef RTHS_TESTLIB_H
#define RTHS_TESTLIB_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

/* Asserts |actual - expected| <= tol, printing all three on failure. */
#define assert_close(actual, expected, tol)                                                        \
    rths_test_assert_close((actual), (expected), (tol), #actual, __FILE__, __LINE__)
void rths_test_assert_close(double actual, double expected, double tol, const char *expr,
                            const char *file, int line);

/* Relative: |actual - expected| <= rel * |expected|. */
#define assert_rel(actual, expected, rel)                                                          \
    rths_test_assert_close((actual), (expected), (rel)*fabs(expected), #actual, __FILE__, __LINE__)

/* Path inside the source tree (tests run with RTHS_SOURCE_DIR set by ctest). */
const char *rths_test_source_path(const char *relative);

#endif
