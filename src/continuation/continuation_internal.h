/* Continuation's private pieces, shared by the files of src/continuation (not installed): the run
 * state, the predictors, the fold tracker and the step control. */
#ifndef RTHS_CONTINUATION_INTERNAL_H
#define RTHS_CONTINUATION_INTERNAL_H

#include "rths/continuation.h"

enum { CONT_LD = RTHS_MAX_UNKNOWNS };

/* Scaled unknowns of the branch: targets / amp_scale, omega / omega_scale. */
typedef struct cont_scaling {
    double amp_scale, omega_scale;
    int harmonics;
} cont_scaling;

int cont_pack(const cont_scaling *sc, const rths_solution *s, double *u);

/* Fold tracker. Correction error makes the frequency jitter where the branch is vertical, so a
 * turn counts only once two consecutive points have moved back from its extreme by more than a
 * margin: 5 % of the step, or 3 sqrt(2) times the points' local frequency scatter about their
 * neighbours when larger (docs/method.md, "Continuation", Folds); the fold is then located on the
 * parabola through the extreme point and its neighbours. The same tracker replays a resumed
 * journal. */
typedef struct cont_fold_tracker {
    int wdir;    /* direction the frequency currently moves along the branch (+-1, 0: unknown) */
    int ext_idx; /* point of the extreme frequency on the current segment */
    int segment;
    double *svals; /* cumulative scaled arclength of each point */
} cont_fold_tracker;

/* The next guess: unknowns (m), omega, the arclength row, the step it took. */
typedef struct cont_prediction {
    double u[CONT_LD];
    double omega_rad_s;
    rths_arclength arc;
    double step_used;
    int natural_fallback; /* an arclength run's natural step (see cont_run.natural_next) */
    int trust_declined;   /* model predictions set aside for the targets' trust region */
} cont_prediction;

/* The failed corrections remembered to name what stopped a sweep (continuation.c). */
enum { CONT_RECENT_FAILURES = 16 };
typedef struct cont_failure {
    char msg[512];
} cont_failure;

typedef struct cont_run {
    const rths_continuation_options *opt;
    rths_rig *rig;
    int harmonics;
    rths_corrector *corr;
    cont_scaling sc;
    rths_point *pts;
    int n, cap;
    cont_fold_tracker folds;
    double dir;     /* +1 up in frequency, -1 down */
    double ds;      /* arclength: step multiplier of the secant */
    double step_hz; /* natural: frequency step */
    int consecutive;
    /* arclength on a branch without folds: the last correction moved the frequency back, so the
     * next one is a natural step forward */
    int natural_next;
    double first_u[CONT_LD]; /* the first point's retry guess */
    rths_continuation_result *res;
    rths_point_fn on_point;
    void *user;
    cont_failure recent[CONT_RECENT_FAILURES]; /* ring of the last failures' messages */
    int n_recent_total;                        /* failures remembered so far */
    int resumed_run; /* resumed after journaled points: new points carry rths_point.resumed */
} cont_run;

/* predict.c: the predictors */
void cont_predict(cont_run *run, cont_prediction *pr);

/* fold.c */
/* Point n (just accepted) extends the branch: its arclength, and a fold located before it.
 * notify: re-report the points whose fold flag changed through on_point (not on replay). */
int cont_fold_track(cont_run *run, int n, int notify);

#endif
