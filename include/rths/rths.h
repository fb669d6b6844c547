/* rths.h: the stable C API of librths (documented in docs/c-api.md), the one header a program or a
 * language binding (python/rths) needs.
 *
 * Conventions
 *  - Every function that can fail returns a status, RTHS_OK (0), RTHS_EFAIL (1: numerics, I/O, rig
 *    fault) or RTHS_EINPUT (2: bad input), and fills *err (may be NULL) with the same code and a
 *    message; configuration errors read "FILE:LINE:COL: key 'a.b': what is wrong" (or
 *    "--set a.b=...: ..." for an override).
 *  - Objects are opaque handles made by one function and freed by its *_free (NULL is accepted).
 *  - Results are tables of named double columns, named exactly as the columns of the CSV files a
 *    run folder holds (frf.csv, modes.csv, ...), plus the run's summary.json as text.
 *  - SI units everywhere, as in the column names. Thread safety: one handle per thread.
 *
 * Adding functions keeps RTHS_API_VERSION; changing or removing one raises it (and the library's
 * SONAME). */
#ifndef RTHS_RTHS_H
#define RTHS_RTHS_H

#include "rths/core.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* 2: rths_error's message grew to RTHS_ERROR_MSG_LEN (8192) bytes, from the 1024 version 1
 * documented, and the layout queries below were added. */
#define RTHS_API_VERSION 2

/* RTHS_API_VERSION of the library actually loaded (compare with the header's). */
int rths_api_version(void);
/* The rths release, e.g. "0.1.0". */
const char *rths_api_release(void);

/* ---- the layout of the structs a caller allocates (part of the ABI) ----
 * rths_error, rths_api_frf_options and rths_api_simulate_options are allocated by the caller. A
 * binding that declares them itself instead of compiling this header (python/rths/_lib.py through
 * ctypes) checks its declaration against the library it loaded, and refuses to use a library whose
 * layout differs: a smaller rths_error than the library's is overwritten past its end. */

/* sizeof(type) as this library was compiled, for "rths_error", "rths_api_frf_options" and
 * "rths_api_simulate_options"; 0 for any other name. */
size_t rths_api_sizeof(const char *type);
/* offsetof(type, field) as this library was compiled (e.g. "rths_error", "msg"); -1 for an
 * unknown type or field. */
long rths_api_offsetof(const char *type, const char *field);

/* ---- configuration ---- */

typedef struct rths_api_config rths_api_config;

/* Reads the YAML test description at path (NULL: defaults only) with overrides "a.b=value" applied
 * in order (as the CLI's --set), and checks its structural part (structure, split, forcing, model)
 * at once. Every operation re-reads the file, checking the sections it uses and refusing unknown
 * keys in them, as the command of the same name does. */
int rths_api_config_load(const char *path, const char *const *overrides, int n_overrides,
                         rths_api_config **out, rths_error *err);
void rths_api_config_free(rths_api_config *cfg);
/* Degrees of freedom of the configured assembly. */
int rths_api_config_dofs(const rths_api_config *cfg);
/* The value of key ("split.mass_ratio") as configured (the file with the overrides applied), as
 * text: a scalar as written ("0.33", "true", "shaker"), a list of numbers as "[1, 2.5]", a matrix
 * as "[[1, 0], [0, 1]]" (%.17g). *text is malloc'ed (free with rths_api_free). RTHS_EINPUT for a
 * key that is not set (its default applies; docs/config.md) or that holds a mapping. */
int rths_api_config_get(const rths_api_config *cfg, const char *key, char **text, rths_error *err);
/* Writes len bytes of data to path as every run folder's files are written: to a temporary name
 * in the same folder, renamed into place when complete (a crash never leaves half a file). */
int rths_api_write_file(const char *path, const char *data, size_t len, rths_error *err);
/* Frees what the library allocated for the caller (rths_api_config_get's text). */
void rths_api_free(void *p);

/* ---- results: named tables of doubles, a summary, a folder ---- */

typedef struct rths_result rths_result;

