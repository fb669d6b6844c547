/* A base-excited test (forcing.type: base) measures and reports displacements relative to the
 * ground. A ground acceleration A cos(wt) moves the ground by -A / w^2 cos(wt), so the absolute
 * interface displacement's complex amplitude is X_rel - A / w^2 (x = a cos + b sin = Re((a - i b)
 * e^{iwt})). absolute.csv gives it for every accepted point beside the true assembly's, which a
 * base-excited structure's absolute response is usually specified by. */
#include "run/frf_internal.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>

/* The reported (matched, when reported) fundamental of the physical interface, relative. */
static double complex reported_relative(const rths_point *pt) {
    const rths_solution *s = &pt->sol;
    int matched = s->have_matched && s->amplitude_m == s->matched_amplitude_m;
    double a = matched ? s->matched_a[0] : s->eval.phys.a[1];
    double b = matched ? s->matched_b[0] : s->eval.phys.b[1];
    return a - I * b;
}

int frf_write_absolute_csv(rths_report *rep, const frf_state *run, rths_error *err) {
    const rths_setup *s = run->setup;
    int n = s->assembly.n, iface = s->split.int_dofs[0];
    static const char *const header[] = {"point", "frequency_hz", "absolute_amplitude_m",
                                         "truth_absolute_amplitude_m", "relative_amplitude_m"};
    char *path = rths_report_path(rep, "absolute.csv");
    double complex *x = calloc((size_t)n, sizeof *x);
    rths_csv *csv = NULL;
    int rc = path && x ? rths_csv_open(path, 5, header, &csv, err)
                       : rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < run->n && !rc; i++) {
        const rths_point *pt = &run->pts[i];
        double w = 2 * M_PI * pt->sol.frequency_hz, ground = -s->forcing_amplitude_n / (w * w);
        double truth = NAN;
        if (!s->has_bilinear && !rths_frf(n, s->assembly.mass, s->assembly.damping,
                                          s->assembly.stiffness, s->force, w, x, err))
            truth = cabs(x[iface] + ground);
        double complex rel = reported_relative(pt);
        double row[5] = {pt->index, pt->sol.frequency_hz, cabs(rel + ground), truth,
                         pt->sol.amplitude_m};
        if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing absolute.csv");
    }
    rc = rths_csv_finish(csv, rc, err);
    free(x);
    free(path);
    return rc;
}
