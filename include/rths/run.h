/* rths run: a whole frequency-response test as one library call, what `rths frf` does, for the
 * CLI and for C or Python callers: configuration -> rig -> continuation -> journal -> outputs
 * (journal.jsonl, frf.csv, truth.csv, summary.json, figures, run.log, config.yaml in out_dir).
 *
 *   rths_run_frf_options o = {.cfg = cfg, .setup = &setup, .out_dir = "out/run"};
 *   rths_run_callbacks cb = {.on_point = my_point, .should_cancel = my_cancel, .user = me};
 *   rths_run_frf_result r;
 *   int rc = rths_run_frf(&o, &cb, &r, &err);
 *
 * Bad input (configuration, a journal of another run, an occupied folder) is refused with
 * RTHS_EINPUT before anything is written. Once the run started, everything accepted is saved
 * however it ends: normally, at the point limit, cancelled through should_cancel (RTHS_OK,
 * r.status RTHS_RUN_CANCELLED), short of its end by failed corrections (RTHS_EFAIL, r.status
 * RTHS_RUN_STOPPED, the error naming the cause), or by a rig fault or I/O error (RTHS_EFAIL). */
#ifndef RTHS_RUN_H
#define RTHS_RUN_H

#include "rths/continuation.h"
#include "rths/floquet.h"
#include "rths/setup.h"

#include <stdint.h>

/* What the seed's flowchart ("paper" strategy) changes in the configuration besides the iteration
 * defaults: apply these overrides first when loading it (later overrides still win). */
extern const char *const rths_run_paper_overrides[];
enum { RTHS_RUN_PAPER_OVERRIDES = 3 };

typedef struct rths_run_frf_options {
    rths_config *cfg;        /* loaded (with overrides); the run reads its sections from it */
    const rths_setup *setup; /* structure, split, forcing read from cfg */
    const char *out_dir;     /* created; must not hold a run unless resume */
    const char *strategy;    /* "default" (NULL) or "paper" */
    int harmonics;           /* 1..3; 0: iteration.harmonics */
    int resume;              /* continue the run in out_dir from its journal */
    const char *rig_uri;     /* tcp://HOST:PORT: a controller process; NULL: the virtual rig */
    int force;    /* run even when the true response exceeds controller.limits.displacement_m, and
                     accept (flagged) a point below the measured noise floor */
    int has_seed; /* noise seed of the virtual rig (else rig.seed) */
    uint64_t seed;
    /* recorded in run.log and summary.json */
    const char *config_path;
    const char *const *overrides;
    int n_overrides;
    int argc;
    char **argv;
    /* a rig of the caller's to measure on instead of creating one (rig_uri NULL): the run takes
     * it over and destroys it when it ends, also on error; treated like a real rig (its physical
     * part may be nonlinear whatever the model says). NULL: the virtual rig or rig_uri */
    rths_rig *rig;
    /* with rig_uri: reset the controller's latched fault before the run (rths_rig_clear_fault,
     * logged in run.log); RTHS_EFAIL with the controller's answer when it refuses */
    int reset_fault;
    /* a multi-site test's controllers (rig.sites), one URI per site in rig.sites' order, from
     * `--rig` given once per site (n_site_uris >= 2; rig_uri NULL): they override
     * rig.sites.N.uri. 0: rig_uri, or the URIs in rig.sites */
    const char *const *site_uris;
    int n_site_uris;
} rths_run_frf_options;

typedef struct rths_run_callbacks {
    /* every accepted point once it is journaled (is_update: a fold flag changed later);
     * non-zero stops the run as a failure */
    rths_point_fn on_point;
    /* after every correction attempt, for a progress display */
    rths_progress_fn on_progress;
    /* polled after every accepted point: non-zero ends the run cleanly (all saved) */
    int (*should_cancel)(void *user);
    void *user;
} rths_run_callbacks;

