/* evaluations.csv: every evaluation the corrector made, what it was for and what it measured, a
 * row each, flushed as it is written (docs/method.md, "Outputs"). The accepted points' rows are
 * in frf.csv; this file shows where the rig time between them went: predictions, Newton steps,
 * line-search trials, finite-difference columns, the matched estimate's gain probes and accuracy
 * steps, failed corrections included. */
#include "run/frf_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* The role is one 0/1 column per role, named by rths_evaluation_role_name in the enum's order,
 * so that the file stays a numeric table (results.mat holds every CSV of the run as one) and a
 * column's sum counts them. */
enum { ROLES = RTHS_EVALUATION_ACCURACY_STEP + 1 };
static const char HEADER_AFTER_ROLES[] =
    "iteration,frequency_hz,mismatch_m,tolerance_m,mismatch_to_tolerance,within_tolerance,damping,"
    "rig_time_s,wait_periods,average_periods,steady,fitted,fit_fallback,refused,resumed\n";

static int write_header(FILE *f) {
    if (fputs("point,correction,", f) == EOF) return EOF;
    for (int r = 0; r < ROLES; r++)
        if (fprintf(f, "%s,", rths_evaluation_role_name((rths_evaluation_role)r)) < 0) return EOF;
    if (fputs(HEADER_AFTER_ROLES, f) == EOF) return EOF;
    return fflush(f);
}

/* A write that failed (disk full, a file size limit) ends the file where it was: run.log says
 * so once; the run goes on, since the rig's test matters more than its diagnostics. */
static void write_failed(frf_state *st, const char *what) {
    if (st->evaluations_failed) return;
    st->evaluations_failed = 1;
    rths_report_log(st->rep,
                    "evaluations.csv: %s failed (%s): the file stops here, the run goes on", what,
                    strerror(errno));
}

int frf_evaluations_open(frf_state *st, rths_error *err) {
    char *path = rths_report_path(st->rep, "evaluations.csv");
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    /* appended to: a resumed run's evaluations follow the interrupted run's (whose last
     * correction's rows stay: the rig spent that time) */
    st->evaluations = fopen(path, "a");
    if (!st->evaluations) {
        int rc = rths_error_set(err, RTHS_EFAIL, "cannot open %s: %s", path, strerror(errno));
        free(path);
        return rc;
    }
    free(path);
    if (ftell(st->evaluations) == 0 && write_header(st->evaluations) == EOF)
        write_failed(st, "writing the header");
    return RTHS_OK;
}

void frf_on_evaluation(void *user, const rths_evaluation_event *e) {
    frf_state *st = user;
    if (!st->evaluations || st->evaluations_failed) return;
    if (e->role == RTHS_EVALUATION_PREDICTION) st->evaluation_corrections++;
    const rths_evaluation *ev = e->evaluation;
    /* the point this correction would be, had it been accepted (the accepted points so far,
     * resumed ones included) */
    int n = fprintf(st->evaluations, "%d,%d,", st->n, st->evaluation_corrections);
    for (int r = 0; r < ROLES && n >= 0; r++)
        n = fprintf(st->evaluations, "%d,", (int)e->role == r);
    if (n >= 0)
        n = fprintf(
            st->evaluations, "%d,%.17g,%.17g,%.17g,%.17g,%d,%.17g,%.17g,%d,%d,%d,%d,%d,%d,%d\n",
            e->iteration, e->frequency_hz, e->mismatch_m, e->tolerance_m, e->mismatch_to_tolerance,
            e->within_tolerance, e->damping, e->rig_time_s, ev->wait_periods, ev->average_periods,
            ev->steady, ev->fitted, ev->fit_fallback, e->refused, st->opt->resume ? 1 : 0);
    if (n < 0 || fflush(st->evaluations) == EOF) write_failed(st, "writing a row");
}

void frf_evaluations_close(frf_state *st) {
    if (!st->evaluations) return;
    if (fclose(st->evaluations) == EOF) write_failed(st, "closing the file");
    st->evaluations = NULL;
}
