/* rths_api_chart: the stability chart of the delayed-feedback test as tables, the same numbers as
 * `rths chart` writes to chart.csv, boundary.csv and critical.csv. */
#include "api/api_internal.h"
#include "rths/stability.h"

#include <json-c/json.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The stability.* keys, with the ranges and messages `rths chart` has always used. */
int rths_api_chart_options_read(rths_config *cfg, rths_chart_options *o, rths_error *err) {
    rths_chart_options_default(o);
    long tp, pp, wp, mt, mp, mr, cn;
    int rc;
    if ((rc = rths_config_get_double(cfg, "stability.tau_min_s", 0, o->tau_min_s, 1e-12, 1e3,
                                     &o->tau_min_s, err)) ||
        (rc = rths_config_get_double(cfg, "stability.tau_max_s", 0, o->tau_max_s, 1e-12, 1e3,
                                     &o->tau_max_s, err)) ||
        (rc = rths_config_get_int(cfg, "stability.tau_points", 0, o->tau_points, 2, 5000, &tp,
                                  err)) ||
        (rc = rths_config_get_double(cfg, "stability.p_min", 0, o->p_min, 1e-6, 1 - 1e-6, &o->p_min,
                                     err)) ||
        (rc = rths_config_get_double(cfg, "stability.p_max", 0, o->p_max, 1e-6, 1 - 1e-6, &o->p_max,
                                     err)) ||
        (rc = rths_config_get_int(cfg, "stability.p_points", 0, o->p_points, 1, 5000, &pp, err)) ||
        (rc = rths_config_get_double(cfg, "stability.omega_min_rad_s", 0, o->omega_min_rad_s, 0,
                                     1e9, &o->omega_min_rad_s, err)) ||
        (rc = rths_config_get_double(cfg, "stability.omega_max_rad_s", 0, o->omega_max_rad_s, 1e-9,
                                     1e9, &o->omega_max_rad_s, err)) ||
        (rc = rths_config_get_int(cfg, "stability.omega_points", 0, o->omega_points, 2, 100000, &wp,
                                  err)) ||
        (rc = rths_config_get_int(cfg, "stability.mdbm_tau_points", 0, o->mdbm_tau_points, 2, 5000,
                                  &mt, err)) ||
        (rc = rths_config_get_int(cfg, "stability.mdbm_p_points", 0, o->mdbm_p_points, 2, 5000, &mp,
                                  err)) ||
        (rc = rths_config_get_int(cfg, "stability.mdbm_refine", 0, o->mdbm_refine, 0, 8, &mr,
                                  err)) ||
        (rc = rths_config_get_int(cfg, "stability.chebyshev_nodes", 0, o->chebyshev_nodes, 4, 200,
                                  &cn, err)))
        return rc;
    if (!(o->tau_max_s > o->tau_min_s))
        return rths_config_error_at(cfg, "stability.tau_max_s", err,
                                    "must be above stability.tau_min_s (%g s), got %g s",
                                    o->tau_min_s, o->tau_max_s);
    if (!(o->p_max >= o->p_min))
        return rths_config_error_at(cfg, "stability.p_max", err,
                                    "must not be below stability.p_min (%g), got %g", o->p_min,
                                    o->p_max);
    if (!(o->omega_max_rad_s > o->omega_min_rad_s))
        return rths_config_error_at(cfg, "stability.omega_max_rad_s", err,
                                    "must be above stability.omega_min_rad_s (%g rad/s), got %g",
                                    o->omega_min_rad_s, o->omega_max_rad_s);
    if ((double)mt * (double)(pp > 1 ? mp : 1) * (double)wp > 5e7)
        return rths_config_error_at(cfg, "stability.omega_points", err,
                                    "the MDBM grid (%ld x %ld x %ld) is too large: keep "
                                    "mdbm_tau_points x mdbm_p_points x omega_points below 5e7",
                                    mt, mp, wp);
    o->tau_points = (int)tp, o->p_points = (int)pp, o->omega_points = (int)wp;
    o->mdbm_tau_points = (int)mt, o->mdbm_p_points = (int)mp, o->mdbm_refine = (int)mr;
    o->chebyshev_nodes = (int)cn;
    return RTHS_OK;
}

/* p where the essential bound changes sign along the chart's rows (linear interpolation of
 * ln-rates), NaN when it does not. */
double rths_api_chart_essential_limit(const rths_chart *c) {
    for (int j = 0; j + 1 < c->np; j++) {
        double a = c->essential_rate_times_tau[j], b = c->essential_rate_times_tau[j + 1];
        if (!isfinite(a) || !isfinite(b)) continue;
        if ((a < 0) != (b < 0)) return c->p[j] + (c->p[j + 1] - c->p[j]) * a / (a - b);
        if (a == 0) return c->p[j];
    }
    return NAN;
}

