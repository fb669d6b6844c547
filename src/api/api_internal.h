/* The C API's own plumbing (src/api): the handles behind rths.h and what the operations share. */
#ifndef RTHS_API_INTERNAL_H
#define RTHS_API_INTERNAL_H

#include "rths/config.h"
#include "rths/report.h"
#include "rths/rths.h"
#include "rths/setup.h"

struct json_object;

struct rths_api_config {
    char *path;       /* NULL: defaults only */
    char **overrides; /* "a.b=value" */
    int n_overrides;
    int dofs;
};

/* A configuration as a command holds it (rths.h): read once, the setup read from it when asked. */
struct rths_api_command_config {
    rths_config *config;
    rths_setup setup; /* zero unless has_setup */
    int has_setup;
    char *path; /* NULL: defaults only */
    char **overrides;
    int n_overrides;
};

/* A command's run folder (rths.h): the report module's output folder. */
struct rths_api_run_folder {
    rths_report *report;
};

/* A gnuplot figure of a result: written after the tables and the summary (rths_plot). */
typedef struct rths_api_figure {
    char *name; /* basename: NAME.gp, NAME.png, NAME.svg */
    int width_px, height_px;
    char *body; /* the script after the terminal lines */
} rths_api_figure;

struct rths_result {
    rths_table *tables;
    int n_tables;
    char *summary_json; /* never NULL once made */
    char *config_yaml;  /* never NULL once made */
    char *dir;          /* NULL: no folder */
    char *text;         /* what the command prints (rths_result_text); never NULL once made */
    size_t text_len;
    char **log; /* run.log lines, written between the tables and the summary */
    int n_log;
    rths_api_figure *figures;
    int n_figures;
    char **file_names, **file_texts; /* text files written before the tables (tuned.yaml) */
    int n_files;
    int out_of_memory; /* a text or log line could not be kept: the writer fails */
};

/* The configuration read afresh (every getter unasked) with the structural setup: an operation
 * reads its own sections from it, then checks it (rths_api_check_config). */
int rths_api_load(const rths_api_config *cfg, rths_config **out, rths_setup *setup,
                  rths_error *err);
void rths_api_unload(rths_config *c, rths_setup *setup);
/* Unknown keys refused in the setup's sections and in own (NULL-terminated), the other sections
 * of the rths configuration accepted whole (as the CLI's commands do). */
int rths_api_check_config(rths_config *c, const char *const *own, rths_error *err);

/* The commands' computations behind the entry points of rths.h, on the library's types: the
 * stable operations (rths_api_model, rths_api_chart, ...) call them too, so a command and its
 * operation share one implementation. */
typedef struct rths_api_model_timing {
    double modes_s, frf_prepare_s, frf_s; /* wall seconds of the stages */
    char modes_method[32];                /* "banded, dsbgvd" or "dense, dsygvd" */
    char frf_method[64];                  /* rths_frf_method_name */
    int frf_points, frf_dofs;             /* true_frf's rows and DoFs */
} rths_api_model_timing;
/* rths_api_model's result (tables "modes", "true_frf", the summary naming config_path and the
 * overrides) from the setup read from the configuration; timing may be NULL. */
int rths_api_model_compute(const rths_setup *setup, const char *config_path,
                           const char *const *overrides, int n_overrides, rths_result **out,
                           rths_api_model_timing *timing, rths_error *err);
struct rths_chart;
struct rths_chart_options;
typedef struct rths_api_chart_facts {
    double seconds;                   /* the chart's computation, wall seconds */
    double p_essential;               /* essential-spectrum limit of p (NaN: none in the range) */
    int stable_points;                /* grid points labelled stable */
    char essential_statement[512];    /* summary.json's essential_spectrum.statement */
    double probe_p[4];                /* the configured p, then 0.6, 0.67, 0.8 */
    double probe_critical_delay_s[4]; /* located stand-alone at probe_p (NaN: none found) */
    double probe_crossing_omega_rad_s[4];
} rths_api_chart_facts;
/* rths_api_chart's result (tables "chart", "boundary", "critical", the summary naming config_path
 * and the overrides) from the setup and the stability options read from the configuration. chart
 * (may be NULL) receives the computed chart (free with rths_chart_free); facts may be NULL. */
