/* The steady state from the transient (docs/method.md, "One evaluation", the fitted evaluation):
 * per-period Fourier coefficients after a target or frequency change are
 *   y_i(q) = a_i + sum_j c_ij z_j^q + noise,   q = 0 .. K-1,
 * the z_j = exp(lambda_j T) of the rig's decaying free modes, shared by every coefficient. The
 * z_j are the roots of z^n + alpha_1 z^(n-1) + ... + alpha_n, found by Prony on the periods'
 * differences (shared by all series) and refined by variable projection; a_i and c_ij are linear
 * least squares. Private to src/iterate (not installed). */
#ifndef RTHS_ITERATE_TRANSIENT_FIT_H
#define RTHS_ITERATE_TRANSIENT_FIT_H

#include <complex.h>

enum { TRANSIENT_FIT_MAX_ORDER = 8, TRANSIENT_FIT_RESIDUAL_MARGIN = 3 };

typedef struct transient_fit {
    int order;   /* n, the decaying terms fitted (0: none, the series' mean) */
    int periods; /* K */
    double alpha[TRANSIENT_FIT_MAX_ORDER];
    double complex z[TRANSIENT_FIT_MAX_ORDER];
    double max_abs_z;
    /* the shared parameters' part of the covariance (the Schur complement of the normal
     * matrix's block-arrow form, inverted), in units of alpha; order x order */
    double shared_cov[TRANSIENT_FIT_MAX_ORDER * TRANSIENT_FIT_MAX_ORDER];
    /* pooled lag-1 autocorrelation of the standardised residuals (white noise: about 0) */
    double lag1;
    /* the residuals' root mean square per period over all series, sqrt(sum_i RSS_i / K), in the
     * series' unit: what the model leaves unexplained (noise, or a misfit) */
    double rms_residual;
    int ok; /* 1: the fit ran (a singular or failed fit leaves 0) */
} transient_fit;

/* Fits m series of K periods (series i at y[i * K + q]) with one shared set of up to max_order
 * poles, choosing the order by the Bayesian information criterion. prior_var (may be NULL): each
 * series' per-period noise variance measured elsewhere, with prior_dof degrees of freedom, pooled
 * with the residual's. Writes a_inf[i] and se[i] (standard error including the poles' own
 * uncertainty), noise_var[i] (may be NULL: the per-period noise variance the standard error
 * assumed) and the fit. Returns 0, or -1 when nothing could be fitted (K too small). */
int transient_fit_series(int m, int K, const double *y, int max_order, const double *prior_var,
                         double prior_dof, transient_fit *fit, double *a_inf, double *se,
                         double *noise_var);

/* The same with the order limited so that every series keeps `margin` residual degrees of
 * freedom beyond the decaying terms' (transient_fit_series: TRANSIENT_FIT_RESIDUAL_MARGIN,
 * 3; iteration.settle.fit_residual_margin). */
int transient_fit_series_margin(int m, int K, const double *y, int max_order, int margin,
                                const double *prior_var, double prior_dof, transient_fit *fit,
                                double *a_inf, double *se, double *noise_var);

/* One more series with the poles of `fit` held (the other harmonics, output DoFs): its
 * steady-state value and standard error; the poles' uncertainty enters as in the fit. */
void transient_fit_apply(const transient_fit *fit, const double *y, double *a_inf, double *se);

#endif
