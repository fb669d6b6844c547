/* modal.csv and frf.uff of an FRF run (docs/method.md, "Complex FRF and modal identification"):
 * the modes in the tested range identified from the hybrid receptance (modal_id.h) beside the
 * true assembly's, and the measured receptances in universal file format 58 (uff58.h). */
#include "run/frf_internal.h"
#include "run/frf_receptance.h"
#include "run/modal_id.h"
#include "run/uff58.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Bootstrap replicates for the modal standard errors: their relative precision is about
 * 1 / sqrt(2 (B - 1)), 5 % at 200. Fixed seed: the same run writes the same modal.csv. */
enum { MODAL_BOOTSTRAP = 200 };
static const uint64_t MODAL_SEED = 0x6d6f64616cULL;

/* One interface DoF's accepted, converged points: frequency, receptance, its parts' SE. */
typedef struct dof_points {
    int n;
    double *f_hz, *se;
    double complex *h;
} dof_points;

static int gather(const frf_state *run, int d, dof_points *p) {
    memset(p, 0, sizeof *p);
    size_t cap = (size_t)(run->n > 0 ? run->n : 1);
    p->f_hz = malloc(cap * sizeof *p->f_hz);
    p->se = malloc(cap * sizeof *p->se);
    p->h = malloc(cap * sizeof *p->h);
    if (!p->f_hz || !p->se || !p->h) return -1;
    for (int i = 0; i < run->n; i++) {
        double complex h;
        double se;
        const rths_point *pt = &run->pts[i];
        if (!pt->sol.converged || frf_receptance_point(run->setup, pt, d, &h, &se) ||
            !isfinite(creal(h)) || !isfinite(cimag(h)))
            continue;
        p->f_hz[p->n] = pt->sol.frequency_hz;
        p->h[p->n] = h;
        p->se[p->n++] = se;
    }
    return 0;
}

static void release(dof_points *p) {
    free(p->f_hz);
    free(p->se);
    free(p->h);
}

/* The modal constant's unit (the receptance's times (rad/s)^2) as a column-name suffix, for the
 * interface DoFs together: 1/kg for forced translations; m_or_rad_... when displacements and
 * rotations mix (a beam's tip: the row's dof_is_rotation column says which). */
static const char *modal_constant_unit(const rths_setup *s, int dofs) {
    int rot = 0, trans = 0;
    for (int d = 0; d < dofs; d++) {
        int r = rths_setup_dof_is_rotation(s, s->split.int_dofs[d]);
        rot |= r;
        trans |= !r;
    }
    if (s->base_excitation) return rot && trans ? "m_or_rad_per_m" : rot ? "rad_per_m" : "m_per_m";
    return rot && trans ? "m_or_rad_per_n_s2" : rot ? "rad_per_n_s2" : "per_kg";
}

enum { MODAL_COLUMNS = 19 };

/* modal.csv: a row per (interface DoF, true mode in the tested range), ascending in frequency;
 * the identified values NaN where the fit failed (run.log says why). */
