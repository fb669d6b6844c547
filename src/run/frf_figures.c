/* The FRF test's figures (docs/method.md, "Figures"): frf (amplitude, deviation from the truth,
 * interface error), bode (receptance amplitude and phase, deviation), nyquist, iterations. One
 * convention (report.h): bars are +-3 standard errors, legends in the right margin outside every
 * plot, units chosen per magnitude, the truth's modes drawn and labelled. Data come from frf.csv
 * and truth.csv by column name; what neither holds (the deviation from the truth at each point's
 * own frequency) is written into the script as a data block. */
#include "run/frf_internal.h"
#include "run/frf_receptance.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The plots span the same horizontal extent in every panel; legends sit right of it. */
static const double PLOT_LEFT = 0.09, PLOT_RIGHT = 0.72, KEY_X = 0.735;

static void panel(FILE *g, double top, double bottom, const char *title, double key_x) {
    fprintf(g,
            "set tmargin at screen %.4f\nset bmargin at screen %.4f\n"
            "set lmargin at screen %.4f\nset rmargin at screen %.4f\n"
            "set key at screen %.4f, screen %.4f left top Left reverse samplen 2 spacing 1.1 "
            "noautotitle\n"
            "set title %s%s%s noenhanced offset 0,-0.3\n",
            top, bottom, PLOT_LEFT, PLOT_RIGHT, key_x, top, title ? "\"" : "",
            title ? title : "\"\"", title ? "\"" : "");
}

/* The truth's modes inside [lo, hi]: dotted vertical lines, labelled at the foot of the panel
 * (where the response of a lightly damped mode is far from its line). labels 0: lines only. */
static void mode_lines(FILE *g, const rths_modes *modes, double lo, double hi, int labels) {
    fprintf(g, "unset arrow\nunset label\n");
    for (int r = 0; modes && r < modes->n; r++) {
        double f = modes->frequency_hz[r];
        if (!(f >= lo && f <= hi)) continue;
        fprintf(g,
                "set arrow from first %.9g, graph 0 to first %.9g, graph 1 nohead dt 3 lw 1.2 "
                "lc rgb 'gray40' back\n",
                f, f);
        if (labels)
            fprintf(g,
                    "set label 'mode %d: %.4f Hz' at first %.9g, graph 0.05 left offset 0.6,0 "
                    "font ',10' tc rgb 'gray25' front\n",
                    r + 1, f, f);
    }
}

/* Plotted frequency range: the points' and the truth's. */
static void frequency_range(const frf_state *run, const rths_truth_curve *t, double *lo,
                            double *hi) {
    *lo = INFINITY;
    *hi = -INFINITY;
    for (int i = 0; i < run->n; i++) {
        *lo = fmin(*lo, run->pts[i].sol.frequency_hz);
        *hi = fmax(*hi, run->pts[i].sol.frequency_hz);
    }
    for (int j = 0; j < t->n; j++) {
        *lo = fmin(*lo, t->freq_hz[j]);
        *hi = fmax(*hi, t->freq_hz[j]);
    }
}

/* Interface DoF d's reported amplitude and standard error at a point (frf.csv's amplitude_m /
 * dof<d>_amplitude_m). */
static int point_amplitude(const frf_state *run, const rths_point *pt, int d, double *a,
                           double *se) {
    const rths_solution *s = &pt->sol;
    int dofs = run->setup->split.n_int;
    if (dofs == 1 || d == 0) {
        *a = s->amplitude_m;
        *se = s->amplitude_se_m;
        if (dofs == 1) return 0;
    }
    if (s->interface_dofs != dofs) return -1;
    *a = s->dof_amplitude_m[d];
    *se = s->dof_amplitude_se_m[d];
    return 0;
}

/* $dev: per converged point, the frequency, then per interface DoF the deviation of the reported
 * amplitude from the truth at its frequency on its branch (%) and 3 standard errors (%). */
