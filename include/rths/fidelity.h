/* rths fidelity: what the numerical substructure's integration scheme does to a hybrid test's
 * result (docs/method.md, "Numerical substructure integration"), computed in the frequency domain
 * without time stepping.
 *
 * The model of a converged iterative hybrid test at a perfect interface match:
 *   - the physical substructure (split->mass_phys, ...) is continuous time:
 *       D_p(w) Q_p = F_p + E lambda,   D_p = K_p - w^2 M_p + i w C_p,
 *     where lambda is the force the actuator applies to the physical interface DoFs (E selects
 * them);
 *   - the numerical substructure is discretised at step h with one scheme and driven by sampled
 *     inputs: the interface force -lambda (Newton's third law: what the physical side pushes back
 *     with, measured by the load cell) and the forcing on the interface and numerical DoFs. For a
 *     sampled harmonic input u_k = Re(U z^k), z = e^{i w h}, its steady state is
 *       X = (z I - Ad)^{-1} (b_prev + z b_curr) U      (x_{k+1} = Ad x_k + b_prev u_k + b_curr
 * u_{k+1});
 *   - the interface displacements (fundamental harmonic) agree: E^T Q_p = Q_n(interface).
 * One complex linear system of size (np + n_int) per frequency gives lambda and every DoF.
 *
 * Forcing on an internal physical DoF acts on the continuous physical side; forcing on an interface
 * or numerical DoF is applied by the controller to the numerical model, so it is sampled too.
 * As h -> 0 every scheme tends to the true assembly's analytic FRF (the split recombines exactly).
 */
#ifndef RTHS_FIDELITY_H
#define RTHS_FIDELITY_H

#include "rths/config.h"
#include "rths/model.h"
#include "rths/reduce.h"

#include <complex.h>

/* Curve index for the true assembly's analytic FRF (the schemes are 0..RTHS_SCHEME_COUNT-1). */
#define RTHS_FIDELITY_TRUE (-1)
/* Curve index for the hybrid test with the numerical substructure reduced (reduce.h) but not
 * discretised: the reduction's error alone (equal to the true curve without a reduction). */
#define RTHS_FIDELITY_REDUCED (-2)

typedef struct rths_fidelity rths_fidelity;

/* Builds the hybrid model of split s under force (n assembly DoFs, N amplitudes) with the numerical
 * substructure discretised at step h_s by every scheme. Copies what it needs from s and force. */
int rths_fidelity_create(const rths_split *s, const double *force, double h_s, rths_fidelity **out,
                         rths_error *err);
/* The same with the numerical substructure replaced by its reduction red (n = split's nn,
 * interface first; NULL: none), as the real-time controller integrates it: every scheme's curve
 * then carries the reduction's error and the scheme's. The true assembly's FRF takes banded
 * solves when the assembly is banded, so a 1000-DoF model costs O(n) per frequency. */
int rths_fidelity_create_reduced(const rths_split *s, const double *force, double h_s,
                                 const rths_reduced *red, rths_fidelity **out, rths_error *err);
void rths_fidelity_free(rths_fidelity *f);
int rths_fidelity_dofs(const rths_fidelity *f); /* n, the assembly's DoF count */

/* Complex amplitudes x_out[0..n-1] (assembly order, m) of every DoF at omega for curve (a scheme or
 * RTHS_FIDELITY_TRUE). On the interface both sides agree by construction. */
int rths_fidelity_response(const rths_fidelity *f, int curve, double omega_rad_s,
                           double complex *x_out, rths_error *err);

/* The highest amplitude of DoF dof (0-based) for curve over [lo_hz, hi_hz]: a scan of `points`
 * (>= 3) uniform frequencies locates the peak, then golden-section search refines it to a relative
 * frequency precision of about 1e-10, so the result does not depend on the scan's resolution as
 * long as the scan separates the peak from its neighbours. */
int rths_fidelity_peak(const rths_fidelity *f, int curve, int dof, double lo_hz, double hi_hz,
                       int points, double *peak_hz, double *peak_amplitude_m, rths_error *err);

/* The sweep of `rths fidelity` (docs/config/fidelity.md). */
typedef struct rths_fidelity_options {
    double start_hz, end_hz; /* default: +-10 % around the second natural frequency */
    int points;              /* uniform frequencies, default 1001 */
    /* with nonlinear elements: how many of the grid's frequencies (evenly spread, both ends
     * included) the real-time step is run at against the harmonic-balance truth; default 11 */
    int nonlinear_points;
} rths_fidelity_options;

/* Reads fidelity.start_hz, end_hz, points and nonlinear_points (<= points); the defaults come from
 * assembly a's modes (the second mode, where the seed's hybrid test is hardest; the first for a
 * one-DoF structure). Refuses, located, values out of range and end_hz <= start_hz. */
int rths_fidelity_config_read(rths_config *cfg, const rths_assembly *a, rths_fidelity_options *o,
                              rths_error *err);

/* The same with the defaults given: start_hz..end_hz (end_hz raised to 1.1 start_hz when a
 * given fidelity.start_hz passes it) and points (3..1000000) frequencies. */
int rths_fidelity_config_read_band(rths_config *cfg, double start_hz, double end_hz, int points,
                                   rths_fidelity_options *o, rths_error *err);

/* The frequencies to tabulate: o's uniform grid merged with `extra` (e.g. every curve's exact
 * peak), sorted, duplicates removed. *freqs is malloc'ed. */
int rths_fidelity_frequencies(const rths_fidelity_options *o, const double *extra, int n_extra,
                              double **freqs, int *count, rths_error *err);

/* The half-power distance of curve's peak of DoF dof (peak_amplitude_m at peak_hz) above it:
 * the first frequency, stepping by step_hz from the peak up to end_hz, where the amplitude falls
 * below peak / sqrt(2), minus peak_hz; 0 when it does not fall within that range. */
double rths_fidelity_half_power_hz(const rths_fidelity *f, int curve, int dof, double peak_hz,
                                   double peak_amplitude_m, double end_hz, double step_hz);

#endif
