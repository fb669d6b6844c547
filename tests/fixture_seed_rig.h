/* The seed rig for the cmocka tests: examples/four_storey.yaml (or another example), loaded with
 * --set style overrides and its setup read, failing the calling test with the library's message
 * when either is refused. One copy of what test_controller, test_rig_virtual, test_io and
 * test_run each built themselves. Named fixture_*, not test_*, so CMake does not register it as a
 * test of its own; it is linked into every test executable. */
#ifndef RTHS_FIXTURE_SEED_RIG_H
#define RTHS_FIXTURE_SEED_RIG_H

#include "rths/config.h"
#include "rths/setup.h"

/* the seed building: four storeys, the top one physical (docs/method.md) */
#define RTHS_FIXTURE_SEED "examples/four_storey.yaml"

/* The example (a path relative to the source tree) with n_sets overrides ("key=value"). */
rths_config *rths_fixture_config(const char *example, const char *const *sets, int n_sets);

/* The same, and its setup read into *s; *cfg receives the configuration (freed by the caller). */
void rths_fixture_setup(const char *example, const char *const *sets, int n_sets, rths_config **cfg,
                        rths_setup *s);

/* The seed rig itself: rths_fixture_config / rths_fixture_setup of RTHS_FIXTURE_SEED. */
rths_config *rths_fixture_seed_config(const char *const *sets, int n_sets);
void rths_fixture_seed_setup(const char *const *sets, int n_sets, rths_config **cfg, rths_setup *s);

#endif
