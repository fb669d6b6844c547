/* The physical loop of docs/method.md, "Tuning the gains": the sampled physical substructure,
 * actuator and delay, closed by the controller's discrete PD. A transfer-function actuator is
 * realised by the plant's own code (plant_tf_form_of, src/plant/plant_internal.h). The
 * continuous state matrix is assembled here as the plant's side_state_matrix does for its linear
 * side, but from the tuner's matrices (rths_pd_loop_spec) rather than a built plant; the
 * sampling (hold and fractional delay, for the loop's frequency response) is the tuner's own.
 * tests/test_tune.c checks the model against the virtual rig itself. */
#include "rths/tune.h"

#include "plant/plant_internal.h"
#include "tune/tune_internal.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* frequency grid of the margins: log-spaced up to Nyquist */
#define GRID_POINTS 3000

struct rths_pd_loop {
    int nz;            /* continuous state: q, v, actuator states */
    int ni;            /* interface DoFs: the last ni displacements, one effort channel each */
    int iface;         /* index of the first interface displacement in the state */
    int delay;         /* whole samples of the transport delay */
    double fraction;   /* and the fraction of a sample beyond them, [0, 1) */
    int linear_hold;   /* the force command ramps from the last sample's value */
    double h, alpha;   /* sample period; the differentiator's low-pass pole */
    double input_gain; /* command per demand volt: the shaker's gain, 1 for a transfer function */
    double *phi;       /* nz x nz: e^{A h} */
    /* z_{k+1} = phi z_k + e[0] w_{k-D} + e[1] w_{k-D-1} + e[2] w_{k-D-2}, w_j = g u_j: the
     * command's samples that act during sample k through the hold and the fractional delay;
     * nz x ni each, one column per effort channel */
    double *e[3];
    /* the open loop's frequency response P(e^{i theta}), ni x ni per frequency (column-major,
     * ni * ni entries from p + g ni^2): effort demand j to interface displacement i */
    double theta[GRID_POINTS];
    double complex *p;
    /* the PD's derivative path per kd: (1 - alpha)(1 - z^-1) / (h (1 - alpha z^-1)) */
    double complex dterm[GRID_POINTS];
};

void rths_pd_loop_destroy(rths_pd_loop *loop) {
    if (!loop) return;
    free(loop->phi), free(loop->e[0]), free(loop->e[1]), free(loop->e[2]);
    free(loop->p);
    free(loop);
}

int rths_pd_loop_delay_samples(const rths_pd_loop *loop) {
    return loop->delay;
}

double rths_pd_loop_delay_fraction(const rths_pd_loop *loop) {
    return loop->fraction;
}

/* The actuator's continuous states (as the plant's actuator_realise, for one actuator): a shaker's
 * lag (na 1) or none; a transfer function F = (N U - V(s) x') / D in observer canonical form
 * (plant_tf_form_of). */
typedef struct {
    int na, tf;
    double lag_rate, out, spring, d;
    double a[RTHS_ACTUATOR_MAX_ORDER * RTHS_ACTUATOR_MAX_ORDER];
    double bu[RTHS_ACTUATOR_MAX_ORDER], bv[RTHS_ACTUATOR_MAX_ORDER];
} actuator_model;

static int actuator_model_of(const rths_plant_options *o, actuator_model *m, rths_error *err) {
    memset(m, 0, sizeof *m);
    const rths_actuator_options *a = &o->actuator;
    if (a->model != RTHS_ACTUATOR_TRANSFER_FUNCTION) {
        m->lag_rate = o->lag_cutoff_hz > 0 ? 2 * M_PI * o->lag_cutoff_hz : 0;
        m->na = m->lag_rate > 0;
        m->out = 1;
        return RTHS_OK;
    }
    int nd = a->denominator_count, nn = a->numerator_count, order = nd - 1;
    int nv = a->velocity_feedback_count > 0 ? a->velocity_feedback_count : 1;
    if (nd < 1 || nd > RTHS_ACTUATOR_MAX_ORDER + 1 || nn < 1 || nn > nd || a->denominator[0] == 0 ||
        (order > 0 && nv > order))
        return rths_error_set(err, RTHS_EINPUT,
                              "transfer_function actuator: %d numerator, %d denominator and %d "
                              "velocity coefficients are outside what the plant realises",
                              nn, nd, nv);
    m->tf = 1;
    m->na = order;
    m->spring = a->displacement_output ? a->connection_stiffness_n_per_m : 0.0;
    m->out = a->displacement_output ? a->connection_stiffness_n_per_m : 1.0;
    plant_tf_form form;
    plant_tf_form_of(a, &form);
    m->d = form.d;
    memcpy(m->a, form.a, sizeof m->a);
    memcpy(m->bu, form.bu, sizeof m->bu);
    memcpy(m->bv, form.bv, sizeof m->bv);
    return RTHS_OK;
}

