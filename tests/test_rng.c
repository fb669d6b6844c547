/* The deterministic random numbers (core.h): the ziggurat's normal draws against the standard
 * normal's closed forms, and the block draw against one-by-one draws. */
#include "rths/core.h"
#include "testlib.h"

#include <math.h>
#include <stdlib.h>

enum { DRAWS = 4000000 };

/* Moments and tail shares of 4e6 draws. Every tolerance is five standard errors of the sample
 * statistic under the true distribution (a correct generator fails one in ~1.7e6 runs; the
 * seed is fixed, so the test is deterministic): mean 1/sqrt(N); variance sqrt(2/N); fourth
 * moment sqrt((105 - 9) / N); a share P sqrt(P (1 - P) / N). A generator with a wrong layer
 * table, a missing tail or wedge, or the index bits reused by the uniform misses by far more. */
static void normal_draws_follow_the_standard_normal(void **state) {
    (void)state;
    rths_rng rng;
    rths_rng_seed(&rng, 7);
    const double n = DRAWS, edges[4] = {1.0, 2.0, 3.0, 3.5};
    double s1 = 0, s2 = 0, s4 = 0, lag1 = 0, prev = 0;
    long beyond[4] = {0, 0, 0, 0};
    for (long i = 0; i < DRAWS; i++) {
        double x = rths_rng_normal(&rng), x2 = x * x;
        s1 += x, s2 += x2, s4 += x2 * x2, lag1 += x * prev;
        prev = x;
        for (int e = 0; e < 4; e++)
            beyond[e] += fabs(x) > edges[e];
    }
    assert_close(s1 / n, 0.0, 5 / sqrt(n));
    assert_close(s2 / n, 1.0, 5 * sqrt(2 / n));
    assert_close(s4 / n, 3.0, 5 * sqrt(96 / n));
    assert_close(lag1 / n, 0.0, 5 / sqrt(n)); /* successive draws uncorrelated */
    for (int e = 0; e < 4; e++) {
        double p = erfc(edges[e] / sqrt(2.0)); /* P(|x| > edge) */
        assert_close(beyond[e] / n, p, 5 * sqrt(p * (1 - p) / n));
    }
}

/* rths_rng_normals fills a block with the very numbers rths_rng_normal would draw, in order,
 * and leaves the generator where those draws would: the plant's pooled sensor noise is the same
 * sequence as drawing per reading. */
static void block_draws_equal_single_draws(void **state) {
    (void)state;
    rths_rng one, block;
    rths_rng_seed(&one, 42);
    rths_rng_seed(&block, 42);
    double got[257];
    for (int round = 0; round < 40; round++) {
        int n = 1 + (round * 37) % 257;
        rths_rng_normals(&block, got, n);
        for (int i = 0; i < n; i++)
            assert_true(got[i] == rths_rng_normal(&one));
    }
    assert_true(rths_rng_next(&one) == rths_rng_next(&block));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(normal_draws_follow_the_standard_normal),
        cmocka_unit_test(block_draws_equal_single_draws),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