int rths_result_table_count(const rths_result *r);
/* Name of table t (0 <= t < count): the CSV file's name without ".csv" ("frf", "modes"). */
const char *rths_result_table_name(const rths_result *r, int t);
/* Index of the table called name, or -1. */
int rths_result_table_index(const rths_result *r, const char *name);
int rths_result_rows(const rths_result *r, int t);
int rths_result_columns(const rths_result *r, int t);
const char *rths_result_column_name(const rths_result *r, int t, int column);
/* rows values, valid until rths_result_free. */
const double *rths_result_column(const rths_result *r, int t, int column);
/* summary.json's text ("" when there is none). */
const char *rths_result_summary_json(const rths_result *r);
/* config.yaml's text, the configuration as resolved ("" when the result has no folder). */
const char *rths_result_config_yaml(const rths_result *r);
/* What the command of the same name prints on success (its standard output), "" for the
 * operations that print nothing. */
const char *rths_result_text(const rths_result *r);
/* The run folder, or NULL when the result was not written to one. */
const char *rths_result_dir(const rths_result *r);
void rths_result_free(rths_result *r);

/* ---- operations ---- */

/* rths model: modes and analytic FRF of the true assembly. Tables "modes" (mode, frequency_hz,
 * omega_rad_s, damping_ratio, phi<i>_per_sqrt_kg) and "true_frf" (frequency_hz,
 * x<i>_amplitude_m, x<i>_phase_rad), equal to the CLI's modes.csv and true_frf.csv. out_dir (may
 * be NULL) also writes them there as a run folder (CSV, summary.json, config.yaml, results.mat). */
int rths_api_model(const rths_api_config *cfg, const char *out_dir, rths_result **out,
                   rths_error *err);

/* rths chart: stability chart of the delayed-feedback test over (tau, p) with the stability.*
 * keys. Tables "chart" (tau_s, p, max_real_part_per_s, stable; p outer, tau inner), "boundary"
 * (tau_s, p, omega_rad_s), "critical" (p, critical_delay_s, crossing_omega_rad_s), equal to the
 * CLI's CSV files. out_dir as for rths_api_model. */
int rths_api_chart(const rths_api_config *cfg, const char *out_dir, rths_result **out,
                   rths_error *err);

/* rths tune: PD and grounding gains from the model (docs/method.md, "Tuning the gains"), every
 * interface DoF. delay_s < 0: the configured delay as the virtual rig holds it (whole samples);
 * otherwise the physical loop's delay, s, in [0, 0.1] (as --delay). Table "loop" (frequency_hz,
 * then the configured and the tuned loop's *_loop_gain_db, *_loop_phase_deg, *_sensitivity_db;
 * with several interface DoFs each loop's, broken with the others closed, prefixed dof<d>_),
 * equal to the CLI's loop.csv; the summary as summary.json, its "tuned_yaml" the keys to paste.
 * out_dir as for rths_api_model (also tuned.yaml there). RTHS_EFAIL when no gains meet the
 * rule. */
int rths_api_tune(const rths_api_config *cfg, double delay_s, const char *out_dir,
                  rths_result **out, rths_error *err);

/* rths fidelity: the converged hybrid test's interface FRF for every integration scheme of the
 * numerical substructure against the true assembly, with the fidelity.* keys (docs/method.md,
 * "Numerical substructure integration"). Table "fidelity" (frequency_hz, true_amplitude_m,
 * <scheme>_amplitude_m), equal to the CLI's fidelity.csv (on a sparse model the real-time
 * reduction's interface FRF error instead: docs/config/fidelity.md); the summary's "curves" give
 * each curve's peak_hz, peak_amplitude_m and peak_error_percent; rths_result_text the table the CLI
 * prints. out_dir as for rths_api_model (also fidelity.gp/.png/.svg there). */
int rths_api_fidelity(const rths_api_config *cfg, const char *out_dir, rths_result **out,
                      rths_error *err);

/* rths simulate: one hybrid test at a fixed target (iterative mode) or the conventional test
 * with the feedback loop closed (feedback mode), as the command's options. */
/* The most target harmonics per interface DoF, and interface DoFs, a test can have. */
#define RTHS_API_MAX_HARMONICS 5
#define RTHS_API_MAX_INTERFACE_DOFS 4