/* Over a length L: e^{A L}, G(L) = int_0^L e^{A (L - s)} B ds and J(L) = int_0^L e^{A (L - s)} B s
 * ds (nz x ni, a column per input) from one exponential of [[A, B, 0], [0, 0, I], [0, 0, 0]] L
 * (Van Loan). */
static int hold_integrals(int nz, int ni, const double *a, const double *b, double length,
                          double *phi, double *g, double *j_out) {
    int N = nz + 2 * ni;
    double *aug = rths_mat_new(N, N), *e = rths_mat_new(N, N);
    int rc = aug && e ? 0 : -1;
    if (!rc) {
        for (int j = 0; j < nz; j++)
            for (int i = 0; i < nz; i++)
                RTHS_AT(aug, N, i, j) = a[i + (size_t)j * nz] * length;
        for (int c = 0; c < ni; c++) {
            for (int i = 0; i < nz; i++)
                RTHS_AT(aug, N, i, nz + c) = b[i + (size_t)c * nz] * length;
            RTHS_AT(aug, N, nz + c, nz + ni + c) = length;
        }
        rc = rths_expm(N, aug, e);
    }
    if (!rc) {
        for (int j = 0; j < nz; j++)
            for (int i = 0; i < nz; i++)
                phi[i + (size_t)j * nz] = RTHS_AT(e, N, i, j);
        for (int c = 0; c < ni; c++)
            for (int i = 0; i < nz; i++) {
                g[i + (size_t)c * nz] = RTHS_AT(e, N, i, nz + c);
                j_out[i + (size_t)c * nz] = RTHS_AT(e, N, i, nz + ni + c);
            }
    }
    rths_mat_free(aug), rths_mat_free(e);
    return rc;
}

/* The command before the fractional delay is, over sample j, a ramp from w_{j-D-1} to w_{j-D}
 * (linear hold) or w_{j-D} held (step). Delayed by f h more, sample k sees over [f h, h] the
 * first (1 - f) h of its own segment and over [0, f h] the last f h of the previous one, each
 * integrated exactly: a linear piece c0 + (c1 - c0) s / h over a part of length L contributes
 * G(L) c0 + J(L) (c1 - c0) / h, the first part carried to the sample's end by e^{A (1 - f) h}.
 * Every effort channel (a column of b) goes through the same hold and delay. */
static int discretise(rths_pd_loop *loop, int nz, const double *a, const double *b) {
    const double h = loop->h, f = loop->fraction, l2 = (1 - f) * h, l1 = f * h;
    const int ni = loop->ni;
    const size_t cols = (size_t)nz * (size_t)ni;
    double *phi2 = calloc((size_t)nz * (size_t)nz, sizeof(double)),
           *tmp = calloc((size_t)nz * (size_t)nz, sizeof(double)),
           *g = calloc(cols, sizeof(double)), *jj = calloc(cols, sizeof(double)),
           *part = calloc((size_t)nz, sizeof(double));
    int rc = phi2 && tmp && g && jj && part ? 0 : -1;
    if (!rc) rc = hold_integrals(nz, ni, a, b, h, loop->phi, g, jj);
    if (!rc) rc = hold_integrals(nz, ni, a, b, l2, phi2, g, jj);
    for (size_t i = 0; !rc && i < cols; i++) {
        if (loop->linear_hold) {
            /* ramp from w_{k-D-1} to w_{k-D}, its first (1 - f) h */
            loop->e[0][i] += jj[i] / h;
            loop->e[1][i] += g[i] - jj[i] / h;
        } else {
            loop->e[0][i] += g[i];
        }
    }
    if (!rc && l1 > 0) {
        rc = hold_integrals(nz, ni, a, b, l1, tmp, g, jj);
        /* the previous segment's last f h: a ramp from f w_{k-D-2} + (1 - f) w_{k-D-1} by
         * (w_{k-D-1} - w_{k-D-2}) s / h (linear), or w_{k-D-1} held (step) */
        for (int c = 0; !rc && c < ni; c++) {
            const double *gc = g + (size_t)c * nz, *jc = jj + (size_t)c * nz;
            for (int w = 1; w <= 2; w++) {
                for (int i = 0; i < nz; i++)
                    part[i] = !loop->linear_hold ? (w == 1 ? gc[i] : 0.0)
                              : w == 1           ? (1 - f) * gc[i] + jc[i] / h
                                                 : f * gc[i] - jc[i] / h;
                for (int i = 0; i < nz; i++) {
                    double sum = 0;
                    for (int k = 0; k < nz; k++)
                        sum += phi2[i + (size_t)k * nz] * part[k];
                    loop->e[w][i + (size_t)c * nz] += sum;
                }
            }
        }
    }
    free(phi2), free(tmp), free(g), free(jj), free(part);
    return rc;
}

