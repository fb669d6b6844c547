/* Root tracking in the delay and the critical delay.
 *
 * A spectral computation per delay is far too slow for a 200 x 200 chart, and the roots move
 * continuously with tau, so one spectral labelling seeds a set of roots that Newton then follows
 * (Euler predictor dlambda/dtau = -D_tau / D_lambda). Whenever following becomes doubtful (Newton
 * fails, a root jumps by a sizeable part of its distance to its neighbours, two roots merge as a
 * real pair does before turning complex), the step is halved, and after a few halvings the set is
 * re-seeded by the spectral method at the new delay. */
#include "stability_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TRACK_MAX_ROOTS 64

void rths_tracker_free(rths_tracker *t) {
    free(t->roots);
    memset(t, 0, sizeof *t);
}

int rths_tracker_seed(rths_tracker *t, const rths_dde *d, double tau, int nodes, rths_error *err) {
    double complex *r;
    int nr;
    int rc = rths_dde_spectral_roots(d, tau, nodes, 0, &r, &nr, err);
    if (rc) return rc;
    if (nr > TRACK_MAX_ROOTS) nr = TRACK_MAX_ROOTS; /* sorted: keep the rightmost */
    free(t->roots);
    t->roots = r;
    t->n = nr;
    t->tau = tau;
    t->d = d;
    t->nodes = nodes;
    t->reseeds++;
    return RTHS_OK;
}

double rths_tracker_max_real(const rths_tracker *t, double *imag) {
    double best = -INFINITY, im = NAN;
    for (int i = 0; i < t->n; i++)
        if (creal(t->roots[i]) > best) best = creal(t->roots[i]), im = cimag(t->roots[i]);
    if (imag) *imag = im;
    return best;
}

/* One attempt from t->tau to tau1 into r1; 0 if every root followed cleanly. */
static int try_step(const rths_tracker *t, double tau1, double complex *r1) {
    const rths_dde *d = t->d;
    double dtau = tau1 - t->tau;
    for (int i = 0; i < t->n; i++) {
        double complex l = t->roots[i], gl, gt;
        double sep = INFINITY;
        for (int j = 0; j < t->n; j++) {
            if (j != i) sep = fmin(sep, cabs(l - t->roots[j]));
            sep = fmin(sep, cabs(l - conj(t->roots[j])) + (j == i && cimag(l) == 0 ? INFINITY : 0));
        }
        /* at a root converged to the last bit the LU may hit an exact zero pivot; the ratio
         * D_tau / D_lambda the predictor needs is smooth there, so take it a hair away */
        if (rths_dde_char(d, t->tau, l, NULL, &gl, &gt) &&
            rths_dde_char(d, t->tau, l + 1e-9 * (1.0 + cabs(l)), NULL, &gl, &gt))
            return -1;
        if (gl == 0.0) return -1;
        double complex pred = l - gt / gl * dtau;
        double complex c = pred;
        if (rths_dde_newton(d, tau1, &c)) return -1;
        double move = cabs(c - pred), limit = 0.3 * sep;
        double scale = 1e-9 * (1.0 + cabs(l));
        if (move > limit && move > scale) return -1;
        if (cimag(c) < 0) c = conj(c);
        r1[i] = c;
    }
    for (int i = 0; i < t->n; i++)
        for (int j = i + 1; j < t->n; j++)
            if (cabs(r1[i] - r1[j]) <= 1e-7 * (1.0 + cabs(r1[i]))) return -1;
    return 0;
}

int rths_tracker_step(rths_tracker *t, double tau1, rths_error *err) {
    double complex buf[TRACK_MAX_ROOTS];
    int halvings = 0;
    while (t->tau != tau1) {
        double target = tau1;
        int ok = 0;
        for (halvings = 0; halvings < 6; halvings++) {
            if (try_step(t, target, buf) == 0) {
                ok = 1;
                break;
            }
            target = t->tau + 0.5 * (target - t->tau);
        }
        if (!ok) return rths_tracker_seed(t, t->d, tau1, t->nodes, err);
        memcpy(t->roots, buf, (size_t)t->n * sizeof *buf);
        t->tau = target;
    }
    return RTHS_OK;
}

