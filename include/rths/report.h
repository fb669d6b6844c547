/* rths report: the output folder of a run. CSV (C locale, full precision, SI units in the header),
 * JSON summary (json-c), figures (gnuplot scripts saved beside the data, PNG + SVG), run.log.
 *
 * Every file is written to a temporary name in the same folder and renamed into place when
 * complete, so a crash never leaves a half-written result. The folder is created (with parents) on
 * open. */
#ifndef RTHS_REPORT_H
#define RTHS_REPORT_H

#include "rths/core.h"

#include <stdio.h>

struct json_object;

/* ---- the run folder ---- */

typedef struct rths_report rths_report;

/* Creates dir (mkdir -p) and opens run.log (appended, so a resumed run keeps its history).
 * command/argc/argv are logged as the first line.
 *
 * A run folder belongs to one command. A folder whose run.log shows an earlier run of another
 * command is refused (RTHS_EINPUT, nothing written): the two runs' files would mix. An earlier run
 * of the same command is replaced: the files it wrote (listed in its .rths-files, see
 * rths_report_close) are removed first, unless argv holds "--resume" (the run continues the earlier
 * one). Files the command did not write (a user's notes, say) are never touched. */
int rths_report_open(const char *dir, const char *command, int argc, char **argv, rths_report **out,
                     rths_error *err);
/* Writes results.mat (rths_report_write_mat) unless already written and nothing changed since,
 * lists the files this run wrote in DIR/.rths-files (what a later run of the same command removes),
 * closes run.log and frees rep. A results.mat that cannot be written costs a warning on stderr and
 * in run.log, not the run: the CSV files are the data. */
void rths_report_close(rths_report *rep);
const char *rths_report_dir(const rths_report *rep);
/* dir/name, malloc'ed (caller frees). The name is remembered as one of this run's files (for
 * results.mat and .rths-files). */
/* DIR/NAME, malloc'ed (NULL: out of memory). */
char *rths_path_join(const char *dir, const char *name);
/* The whole file, NUL-terminated, malloc'ed, its length in *len (may be NULL); growing by
 * doubling from 64 KiB it stops once the buffer reaches max_bytes. NULL if it cannot be opened
 * or read. */
