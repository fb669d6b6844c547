/* rths_api_frf: the FRF test (rths frf) behind the C API, a thin layer over the run module's
 * rths_run_frf (include/rths/run.h), which holds the test's orchestration for the CLI and the API
 * alike. Until that module is part of the library, rths_api_frf_available() is 0 and rths_api_frf
 * says so; the options and callbacks below are what rths_run_frf is given. */
#include "api/api_internal.h"

#include <string.h>

void rths_api_frf_options_default(rths_api_frf_options *o) {
    memset(o, 0, sizeof *o);
    o->strategy = "default";
}

int rths_api_frf_available(void) {
    return 0;
}

int rths_api_frf(const rths_api_config *cfg, const rths_api_frf_options *o, rths_result **out,
                 rths_error *err) {
    *out = NULL;
    if (!cfg || !o || !o->out_dir)
        return rths_error_set(err, RTHS_EINPUT, "rths_api_frf needs a configuration and out_dir");
    return rths_error_set(err, RTHS_EFAIL,
                          "this librths has no FRF run (the run module, include/rths/run.h, is "
                          "not built in)");
}
