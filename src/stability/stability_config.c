/* The stability section of the configuration (docs/config/stability.md): the chart's grid, the
 * MDBM boundary search and the spectral discretisation, read with the configuration's getters so
 * every refusal is located. */
#include "rths/stability.h"

int rths_chart_config_read(rths_config *cfg, rths_chart_options *o, rths_error *err) {
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
    /* the MDBM grid's cells are evaluated one by one: bound the work and the memory */
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