typedef struct rths_api_simulate_options {
    const char *out_dir; /* run folder (may be NULL: the result only) */
    double frequency_hz; /* forcing frequency, Hz, in (0, 1e5] (as --frequency) */
    int periods;         /* forcing periods, 1..100000 (as --periods) */
    int feedback;        /* 0: iterative mode, nonzero: feedback mode (as --mode) */
    double delay_s;      /* feedback mode: > 0 the pure-delay model (as --delay), 0 the rig */
    int harmonics;       /* iterative: target harmonics per interface DoF, 1..5 */
    int target_dofs;     /* iterative: interface DoFs the target gives (all of them) */
    const double *target_a, *target_b; /* DoF d's A_k, B_k at [d * harmonics + k - 1], m */
    int trace_periods;                 /* iterative: periods in the trace, 0: min(periods, 5) */
    int has_seed;                      /* nonzero: seed replaces rig.seed (as --seed) */
    uint64_t seed;
    const char *rig_uri; /* "tcp://HOST:PORT" of a controller process; NULL: the virtual rig */
    int reset_fault;     /* with rig_uri: reset the controller's latched fault first */
} rths_api_simulate_options;

void rths_api_simulate_options_default(rths_api_simulate_options *o);
/* Runs the test. Tables "coefficients" (one row per period: the Fourier coefficients of the
 * physical and numerical interface displacements, m, and the period's integrity counts) and
 * "trace" (time_s, x_phys_m, x_num_m, target_m, force_n, demand), equal to the CLI's CSV files;
 * the summary as summary.json (final_phys, final_num, final_interface_error_m; in feedback mode
 * diverged, growth_rate_per_s, ...); rths_result_text what the CLI prints. With o->out_dir also
 * the run folder (simulate.gp/.png/.svg). */
int rths_api_simulate(const rths_api_config *cfg, const rths_api_simulate_options *o,
                      rths_result **out, rths_error *err);

/* Reads a finished (or interrupted) run folder: every *.csv as a table, summary.json and
 * config.yaml as text. */
int rths_api_read_run(const char *dir, rths_result **out, rths_error *err);

/* ---- the FRF test (rths frf) ---- */

/* Called for every accepted point with its frf.csv row (n_columns values named as frf.csv's
 * header). Return 0 to go on, anything else to stop the run: it ends as if cancelled. */
typedef int (*rths_api_point_fn)(void *user, int n_columns, const char *const *column_names,
                                 const double *row);
/* Polled before the run and after every accepted point (a point in progress is finished first);
 * nonzero ends the run cleanly: everything accepted is saved (journal.jsonl, frf.csv,
 * summary.json whose stop_reason says "cancelled by the caller"), and the run can be resumed. */
typedef int (*rths_api_cancel_fn)(void *user);

typedef struct rths_api_frf_options {
    const char *out_dir;  /* run folder, required (as --out) */
    const char *strategy; /* "default" (NULL) or "paper" (as --strategy) */
    int harmonics;        /* 1..3, 0: iteration.harmonics (as --harmonics) */
    int has_seed;         /* nonzero: seed replaces rig.seed (as --seed) */
    uint64_t seed;
    int resume;          /* continue the interrupted run in out_dir (as --resume) */
    const char *rig_uri; /* "tcp://HOST:PORT" of a controller process; NULL: the virtual rig */
    rths_api_point_fn on_point;       /* may be NULL */
    rths_api_cancel_fn should_cancel; /* may be NULL */
    void *user;                       /* passed to both */
    int force; /* run even when the true response exceeds controller.limits.displacement_m */
} rths_api_frf_options;

void rths_api_frf_options_default(rths_api_frf_options *o);
/* Nonzero when this library can run FRF tests (it is built with the run module). */
int rths_api_frf_available(void);
/* Runs the test into o->out_dir and returns the folder read back (rths_api_read_run): table "frf"
 * equals frf.csv. A run that stopped on a callback or a cancellation returns RTHS_OK with the
 * result (summary.json's stop_reason says why). A rig fault or I/O error returns RTHS_EFAIL and no
 * result, but the folder still holds everything accepted (rths_api_read_run reads it). */
int rths_api_frf(const rths_api_config *cfg, const rths_api_frf_options *o, rths_result **out,
                 rths_error *err);

/* ---- the web view of a run (rths view, docs/view.md) ---- */

typedef struct rths_api_view rths_api_view;
/* Checks dir (a run folder or a campaign folder) and listen ("ADDR:PORT", "[v6]:PORT"; NULL:
 * 127.0.0.1:8080; port 0: a free one); RTHS_EINPUT naming the problem. Nothing is served yet. */
