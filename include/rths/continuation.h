/* rths continuation: trace the hybrid test's solution in forcing frequency.
 *
 * Natural-parameter sweep or pseudo-arclength continuation (frequency as an unknown) with the
 * seed's step policy (secant predictor u_pred = u_-1 + ds * (u_-1 - u_-2), ds = 1.1 after a
 * success, x0.5 and retry after a failure, erratum 4), bounded step lengths, fold detection and
 * location (sign change of the frequency component of the secant), branch segments between folds.
 * Natural sweeps may instead predict from a model of the residual (model_predictor). A failed
 * first point, having no step to shrink, is retried from the corrector's last iterate.
 */
#ifndef RTHS_CONTINUATION_H
#define RTHS_CONTINUATION_H

#include "rths/iterate.h"

typedef enum { RTHS_CONT_NATURAL = 0, RTHS_CONT_ARCLENGTH = 1 } rths_cont_method;

typedef struct rths_continuation_options {
    double start_hz, end_hz;
    rths_cont_method method;
    double initial_step_hz; /* first frequency step (both methods seed with it) */
    double max_step_hz;     /* natural: largest frequency step */
    double min_step;        /* arclength: smallest step in scaled units before giving up */
    double max_step;        /* arclength: largest step in scaled units */
    double grow, shrink;    /* step multipliers after success / failure (1.1, 0.5) */
    int max_points;
    int max_failures;         /* consecutive failed corrections before the run ends */
    double amplitude_scale_m; /* scaling of target coefficients; 0: from the first point */
    /* natural sweep: 1 predicts from the residual model Phi = J(w) u - f(w): on an LTI rig the
     * per-harmonic gains fitted to the last RTHS_LTI_HISTORY evaluations
     * (rths_corrector_lti_predict), else a least-squares line through the Jacobians and
     * f = J u - Phi of the last 4 points; either seeds the corrector's Jacobians. 0: the seed's
     * secant in the targets */
    int model_predictor;
    /* The branch stays in the requested range: a point more than range_margin * |end - start|
     * beyond start_hz ends the run (the branch left the range), one beyond end_hz is an
     * overshooting step, retried shorter. 0: no range check. */
    double range_margin;
    /* 1: the branch has no folds (a linear structure): a correction that moves the frequency
     * back is a failure (retried with a shorter step), not a turn of the branch */
    int monotonic;
    /* Optional: one line per failed correction (where, how many in a row, why, and what the run
     * does next), for the caller's log (rths frf: run.log) */
    void (*note)(void *user, const char *line);
    void *note_user;
} rths_continuation_options;

typedef struct rths_point {
    int index;         /* 0-based, in acceptance order */
    rths_solution sol; /* targets, omega, measurement, residual */
    int evaluations, iterations;
    double rig_time_s;              /* rig time spent on this point, including failed attempts */
    int fold;                       /* 1 if a fold was located between this point and the next */
    int segment;                    /* branch segment (0, 1, ...): increments after each fold */
    double step;                    /* arclength: scaled step length used to reach this point */
    double secant_omega;            /* frequency component of the secant that arrived here */
    rths_residual residual;         /* the residual record at the solution */
    rths_corrector_saved corrector; /* what the corrector carried on from this point (--resume) */
    /* how often the targets' trust region acted on the way to this point (failed attempts
     * included): a model's prediction set aside, a prediction or corrector step shortened */
    int trust_actions;
    /* 1: measured by a run that resumed the journal (--resume): its rig started again from rest
     * with a fresh noise stream, so it is not the point the uninterrupted run would have
     * measured (docs/journal.md, "What a resume restores") */
    int resumed;
    /* How the point's evaluations reached steady state, failed attempts included (fitted,
     * fallen back to waiting and why, stopped above iteration.target_rel_se) and their rig
     * time: filled by a caller that keeps an rths_settle_tally over the point (rths frf), kept
     * by the journal (docs/journal.md); zero otherwise */
    rths_settle_tally settle;
} rths_point;

typedef struct rths_fold {
    double frequency_hz;
    double amplitude_m; /* physical interface fundamental amplitude at the fold */
    int after_point;    /* the fold lies between this point and the next */
} rths_fold;

/* Called for every accepted point (index increasing) and, with pt->fold set, re-called for a
 * point once a fold is located after it: a journal must treat the second call as an update.
 * A non-zero return stops the run (returned as the run's status). */
typedef int (*rths_point_fn)(void *user, const rths_point *pt, int is_update);
/* Progress after every correction attempt (accepted or not), for a terminal display. */
typedef void (*rths_progress_fn)(void *user, int points, double frequency_hz, double residual_m,
                                 int evaluations, int accepted);

