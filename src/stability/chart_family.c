/* What a chart of a configured split needs besides the chart itself: the family of splits over p
 * that keeps the configured interface shares, and where the essential spectrum changes side. */
#include "rths/stability.h"

#include <math.h>
#include <stdlib.h>

int rths_split_family_of(const rths_assembly *a, const rths_dof_role *roles, const rths_split *s,
                         rths_split_family *out, double **damping_int, double **stiffness_int,
                         rths_error *err) {
    int ni = s->n_int;
    *damping_int = malloc((size_t)ni * (size_t)ni * sizeof **damping_int);
    *stiffness_int = malloc((size_t)ni * (size_t)ni * sizeof **stiffness_int);
    if (!*damping_int || !*stiffness_int) {
        free(*damping_int), free(*stiffness_int);
        *damping_int = *stiffness_int = NULL;
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    /* the physical side's interface block, rows and columns after its internal DoFs */
    for (int i = 0; i < ni; i++)
        for (int j = 0; j < ni; j++) {
            (*damping_int)[i + j * ni] =
                RTHS_AT(s->damping_phys, s->np, s->n_phys + i, s->n_phys + j);
            (*stiffness_int)[i + j * ni] =
                RTHS_AT(s->stiffness_phys, s->np, s->n_phys + i, s->n_phys + j);
        }
    *out = (rths_split_family){a, roles, *damping_int, *stiffness_int};
    return RTHS_OK;
}

double rths_chart_essential_limit(const rths_chart *c) {
    for (int j = 0; j + 1 < c->np; j++) {
        double a = c->essential_rate_times_tau[j], b = c->essential_rate_times_tau[j + 1];
        if (!isfinite(a) || !isfinite(b)) continue;
        if ((a < 0) != (b < 0)) return c->p[j] + (c->p[j + 1] - c->p[j]) * a / (a - b);
        if (a == 0) return c->p[j];
    }
    return NAN;
}