/* Newton on D(i omega; tau) = 0 in the two real unknowns (tau, omega):
 * 1 + i L_lambda d_omega + L_tau d_tau = 0, L = dlog D. */
int rths_refine_crossing(const rths_dde *d, double *tau, double *omega) {
    double t = *tau, w = *omega;
    for (int it = 0; it < 60; it++) {
        double complex gl, gt, det;
        if (rths_dde_char(d, t, I * w, &det, &gl, &gt)) {
            *tau = t, *omega = w;
            return 0;
        }
        double complex a = I * gl; /* d/d omega */
        double a11 = creal(a), a21 = cimag(a), a12 = creal(gt), a22 = cimag(gt);
        double detj = a11 * a22 - a12 * a21;
        if (detj == 0 || !isfinite(detj)) return -1;
        double dw = (-1.0 * a22) / detj, dt = (a21 * 1.0) / detj;
        /* keep tau positive and the step modest */
        if (t + dt <= 0.1 * t) dt = -0.9 * t;
        if (fabs(dt) > 0.5 * t) dt = copysign(0.5 * t, dt);
        if (fabs(dw) > 0.5 * (fabs(w) + 1.0)) dw = copysign(0.5 * (fabs(w) + 1.0), dw);
        t += dt;
        w += dw;
        if (fabs(dt) <= 1e-14 * t && fabs(dw) <= 1e-12 * (1.0 + fabs(w))) {
            *tau = t, *omega = fabs(w);
            return 0;
        }
    }
    return -1;
}

/* Locates the crossing between (tau0, tracker state before) and tau1 where the rightmost real
 * part turned >= 0; r_before/r_after are the rightmost roots on each side. */
int rths_locate_crossing(const rths_dde *d, double tau0, double re0, double tau1, double re1,
                         double omega_guess, double *tau_c, double *omega_c) {
    double tg = tau0 + (tau1 - tau0) * (re0 < re1 ? (-re0) / (re1 - re0) : 0.5);
    double t = tg, w = fabs(omega_guess);
    if (w > 0 && rths_refine_crossing(d, &t, &w) == 0 && t >= tau0 - 0.05 * (tau1 - tau0) &&
        t <= tau1 + 0.05 * (tau1 - tau0)) {
        *tau_c = t;
        *omega_c = w;
        return 0;
    }
    *tau_c = tg; /* linear estimate: the caller's grid decides its precision */
    *omega_c = fabs(omega_guess);
    return -1;
}

int rths_dde_critical_delay(const rths_dde *d, double tau_lo, double tau_hi, int steps, int nodes,
                            double *tau_c, double *omega_c, rths_error *err) {
    *tau_c = NAN;
    *omega_c = NAN;
    if (!(tau_lo > 0 && tau_hi > tau_lo) || steps < 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "critical delay: need 0 < tau_lo < tau_hi and steps >= 1");
    double rt;
    int rc = rths_dde_essential(d, &rt, NULL, NULL, err);
    if (rc) return rc;
    if (rt >= 0) {
        *tau_c = 0.0; /* the neutral chain is unstable for every delay */
        return RTHS_OK;
    }
    rths_tracker t = {0};
    if ((rc = rths_tracker_seed(&t, d, tau_lo, nodes, err))) return rc;
    double im0, re0 = rths_tracker_max_real(&t, &im0);
    if (re0 >= 0) {
        rths_tracker_free(&t);
        return RTHS_OK; /* unstable already at tau_lo: not located here */
    }
    double tau0 = tau_lo;
    for (int k = 1; k <= steps; k++) {
        double tau1 = tau_lo * pow(tau_hi / tau_lo, (double)k / steps);
        if ((rc = rths_tracker_step(&t, tau1, err))) break;
        double im1, re1 = rths_tracker_max_real(&t, &im1);
        if (re1 >= 0) {
            rths_locate_crossing(d, tau0, re0, tau1, re1, im1, tau_c, omega_c);
            break;
        }
        tau0 = tau1, re0 = re1;
    }
    rths_tracker_free(&t);
    return rc;
}