/* P(z) = C (z I - Phi)^{-1} (E0 + E1 z^-1 + E2 z^-2) g z^-D, C picking the interface
 * displacements: ni x ni per frequency */
static int frequency_response(rths_pd_loop *loop) {
    const int nz = loop->nz, ni = loop->ni;
    double complex *m = malloc(sizeof *m * (size_t)nz * (size_t)nz),
                   *rhs = malloc(sizeof *rhs * (size_t)nz * (size_t)ni);
    int rc = m && rhs ? 0 : -1;
    double theta_min = 1e-6 * M_PI;
    for (int g = 0; !rc && g < GRID_POINTS; g++) {
        double th = theta_min * pow(M_PI / theta_min, (double)g / (GRID_POINTS - 1));
        if (g == GRID_POINTS - 1) th = M_PI;
        double complex z = cexp(I * th), zi = 1.0 / z;
        for (int j = 0; j < nz; j++)
            for (int i = 0; i < nz; i++)
                m[i + (size_t)j * nz] = (i == j ? z : 0) - loop->phi[i + (size_t)j * nz];
        for (size_t i = 0; i < (size_t)nz * (size_t)ni; i++)
            rhs[i] = loop->e[0][i] + (loop->e[1][i] + loop->e[2][i] * zi) * zi;
        if (rths_cmat_solve(nz, ni, m, rhs)) {
            rc = -1;
            break;
        }
        loop->theta[g] = th;
        loop->dterm[g] = (1 - loop->alpha) * (1 - zi) / (loop->h * (1 - loop->alpha * zi));
        double complex *pg = loop->p + (size_t)g * ni * ni;
        for (int c = 0; c < ni; c++)
            for (int r = 0; r < ni; r++)
                pg[r + c * ni] = rhs[loop->iface + r + (size_t)c * nz] * loop->input_gain *
                                 cpow(zi, loop->delay);
    }
    free(m), free(rhs);
    return rc;
}