static int write_modal_csv(rths_report *rep, const frf_state *run, const rths_modes *modes,
                           const frf_receptance_columns *rec, rths_error *err) {
    const rths_setup *s = run->setup;
    char names[4][64];
    const char *u = modal_constant_unit(s, rec->dofs);
    snprintf(names[0], sizeof names[0], "modal_constant_real_%s", u);
    snprintf(names[1], sizeof names[1], "modal_constant_imag_%s", u);
    snprintf(names[2], sizeof names[2], "modal_constant_real_se_%s", u);
    snprintf(names[3], sizeof names[3], "modal_constant_imag_se_%s", u);
    char true_name[64];
    snprintf(true_name, sizeof true_name, "true_modal_constant_%s", u);
    const char *header[MODAL_COLUMNS] = {"mode",
                                         "interface_dof",
                                         "dof",
                                         "dof_is_rotation",
                                         "frequency_hz",
                                         "frequency_se_hz",
                                         "damping_ratio",
                                         "damping_ratio_se",
                                         names[0],
                                         names[1],
                                         names[2],
                                         names[3],
                                         "true_frequency_hz",
                                         "true_damping_ratio",
                                         true_name,
                                         "points",
                                         "bootstrap_replicates",
                                         "frequency_deviation_in_se",
                                         "damping_deviation_in_se"};
    char *path = rths_report_path(rep, "modal.csv");
    rths_csv *csv = NULL;
    int rc = path ? rths_csv_open(path, MODAL_COLUMNS, header, &csv, err)
                  : rths_error_set(err, RTHS_EFAIL, "out of memory");
    free(path);
    int n = s->assembly.n;
    for (int d = 0; d < rec->dofs && !rc; d++) {
        dof_points p;
        if (gather(run, d, &p)) {
            release(&p);
            rths_csv_abort(csv);
            return rths_error_set(err, RTHS_EFAIL, "out of memory");
        }
        double lo = INFINITY, hi = -INFINITY;
        for (int k = 0; k < p.n; k++) {
            lo = fmin(lo, p.f_hz[k]);
            hi = fmax(hi, p.f_hz[k]);
        }
        int first = -1, count = 0;
        for (int r = 0; r < modes->n; r++)
            if (modes->frequency_hz[r] >= lo && modes->frequency_hz[r] <= hi) {
                if (first < 0) first = r;
                count++;
            }
        if (count > FRF_MODAL_MAX_MODES) count = FRF_MODAL_MAX_MODES;
        frf_mode_estimate est[FRF_MODAL_MAX_MODES];
        int used = 0, fitted = 0;
        if (count > 0) {
            frf_modal_fit_options o = {count, MODAL_BOOTSTRAP, MODAL_SEED + (uint64_t)d, 0};
            rths_error fit_err;
            fitted = !frf_modal_fit(p.n, p.f_hz, p.h, p.se, &o, est, &used, &fit_err);
            if (!fitted)
                rths_report_log(rep, "modal.csv: interface DoF %d not identified: %s", d + 1,
                                fit_err.msg);
        } else {
            rths_report_log(rep,
                            "modal.csv: no mode of the true assembly between %.4f and %.4f Hz "
                            "(interface DoF %d): nothing to identify",
                            lo, hi, d + 1);
        }
        int j = s->split.int_dofs[d];
        for (int q = 0; q < count && !rc; q++) {
            int r = first + q;
            const double *phi = modes->shapes + (size_t)n * r;
            double participation = 0;
            for (int i = 0; i < n; i++)
                participation += phi[i] * s->forcing_shape[i];
            double truth_a = phi[j] * participation;
            const frf_mode_estimate *e = fitted ? &est[q] : NULL;
            double row[MODAL_COLUMNS] = {
                r + 1,
                d + 1,
                j + 1,
                rths_setup_dof_is_rotation(s, j),
                e ? e->frequency_hz : NAN,
                e ? e->frequency_se_hz : NAN,
                e ? e->damping_ratio : NAN,
                e ? e->damping_ratio_se : NAN,
                e ? creal(e->modal_constant) : NAN,
                e ? cimag(e->modal_constant) : NAN,
                e ? e->modal_constant_se_real : NAN,
                e ? e->modal_constant_se_imag : NAN,
                modes->frequency_hz[r],
                modes->damping_ratio[r],
                truth_a,
                p.n,
                used,
                e ? (e->frequency_hz - modes->frequency_hz[r]) / e->frequency_se_hz : NAN,
                e ? (e->damping_ratio - modes->damping_ratio[r]) / e->damping_ratio_se : NAN};
            if (rths_csv_row(csv, row)) rc = rths_error_set(err, RTHS_EFAIL, "writing modal.csv");
            if (e)
                rths_report_log(rep,
                                "modal.csv: mode %d (interface DoF %d) %.5f +- %.5f Hz, damping "
                                "%.4f +- %.4f %% (truth %.5f Hz, %.4f %%: %+.4f %% and %+.2f %%)",
                                r + 1, d + 1, e->frequency_hz, e->frequency_se_hz,
                                100 * e->damping_ratio, 100 * e->damping_ratio_se,
                                modes->frequency_hz[r], 100 * modes->damping_ratio[r],
                                100 * (e->frequency_hz / modes->frequency_hz[r] - 1),
                                100 * (e->damping_ratio / modes->damping_ratio[r] - 1));
        }
        release(&p);
    }
    return rths_csv_finish(csv, rc, err);
}