static void deviation_block(FILE *g, const frf_state *run, int dofs,
                            const double complex *truth_at) {
    const rths_setup *s = run->setup;
    /* comma-separated with a header line, as the script reads every file */
    fprintf(g, "$dev << EOD\nfrequency_hz");
    for (int d = 0; d < dofs; d++)
        fprintf(g, ",deviation_%d_percent,bar_%d_percent", d + 1, d + 1);
    fprintf(g, "\n");
    for (int i = 0; i < run->n; i++) {
        const rths_point *pt = &run->pts[i];
        if (!pt->sol.converged) continue;
        double f = pt->sol.frequency_hz, truth[RTHS_MAX_INTERFACE_DOFS];
        for (int d = 0; d < RTHS_MAX_INTERFACE_DOFS; d++)
            truth[d] = NAN;
        if (s->has_bilinear)
            truth[0] = rths_truth_branch_amplitude_m(s, &run->truth, f, pt->sol.amplitude_m, NULL);
        else
            for (int d = 0; d < dofs; d++)
                truth[d] =
                    cabs(truth_at[i * RTHS_MAX_INTERFACE_DOFS + d]) * fabs(s->forcing_amplitude_n);
        fprintf(g, "%.10g", f);
        for (int d = 0; d < dofs; d++) {
            double a, se;
            if (point_amplitude(run, pt, d, &a, &se) || !(truth[d] > 0))
                fprintf(g, ",NaN,NaN");
            else
                fprintf(g, ",%.8g,%.8g", 100 * (a / truth[d] - 1), 300 * se / truth[d]);
        }
        fprintf(g, "\n");
    }
    fprintf(g, "EOD\n");
}

/* The unit of interface DoF d's amplitudes (m or rad by the DoF) for values up to max_abs. */
static double dof_unit(const rths_setup *s, int d, double max_abs, char *label, size_t size) {
    int rot = rths_setup_dof_is_rotation(s, s->split.int_dofs[d]);
    return rths_plot_unit(max_abs, rot ? "rad" : "m", label, size);
}

/* frf.png: amplitude against the truth (top), deviation from the truth (middle), interface error
 * (bottom); every interface DoF, one colour each (rotations on the right-hand axis). */
