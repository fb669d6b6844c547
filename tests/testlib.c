#include "testlib.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

void rths_test_assert_close(double actual, double expected, double tol, const char *expr,
                            const char *file, int line) {
    if (!(fabs(actual - expected) <= tol)) {
        print_error("%s = %.17g, expected %.17g within %.3g (off by %.3g)\n", expr, actual,
                    expected, tol, fabs(actual - expected));
        _fail(file, line);
    }
}

const char *rths_test_source_path(const char *relative) {
    static char buf[4096];
    const char *root = getenv("RTHS_SOURCE_DIR");
    snprintf(buf, sizeof buf, "%s/%s", root ? root : ".", relative);
    return buf;
}
