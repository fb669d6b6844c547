/* The linear time-invariant rig's structure: one complex gain per harmonic, and the local model
 * of the residual fitted to the evaluation history (the residual-model predictor's basis). */
#include "iterate/corrector_internal.h"

#include <math.h>
#include <string.h>

/* A linear time-invariant rig maps each harmonic of the target to the same harmonic alone, by a
 * complex gain g_k: (Phi_a + i Phi_b)_k = g_k (A* + i B*)_k, i.e. the 2N x 2N Jacobian (cos rows
 * and columns k, sin rows and columns N + k) has blocks [[Re g, -Im g], [Im g, Re g]] on the
 * diagonal and zeros elsewhere. With several interface DoFs the unknowns hold P = N n Fourier
 * pairs, pair p = d N + k for DoF d and harmonic k (iterate.h), and every DoF's harmonic k drives
 * every DoF's harmonic k: the gain of harmonic k is a complex n x n matrix, whose entry (d, e) is
 * the block of rows of pair d N + k and columns of pair e N + k. */
void lti_pair_block(double *J, int P, int p, int q, double complex g) {
    J[p + q * LD] = creal(g);
    J[p + (P + q) * LD] = -cimag(g);
    J[P + p + q * LD] = cimag(g);
    J[P + p + (P + q) * LD] = creal(g);
}

void lti_block(double *J, int N, int k, double complex g) {
    lti_pair_block(J, N, k, k, g);
}

double complex lti_gain(const double *J, int P, int p, int q) {
    return 0.5 * (J[p + q * LD] + J[P + p + (P + q) * LD]) +
           I * 0.5 * (J[P + p + q * LD] - J[p + (P + q) * LD]);
}

/* Pairs p and q (0..P-1) of a problem with `dofs` interface DoFs belong to the same harmonic. */
static int lti_coupled(int P, int dofs, int p, int q) {
    int N = P / dofs;
    return p % N == q % N;
}

/* Whether the target block of a measured J is of the LTI form: its Frobenius distance from the
 * nearest LTI form is within 5 % of its size plus what entry noise of std noise_entry explains
 * (the distance has 4P^2 - 2 N n^2 degrees of freedom; twice its expected size under noise
 * alone). */
int lti_like(const double *J, int P, int dofs, double noise_entry) {
    int n = 2 * P;
    double total = 0, off = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double v = J[i + j * LD];
            total += v * v;
            if (!lti_coupled(P, dofs, i % P, j % P)) off += v * v;
        }
    for (int p = 0; p < P; p++)
        for (int q = 0; q < P; q++) {
            if (!lti_coupled(P, dofs, p, q)) continue;
            double complex g = lti_gain(J, P, p, q);
            double form[2][2] = {{creal(g), -cimag(g)}, {cimag(g), creal(g)}};
            int row[2] = {p, P + p}, col[2] = {q, P + q};
            for (int a = 0; a < 2; a++)
                for (int b = 0; b < 2; b++) {
                    double d = J[row[a] + col[b] * LD] - form[a][b];
                    off += d * d;
                }
        }
    double dof = 4.0 * P * P - 2.0 * (P / dofs) * dofs * dofs;
    return total > 0 && sqrt(off) <= 0.05 * sqrt(total) + 2.0 * noise_entry * sqrt(dof);
}

void lti_project(double *J, int P, int dofs) {
    double complex g[RTHS_MAX_HARMONICS * RTHS_MAX_HARMONICS];
    for (int p = 0; p < P; p++)
        for (int q = 0; q < P; q++)
            g[p + P * q] = lti_gain(J, P, p, q);
    for (int j = 0; j < 2 * P; j++)
        for (int i = 0; i < 2 * P; i++)
            J[i + j * LD] = 0;
    for (int p = 0; p < P; p++)
        for (int q = 0; q < P; q++)
            if (lti_coupled(P, dofs, p, q)) lti_pair_block(J, P, p, q, g[p + P * q]);
}