typedef enum {
    RTHS_RUN_COMPLETED = 0, /* reached the end frequency */
    /* ended early: the point limit (rths_run_frf returns RTHS_OK), or short of the end
     * frequency by failed corrections, the step limit or the branch leaving the range
     * (RTHS_EFAIL, the error naming the cause) */
    RTHS_RUN_STOPPED = 1,
    RTHS_RUN_CANCELLED = 2, /* should_cancel asked for it */
    RTHS_RUN_FAILED = 3     /* rig fault, I/O error, or the point callback stopped it */
} rths_run_status;

typedef struct rths_run_frf_result {
    rths_run_status status;
    int points, converged_points, resumed_points, evaluations, folds;
    double rig_time_s, wall_time_s;
    double max_relative_error_vs_truth; /* see rths_truth_relative_error */
    char stop_reason[RTHS_ERROR_MSG_LEN + 256];
    int outputs_written; /* 1: frf.csv and summary.json were written (the counts are valid) */
} rths_run_frf_result;

/* frf.csv's columns of a one-DoF run, and an accepted point's row as frf.csv has it (what a point
 * callback of the C API receives): the RTHS_RUN_FRF_LEADING_COLUMNS from "point" to "stable",
 * then the RTHS_RUN_FRF_TAIL_COLUMNS that always end a row (late_samples,
 * clipped_demand_samples, saturated_sensor_samples: the accepted evaluation's integrity counts;
 * resumed: 1 when a resumed run measured the point; below_noise_floor: 1 when --force accepted
 * the point below the measured noise floor), after any per-DoF or optional columns. */
enum {
    RTHS_RUN_FRF_LEADING_COLUMNS = 24,
    RTHS_RUN_FRF_TAIL_COLUMNS = 5,
    RTHS_RUN_FRF_COLUMNS = RTHS_RUN_FRF_LEADING_COLUMNS + RTHS_RUN_FRF_TAIL_COLUMNS
};
extern const char *const rths_run_frf_columns[RTHS_RUN_FRF_COLUMNS];
void rths_run_frf_row(const rths_point *pt, double *row);
/* With several interface DoFs (n > 1) frf.csv adds, for every interface DoF d = 1..n (the split's
 * interface order), dof<d>_amplitude_m (the matched estimate when the strategy reports it, else
 * the measurement), dof<d>_numerical_amplitude_m, dof<d>_phase_rad, dof<d>_interface_error_m
 * and dof<d>_amplitude_se_m (the standard error of dof<d>_amplitude_m) of the fundamental after
 * the leading columns, before the tail; one DoF keeps the columns above alone. */
enum {
    RTHS_RUN_FRF_DOF_COLUMNS = 5,
    RTHS_RUN_FRF_MAX_COLUMNS =
        RTHS_RUN_FRF_COLUMNS + RTHS_RUN_FRF_DOF_COLUMNS * RTHS_MAX_INTERFACE_DOFS
};
int rths_run_frf_column_count(int interface_dofs);
/* Column i's name for a run with interface_dofs DoFs (NULL beyond the count). */
const char *rths_run_frf_column_name(int interface_dofs, int i);
/* The point's row with rths_run_frf_column_count(interface_dofs) entries. */
void rths_run_frf_row_dofs(const rths_point *pt, int interface_dofs, double *row);

/* ---- the experimental Floquet estimate at a held orbit (docs/method.md, "Experimental Floquet
 * multipliers"): configuration keys stability.experimental_floquet (off by default),
 * stability.floquet_periods, stability.floquet_perturbation_v, stability.floquet_cutoff_hz,
 * stability.floquet_samples_per_period, stability.floquet_max_order,
 * stability.floquet_phase_harmonics, stability.floquet_phase_bins,
 * stability.floquet_varying_lags ---- */
typedef struct rths_floquet_measure_options {
    int enabled;
    int periods;              /* whole forcing periods recorded under the perturbation: 120 */
    double perturbation_v;    /* RMS of the demand perturbation, V: 0.02 */
    double cutoff_hz;         /* its band limit (two first-order low-passes): 5 Hz */
    int samples_per_period;   /* phase grid P: 16 */
    double sample_rate_hz;    /* the controller's (controller.sample_rate_hz): sizes the record */
    uint64_t seed;            /* of the perturbation; the run adds the point index */
    rths_floquet_options fit; /* rths_floquet_defaults with max_order 24 */
} rths_floquet_measure_options;