int rths_api_chart_compute(const rths_setup *setup, const struct rths_chart_options *o,
                           const char *config_path, const char *const *overrides, int n_overrides,
                           rths_result **out, struct rths_chart *chart, rths_api_chart_facts *facts,
                           rths_error *err);
/* rths_api_tune's result from the configuration (its rig and controller sections read and
 * checked here) and the setup read from it. */
int rths_api_tune_compute(rths_config *c, const rths_setup *setup, double delay_s,
                          const char *config_path, const char *const *overrides, int n_overrides,
                          rths_result **out, rths_error *err);
/* rths_api_fidelity's result from the configuration (its fidelity and controller sections read
 * and checked here) and the setup read from it. */
int rths_api_fidelity_compute(rths_config *c, const rths_setup *setup, const char *config_path,
                              const char *const *overrides, int n_overrides, rths_result **out,
                              rths_error *err);
/* rths_api_simulate_prepare on the library's types; config_path and the overrides (kept by
 * pointer: they must outlive the simulation) are named in the result's summary. */
int rths_api_simulation_prepare(rths_config *c, const rths_setup *setup,
                                const rths_api_simulate_options *o, const char *config_path,
                                const char *const *overrides, int n_overrides,
                                rths_api_simulation **out, rths_error *err);
/* rths_api_simulate_run logging into rep (may be NULL). */
int rths_api_simulation_run(rths_api_simulation *s, rths_report *rep, rths_result **out,
                            rths_error *err);
/* rths_api_result_write into rep, and its parts in order (the result's own text files such as
 * tuned.yaml, then tables, run.log lines, summary, figures). */
int rths_result_write_report(const rths_result *r, rths_report *rep, rths_error *err);
int rths_result_write_tables(const rths_result *r, rths_report *rep, rths_error *err);
int rths_result_write_log(const rths_result *r, rths_report *rep, rths_error *err);
int rths_result_write_summary(const rths_result *r, rths_report *rep, rths_error *err);
int rths_result_write_figures(const rths_result *r, rths_report *rep, rths_error *err);

int rths_result_new(rths_result **out, rths_error *err);
/* Takes the table over (*t is emptied). */
int rths_result_take_table(rths_result *r, rths_table *t, rths_error *err);
/* A table from column arrays (copied). */
int rths_result_add_columns(rths_result *r, const char *name, int rows, int columns,
                            const char *const *names, const double *const *data, rths_error *err);
/* The summary every command's result starts with: rths_json_summary_new(command) plus who asked
 * (config_file when config_path is given, overrides). NULL when out of memory. */
struct json_object *rths_api_summary_new(const char *command, const char *config_path,
                                         const char *const *overrides, int n_overrides);
/* Appends to r's printed text / adds a run.log line (printf-style); out of memory is remembered
 * and reported by the writer. */
void rths_result_printf(rths_result *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void rths_result_log(rths_result *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* A text file of r (copied: NAME in the folder), written by the writer before the tables. */
int rths_result_add_file(rths_result *r, const char *name, const char *text, rths_error *err);
/* A figure of r (copied), drawn by the writer after the summary. */
int rths_result_add_figure(rths_result *r, const char *name, int width_px, int height_px,
                           const char *body, rths_error *err);
/* summary (consumed: json_object_put) becomes r's summary text. */
int rths_result_set_summary(rths_result *r, struct json_object *summary, rths_error *err);
/* Writes r as the run folder dir of command: config.yaml, one CSV per table, summary.json,
 * results.mat (at close), run.log; then r->dir and r->config_yaml are set. */
int rths_result_write_folder(rths_result *r, const rths_config *c, const char *dir,
                             const char *command, rths_error *err);
/* The end of every rths_api_COMMAND call: after a successful compute (rc 0), r is written as the
 * run folder out_dir when one is given; then r goes to *out, or is freed when anything failed.
 * Returns the status. */
int rths_api_finish(rths_result *r, int rc, const rths_config *c, const char *out_dir,
                    const char *command, rths_result **out, rths_error *err);

#endif