typedef struct rths_continuation_result {
    int points;
    int converged_points;
    int failures;    /* failed corrections (each retried with a smaller step; the first point
                      * from the last iterate) */
    int evaluations; /* all evaluations, failed attempts included */
    double rig_time_s;
    int n_folds;
    rths_fold folds[32];
    int reached_end; /* 1 if the end frequency was reached */
    /* 1 if the run ended short of the end frequency for a reason of its own: failed corrections
     * (max_failures, the arclength step below min_step) or the branch leaving the range; the
     * stop reason then names the most frequent cause among the last failures. 0 when it reached
     * the end, the point limit (max_points) or a handler stopped it. */
    int stopped_short;
    char stop_reason[RTHS_ERROR_MSG_LEN + 256];
} rths_continuation_result;

void rths_continuation_defaults(rths_continuation_options *opt);
int rths_continuation_config_read(rths_config *cfg, rths_continuation_options *opt,
                                  rths_error *err);

/* Runs from start_hz (or after the resume points, the last two of which seed the secant) until
 * end_hz is passed, max_points are accepted, or max_failures corrections fail in a row. Every
 * accepted point goes to on_point before the next is attempted. Returns RTHS_OK when the run ended
 * normally (result->stop_reason says why), RTHS_EFAIL on a rig fault or callback failure. */
int rths_continuation_run(rths_rig *rig, const rths_continuation_options *opt,
                          const rths_settle_options *settle, const rths_newton_options *newton,
                          int harmonics, double amplitude_n, const rths_point *resume, int n_resume,
                          rths_point_fn on_point, rths_progress_fn on_progress, void *user,
                          rths_continuation_result *result, rths_error *err);

/* The same on a zero problem built by the caller (e.g. rths_frequency_problem: the numerical
 * substructure solved on the host) that evaluates on rig. */
int rths_continuation_run_problem(const rths_zero_problem *problem, rths_rig *rig,
                                  const rths_continuation_options *opt,
                                  const rths_newton_options *newton, int harmonics,
                                  const rths_point *resume, int n_resume, rths_point_fn on_point,
                                  rths_progress_fn on_progress, void *user,
                                  rths_continuation_result *result, rths_error *err);

/* The fold-based stability label of a point: 1 stable, 0 unstable. A saddle-node fold of the
 * periodic response is where the determinant of the target block of the Jacobian changes sign
 * along the branch (the arclength-augmented one does not), and stability changes there; the label
 * is anchored at the first point, taken as stable (a sweep starting away from resonance), and
 * flips at every located fold, i.e. it is the parity of the branch segment. */
int rths_point_stable(const rths_point *pt);

/* Physical interface fundamental amplitude of a point, m. */
double rths_point_amplitude_m(const rths_point *pt);

/* ---- journal: one JSON line per accepted point, flushed and synced per record ----
 * Format (header, point and update records, the corrector state) in docs/journal.md. This rths
 * writes format RTHS_JOURNAL_FORMAT and reads it and format 2. */
#define RTHS_JOURNAL_FORMAT 3

typedef struct rths_journal rths_journal;

/* Opens path for appending (creating it with a header line naming the strategy). */
int rths_journal_open(const char *path, const char *strategy, rths_journal **out, rths_error *err);
/* The same, the header also recording the rig's noise seed given for the run (seed: its text, or
 * NULL when none was given and the configuration's rig.seed applies). */
int rths_journal_open_seeded(const char *path, const char *strategy, const char *seed,
                             rths_journal **out, rths_error *err);
/* The seed the header recorded: *known 0 for a journal that records none (format 2); else
 * *seed is its text (caller frees) or NULL. */
int rths_journal_read_seed(const char *path, int *known, char **seed, rths_error *err);
/* The same, the header also recording the rig the run measured on ("virtual" or the controller
 * process's tcp://HOST:PORT; NULL: not recorded). */
int rths_journal_open_run(const char *path, const char *strategy, const char *seed, const char *rig,
                          rths_journal **out, rths_error *err);
/* A text field of the header (e.g. "seed", "rig"): *known 0 when the header has none; else
 * *value is its text (caller frees) or NULL for a JSON null. */
int rths_journal_read_header_text(const char *path, const char *key, int *known, char **value,
                                  rths_error *err);
/* Appends a point (is_update: a later line for the same index replaces the earlier one). */
int rths_journal_append(rths_journal *j, const rths_point *pt, int is_update, rths_error *err);
/* Records a resume after n_points points, with the configuration changes it was allowed
 * ("key: was -> now"); readers skip the record. */
int rths_journal_append_resume(rths_journal *j, int n_points, const char *const *changes,
                               int n_changes, rths_error *err);
void rths_journal_close(rths_journal *j);

/* Reads a journal: the points in index order, updates applied. A torn last line (the process was
 * killed mid-write) is ignored; any other malformed line is an error naming the line. *strategy
 * receives the header's strategy (caller frees). Indices must run 0..n-1 without gaps. */
int rths_journal_read(const char *path, rths_point **points, int *n_points, char **strategy,
                      rths_error *err);

#endif