char *rths_read_file(const char *path, size_t max_bytes, size_t *len);
char *rths_report_path(const rths_report *rep, const char *name);
/* One timestamped line in run.log, flushed. */
void rths_report_log(rths_report *rep, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* ---- atomic files ---- */

/* Writes data to path via path.tmp.<pid> + fsync + rename. */
int rths_write_file_atomic(const char *path, const char *data, size_t len, rths_error *err);

/* A stream whose content appears at path only on rths_atomic_commit. */
typedef struct rths_atomic_file rths_atomic_file;
int rths_atomic_open(const char *path, rths_atomic_file **out, FILE **stream, rths_error *err);
int rths_atomic_commit(rths_atomic_file *f, rths_error *err); /* flush, fsync, rename, free */
void rths_atomic_abort(rths_atomic_file *f);                  /* remove the temp file, free */

/* ---- CSV ---- */

/* Numbers are written with %.17g in the C locale (round-trip exact); NaN as "nan". */
typedef struct rths_csv rths_csv;
int rths_csv_open(const char *path, int n_columns, const char *const *header, rths_csv **out,
                  rths_error *err);
int rths_csv_row(rths_csv *csv, const double *values);
int rths_csv_close(rths_csv *csv, rths_error *err); /* commit (rename into place) */
void rths_csv_abort(rths_csv *csv);
/* Ends a CSV the way a writer loop wants: rc != 0 (the loop failed) aborts it and returns rc,
 * rc == 0 commits it and returns the commit's status. csv may be NULL (returns rc). */
int rths_csv_finish(rths_csv *csv, int rc, rths_error *err);

/* ---- JSON ---- */

/* Pretty-printed, atomic. Adds nothing to obj. */
int rths_json_write(const char *path, struct json_object *obj, rths_error *err);
/* A new object with "rths_version", "command", "created_utc" filled: the start of a summary. */
struct json_object *rths_json_summary_new(const char *command);

/* ---- figures ---- */

/* Writes dir/basename.gp and runs gnuplot on it in dir, producing basename.png and basename.svg.
 * body is the plot itself (labels, ranges, plot commands referring to data files by their names
 * relative to dir); the terminal lines are added here and the body is emitted twice (PNG, SVG).
 * width_px x height_px is the PNG size (SVG the same). If gnuplot is not installed, or fails, a
 * warning goes to stderr (and run.log when rep is given) and the call still returns RTHS_OK: data
 * matter more than pictures. */
int rths_plot(rths_report *rep, const char *dir, const char *basename, int width_px, int height_px,
              const char *body, rths_error *err);

/* The figures' convention (docs/method.md, "Figures"): error bars are +-3 standard errors; the
 * interface error has its own panel; a deviation-from-truth panel under every FRF; legends
 * outside the plot area; units chosen per magnitude. rths_plot_unit picks the unit for values of
 * magnitude up to max_abs in an SI unit si ("m", "rad", "m/N", ...): the SI unit scaled by a
 * power of 1000 (m, mm, µm, nm, pm) so that max_abs reads between 1 and 1000 in it; the label
 * (UTF-8, at most 23 bytes) into label, the factor SI values are multiplied by returned. */
double rths_plot_unit(double max_abs, const char *si, char *label, size_t size);
/* Colour of the d-th curve (0-based, cycling): the figures' one palette. */
const char *rths_plot_colour(int d);

/* ---- tables read back from CSV ---- */

/* A CSV file written by rths_csv_*: named columns of doubles ("nan" reads as NaN). */
typedef struct rths_table {
    char *name; /* file name without ".csv" */
    int rows, columns;
    char **column_names; /* columns */
    double **data;       /* columns arrays of rows values */
} rths_table;

/* Reads path (header line of names, then rows of numbers, all of the same length). */
int rths_csv_read(const char *path, rths_table *out, rths_error *err);
/* A table of rows x columns zeros with copies of the names (for arrays that have no CSV). */
int rths_table_create(const char *name, int rows, int columns, const char *const *column_names,
                      rths_table *out, rths_error *err);
void rths_table_free(rths_table *t);

/* ---- results.mat (MAT 7.3, libmatio over HDF5): the run folder for MATLAB, h5py, Julia ---- */

/* Adds a table that has no CSV file to this run's results.mat (copied): e.g. the per-point
 * harmonic coefficients of an FRF run, one row per (point, harmonic). Its name must not be one of
 * the run's CSV names. */
int rths_report_add_table(rths_report *rep, const rths_table *table, rths_error *err);
/* Writes DIR/results.mat from what this run wrote into DIR: one struct per CSV file (named as the
 * file without .csv, one field per column, named as the column, a column vector each), the tables
 * added by rths_report_add_table likewise, `summary` (summary.json as a struct: numbers, strings,
 * booleans as 0/1, lists, nested objects) and `summary_json` (its text), `config_yaml` (config.yaml
 * as text), and for a folder with a journal.jsonl (an FRF run) `harmonics`: per accepted point the
 * measured Fourier coefficients phys_a<k>_m, phys_b<k>_m, num_..., their standard errors
 * phys_se_..., num_se_... (k = 0..RTHS_MAX_HARMONICS) and the target's target_a<k>_m, target_b<k>_m
 * (k = 1..RTHS_MAX_HARMONICS, 0 beyond the harmonics matched), unless the run added its own table
 * called harmonics. Written to a temporary name and renamed. Does nothing when the run wrote
 * neither a CSV file nor summary.json. */
int rths_report_write_mat(rths_report *rep, rths_error *err);
/* The same for any folder, from the named CSV files (NULL: every *.csv in dir) and extra tables. */
int rths_matfile_write(const char *dir, const char *const *csv_names, int n_csv,
                       const rths_table *extra, int n_extra, rths_error *err);

/* ---- progress on stderr ---- */

/* True when stderr is a terminal and quiet is 0: the caller may print \r progress lines. */
int rths_progress_enabled(int quiet);

struct rths_setup;
struct rths_modes;
/* The excitation as configured, into a summary: excitation "force" with forcing_dof (1-based)
 * and forcing_amplitude_n, or "base" with base_acceleration_amplitude_m_s2. */
void rths_summary_add_excitation(struct json_object *root, const struct rths_setup *s);
/* The results of `rths model` (modes, interface peak, the setup's facts) added to a summary. */
void rths_model_summary_add(struct json_object *root, const struct rths_setup *s,
                            const struct rths_modes *m, int points, double peak_amp_m,
                            double peak_hz);

#endif