int rths_pd_loop_create(const rths_pd_loop_spec *spec, rths_pd_loop **out, rths_error *err) {
    *out = NULL;
    const rths_plant_options *o = spec->rig;
    int n = spec->n, ni = spec->ni > 0 ? spec->ni : 1;
    if (n < 1 || ni > n || ni > RTHS_MAX_INTERFACE_DOFS || !(spec->sample_rate_hz > 0) ||
        spec->velocity_cutoff_hz < 0 || !(spec->velocity_cutoff_hz < 0.5 * spec->sample_rate_hz))
        return rths_error_set(err, RTHS_EINPUT,
                              "PD loop: %d DoFs, %d interface DoFs, sample rate %g Hz, velocity "
                              "cut-off %g Hz (needs >= 1 DoF, 1 to %d interface DoFs among them, "
                              "a positive rate, a cut-off in [0, rate / 2))",
                              n, ni, spec->sample_rate_hz, spec->velocity_cutoff_hz,
                              RTHS_MAX_INTERFACE_DOFS);
    actuator_model act;
    int rc = actuator_model_of(o, &act, err);
    if (rc) return rc;
    if (act.tf && ni > 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "PD loop: a transfer_function actuator drives one interface DoF "
                              "(as the virtual plant); this loop has %d",
                              ni);
    rths_pd_loop *loop = calloc(1, sizeof *loop);
    if (!loop) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    loop->h = 1.0 / spec->sample_rate_hz;
    loop->alpha =
        spec->velocity_cutoff_hz > 0 ? exp(-2 * M_PI * spec->velocity_cutoff_hz * loop->h) : 0.0;
    /* whole samples and a fraction; a fraction within 1e-9 of a whole sample is none */
    double samples = o->delay_s * spec->sample_rate_hz;
    loop->delay = (int)floor(samples + 1e-9);
    loop->fraction = samples - loop->delay > 1e-9 ? samples - loop->delay : 0.0;
    loop->linear_hold = o->linear_hold;
    loop->input_gain = act.tf ? 1.0 : o->gain_n_per_v;
    loop->ni = ni;
    loop->iface = n - ni;
    /* a lag per effort channel (the actuators' lags are equal, so they commute with the
     * transform) */
    int na = act.tf ? act.na : ni * act.na;
    int nz = loop->nz = 2 * n + na;
    loop->phi = calloc((size_t)nz * (size_t)nz, sizeof(double));
    for (int k = 0; k < 3; k++)
        loop->e[k] = calloc((size_t)nz * (size_t)ni, sizeof(double));
    loop->p = calloc((size_t)GRID_POINTS * (size_t)ni * (size_t)ni, sizeof *loop->p);
    double *minv = rths_mat_new(n, n), *mm = rths_mat_new(n, n), *a = rths_mat_new(nz, nz),
           *b = calloc((size_t)nz * (size_t)ni, sizeof(double));
    if (!loop->phi || !loop->e[0] || !loop->e[1] || !loop->e[2] || !loop->p || !minv || !mm || !a ||
        !b) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    /* the shaker's armature moves with the interface, each at its actuator's point: T diag(m_a)
     * T^T on the interface block (plant_build.c); a transfer function's mass is the structure's */
    memcpy(mm, spec->mass, sizeof(double) * (size_t)n * (size_t)n);
    const double *t = spec->actuator_transform;
    for (int d = 0; !act.tf && d < ni; d++)
        for (int e = 0; e < ni; e++) {
            double arm = 0;
            if (!t)
                arm = d == e ? o->armature_mass_kg : 0.0;
            else
                for (int c = 0; c < ni; c++)
                    arm += t[d + c * ni] * t[e + c * ni] * o->armature_mass_kg;
            RTHS_AT(mm, n, n - ni + d, n - ni + e) += arm;
        }
    if (rths_mat_inverse(n, mm, minv)) {
        rc = rths_error_set(err, RTHS_EINPUT, "PD loop: the physical mass matrix is singular");
        goto done;
    }
    for (int i = 0; i < n; i++) {
        RTHS_AT(a, nz, i, n + i) = 1.0;
        for (int j = 0; j < n; j++) {
            double mk = 0, mc = 0;
            for (int l = 0; l < n; l++) {
                mk += RTHS_AT(minv, n, i, l) * RTHS_AT(spec->stiffness, n, l, j);
                mc += RTHS_AT(minv, n, i, l) * RTHS_AT(spec->damping, n, l, j);
            }
            RTHS_AT(a, nz, n + i, j) = -mk;
            RTHS_AT(a, nz, n + i, n + j) = -mc;
        }
        for (int c = 0; c < ni; c++) {
            double to_iface = RTHS_AT(minv, n, i, n - ni + c);
            if (act.lag_rate > 0) RTHS_AT(a, nz, n + i, 2 * n + c) = to_iface;
            if (act.tf && act.na > 0)
                RTHS_AT(a, nz, n + i, 2 * n + act.na - 1) = to_iface * act.out;
            if (act.tf && act.spring > 0) RTHS_AT(a, nz, n + i, n - 1) -= to_iface * act.spring;
            /* the command's direct path: the unlagged shaker's force, a transfer function's
             * feedthrough */
            if (!act.tf && act.lag_rate <= 0) b[n + i + (size_t)c * nz] = to_iface;
            if (act.tf) b[n + i + (size_t)c * nz] = to_iface * act.out * act.d;
        }
    }
    for (int c = 0; act.lag_rate > 0 && c < ni; c++) {
        RTHS_AT(a, nz, 2 * n + c, 2 * n + c) = -act.lag_rate;
        b[2 * n + c + (size_t)c * nz] = act.lag_rate;
    }
    for (int i = 0; act.tf && i < act.na; i++) {
        for (int j = 0; j < act.na; j++)
            RTHS_AT(a, nz, 2 * n + i, 2 * n + j) = act.a[i + j * act.na];
        RTHS_AT(a, nz, 2 * n + i, 2 * n - 1) = act.bv[i];
        b[2 * n + i] = act.bu[i];
    }
    if (discretise(loop, nz, a, b) || frequency_response(loop))
        rc = rths_error_set(err, RTHS_EFAIL, "PD loop: the sampled model could not be formed");
done:
    rths_mat_free(minv), rths_mat_free(mm), rths_mat_free(a), free(b);
    if (rc) {
        rths_pd_loop_destroy(loop);
        return rc;
    }
    *out = loop;
    return RTHS_OK;
}

int rths_pd_loop_dofs(const rths_pd_loop *loop) {
    return loop->ni;
}

/* Closed loop, state X_k = [z_k; u_{k-1} .. u_{k-D-2}; x_{k-1}; v_{k-1}] (the history, x and v
 * ni entries each, DoF fastest): the controller reads x_k, the interface displacements, forms
 * v_k = alpha v_{k-1} + (1 - alpha)(x_k - x_{k-1}) / h, demands u_k = -kp x_k - kd v_k per DoF
 * (the target's terms are inputs, not states); the plant takes the commands g u_{k-D},
 * g u_{k-D-1}, g u_{k-D-2} through E0, E1, E2 (discretise), as plant.c's rths_plant_advance for a
 * whole-sample delay. */
