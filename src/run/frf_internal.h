/* The FRF run's state, shared by the files of src/run (not installed). */
#ifndef RTHS_RUN_FRF_INTERNAL_H
#define RTHS_RUN_FRF_INTERNAL_H

#include <stdio.h>

#include "rths/live.h"
#include "rths/report.h"
#include "rths/run.h"
#include "rths/truth.h"
#include "run/frf_dof_columns.h"

/* The experimental Floquet estimate of one point (stability.experimental_floquet). */
typedef struct frf_floquet_point {
    int measured; /* 0: not measured (option off, a resumed point, or the estimate failed) */
    double max_abs, max_abs_se;
    int label; /* RTHS_FLOQUET_STABLE, _UNSTABLE or _UNDETERMINED (floquet.h) */
    int trustworthy;
} frf_floquet_point;

/* The true assembly's largest Floquet multiplier modulus, to judge the experimental estimate:
 * with a bilinear leg the truth curve's (truth.csv's shooting solution), else e^{sigma T} of the
 * least damped eigenvalue's real part sigma. */
typedef struct frf_floquet_truth {
    int linear;
    double decay_rate_per_s; /* linear: sigma, 1/s (negative when stable) */
} frf_floquet_truth;

typedef struct frf_state {
    const rths_run_frf_options *opt;
    const rths_run_callbacks *cb;
    const rths_setup *setup;
    const char *strategy;
    int paper;
    rths_settle_options settle;
    rths_newton_options newton;
    rths_continuation_options cont;
    int harmonics;
    double trace_hz; /* output.trace_frequency_hz: the point of the Lissajous figure (0: peak) */
    rths_rig *rig;
    rths_rig
        *virtual_rig; /* the in-process rig behind the observing one (NULL: remote), owned by rig */
    rths_rig *inner_rig;  /* the rig behind the observing one (virtual, remote or the caller's) */
    int disarmed;         /* the rig was brought to its safe state after the last point */
    char reset_note[700]; /* --reset-fault: what was reset, logged once run.log exists */
    rths_report *rep;
    rths_journal *journal;
    rths_error point_err;    /* why the point handler stopped the run (journal, callback) */
    char limit_warning[600]; /* --force over a predicted limit: logged once the log exists */
    rths_live *live;         /* live.json for `rths view`, closed when the continuation ends */
    char *journal_path;
    rths_point *resume_pts;
    int n_resume;
    rths_point *pts; /* accepted points in index order (updates replace) */
    int n, cap;
    rths_truth_curve truth;
    rths_continuation_result result;
    int cancelled;
    int stopped_short; /* ended short of end_hz by failures or the range: a failure (exit 1) */
    int lock_fd;       /* DIR/run.lock, flock'ed while the run owns the folder */
    char *lock_path;   /* its path, removed when the run releases the folder */
    /* --resume: the configuration keys that changed (allowed ones), "key: was -> now" */
    char changes[8][256];
    int n_changes;
    char seed_buf[32];
    const char *seed_text; /* --seed as text (recorded in the journal), NULL when not given */
    double wall_time_s, trace_rig_time_s, max_truth_error;
    rths_floquet_measure_options floquet; /* stability.experimental_floquet and its keys */
    frf_floquet_point *floquet_pts;  /* by point index, cap entries (the option on; else NULL) */
    double floquet_rig_time_s;       /* rig time spent on the perturbed records */
    frf_floquet_truth floquet_truth; /* computed when the option is on */
    frf_dof_columns dof_cols;        /* output.dofs' columns (count 0 without it) */
    /* evaluations.csv: every evaluation of the corrector, a row each, flushed per row */
    FILE *evaluations;
    int evaluation_corrections; /* correction attempts begun (each begins with a prediction) */
    int evaluations_failed;     /* a write failed: logged once, the file left as it was */
} frf_state;

enum { FRF_MAX_CHANGES = 8 };

/* The rig a run measures on, as its journal records it: "virtual", the tcp:// URI, or "caller"
 * (rths_run_frf_options.rig). */
