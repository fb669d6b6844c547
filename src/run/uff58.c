/* Universal file format dataset 58 writer (see uff58.h). */
#include "run/uff58.h"

#include <math.h>
#include <string.h>

/* A fixed-width text field: cut to width, "NONE" when empty. */
static void field(char *out, size_t width, const char *text) {
    snprintf(out, width + 1, "%s", text && *text ? text : "NONE");
}

static int axis_line(FILE *out, const frf_uff58_axis *a) {
    char label[21], units[21];
    field(label, 20, a->label);
    field(units, 20, a->units);
    /* Format(I10,3I5,2(1X,20A1)) */
    return fprintf(out, "%10d%5d%5d%5d %-20s %-20s\n", a->data_type, a->length_exp, a->force_exp,
                   a->temperature_exp, label, units) < 0;
}

int frf_uff58_write(FILE *out, const frf_uff58_record *r) {
    int bad = fprintf(out, "%6d\n%6d\n", -1, 58) < 0;
    for (int i = 0; i < 5; i++) {
        char line[81];
        field(line, 80, r->id[i]);
        bad |= fprintf(out, "%s\n", line) < 0;
    }
    /* record 6, Format(2(I5,I10),2(1X,10A1,I10,I4)): function type 4 (frequency response
     * function), id, version 0, load case 0 (single-point excitation), response and reference */
    bad |= fprintf(out, "%5d%10d%5d%10d %-10s%10d%4d %-10s%10d%4d\n", 4, r->function_id, 0, 0,
                   "NONE", r->response_node, r->response_direction, "NONE", r->reference_node,
                   r->reference_direction) < 0;
    /* record 7, Format(3I10,3E13.5): complex double (6), n points, uneven abscissa (0) */
    bad |= fprintf(out, "%10d%10d%10d%13.5E%13.5E%13.5E\n", 6, r->n, 0, 0.0, 0.0, 0.0) < 0;
    bad |= axis_line(out, &r->abscissa);
    bad |= axis_line(out, &r->numerator);
    bad |= axis_line(out, &r->denominator);
    const frf_uff58_axis none = {0, 0, 0, 0, "NONE", "NONE"};
    bad |= axis_line(out, &none);  /* record 11: no z axis */
    for (int k = 0; k < r->n; k++) /* record 12, Format(E13.5,2E20.12) */
        bad |= fprintf(out, "%13.5E%20.12E%20.12E\n", r->frequency_hz[k], creal(r->value[k]),
                       cimag(r->value[k])) < 0;
    bad |= fprintf(out, "%6d\n", -1) < 0;
    return bad ? -1 : 0;
}
