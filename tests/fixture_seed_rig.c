/* The seed rig fixture of the cmocka tests (fixture_seed_rig.h). */
#include "fixture_seed_rig.h"

#include "testlib.h"

rths_config *rths_fixture_config(const char *example, const char *const *sets, int n_sets) {
    rths_config *cfg = NULL;
    rths_error err;
    if (rths_config_load(rths_test_source_path(example), sets, n_sets, &cfg, &err))
        fail_msg("%s", err.msg);
    return cfg;
}

void rths_fixture_setup(const char *example, const char *const *sets, int n_sets, rths_config **cfg,
                        rths_setup *s) {
    rths_error err;
    *cfg = rths_fixture_config(example, sets, n_sets);
    if (rths_setup_read(*cfg, s, &err)) fail_msg("%s", err.msg);
}

rths_config *rths_fixture_seed_config(const char *const *sets, int n_sets) {
    return rths_fixture_config(RTHS_FIXTURE_SEED, sets, n_sets);
}

void rths_fixture_seed_setup(const char *const *sets, int n_sets, rths_config **cfg,
                             rths_setup *s) {
    rths_fixture_setup(RTHS_FIXTURE_SEED, sets, n_sets, cfg, s);
}