/* Least-squares fit of the local LTI model (see corrector_memory.history) at omega: per
 * harmonic, Phi = g z - f and x = r z + e with each of g, f, r, e a line in w (on the virtual
 * rig a quadratic fitted the noise and made the matched estimate worse: 12 of 492 points beyond
 * three standard errors against none); returns the gains g and r at omega, the prediction
 * z = f / g and, if var_ratio is given, the variance E|d(r/g)|^2 of the ratio that maps a residual
 * onto the response, from the fits' scatter (noise and model error alike). */
enum { LTI_UNKNOWNS = 2 * LTI_TERMS };

/* The history holds at least `unknowns` + 2 evaluations at LTI_TERMS or more distinct frequencies;
 * *spread: the largest |w - omega|. */
int lti_history_usable(const corrector_memory *mem, double omega, int unknowns, double *spread) {
    int count = mem->history_count, distinct = 0;
    if (count < unknowns + 2) return 0;
    double seen[LTI_TERMS];
    *spread = 0;
    for (int e = 0; e < count; e++) {
        double w = mem->history[e].omega_rad_s;
        *spread = fmax(*spread, fabs(w - omega));
        int known = 0;
        for (int q = 0; q < distinct; q++)
            known |= seen[q] == w;
        if (!known && distinct < LTI_TERMS) seen[distinct++] = w;
    }
    return distinct >= LTI_TERMS && *spread > 0;
}

typedef struct {
    double complex rows[RTHS_LTI_HISTORY][LTI_UNKNOWNS];
    double complex ata[LTI_UNKNOWNS * LTI_UNKNOWNS], atb[3 * LTI_UNKNOWNS];
} lti_normal;

/* Normal equations of harmonic k's fit. Unknowns: g's and f's (or r's and e's) coefficients of
 * 1, d with d = (w - omega) / spread, z scaled by zs, so they are well scaled; value at omega = the
 * constant term. Three right-hand sides: Phi, x, and e_0 for (A^H A)^-1's (0, 0) entry, the
 * variance factor of g0 and r0. */
static void lti_normal_equations(const corrector_memory *mem, int N, int k, double omega,
                                 double spread, double zs, lti_normal *ne) {
    enum { U = LTI_UNKNOWNS };
    memset(ne, 0, sizeof *ne);
    ne->atb[2 * U] = 1.0;
    for (int e = 0; e < mem->history_count; e++) {
        double d = (mem->history[e].omega_rad_s - omega) / spread, dj = 1;
        double complex z = (mem->history[e].target[k] + I * mem->history[e].target[N + k]) / zs;
        for (int j = 0; j < LTI_TERMS; j++, dj *= d) {
            ne->rows[e][j] = z * dj;
            ne->rows[e][LTI_TERMS + j] = -dj;
        }
        double complex phi = mem->history[e].phi[k] + I * mem->history[e].phi[N + k];
        double complex x = mem->history[e].response[k] + I * mem->history[e].response[N + k];
        for (int p = 0; p < U; p++) {
            for (int q = 0; q < U; q++)
                ne->ata[p + U * q] += conj(ne->rows[e][p]) * ne->rows[e][q];
            ne->atb[p] += conj(ne->rows[e][p]) * phi;
            ne->atb[U + p] += conj(ne->rows[e][p]) * x; /* e's terms come out negated, unused */
        }
    }
}

/* E|d(r/g)|^2 of harmonic k from the scatter of the solved fit about the history; *var_matched
 * (if given): the scatter of the combination x - (r/g) Phi the matched estimate forms, per
 * evaluation (m^2, complex): the noise as it shows between evaluations, which also holds what the
 * periods of one evaluation cannot show (noise correlated from period to period, as the
 * numerical side's resonant response to sensor noise is). */
