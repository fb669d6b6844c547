/* Time-domain simulation of the conventional delayed-feedback hybrid test (seed §2 model): the
 * physical substructure's interface is driven to the numerical interface displacement delayed by
 * tau (an ideal delayed actuator), and the force the physical substructure needs at its interface
 * is fed back to the numerical substructure without delay. Continuous time, classical RK4 at a
 * step much finer than tau; the delayed interface position, velocity and acceleration come from a
 * ring buffer of past steps (cubic Hermite for position and velocity, linear for acceleration).
 * Because the step is at most tau/20, every delayed instant lies in completed steps, so the scheme
 * stays explicit. The acceleration history is what carries the neutral term: with p <= 1/2 it
 * grows by (1-p)/p per delay, exactly the essential spectrum of the delay equation. */
#include "rths/stability.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void rths_delay_sim_result_free(rths_delay_sim_result *r) {
    if (!r) return;
    free(r->t_s);
    free(r->x_phys_m);
    free(r->x_num_m);
    memset(r, 0, sizeof *r);
}

typedef struct sim {
    int ph, ni, nn,
        np; /* internal physical, interface, numerical substructure size, physical size */
    const rths_split *s;
    double *m11inv;  /* ph x ph */
    double *nminv;   /* nn x nn */
    double *fp, *fn; /* force amplitudes: physical internal (ph), numerical side (nn) */
    double w;        /* forcing rad/s */
    double h, tau;
    /* ring buffer of interface history: position, velocity, acceleration per step */
    int cap;
    double *hx, *hv, *ha; /* cap x ni */
    long newest;          /* index of the newest stored step (step k at time k h) */
    double *tmp;          /* scratch */
} sim;

/* delayed interface values at time s (zero before the start: at rest) */
static void delayed(const sim *S, double s, double *d, double *v, double *a) {
    int ni = S->ni;
    if (s <= 0) {
        memset(d, 0, (size_t)ni * sizeof *d);
        memset(v, 0, (size_t)ni * sizeof *v);
        memset(a, 0, (size_t)ni * sizeof *a);
        return;
    }
    long m = (long)floor(s / S->h);
    if (m >= S->newest) m = S->newest - 1; /* rounding at the very edge */
    if (m < 0) m = 0;
    double th = (s - m * S->h) / S->h, h = S->h;
    int i0 = (int)(m % S->cap), i1 = (int)((m + 1) % S->cap);
    double h00 = (1 + 2 * th) * (1 - th) * (1 - th), h10 = th * (1 - th) * (1 - th);
    double h01 = th * th * (3 - 2 * th), h11 = th * th * (th - 1);
    for (int k = 0; k < ni; k++) {
        double x0 = S->hx[i0 * ni + k], x1 = S->hx[i1 * ni + k];
        double v0 = S->hv[i0 * ni + k], v1 = S->hv[i1 * ni + k];
        double a0 = S->ha[i0 * ni + k], a1 = S->ha[i1 * ni + k];
        d[k] = h00 * x0 + h10 * h * v0 + h01 * x1 + h11 * h * v1;
        v[k] = h00 * v0 + h10 * h * a0 + h01 * v1 + h11 * h * a1;
        a[k] = (1 - th) * a0 + th * a1;
    }
}