static int plot_frf(rths_report *rep, const frf_state *run, const rths_truth_curve *t,
                    const rths_modes *modes, const char *title, const double complex *truth_at,
                    rths_error *err) {
    const rths_setup *s = run->setup;
    int dofs = s->split.n_int < RTHS_MAX_INTERFACE_DOFS ? s->split.n_int : RTHS_MAX_INTERFACE_DOFS;
    double lo, hi;
    frequency_range(run, t, &lo, &hi);
    /* the largest amplitude and interface error of the translations and of the rotations */
    double max_amp[2] = {0, 0}, max_err = 0, min_err = INFINITY, max_rot_err = 0;
    int any_unstable = 0, any_fold = 0, any_unstable_pt = 0, rot_axis = 0;
    for (int d = 0; d < dofs; d++)
        rot_axis |= d > 0 && rths_setup_dof_is_rotation(s, s->split.int_dofs[d]);
    for (int i = 0; i < run->n; i++) {
        const rths_point *pt = &run->pts[i];
        for (int d = 0; d < dofs; d++) {
            double a, se;
            int rot = d > 0 && rths_setup_dof_is_rotation(s, s->split.int_dofs[d]);
            if (!point_amplitude(run, pt, d, &a, &se) && isfinite(a))
                max_amp[rot] = fmax(max_amp[rot], a + 3 * se);
        }
        for (int d = 1; d < dofs && pt->sol.eval.interface_dofs == dofs; d++)
            if (rths_setup_dof_is_rotation(s, s->split.int_dofs[d])) {
                const rths_fourier *ph = &pt->sol.eval.phys_dof[d], *nu = &pt->sol.eval.num_dof[d];
                max_rot_err = fmax(max_rot_err, hypot(ph->a[1] - nu->a[1], ph->b[1] - nu->b[1]));
            }
        double e = frf_harmonic_error(pt, 1);
        max_err = fmax(max_err, e);
        if (e > 0) min_err = fmin(min_err, e);
        min_err = fmin(min_err, pt->sol.tolerance_m);
        max_err = fmax(max_err, pt->sol.tolerance_m);
        any_fold |= pt->fold;
        any_unstable_pt |= !rths_point_stable(pt);
    }
    for (int j = 0; j < t->n; j++) {
        any_unstable |= !t->stable[j];
        max_amp[0] = fmax(max_amp[0], t->amp_m[j]);
        for (int d = 1; d < t->dofs && t->amp_dof_m; d++) {
            int rot = rths_setup_dof_is_rotation(s, s->split.int_dofs[d]);
            max_amp[rot] = fmax(max_amp[rot], t->amp_dof_m[d * t->n + j]);
        }
    }
    /* a right-hand axis (rotations) takes its labels' room: the legends go further right */
    double key_x = rot_axis ? 0.785 : KEY_X;
    char unit[2][24], err_unit[24];
    double scale[2];
    scale[0] = dof_unit(s, 0, max_amp[0], unit[0], sizeof unit[0]);
    scale[1] = rths_plot_unit(max_amp[1], "rad", unit[1], sizeof unit[1]);
    double err_scale = rths_plot_unit(max_err, "m", err_unit, sizeof err_unit);
    char rot_err_unit[24];
    double rot_err_scale = rths_plot_unit(max_rot_err, "rad", rot_err_unit, sizeof rot_err_unit);

    char *body = NULL;
    size_t size = 0;
    FILE *g = open_memstream(&body, &size);
    if (!g) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    fprintf(g,
            "set datafile separator ','\nset datafile columnheaders\nset grid\n"
            "set xrange [%.9g:%.9g]\nset multiplot title \"%s\" noenhanced\n",
            lo, hi, title);
    deviation_block(g, run, dofs, truth_at);
    /* top: the amplitude */
    panel(g, 0.93, 0.50, "Interface response, fundamental (bars: ±3 standard errors)", key_x);
    mode_lines(g, modes, lo, hi, 1);
    fprintf(g, "set format x ''\nset xlabel ''\nset ylabel 'Amplitude (%s)'\nset yrange [0:*]\n",
            unit[0]);
    if (rot_axis)
        fprintf(g,
                "set y2label 'Rotation amplitude (%s)'\nset y2tics\nset ytics nomirror\n"
                "set y2range [0:*]\n",
                unit[1]);
    const char *first = dofs > 1 ? ", interface DoF 1" : "";
    fprintf(g,
            "plot 'truth.csv' using 1:(column('stable') == 1 ? column('amplitude_m') * %g : 1/0) "
            "with lines lw 2 lc rgb 'black' title '%s%s%s'",
            scale[0], dofs > 1 ? "truth" : "true assembly", first, any_unstable ? ", stable" : "");
    if (any_unstable)
        fprintf(g,
                ", \\\n  'truth.csv' using 1:(column('stable') == 0 ? column('amplitude_m') * %g : "
                "1/0) with lines lw 2 dt 2 lc rgb 'gray40' title 'true assembly, unstable'",
                scale[0]);
    fprintf(g,
            ", \\\n  'frf.csv' using 'frequency_hz':(column('stable') == 1 ? "
            "column('amplitude_m') * %g : 1/0):(3 * column('amplitude_se_m') * %g) with "
            "yerrorbars pt 7 ps 0.8 lc rgb '%s' title '%s%s%s'",
            scale[0], scale[0], rths_plot_colour(0), dofs > 1 ? "hybrid" : "hybrid test", first,
            any_unstable_pt ? ", stable" : "");
    if (any_unstable_pt)
        fprintf(g,
                ", \\\n  'frf.csv' using 'frequency_hz':(column('stable') == 0 ? "
                "column('amplitude_m') * %g : 1/0) with points pt 6 ps 1.0 lw 1.5 lc rgb '%s' "
                "title 'hybrid, unstable (fold label)'",
                scale[0], rths_plot_colour(0));
    if (any_fold)
        fprintf(g,
                ", \\\n  'frf.csv' using 'frequency_hz':(column('fold') == 1 ? "
                "column('amplitude_m') * %g : 1/0) with points pt 6 ps 3 lw 2 lc rgb '#d62728' "
                "title 'fold located after this point'",
                scale[0]);
    for (int d = 1; d < dofs; d++) {
        int dof = s->split.int_dofs[d];
        int rot = rths_setup_dof_is_rotation(s, dof);
        const char *axes = rot ? " axes x1y2" : "";
        char what[64];
        snprintf(what, sizeof what, "interface DoF %d%s", d + 1, rot ? " (right)" : "");
        fprintf(g,
                ", \\\n  'truth.csv' using 1:(column('dof%d_amplitude_m') * %g)%s with lines lw 2 "
                "lc rgb '%s' title 'truth, %s', \\\n"
                "  'frf.csv' using 'frequency_hz':(column('dof%d_amplitude_m') * %g):(3 * "
                "column('dof%d_amplitude_se_m') * %g)%s with yerrorbars pt 7 ps 0.8 lc rgb '%s' "
                "title 'hybrid, %s'",
                d + 1, scale[rot], axes, rths_plot_colour(d), what, d + 1, scale[rot], d + 1,
                scale[rot], axes, rths_plot_colour(d), what);
    }
    fprintf(
        g,
        "\nunset y2label\nunset y2tics\nset ytics mirror\nset yrange [*:*]\nset y2range [*:*]\n");
    /* middle: deviation from the truth */
    panel(g, 0.46, 0.27, NULL, key_x);
    mode_lines(g, modes, lo, hi, 0);
    fprintf(g, "set ylabel \"Deviation from\\ntruth (%%)\"\nplot 0 with lines lc rgb 'black' "
               "lw 1 notitle");
    /* several DoFs: each drawn shifted in frequency by a fraction of the span, so bars that
     * coincide stay visible (said in the panel's legend) */
    double shift = dofs > 1 ? 0.012 * (hi - lo) : 0;
    for (int d = 0; d < dofs; d++) {
        char which[48] = "(A - A_{true}) / A_{true}, ±3 SE";
        if (dofs > 1)
            snprintf(which, sizeof which, "DoF %d, drawn %+.2g Hz", d + 1,
                     (d - 0.5 * (dofs - 1)) * shift);
        fprintf(g,
                ", \\\n  $dev using ($1 + %.6g):%d:%d with yerrorbars pt %d ps 0.7 lc rgb '%s' "
                "title '%s'",
                (d - 0.5 * (dofs - 1)) * shift, 2 + 2 * d, 3 + 2 * d, 7 + 2 * d,
                rths_plot_colour(d), which);
    }
    /* bottom: the interface error and the tolerance it met (log scale) */
    fprintf(g, "\n");
    panel(g, 0.23, 0.07, NULL, key_x);
    mode_lines(g, modes, lo, hi, 0);
    if (rot_axis)
        fprintf(g,
                "set logscale y2\nset format y2 '10^{%%T}'\nset y2tics\nset ytics nomirror\n"
                "set y2label \"Rotation error (%s)\"\n",
                rot_err_unit);
    fprintf(g,
            "set format x '%%g'\nset xlabel 'Forcing frequency (Hz)'\nset logscale y\n"
            "set format y '10^{%%T}'\nset ylabel \"Interface error,\\nfundamental (%s)\"\n"
            "plot 'frf.csv' using 'frequency_hz':(column('tolerance_m') * %g) with steps lw 1.5 "
            "lc rgb 'gray50' title 'tolerance'",
            err_unit, err_scale);
    if (dofs == 1)
        fprintf(g,
                ", \\\n  'frf.csv' using 'frequency_hz':(column('interface_error_m') > 0 ? "
                "column('interface_error_m') * %g : 1/0) with points pt 7 ps 0.7 lc rgb '%s' "
                "title '|x_{phys} - x_{num}|'",
                err_scale, rths_plot_colour(0));
    for (int d = 0; d < dofs && dofs > 1; d++) {
        int rot = rths_setup_dof_is_rotation(s, s->split.int_dofs[d]);
        fprintf(g,
                ", \\\n  'frf.csv' using 'frequency_hz':(column('dof%d_interface_error_m') > 0 "
                "? column('dof%d_interface_error_m') * %g : 1/0)%s with points pt 7 ps 0.7 lc rgb "
                "'%s' title '|x_{phys} - x_{num}|, DoF %d%s'",
                d + 1, d + 1, rot ? rot_err_scale : err_scale, rot ? " axes x1y2" : "",
                rths_plot_colour(d), d + 1, rot ? " (right)" : "");
    }
    fprintf(g, "\nunset multiplot\n");
    (void)min_err;
    (void)max_rot_err;
    int rc = fclose(g) ? rths_error_set(err, RTHS_EFAIL, "out of memory") : 0;
    if (!rc)
        rc = rths_plot(rep, rths_report_dir(rep), "frf",
                       rot_axis   ? 1600
                       : dofs > 1 ? 1450
                                  : 1300,
                       1100, body, err);
    free(body);
    return rc;
}