double rths_pd_loop_radius_dofs(const rths_pd_loop *loop, const double *kp, const double *kd) {
    const int nz = loop->nz, ni = loop->ni, D = loop->delay, hist = nz, xprev = nz + (D + 2) * ni,
              vprev = xprev + ni, N = vprev + ni;
    double *w = rths_mat_new(N, N), *r = calloc((size_t)N * (size_t)ni, sizeof(double)),
           *cmd = calloc(3 * (size_t)N * (size_t)ni, sizeof(double));
    if (!w || !r || !cmd) {
        rths_mat_free(w), free(r), free(cmd);
        return -1;
    }
    const double rate = 1.0 / loop->h, a = loop->alpha;
    /* v_k as a row over X */
    double v_x = (1 - a) * rate, v_xprev = -(1 - a) * rate, v_v = a;
    /* u_k[d] = -kp[d] x_k[d] - kd[d] v_k[d]: row d of r (r + d N) */
    for (int d = 0; d < ni; d++) {
        double *rd = r + (size_t)d * N;
        rd[loop->iface + d] = -kp[d] - kd[d] * v_x;
        rd[xprev + d] = -kd[d] * v_xprev;
        rd[vprev + d] = -kd[d] * v_v;
    }
    /* the commands g u_{k-D-j}[d], j = 0, 1, 2, as rows over X: u_k itself or a history entry */
    for (int j = 0; j < 3; j++)
        for (int d = 0; d < ni; d++) {
            double *row = cmd + ((size_t)j * ni + d) * N;
            if (D + j == 0)
                for (int c = 0; c < N; c++)
                    row[c] = loop->input_gain * r[(size_t)d * N + c];
            else
                row[hist + (D + j - 1) * ni + d] = loop->input_gain;
        }
    for (int i = 0; i < nz; i++) {
        for (int j = 0; j < nz; j++)
            RTHS_AT(w, N, i, j) = loop->phi[i + (size_t)j * nz];
        for (int j = 0; j < 3; j++)
            for (int d = 0; d < ni; d++)
                for (int c = 0; c < N; c++)
                    RTHS_AT(w, N, i, c) +=
                        loop->e[j][i + (size_t)d * nz] * cmd[((size_t)j * ni + d) * N + c];
    }
    for (int d = 0; d < ni; d++) {
        for (int c = 0; c < N; c++)
            RTHS_AT(w, N, hist + d, c) = r[(size_t)d * N + c];
        for (int k = 1; k <= D + 1; k++)
            RTHS_AT(w, N, hist + k * ni + d, hist + (k - 1) * ni + d) = 1.0;
        RTHS_AT(w, N, xprev + d, loop->iface + d) = 1.0;
        RTHS_AT(w, N, vprev + d, loop->iface + d) = v_x;
        RTHS_AT(w, N, vprev + d, xprev + d) = v_xprev;
        RTHS_AT(w, N, vprev + d, vprev + d) = v_v;
    }
    double radius = rths_spectral_radius(N, w);
    rths_mat_free(w), free(r), free(cmd);
    return radius;
}

double rths_pd_loop_radius(const rths_pd_loop *loop, double kp, double kd) {
    double kps[RTHS_MAX_INTERFACE_DOFS], kds[RTHS_MAX_INTERFACE_DOFS];
    for (int d = 0; d < loop->ni; d++)
        kps[d] = kp, kds[d] = kd;
    return rths_pd_loop_radius_dofs(loop, kps, kds);
}

int rths_pd_loop_points(void) {
    return GRID_POINTS;
}

/* The plant loop d sees with the other loops closed by their PDs (K_o = kp_o + kd_o dterm),
 * from effort demand d to displacement d:
 *   P_dd - P_do K_o (I + P_oo K_o)^{-1} P_od,
 * at every frequency of the grid; with one DoF, P itself. */
static int effective_plant(const rths_pd_loop *loop, int d, const double *kp, const double *kd,
                           double complex *out) {
    const int ni = loop->ni, m = ni - 1;
    if (ni == 1) {
        memcpy(out, loop->p, sizeof *out * GRID_POINTS);
        return 0;
    }
    int others[RTHS_MAX_INTERFACE_DOFS];
    for (int j = 0, k = 0; j < ni; j++)
        if (j != d) others[k++] = j;
    double complex a[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_INTERFACE_DOFS], y[RTHS_MAX_INTERFACE_DOFS],
        kk[RTHS_MAX_INTERFACE_DOFS];
    for (int g = 0; g < GRID_POINTS; g++) {
        const double complex *pg = loop->p + (size_t)g * ni * ni;
        for (int k = 0; k < m; k++)
            kk[k] = kp[others[k]] + kd[others[k]] * loop->dterm[g];
        for (int r = 0; r < m; r++) {
            for (int c = 0; c < m; c++)
                a[r + c * m] = (r == c ? 1.0 : 0.0) + pg[others[r] + others[c] * ni] * kk[c];
            y[r] = pg[others[r] + d * ni];
        }
        if (rths_cmat_solve(m, 1, a, y)) return -1;
        double complex pe = pg[d + d * ni];
        for (int k = 0; k < m; k++)
            pe -= pg[d + others[k] * ni] * kk[k] * y[k];
        out[g] = pe;
    }
    return 0;
}