/* y = (x_p, v_p, xi, xi'); dy = derivative at time t. */
static void rhs(const sim *S, double t, const double *y, double *dy) {
    const rths_split *s = S->s;
    int ph = S->ph, ni = S->ni, nn = S->nn, np = S->np;
    const double *xp = y, *vp = y + ph, *xi = y + 2 * ph, *vi = y + 2 * ph + nn;
    double *d = S->tmp, *v = d + ni, *a = v + ni, *r = a + ni, *fint = r + (ph > nn ? ph : nn);
    delayed(S, t - S->tau, d, v, a);
    double c = cos(S->w * t);
    /* physical internal accelerations */
    double *ap = dy + ph;
    for (int i = 0; i < ph; i++) {
        double acc = S->fp[i] * c;
        for (int j = 0; j < ph; j++)
            acc -= RTHS_AT(s->damping_phys, np, i, j) * vp[j] +
                   RTHS_AT(s->stiffness_phys, np, i, j) * xp[j];
        for (int j = 0; j < ni; j++)
            acc -= RTHS_AT(s->mass_phys, np, i, ph + j) * a[j] +
                   RTHS_AT(s->damping_phys, np, i, ph + j) * v[j] +
                   RTHS_AT(s->stiffness_phys, np, i, ph + j) * d[j];
        r[i] = acc;
    }
    for (int i = 0; i < ph; i++) {
        double acc = 0;
        for (int j = 0; j < ph; j++)
            acc += RTHS_AT(S->m11inv, ph, i, j) * r[j];
        ap[i] = acc;
    }
    /* force the physical substructure needs at its (delayed) interface */
    for (int i = 0; i < ni; i++) {
        double f = 0;
        for (int j = 0; j < ph; j++)
            f += RTHS_AT(s->mass_phys, np, ph + i, j) * ap[j] +
                 RTHS_AT(s->damping_phys, np, ph + i, j) * vp[j] +
                 RTHS_AT(s->stiffness_phys, np, ph + i, j) * xp[j];
        for (int j = 0; j < ni; j++)
            f += RTHS_AT(s->mass_phys, np, ph + i, ph + j) * a[j] +
                 RTHS_AT(s->damping_phys, np, ph + i, ph + j) * v[j] +
                 RTHS_AT(s->stiffness_phys, np, ph + i, ph + j) * d[j];
        fint[i] = f;
    }
    for (int i = 0; i < nn; i++) {
        double acc = S->fn[i] * c - (i < ni ? fint[i] : 0.0);
        for (int j = 0; j < nn; j++)
            acc -= RTHS_AT(s->damping_num, nn, i, j) * vi[j] +
                   RTHS_AT(s->stiffness_num, nn, i, j) * xi[j];
        r[i] = acc;
    }
    double *ai = dy + 2 * ph + nn;
    for (int i = 0; i < nn; i++) {
        double acc = 0;
        for (int j = 0; j < nn; j++)
            acc += RTHS_AT(S->nminv, nn, i, j) * r[j];
        ai[i] = acc;
    }
    memcpy(dy, vp, (size_t)ph * sizeof *dy);
    memcpy(dy + 2 * ph, vi, (size_t)nn * sizeof *dy);
}