/* $rec<d>: per converged point, frequency, |H| (unit), 3 SE (unit), phase (deg), 3 SE of the
 * phase (deg, SE / |H|), Re H, Im H (unit), |H - H_true| / |H_true| (%), 3 SE / |H_true| (%). */
static void receptance_block(FILE *g, const frf_state *run, int d, double scale,
                             const double complex *truth_at) {
    const rths_setup *s = run->setup;
    fprintf(g,
            "$rec%d << EOD\nfrequency_hz,magnitude,magnitude_bar,phase_deg,phase_bar_deg,real,"
            "imag,deviation_percent,bar_percent\n",
            d + 1);
    for (int i = 0; i < run->n; i++) {
        const rths_point *pt = &run->pts[i];
        double complex h;
        double se;
        if (!pt->sol.converged || frf_receptance_point(s, pt, d, &h, &se) || !isfinite(cabs(h)))
            continue;
        double f = pt->sol.frequency_hz, mag = cabs(h);
        double complex truth = truth_at[i * RTHS_MAX_INTERFACE_DOFS + d];
        double dev = 100 * cabs(h - truth) / cabs(truth), bar = 300 * se / cabs(truth);
        if (s->has_bilinear) {
            /* the shooting truth (truth.csv) has the amplitude on each branch, not the phase:
             * |H| against |H_true| = A_true / F on the point's branch (frf.png's deviation) */
            double a_true = d == 0 ? rths_truth_branch_amplitude_m(s, &run->truth, f,
                                                                   pt->sol.amplitude_m, NULL)
                                   : NAN,
                   h_true = a_true / fabs(s->forcing_amplitude_n);
            dev = 100 * (mag / h_true - 1);
            bar = 300 * se / h_true;
        }
        fprintf(g, "%.10g,%.8g,%.8g,%.8g,%.8g,%.8g,%.8g,%.8g,%.8g\n", f, mag * scale,
                3 * se * scale, carg(h) * 180 / M_PI, mag > 0 ? 3 * se / mag * 180 / M_PI : NAN,
                creal(h) * scale, cimag(h) * scale, dev, bar);
    }
    fprintf(g, "EOD\n");
}