/* The chart's three tables, rows in the CLI's order (chart: p outer, tau inner). */
static int chart_tables(rths_result *r, const rths_chart *c, rths_error *err) {
    static const char *const h_chart[] = {"tau_s", "p", "max_real_part_per_s", "stable"};
    static const char *const h_bound[] = {"tau_s", "p", "omega_rad_s"};
    static const char *const h_crit[] = {"p", "critical_delay_s", "crossing_omega_rad_s"};
    size_t cells = (size_t)c->nt * (size_t)c->np;
    double *grid = calloc(4 * cells + 1, sizeof *grid);
    if (!grid) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int j = 0; j < c->np; j++)
        for (int i = 0; i < c->nt; i++) {
            size_t k = (size_t)i + (size_t)j * (size_t)c->nt;
            grid[k] = c->tau[i];
            grid[cells + k] = c->p[j];
            grid[2 * cells + k] = c->max_real[k];
            grid[3 * cells + k] = c->stable[k];
        }
    const double *d_chart[4] = {grid, grid + cells, grid + 2 * cells, grid + 3 * cells};
    const double *d_bound[3] = {c->b_tau, c->b_p, c->b_omega};
    const double *d_crit[3] = {c->p, c->critical_tau, c->critical_omega};
    int rc = rths_result_add_columns(r, "chart", (int)cells, 4, h_chart, d_chart, err);
    if (!rc) rc = rths_result_add_columns(r, "boundary", c->n_boundary, 3, h_bound, d_bound, err);
    if (!rc) rc = rths_result_add_columns(r, "critical", c->np, 3, h_crit, d_crit, err);
    free(grid);
    return rc;
}

static struct json_object *chart_summary(const rths_chart_options *o, const rths_chart *c) {
    json_object *root = rths_json_summary_new("chart");
    if (!root) return NULL;
    int n_stable = 0;
    for (int k = 0; k < c->nt * c->np; k++)
        n_stable += c->stable[k];
    double p_ess = rths_api_chart_essential_limit(c);
    json_object_object_add(root, "tau_points", json_object_new_int(o->tau_points));
    json_object_object_add(root, "p_points", json_object_new_int(o->p_points));
    json_object_object_add(root, "stable_points", json_object_new_int(n_stable));
    json_object_object_add(root, "boundary_points", json_object_new_int(c->n_boundary));
    json_object_object_add(root, "essential_spectrum_p_limit",
                           isfinite(p_ess) ? json_object_new_double(p_ess) : NULL);
    return root;
}

/* The split's interface damping / stiffness shares, which hold for every p (as the CLI). */
static int interface_shares(const rths_split *sp, double **cint, double **kint, rths_error *err) {
    int ni = sp->n_int;
    *cint = malloc((size_t)ni * ni * sizeof **cint);
    *kint = malloc((size_t)ni * ni * sizeof **kint);
    if (!*cint || !*kint) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < ni; i++)
        for (int j = 0; j < ni; j++) {
            (*cint)[i + j * ni] = RTHS_AT(sp->damping_phys, sp->np, sp->n_phys + i, sp->n_phys + j);
            (*kint)[i + j * ni] =
                RTHS_AT(sp->stiffness_phys, sp->np, sp->n_phys + i, sp->n_phys + j);
        }
    return RTHS_OK;
}

int rths_api_chart(const rths_api_config *cfg, const char *out_dir, rths_result **out,
                   rths_error *err) {
    *out = NULL;
    if (!cfg) return rths_error_set(err, RTHS_EINPUT, "no configuration given");
    static const char *const own[] = {"stability", NULL};
    rths_config *c;
    rths_setup setup;
    rths_chart_options o;
    rths_chart chart;
    int have_chart = 0;
    rths_result *r = NULL;
    double *cint = NULL, *kint = NULL;
    int rc = rths_api_load(cfg, &c, &setup, err);
    if (rc) return rc;
    if (!(rc = rths_api_chart_options_read(c, &o, err))) rc = rths_api_check_config(c, own, err);
    if (!rc) rc = interface_shares(&setup.split, &cint, &kint, err);
    if (!rc) {
        rths_split_family fam = {&setup.assembly, setup.roles, cint, kint};
        o.progress = 0;
        rc = rths_chart_compute(rths_split_family_build, &fam, &o, &chart, err);
        have_chart = !rc;
    }
    if (!rc) rc = rths_result_new(&r, err);
    if (!rc) rc = chart_tables(r, &chart, err);
    if (!rc) rc = rths_result_set_summary(r, chart_summary(&o, &chart), err);
    if (!rc && out_dir) rc = rths_result_write_folder(r, c, out_dir, "chart", err);
    if (have_chart) rths_chart_free(&chart);
    free(cint);
    free(kint);
    rths_api_unload(c, &setup);
    if (rc) {
        rths_result_free(r);
        return rc;
    }
    *out = r;
    return RTHS_OK;
}