int rths_api_view_open(const char *dir, const char *listen, rths_api_view **out, rths_error *err);
/* The address it serves on, and whether that is a loopback address (else the page, which has no
 * authentication, is reachable from other machines). */
const char *rths_api_view_host(const rths_api_view *v);
int rths_api_view_host_is_loopback(const rths_api_view *v);
/* Starts serving (threads of its own: block the signals they must not take first). */
int rths_api_view_serve(rths_api_view *v, rths_error *err);
/* The bound port once served, -1 before. */
int rths_api_view_port(const rths_api_view *v);
/* Stops serving (every connection closed) and frees v (NULL accepted). */
void rths_api_view_stop(rths_api_view *v);

/* ---- the controller process (rths controller, docs/protocol.md) ---- */

typedef struct rths_api_controller rths_api_controller;
/* Builds the real-time controller from the configuration (as `rths controller --config`: the
 * numerical substructure, the simulated plant or the io section's plug-in, the server section)
 * and starts it: the paced loop and the network thread serving one host on listen ("ADDR:PORT",
 * "[v6]:PORT"; NULL: the command's default, loopback; port 0: a free one), and the process's web
 * page on view_listen (NULL: none). site: 1-based site of a multi-site test (rig.sites), 0 the
 * whole test. Returns once it listens; it runs until rths_api_controller_stop. Its threads start
 * with SIGINT and SIGTERM blocked (the caller's mask is restored), so they never take a signal
 * meant for the program. Bad input is RTHS_EINPUT before anything runs; a port in use
 * RTHS_EFAIL. It prints nothing. */
int rths_api_controller_start(const rths_api_config *cfg, const char *listen, int site,
                              const char *view_listen, rths_api_controller **out, rths_error *err);
/* The bound port (the one chosen for port 0); the page's, -1 without one. */
int rths_api_controller_port(const rths_api_controller *c);
int rths_api_controller_view_port(const rths_api_controller *c);
/* Stops it (the actuator disarmed, the host's connection and the page closed) and frees c (NULL
 * accepted). stats (may be NULL) receives a result whose summary holds the loop's statistics:
 * samples, overruns, lateness_p50_s, lateness_p99_s, lateness_p999_s, worst_lateness_s,
 * step_mean_s, step_max_s, fault (a lateness beyond the loop's 50 ms histogram reads as just
 * above 0.05 s). RTHS_EFAIL when the loop stalled in the I/O device (c is still freed). */
int rths_api_controller_stop(rths_api_controller *c, rths_result **stats, rths_error *err);
/* The machine's latency test (`rths controller --latency-test`): the paced loop alone for
 * seconds, in (0, 3600], at controller.sample_rate_hz with the server section's real-time set-up
 * (cfg may be NULL: the defaults). The summary holds samples (seconds x rate, rounded),
 * sample_rate_hz, overruns, lateness_p50_s ... lateness_p999_s, worst_lateness_s, sched_fifo,
 * memory_locked, pinned; rths_result_text the line the command prints. Blocks for the duration. */
int rths_api_controller_latency(const rths_api_config *cfg, double seconds, rths_result **out,
                                rths_error *err);

/* ---- the rths command's own entry points (src/cli) ----
 * Each command's whole job on a configuration the command has read once, and the run folder it
 * writes through the one result writer: `rths model` and rths_api_model (and so on) share their
 * tables, summary and CSV writer through these. The command includes nothing of the library but
 * this header (tests/cli/layering.sh); the handles below are opaque. Made for the rths command:
 * outside RTHS_API_VERSION, they change with it. */

/* A configuration as a command holds it: the file read once with the overrides applied in order,
 * and (with RTHS_API_READ_SETUP) the structural setup read from it (structure, split, forcing,
 * model). The command's entry point reads its own sections from it and refuses unknown keys in
 * them, so the check sees every key the run asked for. */
typedef struct rths_api_command_config rths_api_command_config;
enum { RTHS_API_READ_SETUP = 1 };
/* path NULL: defaults only. The overrides are copied. RTHS_EINPUT with the located message
 * ("FILE:LINE:COL: key 'a.b': ...") for bad input; nothing is left allocated on failure. */
int rths_api_command_config_load(const char *path, const char *const *overrides, int n_overrides,
                                 unsigned flags, rths_api_command_config **out, rths_error *err);
void rths_api_command_config_free(rths_api_command_config *c);