int rths_pd_loop_response_dof(const rths_pd_loop *loop, int d, const double *kp, const double *kd,
                              double *frequency_hz, double complex *l) {
    if (effective_plant(loop, d, kp, kd, l)) return -1;
    for (int g = 0; g < GRID_POINTS; g++) {
        frequency_hz[g] = loop->theta[g] / (2 * M_PI * loop->h);
        l[g] = (kp[d] + kd[d] * loop->dterm[g]) * l[g];
    }
    return 0;
}

void rths_pd_loop_response(const rths_pd_loop *loop, double kp, double kd, double *frequency_hz,
                           double complex *l) {
    for (int g = 0; g < GRID_POINTS; g++) {
        frequency_hz[g] = loop->theta[g] / (2 * M_PI * loop->h);
        l[g] = (kp + kd * loop->dterm[g]) * loop->p[(size_t)g * loop->ni * loop->ni];
    }
}

/* the phase of L + pi, wrapped to (-pi, pi]: 0 where L is on the negative real axis */
static double phase_from_minus_one(double complex l) {
    return carg(-l);
}

/* The margins from the frequency response of L = (kp + kd dterm) p on the grid, crossings
 * interpolated linearly between grid points (0.5 % of a decade apart); the spectral radius is
 * not touched. */
static void frequency_margins(const rths_pd_loop *loop, const double complex *p, double kp,
                              double kd, rths_loop_margins *out) {
    double to_hz = 1.0 / (2 * M_PI * loop->h);
    double gm = INFINITY, gm_theta = NAN, pm = INFINITY, pm_theta = NAN, bw = NAN;
    double complex prev = 0;
    for (int g = 0; g < GRID_POINTS; g++) {
        double th = loop->theta[g];
        double complex l = (kp + kd * loop->dterm[g]) * p[g];
        if (isnan(bw) && cabs(1.0 / (1.0 + l)) > M_SQRT1_2) bw = g == 0 ? 0 : loop->theta[g - 1];
        if (g > 0) {
            double th0 = loop->theta[g - 1];
            /* phase crossover: L crosses the negative real axis */
            if (cimag(prev) * cimag(l) <= 0 && (creal(prev) < 0 || creal(l) < 0) &&
                cimag(prev) != cimag(l)) {
                double t = cimag(prev) / (cimag(prev) - cimag(l));
                double re = creal(prev) + t * (creal(l) - creal(prev));
                if (re < 0 && re > -1) {
                    double margin = -20 * log10(-re);
                    if (margin < gm) gm = margin, gm_theta = th0 + t * (th - th0);
                }
            }
            /* gain crossover: |L| crosses 1 */
            double a0 = cabs(prev) - 1, a1 = cabs(l) - 1;
            if (a0 * a1 <= 0 && a0 != a1) {
                double t = a0 / (a0 - a1);
                double complex lc = prev + t * (l - prev);
                double margin = fabs(phase_from_minus_one(lc)) * 180 / M_PI;
                if (margin < pm) pm = margin, pm_theta = th0 + t * (th - th0);
            }
        }
        prev = l;
    }
    if (isnan(bw)) bw = M_PI;
    out->gain_margin_db = gm;
    out->gain_margin_hz = gm_theta * to_hz;
    out->phase_margin_deg = pm;
    out->crossover_hz = pm_theta * to_hz;
    out->bandwidth_hz = bw * to_hz;
}

int rths_pd_loop_margins_dof(const rths_pd_loop *loop, int d, const double *kp, const double *kd,
                             rths_loop_margins *out, rths_error *err) {
    double complex *pe = malloc(sizeof *pe * GRID_POINTS);
    if (!pe) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = effective_plant(loop, d, kp, kd, pe);
    if (!rc) frequency_margins(loop, pe, kp[d], kd[d], out);
    free(pe);
    if (rc)
        return rths_error_set(err, RTHS_EFAIL,
                              "the loop of interface DoF %d with the others closed could not be "
                              "formed",
                              d + 1);
    out->spectral_radius = rths_pd_loop_radius_dofs(loop, kp, kd);
    if (out->spectral_radius < 0)
        return rths_error_set(err, RTHS_EFAIL,
                              "the eigenvalues of the closed PD loop could not be computed");
    out->stable = out->spectral_radius < 1;
    return RTHS_OK;
}

