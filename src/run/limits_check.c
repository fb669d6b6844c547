/* Before a test: what `rths model` already knows about it. The true assembly's interface
 * response over the requested range against the rig's displacement limit, so a test that must
 * trip is refused before the rig is armed instead of faulting at its first resonance. */
#include "run/frf_internal.h"

#include "rths/controller.h"

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The truth curve's range: the run's, with a margin (the last step may pass end_hz, the first
 * correction move below start_hz), so every accepted point lies inside the curve it is judged
 * against. */
static void truth_range(const frf_state *st, double *lo, double *hi) {
    *lo = fmin(st->cont.start_hz, st->cont.end_hz);
    *hi = fmax(st->cont.start_hz, st->cont.end_hz);
    double margin = 0.1 * (*hi - *lo);
    *lo = fmax(*lo - margin, 0.5 * *lo);
    *hi += margin;
}

/* The interface force the load cell must read (the force between actuator and specimen), N,
 * and the actuator's own force (plus its moving mass's inertia), at the true assembly's steady
 * response x (every DoF) at omega: the rig's physical substructure with the interface mass it
 * carries (rig.interface_mass, setup.h) needs F_LC = [Z_rig x_phys] on each interface row,
 * Z_rig = K_phys - w^2 M_rig + i w C_phys; forcing on the interface acts on the numerical side.
 * The largest over the interface DoFs of each. */
static void rig_forces(const rths_setup *s, double omega, const double complex *x, double arm_kg,
                       double *load_cell_n, double *actuator_n) {
    const rths_split *sp = &s->split;
    int np = sp->np;
    *load_cell_n = *actuator_n = 0;
    for (int d = 0; d < sp->n_int; d++) {
        int row = sp->n_phys + d;
        double complex f = 0;
        for (int j = 0; j < np; j++) {
            int dof = j < sp->n_phys ? sp->phys_dofs[j] : sp->int_dofs[j - sp->n_phys];
            double m = j >= sp->n_phys ? rths_setup_rig_interface_mass(s, d, j - sp->n_phys)
                                       : RTHS_AT(sp->mass_phys, np, row, j);
            f += (RTHS_AT(sp->stiffness_phys, np, row, j) - omega * omega * m +
                  I * omega * RTHS_AT(sp->damping_phys, np, row, j)) *
                 x[dof];
        }
        double complex actuator = f - omega * omega * arm_kg * x[sp->int_dofs[d]];
        *load_cell_n = fmax(*load_cell_n, cabs(f));
        *actuator_n = fmax(*actuator_n, cabs(actuator));
    }
}

/* A linear structure's predicted rig forces over the run's range against the controller's
 * load-cell limit and the actuator's force limit (action fault): what the rig must push depends
 * on what it carries, the whole interface mass or the specimen's share. Writes the peak beyond a
 * limit into what (empty when none). Dense solves per truth frequency: skipped above
 * RTHS_SETUP_ALL_DOFS_UP_TO DoFs, and for the bilinear leg (no linear response). */
static int rig_force_exceedance(const frf_state *st, const rths_controller_options *copt,
                                const rths_plant_options *popt, char *what, size_t size,
                                rths_error *err) {
    const rths_setup *s = st->setup;
    int n = s->assembly.n;
    what[0] = 0;
    if (s->has_bilinear || s->sparse || n > RTHS_SETUP_ALL_DOFS_UP_TO) return RTHS_OK;
    double complex *x = malloc(sizeof *x * (size_t)n);
    if (!x) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    double f_lo = fmin(st->cont.start_hz, st->cont.end_hz),
           f_hi = fmax(st->cont.start_hz, st->cont.end_hz);
    double act_limit = popt->actuator.force_clip ? 0 : popt->actuator.force_limit_n;
    const rths_truth_curve *t = &st->truth;
    int rc = RTHS_OK;
    double lc_peak = 0, lc_hz = 0, act_peak = 0, act_hz = 0;
    for (int j = 0; j < t->n && !rc; j++) {
        if (t->freq_hz[j] < f_lo || t->freq_hz[j] > f_hi) continue;
        double w = 2 * M_PI * t->freq_hz[j], lc, act;
        rc = rths_frf(n, s->assembly.mass, s->assembly.damping, s->assembly.stiffness, s->force, w,
                      x, err);
        if (rc) break;
        rig_forces(s, w, x, popt->armature_mass_kg, &lc, &act);
        if (lc > lc_peak) lc_peak = lc, lc_hz = t->freq_hz[j];
        if (act > act_peak) act_peak = act, act_hz = t->freq_hz[j];
    }
    const char *mode = rths_interface_mass_name(s->interface_mass);
    if (!rc && lc_peak > copt->force_limit_n)
        snprintf(what, size,
                 "the rig's interface force (load cell) at the true response reaches %.3g N at "
                 "%.4g Hz in [%g, %g] Hz with rig.interface_mass: %s, beyond "
                 "controller.limits.force_n = %g N: the test would trip there",
                 lc_peak, lc_hz, f_lo, f_hi, mode, copt->force_limit_n);
    else if (!rc && act_limit > 0 && act_peak > act_limit)
        snprintf(what, size,
                 "the actuator's force at the true response reaches %.3g N at %.4g Hz in [%g, %g] "
                 "Hz with rig.interface_mass: %s, beyond rig.actuator.limits.force_n = %g N: the "
                 "test would trip there",
                 act_peak, act_hz, f_lo, f_hi, mode, act_limit);
    free(x);
    return rc;
}