static double lti_ratio_variance(const corrector_memory *mem, int N, int k, const lti_normal *ne,
                                 double zs, double complex g0, double complex r0,
                                 double *var_matched) {
    enum { U = LTI_UNKNOWNS };
    int count = mem->history_count;
    double ss_phi = 0, ss_x = 0, ss_m = 0;
    for (int e = 0; e < count; e++) {
        double complex fit_phi = 0, fit_x = 0;
        for (int p = 0; p < U; p++) {
            fit_phi += ne->rows[e][p] * ne->atb[p];
            fit_x += ne->rows[e][p] * ne->atb[U + p];
        }
        double complex phi = mem->history[e].phi[k] + I * mem->history[e].phi[N + k];
        double complex x = mem->history[e].response[k] + I * mem->history[e].response[N + k];
        ss_phi += creal(conj(phi - fit_phi) * (phi - fit_phi));
        ss_x += creal(conj(x - fit_x) * (x - fit_x));
        double complex dm = (x - fit_x) - r0 / g0 * (phi - fit_phi);
        ss_m += creal(conj(dm) * dm);
    }
    if (var_matched) *var_matched = ss_m / (count - U);
    double factor = fabs(creal(ne->atb[2 * U])) / (zs * zs) / (count - U);
    double var_g = ss_phi * factor, var_r = ss_x * factor, ag = cabs(g0);
    return var_r / (ag * ag) + cabs(r0) * cabs(r0) * var_g / (ag * ag * ag * ag);
}

int lti_fit(const corrector_memory *mem, int N, double omega, double complex *g, double complex *r,
            double complex *z_pred, double *var_ratio, double *var_matched) {
    enum { U = LTI_UNKNOWNS };
    double spread;
    if (!lti_history_usable(mem, omega, LTI_UNKNOWNS, &spread)) return -1;
    for (int k = 0; k < N; k++) {
        double zs = 0;
        for (int e = 0; e < mem->history_count; e++)
            zs = fmax(zs, hypot(mem->history[e].target[k], mem->history[e].target[N + k]));
        if (!(zs > 0)) return -1;
        lti_normal ne;
        lti_normal_equations(mem, N, k, omega, spread, zs, &ne);
        /* Two frequencies are not enough when one has a single evaluation: g and f there cannot
         * be told apart, the normal matrix is rank deficient, and zgesv would still answer with
         * made-up gains (and a tiny scatter). Demand a well-conditioned fit. */
        if (!(rths_cmat_hermitian_eigen_ratio(U, ne.ata) > 1e-10)) return -1;
        if (rths_cmat_solve(U, 3, ne.ata, ne.atb) != 0) return -1;
        double complex g0 = ne.atb[0] / zs, f0 = ne.atb[LTI_TERMS], r0 = ne.atb[U] / zs;
        if (!finite_complex(g0) || !(cabs(g0) > 0) || !finite_complex(r0) || !finite_complex(f0))
            return -1;
        g[k] = g0;
        r[k] = r0;
        z_pred[k] = f0 / g0;
        if (var_ratio)
            var_ratio[k] = lti_ratio_variance(mem, N, k, &ne, zs, g0, r0,
                                              var_matched ? &var_matched[k] : NULL);
    }
    return 0;
}

/* Secant update in the LTI form: one pair (s, y) fixes each harmonic's gain, g_k = y_k / s_k,
 * where Broyden would correct one direction of the block. A harmonic whose change is not well
 * above the noise (noise_k, same units) keeps its gain: a gain from noise is worse than a stale
 * one. */
void lti_update(double *J, int N, const double *s, const double *y, const double *noise) {
    for (int k = 0; k < N; k++) {
        double complex sk = s[k] + I * s[N + k], yk = y[k] + I * y[N + k];
        if (cabs(yk) > 3 * noise[k] && cabs(sk) > 0) lti_block(J, N, k, yk / sk);
    }
}

/* Noise of each harmonic's change between two evaluations, in the corrector's scaled units:
 * of the mismatch (both sides of both evaluations) and of the physical response. */
void lti_secant_noise(const rths_residual *r0, const rths_residual *r1, int N, double scale,
                      double *noise_phi, double *noise_resp) {
    const double *se0 = r0->phi_se, *se1 = r1->phi_se;
    for (int k = 0; k < N; k++) {
        double v = 0;
        for (int h = 0; h < 2; h++)
            v += se0[h * N + k] * se0[h * N + k] + se1[h * N + k] * se1[h * N + k];
        noise_phi[k] = sqrt(v) / scale;
        const double *p0 = r0->response_se, *p1 = r1->response_se;
        noise_resp[k] =
            sqrt(p0[k] * p0[k] + p0[N + k] * p0[N + k] + p1[k] * p1[k] + p1[N + k] * p1[N + k]) /
            scale;
    }
}