int rths_pd_loop_margins(const rths_pd_loop *loop, double kp, double kd, rths_loop_margins *out,
                         rths_error *err) {
    double kps[RTHS_MAX_INTERFACE_DOFS], kds[RTHS_MAX_INTERFACE_DOFS];
    for (int d = 0; d < loop->ni; d++)
        kps[d] = kp, kds[d] = kd;
    return rths_pd_loop_margins_dof(loop, 0, kps, kds, out, err);
}

/* The rule of docs/method.md, "Tuning the gains", for loop d with the other loops closed at
 * their gains kp, kd: over kd_d in {0} and 1e-4 .. 1e7 V s/m (4 per decade) and kp_d in
 * 1e-2 .. 1e9 V/m (20 per decade), the pair whose loop has both margins met and whose
 * bandwidth is the largest (ties: the larger kp, then the first kd), with the whole coupled
 * loop stable when check_radius (every loop closed), and also with every gain times
 * margin_factor when that is > 0. kp[d], kd[d] are overwritten. */
int rths_pd_loop_best_dof(const rths_pd_loop *loop, int d, double *kp, double *kd, int check_radius,
                          double margin_factor, double min_gm_db, double min_pm_deg,
                          rths_loop_margins *best, rths_error *err) {
    double complex *pe = malloc(sizeof *pe * GRID_POINTS);
    if (!pe) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (effective_plant(loop, d, kp, kd, pe)) {
        free(pe);
        return rths_error_set(err, RTHS_EFAIL,
                              "the loop of interface DoF %d with the others closed could not be "
                              "formed",
                              d + 1);
    }
    int found = 0;
    double best_bw = -1, best_kp = 0, pick_kp = 0, pick_kd = 0;
    for (int i = -1; i <= 44; i++) {
        double kd_try = i < 0 ? 0.0 : pow(10.0, -4 + 0.25 * i);
        for (int j = 0; j <= 220; j++) {
            double kp_try = pow(10.0, -2 + 0.05 * j);
            rths_loop_margins m;
            frequency_margins(loop, pe, kp_try, kd_try, &m);
            if (!(m.gain_margin_db >= min_gm_db && m.phase_margin_deg >= min_pm_deg)) continue;
            int better = m.bandwidth_hz > best_bw * (1 + 1e-9) ||
                         (m.bandwidth_hz >= best_bw * (1 - 1e-9) && kp_try > best_kp);
            if (!better) continue;
            kp[d] = kp_try, kd[d] = kd_try;
            m.spectral_radius = check_radius ? rths_pd_loop_radius_dofs(loop, kp, kd) : NAN;
            if (check_radius && m.spectral_radius < 0) {
                free(pe);
                return rths_error_set(err, RTHS_EFAIL,
                                      "the eigenvalues of the closed PD loop could not be "
                                      "computed");
            }
            if (check_radius && !(m.spectral_radius < 1)) continue;
            if (check_radius && margin_factor > 0) {
                double kps[RTHS_MAX_INTERFACE_DOFS], kds[RTHS_MAX_INTERFACE_DOFS];
                for (int e = 0; e < loop->ni; e++)
                    kps[e] = margin_factor * kp[e], kds[e] = margin_factor * kd[e];
                if (!(rths_pd_loop_radius_dofs(loop, kps, kds) < 1)) continue;
            }
            m.stable = check_radius;
            *best = m;
            pick_kp = kp_try, pick_kd = kd_try;
            best_bw = m.bandwidth_hz, best_kp = kp_try;
            found = 1;
        }
    }
    free(pe);
    kp[d] = pick_kp, kd[d] = pick_kd;
    if (!found)
        return rths_error_set(err, RTHS_EFAIL,
                              "no PD gains (kp 1e-2 .. 1e9 V/m, kd 0 .. 1e7 V s/m) keep the "
                              "sampled physical loop%s stable with a gain margin of %g dB and a "
                              "phase margin of %g deg",
                              loop->ni > 1 ? " of an interface DoF" : "", min_gm_db, min_pm_deg);
    return RTHS_OK;
}