/* frf.uff: one dataset 58 per interface DoF, the converged points' receptance. */
static int write_uff(rths_report *rep, const frf_state *run, const frf_receptance_columns *rec,
                     rths_error *err) {
    const rths_setup *s = run->setup;
    char *path = rths_report_path(rep, "frf.uff");
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    rths_atomic_file *af = NULL;
    FILE *f = NULL;
    int rc = rths_atomic_open(path, &af, &f, err);
    free(path);
    if (rc) return rc;
    char date[32];
    time_t now = time(NULL);
    struct tm tm;
    strftime(date, sizeof date, "%d-%b-%y %H:%M:%S", gmtime_r(&now, &tm));
    int bad = 0;
    for (int d = 0; d < rec->dofs && !bad; d++) {
        dof_points p;
        if (gather(run, d, &p)) {
            release(&p);
            rths_atomic_abort(af);
            return rths_error_set(err, RTHS_EFAIL, "out of memory");
        }
        int dof = s->split.int_dofs[d];
        int rot = rths_setup_dof_is_rotation(s, dof);
        char id1[128]; /* the UFF58 writer cuts ID lines to the format's 80 columns */
        snprintf(id1, sizeof id1, "rths hybrid test: receptance of interface DoF %d (DoF %d), %s",
                 d + 1, dof + 1, rec->unit[d]);
        /* planar models: translations along X (direction 1), rotations about Y (5); the
         * reference is the forced DoF, or node 0 (the ground) for base excitation */
        int ref_rot = !s->base_excitation && rths_setup_dof_is_rotation(s, s->forcing_dof);
        frf_uff58_record r = {
            .id = {id1,
                   s->base_excitation ? "base excitation: displacement relative to the ground"
                                      : "force excitation",
                   date, "rths", NULL},
            .function_id = d + 1,
            .response_node = dof + 1,
            .response_direction = rot ? 5 : 1,
            .reference_node = s->base_excitation ? 0 : s->forcing_dof + 1,
            .reference_direction = ref_rot ? 5 : 1,
            .abscissa = {18, 0, 0, 0, "Frequency", "Hz"},
            .numerator = {8, rot ? 0 : 1, 0, 0, rot ? "Rotation" : "Displacement",
                          rot ? "rad" : "m"},
            .denominator =
                s->base_excitation
                    ? (frf_uff58_axis){12, 1, 0, 0, "Acceleration", "m/s^2"}
                    : (frf_uff58_axis){13, ref_rot ? 1 : 0, 1, 0, "Force", ref_rot ? "N m" : "N"},
            .n = p.n,
            .frequency_hz = p.f_hz,
            .value = p.h};
        bad = frf_uff58_write(f, &r);
        release(&p);
    }
    if (bad) {
        rths_atomic_abort(af);
        return rths_error_set(err, RTHS_EFAIL, "writing frf.uff failed");
    }
    return rths_atomic_commit(af, err);
}

int frf_write_modal_outputs(rths_report *rep, const frf_state *run, rths_error *err) {
    const rths_setup *s = run->setup;
    frf_receptance_columns rec;
    frf_receptance_columns_init(&rec, s);
    int rc = write_uff(rep, run, &rec, err);
    if (rc) return rc;
    rths_report_log(rep, "wrote frf.uff (universal file format 58, the measured receptance)");
    if (s->has_bilinear) {
        /* has_bilinear is set by any nonlinear element (the bilinear leg, structure.nonlinear's;
         * there is at least one then), so the message names the element */
        if (s->n_nonlinear > 1)
            rths_report_log(rep,
                            "no modal.csv: %d nonlinear elements make the response depend on its "
                            "amplitude, the structure has no modes to identify",
                            s->n_nonlinear);
        else
            rths_report_log(rep,
                            "no modal.csv: a %s element's response depends on its amplitude, the "
                            "structure has no modes to identify",
                            rths_nl_type_name(s->nonlinear[0].type));
        return 0;
    }
    rths_modes modes;
    rths_error merr;
    if (rths_modal_analysis(&s->assembly, &modes, &merr)) {
        rths_report_log(rep, "no modal.csv: the true assembly's modes: %s", merr.msg);
        return 0;
    }
    rc = write_modal_csv(rep, run, &modes, &rec, err);
    rths_modes_free(&modes);
    return rc;
}