/* --force: a warning (kept for the log); otherwise the refusal. */
static int refuse_or_warn(frf_state *st, const char *what, const char *advice, rths_error *err) {
    if (!st->opt->force)
        return rths_error_set(err, RTHS_EINPUT, "%s; %s (--force runs it anyway)", what, advice);
    fprintf(stderr, "rths frf: warning: %s (--force)\n", what);
    if (!st->limit_warning[0])
        snprintf(st->limit_warning, sizeof st->limit_warning, "%s (--force)", what);
    return RTHS_OK;
}

/* A sweep with no mode in or near its range measures a quasi-static or mass-line response: legal,
 * but more often a range typed for another structure (or units off by a factor) than a plan. Says
 * so before arming, naming the nearest mode; a warning on stderr and in run.log. */
static int warn_if_no_mode_in_range(frf_state *st, double f_lo, double f_hi, rths_error *err) {
    /* a nonlinear leg moves the resonance with the amplitude: the linearised modes say nothing of
     * where it lies */
    if (st->setup->has_bilinear) return RTHS_OK;
    /* a sparse model forms no dense assembly to analyse (its lowest modes are `rths model`'s):
     * said in run.log, with the other warnings */
    if (st->setup->sparse) {
        size_t used = strlen(st->limit_warning);
        snprintf(st->limit_warning + used, sizeof st->limit_warning - used,
                 "%sno check that a mode lies in the sweep: the model is sparse (model.solver), "
                 "run `rths model` for its modes",
                 used ? "; " : "");
        return RTHS_OK;
    }
    rths_modes modes = {0};
    int rc = rths_modal_analysis(&st->setup->assembly, &modes, err);
    if (rc) return rc;
    int nearest = -1, inside = 0;
    double gap = INFINITY;
    for (int r = 0; r < modes.n; r++) {
        double f = modes.frequency_hz[r], d = f < f_lo ? f_lo - f : f > f_hi ? f - f_hi : 0;
        /* a mode within three half-power bandwidths (2 zeta f) of the range still shapes it */
        inside |= d <= 3 * 2 * modes.damping_ratio[r] * f;
        if (d < gap) gap = d, nearest = r;
    }
    if (!inside && nearest >= 0) {
        char what[256];
        snprintf(what, sizeof what,
                 "no mode of the true assembly lies in the sweep [%g, %g] Hz (nearest: mode %d "
                 "at %.4g Hz): the test measures the response away from resonance",
                 f_lo, f_hi, nearest + 1, modes.frequency_hz[nearest]);
        fprintf(stderr, "rths frf: warning: %s\n", what);
        size_t used = strlen(st->limit_warning);
        snprintf(st->limit_warning + used, sizeof st->limit_warning - used, "%s%s",
                 used ? "; " : "", what);
    }
    rths_modes_free(&modes);
    return RTHS_OK;
}

int frf_plan_within_limits(frf_state *st, rths_error *err) {
    double lo, hi;
    truth_range(st, &lo, &hi);
    int rc = rths_truth_compute(st->setup, lo, hi, &st->truth, err);
    if (rc) return rc;
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    if ((rc = rths_controller_config_read(st->opt->cfg, &copt, err))) return rc;
    /* the share of late samples an evaluation may hold: the controller's key, enforced by the
     * host's evaluations (the virtual rig runs on a simulated clock and has none) */
    st->settle.max_late_share = copt.max_overrun_share;
    st->settle.transition_periods = (int)ceil(copt.transition_periods);
    /* the peak within the run's own range; every harmonic adds to the displacement */
    double f_lo = fmin(st->cont.start_hz, st->cont.end_hz),
           f_hi = fmax(st->cont.start_hz, st->cont.end_hz), peak = 0, peak_hz = 0;
    const rths_truth_curve *t = &st->truth;
    for (int j = 0; j < t->n; j++) {
        if (t->freq_hz[j] < f_lo || t->freq_hz[j] > f_hi) continue;
        double x =
            t->amp_m[j] + (t->amp_h2_m ? t->amp_h2_m[j] : 0) + (t->amp_h3_m ? t->amp_h3_m[j] : 0);
        if (x > peak) peak = x, peak_hz = t->freq_hz[j];
    }
    char what[512];
    if (peak > copt.displacement_limit_m) {
        snprintf(what, sizeof what,
                 "the true assembly's interface response reaches %.3g m at %.4g Hz in [%g, %g] "
                 "Hz, beyond controller.limits.displacement_m = %g m: the test would trip there",
                 peak, peak_hz, f_lo, f_hi, copt.displacement_limit_m);
        if ((rc = refuse_or_warn(st, what,
                                 "narrow continuation.start_hz/end_hz, lower forcing.amplitude_n "
                                 "or raise the limit",
                                 err)))
            return rc;
    }
    /* the forces: the plant's options give the actuator's limit and moving mass (the virtual
     * rig's; a lab's controller process reads the same keys) */
    rths_plant_options popt;
    rths_plant_defaults(&popt);
    if ((rc = rths_plant_config_read(st->opt->cfg, &popt, err))) return rc;
    if ((rc = rig_force_exceedance(st, &copt, &popt, what, sizeof what, err))) return rc;
    /* a warning, not a refusal: a force trip ends the run cleanly with every point before it
     * kept (tests rely on such runs), and the prediction assumes the rig's forces reach the
     * truth's, which a mismatched or clipped run need not */
    if (what[0]) {
        fprintf(stderr,
                "rths frf: warning: %s (narrow continuation.start_hz/end_hz, lower "
                "forcing.amplitude_n, raise the limit or check rig.interface_mass)\n",
                what);
        if (!st->limit_warning[0])
            snprintf(st->limit_warning, sizeof st->limit_warning, "%s", what);
    }
    return warn_if_no_mode_in_range(st, f_lo, f_hi, err);
}