int rths_delay_feedback_simulate(const rths_assembly *a, const rths_split *s,
                                 const double *force_amplitudes, double forcing_hz, double tau_s,
                                 double duration_s, double h_s, rths_delay_sim_result *out,
                                 rths_error *err) {
    memset(out, 0, sizeof *out);
    out->divergence_time_s = NAN;
    if (!(tau_s > 0) || !isfinite(tau_s))
        return rths_error_set(err, RTHS_EINPUT, "feedback simulation: delay must be > 0 s, got %g",
                              tau_s);
    if (!(duration_s > 0) || !isfinite(duration_s))
        return rths_error_set(err, RTHS_EINPUT, "feedback simulation: duration must be > 0 s");
    if (!(forcing_hz >= 0) || !isfinite(forcing_hz))
        return rths_error_set(err, RTHS_EINPUT,
                              "feedback simulation: forcing frequency must be >= 0");
    if (h_s <= 0) h_s = tau_s / 40;
    if (h_s > tau_s / 20 * (1 + 1e-12))
        return rths_error_set(err, RTHS_EINPUT,
                              "feedback simulation: step %g s must be at most tau/20 = %g s", h_s,
                              tau_s / 20);
    if (s->n != a->n) return rths_error_set(err, RTHS_EINPUT, "split and assembly sizes differ");
    if (duration_s / h_s > 2e8)
        return rths_error_set(err, RTHS_EINPUT,
                              "feedback simulation: %g steps is too many (duration/step)",
                              duration_s / h_s);
    sim S = {0};
    S.s = s;
    S.ph = s->n_phys, S.ni = s->n_int, S.nn = s->nn, S.np = s->np;
    S.w = 2 * M_PI * forcing_hz;
    S.h = h_s, S.tau = tau_s;
    S.cap = (int)ceil(tau_s / h_s) + 8;
    int ph = S.ph, ni = S.ni, nn = S.nn, ny = 2 * ph + 2 * nn;
    S.m11inv = rths_mat_new(ph ? ph : 1, ph ? ph : 1);
    S.nminv = rths_mat_new(nn, nn);
    S.fp = calloc((size_t)ph + 1, sizeof(double));
    S.fn = calloc((size_t)nn, sizeof(double));
    S.hx = calloc((size_t)S.cap * ni, sizeof(double));
    S.hv = calloc((size_t)S.cap * ni, sizeof(double));
    S.ha = calloc((size_t)S.cap * ni, sizeof(double));
    S.tmp = calloc((size_t)(4 * ni + 2 * (ph > nn ? ph : nn) + 4), sizeof(double));
    double *y = calloc((size_t)ny * 6, sizeof(double));
    double complex *xf = malloc((size_t)a->n * sizeof *xf);
    int rc = RTHS_OK;
    long steps = (long)ceil(duration_s / h_s - 1e-9);
    long nwin_cap = 0, nwin = 0;
    double *winmax = NULL, *wint = NULL;
    if (!S.m11inv || !S.nminv || !S.fp || !S.fn || !S.hx || !S.hv || !S.ha || !S.tmp || !y || !xf) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory (feedback simulation)");
        goto done;
    }
    if (ph) {
        double *m11 = rths_mat_new(ph, ph);
        if (!m11) {
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
            goto done;
        }
        for (int i = 0; i < ph; i++)
            for (int j = 0; j < ph; j++)
                RTHS_AT(m11, ph, i, j) = RTHS_AT(s->mass_phys, S.np, i, j);
        int info = rths_mat_inverse(ph, m11, S.m11inv);
        rths_mat_free(m11);
        if (info) {
            rc = rths_error_set(err, RTHS_EINPUT, "physical internal mass matrix is singular");
            goto done;
        }
    }
    if (rths_mat_inverse(nn, s->mass_num, S.nminv)) {
        rc = rths_error_set(err, RTHS_EINPUT, "numerical substructure mass matrix is singular");
        goto done;
    }
    for (int i = 0; i < ph; i++)
        S.fp[i] = force_amplitudes[s->phys_dofs[i]];
    for (int i = 0; i < ni; i++)
        S.fn[i] = force_amplitudes[s->int_dofs[i]];
    for (int i = 0; i < s->n_num; i++)
        S.fn[ni + i] = force_amplitudes[s->num_dofs[i]];
    /* the true assembly's steady amplitude at the first interface DoF: the yardstick */
    rc = rths_frf(a->n, a->mass, a->damping, a->stiffness, force_amplitudes, S.w, xf, err);
    if (rc) goto done;
    out->steady_amplitude_m = cabs(xf[s->int_dofs[0]]);
    double bound = 1e3 * fmax(out->steady_amplitude_m, 1e-12);

    long decim = steps / 20000 + 1;
    long nout = steps / decim + 2;
    out->t_s = malloc((size_t)nout * sizeof(double));
    out->x_phys_m = malloc((size_t)nout * sizeof(double));
    out->x_num_m = malloc((size_t)nout * sizeof(double));
    /* short windows of |x_num| maxima; the envelope is their running maximum over one forcing
     * period (so the forced oscillation itself does not look like growth or decay) */
    double wlen = fmax(4 * tau_s, 50 * h_s);
    wlen = fmin(wlen, duration_s / 8);
    nwin_cap = (long)(duration_s / wlen) + 3;
    winmax = calloc((size_t)nwin_cap, sizeof(double));
    wint = calloc((size_t)nwin_cap, sizeof(double));
    if (!out->t_s || !out->x_phys_m || !out->x_num_m || !winmax || !wint) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory (feedback simulation)");
        goto done;
    }
    double *k1 = y + ny, *k2 = y + 2 * ny, *k3 = y + 3 * ny, *k4 = y + 4 * ny, *yt = y + 5 * ny;
    double dd[64], dv[64], da[64];
    /* step 0 (rest) into the history */
    rhs(&S, 0.0, y, k1);
    for (int k = 0; k < ni; k++) {
        S.hx[k] = y[2 * ph + k];
        S.hv[k] = y[2 * ph + nn + k];
        S.ha[k] = k1[2 * ph + nn + k];
    }
    S.newest = 0;
    long wi = 0;
    double wstart = 0;
    for (long st = 0; st <= steps; st++) {
        double t = st * h_s;
        double xnum = y[2 * ph], xphys;
        if (ni <= 64) {
            delayed(&S, t - tau_s, dd, dv, da);
            xphys = dd[0];
        } else {
            xphys = NAN;
        }
        if (st % decim == 0 || st == steps) {
            out->t_s[out->n] = t;
            out->x_phys_m[out->n] = xphys;
            out->x_num_m[out->n] = xnum;
            out->n++;
        }
        if (t - wstart >= wlen && wi + 1 < nwin_cap) {
            wint[wi] = wstart + 0.5 * wlen;
            wi++;
            wstart = t;
        }
        winmax[wi] = fmax(winmax[wi], fabs(xnum));
        if (!isfinite(xnum) || fabs(xnum) > bound) {
            out->diverged = 1;
            out->divergence_time_s = t;
            break;
        }
        out->end_time_s = t;
        if (st == steps) break;
        rhs(&S, t, y, k1);
        for (int k = 0; k < ny; k++)
            yt[k] = y[k] + 0.5 * h_s * k1[k];
        rhs(&S, t + 0.5 * h_s, yt, k2);
        for (int k = 0; k < ny; k++)
            yt[k] = y[k] + 0.5 * h_s * k2[k];
        rhs(&S, t + 0.5 * h_s, yt, k3);
        for (int k = 0; k < ny; k++)
            yt[k] = y[k] + h_s * k3[k];
        rhs(&S, t + h_s, yt, k4);
        for (int k = 0; k < ny; k++)
            y[k] += h_s / 6 * (k1[k] + 2 * k2[k] + 2 * k3[k] + k4[k]);
        /* store step st+1: its acceleration from the equations at the new state */
        S.newest = st + 1;
        int slot = (int)((st + 1) % S.cap);
        for (int k = 0; k < ni; k++) {
            S.hx[slot * ni + k] = y[2 * ph + k];
            S.hv[slot * ni + k] = y[2 * ph + nn + k];
        }
        S.newest = st; /* rhs at t+h reads history up to step st only */
        rhs(&S, t + h_s, y, k1);
        S.newest = st + 1;
        for (int k = 0; k < ni; k++)
            S.ha[slot * ni + k] = k1[2 * ph + nn + k];
    }
    if (winmax[wi] > 0) {
        wint[wi] = wstart + 0.5 * (out->end_time_s - wstart);
        wi++;
    }
    nwin = wi;
    /* least squares slope of log(envelope) over the second half of the simulated time */
    {
        double span = forcing_hz > 0 ? 1.0 / forcing_hz : 0.0;
        double t_half = 0.5 * out->end_time_s;
        long cnt = 0;
        double sx = 0, sy = 0, sxx = 0, sxy = 0;
        for (long k = 0; k < nwin; k++) {
            if (wint[k] < t_half) continue;
            double env = 0;
            for (long q = k; q >= 0 && wint[q] >= wint[k] - span; q--)
                env = fmax(env, winmax[q]);
            if (!(env > 0) || !isfinite(env)) continue;
            double lx = wint[k], ly = log(env);
            sx += lx, sy += ly, sxx += lx * lx, sxy += lx * ly;
            cnt++;
        }
        double den = cnt * sxx - sx * sx;
        out->growth_rate_per_s = (cnt >= 2 && den > 0) ? (cnt * sxy - sx * sy) / den : NAN;
    }
done:
    rths_mat_free(S.m11inv);
    rths_mat_free(S.nminv);
    free(S.fp), free(S.fn), free(S.hx), free(S.hv), free(S.ha), free(S.tmp);
    free(y), free(xf), free(winmax), free(wint);
    if (rc) rths_delay_sim_result_free(out);
    return rc;
}
