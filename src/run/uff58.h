/* Universal file format, dataset 58 (function at a nodal DoF), ASCII: the measured FRFs for
 * modal-analysis packages (docs/method.md, "Complex FRF and modal identification"). One record
 * per response DoF: complex double ordinates (type 6) at uneven abscissae (the continuation's own
 * frequencies, in point order), records 1-11 as the dataset's definition lays them out, record 12
 * one line per point: frequency (E13.5, six significant digits), real and imaginary part
 * (2E20.12). */
#ifndef RTHS_RUN_UFF58_H
#define RTHS_RUN_UFF58_H

#include <complex.h>
#include <stdio.h>

/* Record 8-10's data characteristics: specific data type (8 displacement, 12 acceleration,
 * 13 excitation force, 18 frequency), the length / force / temperature unit exponents, labels. */
typedef struct frf_uff58_axis {
    int data_type, length_exp, force_exp, temperature_exp;
    const char *label, *units;
} frf_uff58_axis;

typedef struct frf_uff58_record {
    const char *id[5]; /* records 1-5, at most 80 characters each (longer: cut); NULL: "NONE" */
    int function_id;   /* record 6: function identification number, 1.. */
    int response_node, response_direction, reference_node, reference_direction;
    frf_uff58_axis abscissa, numerator, denominator;
    int n;
    const double *frequency_hz;
    const double complex *value;
} frf_uff58_record;

/* Writes one dataset (from its "    -1" to its closing "    -1"); 0, or -1 on a write error. */
int frf_uff58_write(FILE *out, const frf_uff58_record *r);

#endif
