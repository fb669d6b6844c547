/* The results of `rths model` in a summary: the same fields from the CLI and the C API. */
#include "rths/report.h"
#include "rths/setup.h"

#include <json-c/json.h>

void rths_summary_add_excitation(struct json_object *root, const rths_setup *s) {
    /* a base excitation has no forcing DoF, and its amplitude is the ground's acceleration, not
     * a force */
    if (s->base_excitation) {
        json_object_object_add(root, "excitation", json_object_new_string("base"));
        json_object_object_add(root, "base_acceleration_amplitude_m_s2",
                               json_object_new_double(s->forcing_amplitude_n));
    } else {
        json_object_object_add(root, "excitation", json_object_new_string("force"));
        json_object_object_add(root, "forcing_dof", json_object_new_int(s->forcing_dof + 1));
        json_object_object_add(root, "forcing_amplitude_n",
                               json_object_new_double(s->forcing_amplitude_n));
    }
}

void rths_model_summary_add(struct json_object *root, const rths_setup *s, const rths_modes *m,
                            int points, double peak_amp_m, double peak_hz) {
    json_object *modes = json_object_new_array();
    for (int r = 0; r < m->n; r++) {
        json_object *mode = json_object_new_object();
        json_object_object_add(mode, "mode", json_object_new_int(r + 1));
        json_object_object_add(mode, "frequency_hz", json_object_new_double(m->frequency_hz[r]));
        json_object_object_add(mode, "damping_ratio", json_object_new_double(m->damping_ratio[r]));
        json_object_array_add(modes, mode);
    }
    json_object_object_add(root, "config",
                           json_object_new_string(s->chain ? "storey chain" : "matrices"));
    json_object_object_add(root, "dofs", json_object_new_int(s->assembly.n));
    json_object_object_add(root, "mass_ratio", json_object_new_double(s->split.mass_ratio));
    json_object_object_add(root, "interface_dof", json_object_new_int(s->split.int_dofs[0] + 1));
    rths_summary_add_excitation(root, s);
    json_object_object_add(root, "modes", modes);
    json_object_object_add(root, "frf_points", json_object_new_int(points));
    json_object_object_add(root, "interface_peak_amplitude_m", json_object_new_double(peak_amp_m));
    json_object_object_add(root, "interface_peak_frequency_hz", json_object_new_double(peak_hz));
}