/* The receptance's unit label ("µm/N") and factor for interface DoF d. */
static double receptance_unit(const frf_state *run, const rths_truth_curve *t, int d, char *label,
                              size_t size) {
    const rths_setup *s = run->setup;
    double max_abs = 0;
    for (int i = 0; i < run->n; i++) {
        double complex h;
        double se;
        if (!frf_receptance_point(s, &run->pts[i], d, &h, &se) && isfinite(cabs(h)))
            max_abs = fmax(max_abs, cabs(h));
    }
    /* the truth's |H| is its amplitude over the forcing's: no solve of the assembly needed */
    const double *amp = t->dofs > d && t->amp_dof_m ? t->amp_dof_m + (size_t)d * t->n
                        : d == 0                    ? t->amp_m
                                                    : NULL;
    for (int j = 0; amp && j < t->n && s->forcing_amplitude_n != 0; j++)
        if (isfinite(amp[j])) max_abs = fmax(max_abs, amp[j] / fabs(s->forcing_amplitude_n));
    char si[24];
    int rot = rths_setup_dof_is_rotation(s, s->split.int_dofs[d]);
    snprintf(si, sizeof si, "%s/%s", rot ? "rad" : "m", s->base_excitation ? "(m/s^2)" : "N");
    return rths_plot_unit(max_abs, si, label, size);
}

