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

void rths_fixture_quiet_options(int ideal, rths_controller_options *co, rths_plant_options *po) {
    rths_controller_defaults(co);
    rths_plant_defaults(po);
    if (ideal)
        rths_plant_ideal(po);
    else
        po->noise = 0;
}

rths_rig *rths_fixture_rig(const rths_setup *s, const rths_controller_options *co,
                           const rths_plant_options *po) {
    rths_rig *rig = NULL;
    rths_error err;
    if (rths_virtual_rig_create_with(s, co, po, &rig, &err)) fail_msg("%s", err.msg);
    return rig;
}

void rths_fixture_tight_match(rths_settle_options *so, rths_newton_options *no) {
    rths_settle_defaults(so, 0);
    so->rel_tolerance = 1e-6;
    so->abs_tolerance_m = 1e-14;
    so->max_wait_periods = 4000;
    rths_newton_defaults(no, 0);
    no->rel_tolerance = 1e-7;
    no->abs_tolerance_m = 1e-14;
}
