/* The corrector's saved record: what it learnt, as a flat versioned list of numbers (layout in
 * docs/journal.md, "Corrector state"), so a journal can store it and a resumed run continue from
 * the same state bit for bit. */
#include "iterate/corrector_internal.h"

#include <string.h>

/* Offsets into rths_corrector_saved.data (format 1). */
enum {
    S_HAVE_JACOBIAN,
    S_LTI,
    S_UNKNOWNS,
    S_HARMONICS,
    S_JACOBIAN,
    S_RESPONSE_JACOBIAN = S_JACOBIAN + LD * LD,
    S_NOISE_RESPONSE = S_RESPONSE_JACOBIAN + LD * LD,
    S_NOISE_REFERENCE = S_NOISE_RESPONSE + LD,
    S_NOISE_DOF = S_NOISE_REFERENCE + LD,
    S_HISTORY_COUNT,
    S_HISTORY_NEXT,
    S_HISTORY,
    S_HISTORY_ENTRY = 1 + 3 * HISTORY_WIDTH,
    S_LENGTH = S_HISTORY + RTHS_LTI_HISTORY * S_HISTORY_ENTRY
};
_Static_assert(S_LENGTH == RTHS_CORRECTOR_SAVED_MAX, "saved record layout");

static void put(double *dst, const double *src, int n) {
    memcpy(dst, src, sizeof(double) * (size_t)n);
}

void rths_corrector_save(const rths_corrector *c, rths_corrector_saved *out) {
    const corrector_memory *m = &c->mem;
    double *d = out->data;
    memset(out, 0, sizeof *out);
    out->format = RTHS_CORRECTOR_SAVED_FORMAT;
    out->length = S_LENGTH;
    d[S_HAVE_JACOBIAN] = m->have_jacobian;
    d[S_LTI] = m->lti;
    d[S_UNKNOWNS] = c->n;
    d[S_HARMONICS] = c->harmonics;
    put(d + S_JACOBIAN, m->jacobian, LD * LD);
    put(d + S_RESPONSE_JACOBIAN, m->response_jacobian, LD * LD);
    put(d + S_NOISE_RESPONSE, m->noise_ss[0], LD);
    put(d + S_NOISE_REFERENCE, m->noise_ss[1], LD);
    d[S_NOISE_DOF] = m->noise_dof;
    d[S_HISTORY_COUNT] = m->history_count;
    d[S_HISTORY_NEXT] = m->history_next;
    for (int e = 0; e < RTHS_LTI_HISTORY; e++) {
        double *h = d + S_HISTORY + e * S_HISTORY_ENTRY;
        h[0] = m->history[e].omega_rad_s;
        put(h + 1, m->history[e].target, HISTORY_WIDTH);
        put(h + 1 + HISTORY_WIDTH, m->history[e].phi, HISTORY_WIDTH);
        put(h + 1 + 2 * HISTORY_WIDTH, m->history[e].response, HISTORY_WIDTH);
    }
}

int rths_corrector_load(rths_corrector *c, const rths_corrector_saved *in, rths_error *err) {
    const double *d = in->data;
    if (in->format != RTHS_CORRECTOR_SAVED_FORMAT || in->length != S_LENGTH)
        return rths_error_set(err, RTHS_EINPUT,
                              "corrector state of format %d (%d numbers): this rths reads format "
                              "%d (%d numbers)",
                              in->format, in->length, RTHS_CORRECTOR_SAVED_FORMAT, S_LENGTH);
    if (d[S_UNKNOWNS] != c->n || d[S_HARMONICS] != c->harmonics)
        return rths_error_set(err, RTHS_EINPUT,
                              "corrector state for %g unknowns (%g harmonics), the problem has %d "
                              "(%d)",
                              d[S_UNKNOWNS], d[S_HARMONICS], c->n, c->harmonics);
    int count = (int)d[S_HISTORY_COUNT], next = (int)d[S_HISTORY_NEXT];
    if (count < 0 || count > RTHS_LTI_HISTORY || next < 0 || next >= RTHS_LTI_HISTORY)
        return rths_error_set(err, RTHS_EINPUT,
                              "corrector state: history ring %d/%d is not in "
                              "0..%d",
                              count, next, RTHS_LTI_HISTORY);
    corrector_memory *m = &c->mem;
    m->have_jacobian = d[S_HAVE_JACOBIAN] != 0;
    m->lti = d[S_LTI] != 0;
    put(m->jacobian, d + S_JACOBIAN, LD * LD);
    put(m->response_jacobian, d + S_RESPONSE_JACOBIAN, LD * LD);
    put(m->noise_ss[0], d + S_NOISE_RESPONSE, LD);
    put(m->noise_ss[1], d + S_NOISE_REFERENCE, LD);
    m->noise_dof = d[S_NOISE_DOF];
    m->history_count = count;
    m->history_next = next;
    for (int e = 0; e < RTHS_LTI_HISTORY; e++) {
        const double *h = d + S_HISTORY + e * S_HISTORY_ENTRY;
        m->history[e].omega_rad_s = h[0];
        put(m->history[e].target, h + 1, HISTORY_WIDTH);
        put(m->history[e].phi, h + 1 + HISTORY_WIDTH, HISTORY_WIDTH);
        put(m->history[e].response, h + 1 + 2 * HISTORY_WIDTH, HISTORY_WIDTH);
    }
    return RTHS_OK;
}

int rths_corrector_saved_jacobians(const rths_corrector_saved *in, double *jacobian,
                                   double *response_jacobian) {
    if (in->format != RTHS_CORRECTOR_SAVED_FORMAT || in->length != S_LENGTH ||
        !in->data[S_HAVE_JACOBIAN])
        return 0;
    put(jacobian, in->data + S_JACOBIAN, LD * LD);
    put(response_jacobian, in->data + S_RESPONSE_JACOBIAN, LD * LD);
    return 1;
}
