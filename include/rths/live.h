/* rths live: live.json, the state of a run in progress, for the live view (`rths view`, view.h).
 *
 * A run that wants to be watched opens a rths_live on its folder and lets it see the rig: either
 * through the observing rig (rths_live_wrap_rig), which forwards every call to the real rig and
 * notes targets, forcing and every period's interface coefficients, or by filling a
 * rths_live_evaluation itself. After every evaluation live.json is replaced atomically (written to
 * live.json.tmp, then renamed), so a reader sees either the previous or the new file, never a
 * torn one. live.json is a display, not a record: it is not fsync'ed (that would cost
 * milliseconds per evaluation); journal.jsonl stays the durable record of the run.
 *
 * Cost: one JSON text of 5 kB formatted into a preallocated buffer and one write + rename, about
 * 0.1-0.3 ms (bench/bench_view.c; most of it the file system's rename), at most every 0.1 s of
 * wall time (rths_live_set_interval), against seconds of rig time per evaluation in a lab.
 * Nothing here allocates after rths_live_open.
 *
 * live.json (format 1; SI units in the key names):
 *   state "running" | "ended"; point (index of the point being sought); points_accepted;
 *   frequency_hz; iteration (evaluations at this point, 1-based); evaluations_total;
 *   residual_m (interface mismatch of the latest evaluation over the matched harmonics);
 *   residual_history_m (every evaluation of the current point, at most RTHS_LIVE_HISTORY, latest
 *   last); harmonics; target {a_m, b_m} (harmonics 1..N); physical, numerical {a_m, b_m}
 *   (harmonics 0..5 of the latest period, m); period_s; trace {source, time_s, physical_m,
 *   numerical_m} (one period); rig_time_s; wall_time_s (since open); unix_time_s;
 *   health {fault, fault_code, remote, overruns, worst_lateness_s, link_stats}. */
#ifndef RTHS_LIVE_H
#define RTHS_LIVE_H

#include "rths/core.h"
#include "rths/rig.h"

#define RTHS_LIVE_HISTORY 64       /* residual history kept for the current point */
#define RTHS_LIVE_TRACE_SAMPLES 64 /* samples of the one-period trace */

typedef struct rths_live rths_live;

/* One evaluation as the run saw it (for runs that do not use the observing rig, and tests). */
typedef struct rths_live_evaluation {
    double frequency_hz;
    int harmonics; /* matched harmonics 1..RTHS_MAX_HARMONICS */
    double target_a_m[RTHS_MAX_HARMONICS], target_b_m[RTHS_MAX_HARMONICS];
    rths_fourier phys, num; /* latest period's (or the evaluation's averaged) coefficients, m */
    double rig_time_s;      /* rig clock at the end of the evaluation */
    rths_rig_fault fault;
    /* 0: the trace is reconstructed from phys and num; > 0: trace_* hold that many samples of
     * the measured signals (at most RTHS_LIVE_TRACE_SAMPLES are kept) */
    int trace_samples;
    const double *trace_time_s, *trace_phys_m, *trace_num_m;
} rths_live_evaluation;

/* Prepares dir/live.json (nothing is written until the first evaluation). */
int rths_live_open(const char *dir, rths_live **out, rths_error *err);
/* Writes the final state ("state": "ended") and frees. live may be NULL. */
void rths_live_close(rths_live *live);

/* Records one evaluation and replaces live.json, unless it was replaced less than the minimum
 * interval ago (then the next call or rths_live_flush writes it). */
int rths_live_evaluation_done(rths_live *live, const rths_live_evaluation *ev, rths_error *err);

/* Minimum wall time between two replacements of live.json, default 0.1 s (0: every
 * evaluation). A lab evaluation takes seconds, so there every evaluation is written; a virtual rig
 * at full speed does tens per second, more than the page (4 updates per second) can show. */
void rths_live_set_interval(rths_live *live, double min_interval_s);
/* Writes what was recorded but held back by the interval. */
void rths_live_flush(rths_live *live);

/* From the continuation's progress callback, after every correction attempt: point is the index
 * of the point the attempt was for (the callback's `points`), accepted whether it was accepted;
 * the next evaluation then starts the next point's residual history. Replaces live.json when the
 * accepted count changed. */
void rths_live_progress(rths_live *live, int point, double frequency_hz, double residual_m,
                        int accepted);

/* Health of a remote rig's controller (wake-up lateness, overrun cycles), when known. */
void rths_live_link_stats(rths_live *live, long overruns, double worst_lateness_s);

/* The observing rig: forwards every call to inner and, when an evaluation ends (the next
 * set_forcing/set_target after periods were run, or rths_live_progress), publishes the latest
 * period. The new rig owns inner (destroying it destroys inner); out may be &inner, and is set
 * only on success. Once live is closed the rig just forwards. */
int rths_live_wrap_rig(rths_live *live, rths_rig *inner, rths_rig **out, rths_error *err);

/* The JSON text last written (for tests); NUL-terminated, owned by live. */
const char *rths_live_text(const rths_live *live);

#endif