void rths_floquet_measure_defaults(rths_floquet_measure_options *o);
/* Reads the keys above (located errors). The chart's own keys of the stability section are read
 * alongside (rths_chart_config_read), so a typo anywhere in the section is still refused. */
int rths_floquet_measure_config_read(rths_config *cfg, rths_floquet_measure_options *o,
                                     rths_error *err);
/* At the rig's current forcing (frequency_hz) and target, held at a converged point: records the
 * perturbed response, grids it in phase, subtracts the periodic orbit and estimates the
 * multipliers of the assembly (floquet.h). *rig_time_s: the rig time the record took. RTHS_EINPUT
 * when the rig cannot inject a perturbation. */
int rths_floquet_measure(rths_rig *rig, double frequency_hz, const rths_floquet_measure_options *o,
                         uint64_t seed, rths_floquet_estimate *est, double *rig_time_s,
                         rths_error *err);

/* ---- multi-site tests (docs/method.md, "Multi-site tests"): rig.sites lists the sites, each
 * {uri: tcp://HOST:PORT (optional: --rig gives it), interface_dofs: [1-based DoFs of
 * split.interface]}; every interface DoF belongs to exactly one site, every physical DoF to the
 * site whose interface DoFs it is joined to through physical elements (no physical element may
 * join two sites). Each site runs its own `rths controller CONFIG --site N` over the same file,
 * whose split the overrides below restrict to the site. ---- */
#define RTHS_RUN_SITE_MAX_PHYSICAL 64
typedef struct rths_run_site {
    char uri[300]; /* rig.sites.N.uri, "" when absent */
    int n_int;
    int int_dofs[RTHS_MAX_INTERFACE_DOFS]; /* assembly DoFs (0-based), ascending */
    int map[RTHS_MAX_INTERFACE_DOFS];      /* each one's index in the split's interface order */
    int n_phys;
    int phys_dofs[RTHS_RUN_SITE_MAX_PHYSICAL]; /* its physical substructure's DoFs, ascending */
} rths_run_site;
typedef struct rths_run_sites {
    int n; /* 0: rig.sites absent (one rig) */
    rths_run_site site[RTHS_MAX_INTERFACE_DOFS];
    /* 1 when numerical elements join interface DoFs of two sites (through numerical DoFs):
     * only the frequency form (split.numerical_solver: frequency) can run it; coupling_dof is
     * such a numerical DoF (0-based) */
    int numerical_couples_sites;
    int coupling_dof;
} rths_run_sites;

/* Reads rig.sites over the setup (located errors: a DoF in no site or two, a shared physical
 * element, more than RTHS_MAX_INTERFACE_DOFS sites, keys the sites cannot share: rig.actuators,
 * rig.lasers, output.dofs, the interface shares, base excitation). out->n = 0 when absent. */
int rths_run_sites_read(rths_config *cfg, const rths_setup *setup, rths_run_sites *out,
                        rths_error *err);
/* RTHS_EINPUT naming why when the numerical side couples the sites and the real-time form is
 * asked for (each site's controller would need the other sites' motion in real time). */
int rths_run_sites_check_solver(rths_config *cfg, const rths_setup *setup,
                                const rths_run_sites *sites, rths_error *err);
/* The overrides that make the shared configuration site k's (0-based): split.interface,
 * split.physical and split.numerical (every other DoF) and split.mass_ratio (the site's p). */
typedef struct rths_run_site_sets {
    int n;
    char text[4][4096];
} rths_run_site_sets;
int rths_run_site_overrides(const rths_setup *setup, const rths_run_sites *sites, int k,
                            rths_run_site_sets *out, rths_error *err);

/* Runs the test (see above). Returns RTHS_OK when it ran (status says how it ended; also when
 * cancelled), RTHS_EINPUT on bad input (nothing written), RTHS_EFAIL on a failure during it. */
int rths_run_frf(const rths_run_frf_options *opt, const rths_run_callbacks *cb,
                 rths_run_frf_result *result, rths_error *err);

#endif