int rths_pd_loop_best(const rths_pd_loop *loop, double min_gm_db, double min_pm_deg, double *kp,
                      double *kd, rths_loop_margins *best, rths_error *err) {
    double kps[RTHS_MAX_INTERFACE_DOFS] = {0}, kds[RTHS_MAX_INTERFACE_DOFS] = {0};
    int rc = rths_pd_loop_best_dof(loop, 0, kps, kds, 1, 0, min_gm_db, min_pm_deg, best, err);
    *kp = kps[0], *kd = kds[0];
    return rc;
}

/* Several interface DoFs (docs/method.md, "Tuning the gains"): loop d's pick with the others
 * closed at kp, kd. Every pair of the grid above whose loop meets both margins and whose coupled
 * loop is stable at the gains and at margin_factor times all of them is a candidate; its figure
 * is the decay rate of the coupled loop's slowest transient, -ln(spectral radius) per sample
 * (what the host's steady-state detection waits for after each new target); the pick is the
 * widest bandwidth (ties: the larger kp) among the candidates that reach decay_fraction of the
 * fastest decay found. kp[d], kd[d] are overwritten. */
int rths_pd_loop_best_decay_dof(const rths_pd_loop *loop, int d, double *kp, double *kd,
                                double margin_factor, double decay_fraction, double min_gm_db,
                                double min_pm_deg, rths_loop_margins *best, rths_error *err) {
    enum { KD_STEPS = 46, KP_STEPS = 221 };
    double complex *pe = malloc(sizeof *pe * GRID_POINTS);
    rths_loop_margins *cand = malloc(sizeof *cand * KD_STEPS * KP_STEPS);
    double *ckp = malloc(sizeof *ckp * KD_STEPS * KP_STEPS),
           *ckd = malloc(sizeof *ckd * KD_STEPS * KP_STEPS);
    int rc = pe && cand && ckp && ckd ? RTHS_OK : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc && effective_plant(loop, d, kp, kd, pe))
        rc = rths_error_set(err, RTHS_EFAIL,
                            "the loop of interface DoF %d with the others closed could not be "
                            "formed",
                            d + 1);
    int n = 0;
    double best_decay = 0;
    for (int i = -1; !rc && i < KD_STEPS - 1; i++) {
        double kd_try = i < 0 ? 0.0 : pow(10.0, -4 + 0.25 * i);
        for (int j = 0; !rc && j < KP_STEPS; j++) {
            double kp_try = pow(10.0, -2 + 0.05 * j);
            rths_loop_margins m;
            frequency_margins(loop, pe, kp_try, kd_try, &m);
            if (!(m.gain_margin_db >= min_gm_db && m.phase_margin_deg >= min_pm_deg)) continue;
            double kps[RTHS_MAX_INTERFACE_DOFS], kds[RTHS_MAX_INTERFACE_DOFS];
            memcpy(kps, kp, sizeof(double) * (size_t)loop->ni);
            memcpy(kds, kd, sizeof(double) * (size_t)loop->ni);
            kps[d] = kp_try, kds[d] = kd_try;
            m.spectral_radius = rths_pd_loop_radius_dofs(loop, kps, kds);
            if (m.spectral_radius < 0)
                rc = rths_error_set(err, RTHS_EFAIL,
                                    "the eigenvalues of the closed PD loop could not be computed");
            if (rc || !(m.spectral_radius < 1)) continue;
            for (int e = 0; e < loop->ni; e++)
                kps[e] *= margin_factor, kds[e] *= margin_factor;
            if (!(rths_pd_loop_radius_dofs(loop, kps, kds) < 1)) continue;
            m.stable = 1;
            cand[n] = m, ckp[n] = kp_try, ckd[n] = kd_try;
            if (-log(m.spectral_radius) > best_decay) best_decay = -log(m.spectral_radius);
            n++;
        }
    }
    int pick = -1;
    for (int c = 0; !rc && c < n; c++) {
        if (!(-log(cand[c].spectral_radius) >= decay_fraction * best_decay)) continue;
        if (pick < 0 || cand[c].bandwidth_hz > cand[pick].bandwidth_hz * (1 + 1e-9) ||
            (cand[c].bandwidth_hz >= cand[pick].bandwidth_hz * (1 - 1e-9) && ckp[c] > ckp[pick]))
            pick = c;
    }
    if (!rc && pick < 0)
        rc = rths_error_set(err, RTHS_EFAIL,
                            "no PD gains (kp 1e-2 .. 1e9, kd 0 .. 1e7) of interface DoF %d keep "
                            "its loop's gain margin at %g dB and phase margin at %g deg with the "
                            "coupled loop stable at %g times every gain",
                            d + 1, min_gm_db, min_pm_deg, margin_factor);
    if (!rc) {
        *best = cand[pick];
        kp[d] = ckp[pick], kd[d] = ckd[pick];
    }
    free(pe), free(cand), free(ckp), free(ckd);
    return rc;
}