static inline const char *frf_rig_text(const frf_state *st) {
    return st->opt->rig_uri ? st->opt->rig_uri : st->opt->rig ? "caller" : "virtual";
}

/* limits_check.c: computes the truth curve over the run's range (with a margin) and refuses,
 * before anything is written, a test whose true interface response would exceed the rig's
 * displacement limit (RTHS_EINPUT naming the peak and the key), unless opt->force, when it only
 * warns (stderr and run.log). */
int frf_plan_within_limits(frf_state *st, rths_error *err);

/* resume_check.c: refuses a resumed configuration that changes more than end_hz, max_points or
 * the outputs (RTHS_EINPUT naming the key), noting the allowed changes in st->changes. */
int frf_check_resume_config(frf_state *st, rths_error *err);

/* frf_floquet.c: what the truth's largest multiplier modulus needs beyond the truth curve (which
 * carries it with a bilinear leg): a linear structure's least damped decay rate; and the modulus
 * at a point (f_hz, amp_m) on its branch (NaN when the curve has no piece there). */
int frf_floquet_truth_compute(const rths_setup *s, frf_floquet_truth *t, rths_error *err);
double frf_floquet_truth_at(const frf_state *run, double f_hz, double amp_m);

/* frf_evaluations.c: evaluations.csv, opened with the outputs (appended to on --resume) and
 * fed by rths_newton_options.on_evaluation (user: the frf_state) */
int frf_evaluations_open(frf_state *st, rths_error *err);
void frf_on_evaluation(void *user, const rths_evaluation_event *e);
void frf_evaluations_close(frf_state *st);

/* frf_outputs.c */
double frf_harmonic_error(const rths_point *pt, int k);
int frf_write_frf_csv(rths_report *rep, const frf_state *run, rths_error *err);
/* frf_absolute.c: absolute.csv for a base-excited run (absolute interface displacement, hybrid
 * and true, beside the relative one frf.csv reports). */
int frf_write_absolute_csv(rths_report *rep, const frf_state *run, rths_error *err);
/* frf_modal.c: frf.uff (the measured receptance, universal file format 58) and, for a linear
 * structure, modal.csv (the modes in the tested range identified from it beside the truth's);
 * called at the end of frf_write_frf_csv. A failed identification is logged, not an error. */
int frf_write_modal_outputs(rths_report *rep, const frf_state *run, rths_error *err);
int frf_write_truth_csv(rths_report *rep, const frf_state *run, const rths_truth_curve *t,
                        rths_error *err);
int frf_plot_frf(rths_report *rep, const frf_state *run, const rths_truth_curve *t,
                 const char *title, rths_error *err);
/* The Lissajous trace at one accepted point: recorded on the rig (the point's targets again,
 * steady state, 3 periods), then, once the rig is disarmed, written (trace.csv, lissajous.*). */
typedef struct frf_trace {
    rths_trace_sample *samples;
    int n, dofs, point;
    double frequency_hz, rig_time_s;
} frf_trace;
int frf_trace_record(rths_rig *rig, const rths_settle_options *settle, int harmonics,
                     double amplitude_n, const rths_point *pt, frf_trace *out, rths_error *err);
int frf_trace_write(rths_report *rep, const rths_setup *setup, const frf_trace *t, rths_error *err);
void frf_trace_free(frf_trace *t);
int frf_choose_trace_point(const frf_state *run, double trace_hz);
int frf_write_summary(frf_state *run, rths_error *err);
/* The integrity counts (rths_period): per accepted point the evaluation's (pt->residual.eval),
 * over the run every period the rig delivered (rths_rig_integrity_totals). frf_log_integrity
 * writes the totals to run.log; frf_integrity_to_error appends them to a failed run's message
 * when the rig reported any, since they may be why its evaluations were refused. */
void frf_log_integrity(frf_state *run);
void frf_integrity_to_error(frf_state *run, rths_error *err);

#endif