/* A command's run folder: created (with parents) with its run.log and the configuration as
 * resolved (config.yaml). A folder holding a run of another command is refused (RTHS_EINPUT); an
 * earlier run of the same command is replaced (its files removed first) unless argv holds
 * --resume. command, argc and argv (the command line, argv[0] the command) open run.log. */
typedef struct rths_api_run_folder rths_api_run_folder;
int rths_api_run_folder_open(const char *dir, const char *command, int argc, char **argv,
                             const rths_api_command_config *c, rths_api_run_folder **out,
                             rths_error *err);
/* One timestamped line in run.log, flushed. */
void rths_api_run_folder_log(rths_api_run_folder *f, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* results.mat (MAT 7.3) from every table and the summary written so far; RTHS_EFAIL with the
 * reason when it cannot be written. */
int rths_api_run_folder_write_mat(rths_api_run_folder *f, rths_error *err);
/* Lists the files this run wrote (what a later run of the same command replaces), closes run.log
 * and frees f (NULL accepted). */
void rths_api_run_folder_close(rths_api_run_folder *f);
/* Writes r into the open folder: its text files, each table as NAME.csv (the CSV writer of every
 * run folder, %.17g), its run.log lines, summary.json (when r has one), its figures. */
int rths_api_result_write(const rths_result *r, rths_api_run_folder *f, rths_error *err);

/* True when stderr is a terminal and quiet is 0: a command may draw \r progress lines. */
int rths_api_progress_enabled(int quiet);
/* A range as the configuration's getters word it in a message: "in [lo, hi]", "> lo", "in (lo,
 * hi]" (flags: RTHS_API_RANGE_LO_OPEN for lo < x, RTHS_API_RANGE_HI_OPEN for x < hi); buf
 * returned. */
enum { RTHS_API_RANGE_LO_OPEN = 1, RTHS_API_RANGE_HI_OPEN = 2 };
const char *rths_api_range_text(double lo, double hi, unsigned flags, char *buf, size_t size);

/* `rths model`'s whole job (c loaded without RTHS_API_READ_SETUP: the solver path is chosen
 * first, so a sparse model never becomes dense): rths_api_model's tables and summary, the printed
 * report as rths_result_text (out_dir named in it), run.log's lines (the path and why, the stage
 * times) and the figure true_frf. RTHS_EINPUT for an unknown key of structure, split, forcing or
 * model. */
int rths_api_model_run(rths_api_command_config *c, const char *out_dir, rths_result **out,
                       rths_error *err);
/* `rths chart`: rths_api_chart's tables and summary from the stability section (read and checked
 * here) with the printed report (rths_result_text), the file boundary_curves.dat and the figure
 * chart. progress: a progress line on stderr. */
int rths_api_chart_run(rths_api_command_config *c, int progress, rths_result **out,
                       rths_error *err);
/* `rths tune`: rths_api_tune's result (its rig and controller sections read and checked here):
 * table "loop", the summary, the keys to paste as rths_result_text and as the file tuned.yaml,
 * the figure loop. delay_s as rths_api_tune's. */
int rths_api_tune_run(rths_api_command_config *c, double delay_s, rths_result **out,
                      rths_error *err);
/* `rths fidelity`: rths_api_fidelity's result (its fidelity and controller sections read and
 * checked here). */
int rths_api_fidelity_run(rths_api_command_config *c, rths_result **out, rths_error *err);

/* `rths simulate` in two steps, so the command creates its folder only once nothing can refuse
 * the input: _prepare checks o (o->out_dir unused), creates and arms the rig (a virtual rig reads
 * the rig and controller sections, checked here) and refuses bad input with RTHS_EINPUT; _run runs
 * the test (logging into f, may be NULL) and returns rths_api_simulate's result. c must outlive
 * the simulation. */
typedef struct rths_api_simulation rths_api_simulation;
int rths_api_simulate_prepare(rths_api_command_config *c, const rths_api_simulate_options *o,
                              rths_api_simulation **out, rths_error *err);
int rths_api_simulate_run(rths_api_simulation *s, rths_api_run_folder *f, rths_result **out,
                          rths_error *err);
void rths_api_simulation_free(rths_api_simulation *s);

/* `rths frf`'s run (rths_frf's orchestration, docs/method.md) on the configuration c (loaded with
 * RTHS_API_READ_SETUP and the command's overrides, which run.log and summary.json record), with
 * its options as given on the command line. */
#define RTHS_API_FRF_MAX_HARMONICS 3 /* --harmonics' largest value */
/* After every correction attempt: the point's number, frequency, residual, evaluations so far and
 * whether it was accepted (a progress display). */
typedef void (*rths_api_progress_fn)(void *user, int points, double frequency_hz, double residual_m,
                                     int evaluations, int accepted);
typedef struct rths_api_frf_run_options {
    const char *out_dir;  /* created; must not hold a run unless resume */
    const char *strategy; /* "default" (NULL) or "paper" */
    int harmonics;        /* 1..RTHS_API_FRF_MAX_HARMONICS; 0: iteration.harmonics */
    int resume, force;    /* as --resume, --force */
    const char *rig_uri;  /* tcp://HOST:PORT of a controller process; NULL: the virtual rig */
    int reset_fault;      /* with rig_uri: reset its latched fault first */
    const char *const *site_uris; /* a multi-site test's controllers in rig.sites' order (>= 2) */
    int n_site_uris;
    int has_seed;
    uint64_t seed;
    int argc; /* the command line, recorded in run.log */
    char **argv;
    rths_api_progress_fn on_progress; /* may be NULL */
    rths_api_cancel_fn should_cancel; /* polled after every accepted point; may be NULL */
    void *user;                       /* passed to both */
} rths_api_frf_run_options;
typedef struct rths_api_frf_run_summary {
    int cancelled; /* should_cancel ended it (everything accepted saved, resumable) */
    int points, converged_points, resumed_points, evaluations, folds;
    double rig_time_s, wall_time_s;
    double max_relative_error_vs_truth;
    char stop_reason[RTHS_ERROR_MSG_LEN + 256];
    int outputs_written; /* frf.csv and summary.json were written (the counts are valid) */
} rths_api_frf_run_summary;
/* RTHS_OK when it ran (also when cancelled), RTHS_EINPUT on bad input (nothing written),
 * RTHS_EFAIL on a failure during it (what was accepted is saved; r says how far it got). */
int rths_api_frf_run(rths_api_command_config *c, const rths_api_frf_run_options *o,
                     rths_api_frf_run_summary *r, rths_error *err);
/* The overrides --strategy paper applies before the user's (*n of them; later ones still win). */
const char *const *rths_api_frf_paper_overrides(int *n);

/* `rths controller`: the real-time controller process (docs/protocol.md) as the command's
 * options give it. It prints what the command prints ("listening on ADDR:PORT" and with a page
 * "view at http://ADDR:PORT/" on stdout; notices and the loop's statistics on stderr unless
 * quiet). */
typedef struct rths_api_controller_options {
    const char *config_path;      /* the test configuration (may be NULL for the latency test) */
    const char *const *overrides; /* "a.b=value", in order (--set, --io's io.plugin) */
    int n_overrides;
    const char *listen;      /* "ADDR:PORT" or "[V6]:PORT"; NULL: the default (loopback) */
    long site;               /* 1-based site of a multi-site test (rig.sites); 0: the whole test */
    const char *view_listen; /* the process's web page (docs/view.md); NULL: none */
    double duration_s;       /* > 0: stop after this long; else at SIGINT/SIGTERM */
    int quiet;               /* no notices on stderr */
} rths_api_controller_options;
/* The command's usage text with this build's defaults (max_overrides: --set's limit). */
void rths_api_controller_usage(char *out, size_t cap, int max_overrides);
/* RTHS_EINPUT naming listen when it is not ADDR:PORT (port 0..65535). */
int rths_api_controller_check_listen(const char *listen, rths_error *err);
/* Builds the server from the configuration (refusing bad input with RTHS_EINPUT before anything
 * runs), serves one host until a signal or duration_s, stops; RTHS_EFAIL when it cannot listen or
 * the loop stalled in the I/O device. SIGINT and SIGTERM are blocked in the calling thread. */
int rths_api_controller_serve(const rths_api_controller_options *o, rths_error *err);
/* The paced loop alone for seconds at controller.sample_rate_hz (the configuration optional),
 * its wake-up lateness printed on stdout. */
int rths_api_controller_latency_test(const rths_api_controller_options *o, double seconds,
                                     rths_error *err);

#ifdef __cplusplus
}
#endif

#endif