/* bode.png: per interface DoF a column of panels: |H| (log), phase, deviation from the truth. */
static int plot_bode(rths_report *rep, const frf_state *run, const rths_truth_curve *t,
                     const rths_modes *modes, const char *title, const double complex *truth_at,
                     rths_error *err) {
    const rths_setup *s = run->setup;
    frf_receptance_columns rec;
    frf_receptance_columns_init(&rec, s);
    double lo, hi;
    frequency_range(run, t, &lo, &hi);
    char *body = NULL;
    size_t size = 0;
    FILE *g = open_memstream(&body, &size);
    if (!g) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    fprintf(g,
            "set datafile separator ','\nset datafile columnheaders\nset grid\n"
            "set xrange [%.9g:%.9g]\nset multiplot title \"%s\" noenhanced\n",
            lo, hi, title);
    double width = (PLOT_RIGHT - PLOT_LEFT) / rec.dofs;
    for (int d = 0; d < rec.dofs; d++) {
        char unit[24];
        double scale = receptance_unit(run, t, d, unit, sizeof unit);
        receptance_block(g, run, d, scale, truth_at);
        double left = PLOT_LEFT + d * width + (d ? 0.05 : 0), right = left + width - 0.05;
        if (rec.dofs == 1) right = PLOT_RIGHT;
        char heading[96];
        snprintf(heading, sizeof heading, "Receptance of interface DoF %d (DoF %d)%s", d + 1,
                 s->split.int_dofs[d] + 1, d == 0 ? ", bars ±3 standard errors" : "");
        const char *re = rec.names[2 * d], *im = rec.names[2 * d + 1];
        /* amplitude */
        panel(g, 0.92, 0.56, heading, KEY_X);
        fprintf(g, "set lmargin at screen %.4f\nset rmargin at screen %.4f\n", left, right);
        if (d > 0) fprintf(g, "unset key\n");
        mode_lines(g, modes, lo, hi, 1);
        fprintf(g,
                "set format x ''\nset xlabel ''\nset logscale y\nset format y '%%g'\n"
                "set ylabel '|H| (%s)'\n",
                unit);
        if (s->has_bilinear && d == 0)
            /* the shooting truth: its amplitude over the forcing's, stable and unstable */
            fprintf(g,
                    "plot 'truth.csv' using 1:(column('stable') == 1 ? column('amplitude_m') / "
                    "%.9g * %g : 1/0) with lines lw 2 lc rgb 'black' title 'true assembly, "
                    "stable', \\\n"
                    "  'truth.csv' using 1:(column('stable') == 0 ? column('amplitude_m') / %.9g "
                    "* %g : 1/0) with lines lw 2 dt 2 lc rgb 'gray40' title 'true assembly, "
                    "unstable', \\\n",
                    fabs(s->forcing_amplitude_n), scale, fabs(s->forcing_amplitude_n), scale);
        else
            fprintf(g,
                    "plot 'truth.csv' using 1:(sqrt(column('%s')**2 + column('%s')**2) * %g) "
                    "with lines lw 2 lc rgb 'black' title '%s', \\\n",
                    re, im, scale, s->has_bilinear ? "" : "true assembly");
        fprintf(g,
                "  $rec%d using 1:2:3 with yerrorbars pt 7 ps 0.7 lc rgb '%s' title "
                "'hybrid test'\n",
                d + 1, rths_plot_colour(d));
        /* phase */
        panel(g, 0.53, 0.29, NULL, KEY_X);
        fprintf(g, "set lmargin at screen %.4f\nset rmargin at screen %.4f\nunset key\n", left,
                right);
        mode_lines(g, modes, lo, hi, 0);
        fprintf(g,
                "unset logscale y\nset ylabel 'Phase (deg)'\nset ytics 45\n"
                "plot 'truth.csv' using 1:(atan2(column('%s'), column('%s')) * 180 / pi) with "
                "lines lw 2 lc rgb 'black' notitle, \\\n"
                "  $rec%d using 1:4:5 with yerrorbars pt 7 ps 0.7 lc rgb '%s' notitle\n"
                "set ytics autofreq\n",
                im, re, d + 1, rths_plot_colour(d));
        /* deviation */
        panel(g, 0.26, 0.08, NULL, KEY_X);
        fprintf(g, "set lmargin at screen %.4f\nset rmargin at screen %.4f\n", left, right);
        if (d > 0) fprintf(g, "unset key\n");
        mode_lines(g, modes, lo, hi, 0);
        /* a bilinear leg's interface DoFs after the first have no truth: a fixed range keeps
         * gnuplot from warning on the empty panel */
        fprintf(g, "set yrange %s\n", s->has_bilinear && d > 0 ? "[-1:1]" : "[*:*]");
        fprintf(g,
                "set format x '%%g'\nset xlabel 'Forcing frequency (Hz)'\n"
                "set ylabel \"Deviation from\\ntruth (%%)\"\n"
                "plot 0 with lines lc rgb 'black' notitle, \\\n"
                "  $rec%d using 1:8:9 with yerrorbars pt 7 ps 0.7 lc rgb '%s' title "
                "'%s'\n",
                d + 1, rths_plot_colour(d),
                s->has_bilinear ? "(|H| - |H_{true}|) / |H_{true}|, ±3 SE"
                                : "|H - H_{true}| / |H_{true}|, ±3 SE");
    }
    fprintf(g, "unset multiplot\n");
    int rc = fclose(g) ? rths_error_set(err, RTHS_EFAIL, "out of memory") : 0;
    if (!rc)
        rc = rths_plot(rep, rths_report_dir(rep), "bode", rec.dofs > 1 ? 1700 : 1300, 1100, body,
                       err);
    free(body);
    return rc;
}

/* The Nyquist figure's truth, refined where the curve turns fast: truth.csv's grid resolves the
 * amplitude (a few points per half-power bandwidth) but drew the circle as a polygon whose sides
 * near a mode were a tenth of its diameter. Between neighbours whose chord exceeds 1 % of the
 * DoF's largest |H| in any DoF the midpoint is added, up to 8 halvings and NYQUIST_TRUTH_MAX
 * points. Each point is a solve of the assembly: a bilinear leg (no analytic truth), a sparse
 * model or one beyond NYQUIST_REFINED_DOFS keeps truth.csv's grid (returns 0, nothing written).
 * Written as $truth: frequency_hz, then per DoF Re H and Im H in its unit (scale[d]). */
enum { NYQUIST_TRUTH_MAX = 4000, NYQUIST_REFINED_DOFS = 200 };

