/* The seed rig for the cmocka tests: examples/four_storey.yaml (or another example), loaded with
 * --set style overrides and its setup read, failing the calling test with the library's message
 * when either is refused; the virtual rig without noise (or ideal) and the tight match options a
 * comparison with a model needs. One copy of what test_controller, test_rig_virtual, test_io,
 * test_run and test_frequency_problem each built themselves. Named fixture_*, not test_*, so CMake
 * does not register it as a test of its own; it is linked into every test executable. */
#ifndef RTHS_FIXTURE_SEED_RIG_H
#define RTHS_FIXTURE_SEED_RIG_H

#include "rths/config.h"
#include "rths/iterate.h"
#include "rths/rig_virtual.h"
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

/* The virtual rig's options for a comparison with a model: controller and plant defaults, the
 * plant ideal (continuous force, no actuator dynamics, rths_plant_ideal) or, ideal 0, the default
 * rig with its sensor noise off. */
void rths_fixture_quiet_options(int ideal, rths_controller_options *co, rths_plant_options *po);

/* The virtual rig of setup s with these options, failing the calling test when it is refused. */
rths_rig *rths_fixture_rig(const rths_setup *s, const rths_controller_options *co,
                           const rths_plant_options *po);

/* Settle and Newton options for a match solved far below the differences the tests compare:
 * steady state judged to 1e-6 of the amplitude (the default 3e-4 is the host's trade-off for
 * speed; here it would be the error floor), within 4000 periods; converged at 1e-7. */
void rths_fixture_tight_match(rths_settle_options *so, rths_newton_options *no);

#endif
