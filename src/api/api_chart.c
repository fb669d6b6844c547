/* rths_api_chart: the stability chart of the delayed-feedback test as tables, the same numbers as
 * `rths chart` writes to chart.csv, boundary.csv and critical.csv. */
#include "api/api_internal.h"
#include "rths/stability.h"

#include <json-c/json.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

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
    double p_ess = rths_chart_essential_limit(c);
    json_object_object_add(root, "tau_points", json_object_new_int(o->tau_points));
    json_object_object_add(root, "p_points", json_object_new_int(o->p_points));
    json_object_object_add(root, "stable_points", json_object_new_int(n_stable));
    json_object_object_add(root, "boundary_points", json_object_new_int(c->n_boundary));
    json_object_object_add(root, "essential_spectrum_p_limit",
                           isfinite(p_ess) ? json_object_new_double(p_ess) : NULL);
    return root;
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
    rths_split_family fam;
    if (!(rc = rths_chart_config_read(c, &o, err))) rc = rths_api_check_config(c, own, err);
    if (!rc)
        rc = rths_split_family_of(&setup.assembly, setup.roles, &setup.split, &fam, &cint, &kint,
                                  err);
    if (!rc) {
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