static int nyquist_truth_block(FILE *g, const frf_state *run, const rths_truth_curve *t, int dofs,
                               const double *scale) {
    const rths_setup *s = run->setup;
    if (s->has_bilinear || s->sparse || s->assembly.n > NYQUIST_REFINED_DOFS || t->n < 2 ||
        t->n > NYQUIST_TRUTH_MAX)
        return 0;
    for (int j = 1; j < t->n; j++)
        if (!(t->freq_hz[j] > t->freq_hz[j - 1])) return 0; /* not a grid in frequency */
    typedef struct {
        double f;
        double complex h[RTHS_MAX_INTERFACE_DOFS];
    } sample;
    sample *a = malloc(NYQUIST_TRUTH_MAX * sizeof *a), *b = malloc(NYQUIST_TRUTH_MAX * sizeof *b);
    int n = t->n, ok = a && b;
    double max_abs[RTHS_MAX_INTERFACE_DOFS] = {0};
    for (int j = 0; j < n && ok; j++) {
        a[j].f = t->freq_hz[j];
        ok = !frf_receptance_truth_all(s, a[j].f, a[j].h);
        for (int d = 0; d < dofs && ok; d++)
            max_abs[d] = fmax(max_abs[d], cabs(a[j].h[d]));
    }
    for (int pass = 0, added = 1; pass < 8 && added && ok; pass++) {
        int m = 0;
        added = 0;
        for (int j = 0; j < n && ok; j++) {
            b[m++] = a[j];
            if (j + 1 == n || m + (n - j) >= NYQUIST_TRUTH_MAX) continue;
            int coarse = 0;
            for (int d = 0; d < dofs; d++)
                coarse |= cabs(a[j + 1].h[d] - a[j].h[d]) > 0.01 * max_abs[d];
            if (!coarse) continue;
            b[m].f = 0.5 * (a[j].f + a[j + 1].f);
            ok = !frf_receptance_truth_all(s, b[m].f, b[m].h);
            m++;
            added = 1;
        }
        sample *swap = a;
        a = b;
        b = swap;
        n = m;
    }
    if (ok) {
        fprintf(g, "$truth << EOD\nfrequency_hz");
        for (int d = 0; d < dofs; d++)
            fprintf(g, ",real_%d,imag_%d", d + 1, d + 1);
        fprintf(g, "\n");
        for (int j = 0; j < n; j++) {
            fprintf(g, "%.10g", a[j].f);
            for (int d = 0; d < dofs; d++)
                fprintf(g, ",%.8g,%.8g", creal(a[j].h[d]) * scale[d], cimag(a[j].h[d]) * scale[d]);
            fprintf(g, "\n");
        }
        fprintf(g, "EOD\n");
    }
    free(a);
    free(b);
    return ok;
}

/* nyquist.png: Im H against Re H per interface DoF, equal scales, ±3 SE bars in both parts. */
static int plot_nyquist(rths_report *rep, const frf_state *run, const rths_truth_curve *t,
                        const char *title, const double complex *truth_at, rths_error *err) {
    const rths_setup *s = run->setup;
    frf_receptance_columns rec;
    frf_receptance_columns_init(&rec, s);
    char *body = NULL;
    size_t size = 0;
    FILE *g = open_memstream(&body, &size);
    if (!g) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    fprintf(g,
            "set datafile separator ','\nset datafile columnheaders\nset grid\n"
            "set multiplot title \"%s\" noenhanced\n",
            title);
    double width = (PLOT_RIGHT - PLOT_LEFT) / rec.dofs, scales[RTHS_MAX_INTERFACE_DOFS];
    char units[RTHS_MAX_INTERFACE_DOFS][24];
    for (int d = 0; d < rec.dofs; d++)
        scales[d] = receptance_unit(run, t, d, units[d], sizeof units[d]);
    int refined = nyquist_truth_block(g, run, t, rec.dofs, scales);
    for (int d = 0; d < rec.dofs; d++) {
        const char *unit = units[d];
        double scale = scales[d];
        receptance_block(g, run, d, scale, truth_at);
        double left = PLOT_LEFT + d * width + (d ? 0.05 : 0), right = left + width - 0.02;
        char heading[96];
        snprintf(heading, sizeof heading, "Interface DoF %d (DoF %d)", d + 1,
                 s->split.int_dofs[d] + 1);
        panel(g, 0.90, 0.10, heading, KEY_X);
        fprintf(g, "set lmargin at screen %.4f\nset rmargin at screen %.4f\nset size ratio -1\n",
                left, right);
        if (d > 0) fprintf(g, "unset key\n");
        fprintf(g, "set xlabel 'Re H (%s)'\nset ylabel 'Im H (%s)'\n", unit, unit);
        if (refined)
            fprintf(g, "plot $truth using %d:%d with lines lw 2 lc rgb 'black' title '%s', \\\n",
                    2 + 2 * d, 3 + 2 * d, "true assembly");
        else
            fprintf(g,
                    "plot 'truth.csv' using (column('%s') * %g):(column('%s') * %g) with lines "
                    "lw 2 lc rgb 'black' title '%s', \\\n",
                    rec.names[2 * d], scale, rec.names[2 * d + 1], scale,
                    s->has_bilinear ? "" : "true assembly");
        fprintf(g,
                "  $rec%d using 6:7:3:3 with xyerrorbars pt 7 ps 0.7 lc rgb '%s' title "
                "'hybrid test, ±3 SE bars'\n",
                d + 1, rths_plot_colour(d));
    }
    fprintf(g, "unset multiplot\n");
    int rc = fclose(g) ? rths_error_set(err, RTHS_EFAIL, "out of memory") : 0;
    if (!rc)
        rc = rths_plot(rep, rths_report_dir(rep), "nyquist", rec.dofs > 1 ? 1700 : 1200,
                       rec.dofs > 1 ? 800 : 900, body, err);
    free(body);
    return rc;
}

static int plot_iterations(rths_report *rep, const frf_state *run, rths_error *err) {
    int max_iterations = 0, max_count = 0;
    for (int i = 0; i < run->n; i++)
        max_iterations =
            run->pts[i].iterations > max_iterations ? run->pts[i].iterations : max_iterations;
    /* the tallest bar's count: the range clears it by a tenth, so no bar meets the frame */
    for (int k = 0; k <= max_iterations; k++) {
        int count = 0;
        for (int i = 0; i < run->n; i++)
            count += run->pts[i].iterations == k;
        max_count = count > max_count ? count : max_count;
    }
    char body[1024];
    /* the range hugs the bars: no empty tick left of 0 */
    snprintf(body, sizeof body,
             "set datafile separator ','\n"
             "set title 'Newton iterations per accepted point'\n"
             "set xlabel 'Iterations to converge'\n"
             "set ylabel 'Number of points'\n"
             "set boxwidth 0.8\n"
             "set style fill solid 0.6\n"
             "set xtics 1\n"
             "set xrange [-0.6:%g]\n"
             "set grid ytics\n"
             "set yrange [0:%d]\n"
             "unset key\n"
             "plot 'frf.csv' using 16:(1) skip 1 smooth frequency with boxes lc rgb '%s' "
             "title 'points'\n",
             max_iterations + 0.6, max_count > 0 ? max_count + (max_count + 9) / 10 : 1,
             rths_plot_colour(0));
    return rths_plot(rep, rths_report_dir(rep), "iterations", 900, 600, body, err);
}

int frf_plot_frf(rths_report *rep, const frf_state *run, const rths_truth_curve *t,
                 const char *title, rths_error *err) {
    rths_modes modes, *m = NULL;
    rths_error merr;
    /* a bilinear leg's response has no modes of its own: no mode lines then */
    /* a sparse model forms no dense assembly: its modes are `rths model`'s (no mode lines) */
    if (!run->setup->has_bilinear && !run->setup->sparse &&
        !rths_modal_analysis(&run->setup->assembly, &modes, &merr))
        m = &modes;
    /* the truth's receptance at each point's frequency, one solve per point for all three
     * figures (a solve per point, DoF and figure took minutes on a 1000-DoF model) */
    double complex *truth_at =
        malloc(((size_t)run->n + 1) * RTHS_MAX_INTERFACE_DOFS * sizeof *truth_at);
    if (!truth_at) {
        if (m) rths_modes_free(m);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int i = 0; i < run->n; i++) {
        double complex *h = truth_at + (size_t)i * RTHS_MAX_INTERFACE_DOFS;
        for (int d = 0; d < RTHS_MAX_INTERFACE_DOFS; d++)
            h[d] = NAN;
        if (!run->setup->has_bilinear && run->pts[i].sol.converged)
            frf_receptance_truth_all(run->setup, run->pts[i].sol.frequency_hz, h);
    }
    int rc = plot_frf(rep, run, t, m, title, truth_at, err);
    if (!rc) rc = plot_bode(rep, run, t, m, title, truth_at, err);
    if (!rc) rc = plot_nyquist(rep, run, t, title, truth_at, err);
    if (!rc) rc = plot_iterations(rep, run, err);
    if (m) rths_modes_free(m);
    free(truth_at);
    return rc;
}
