/* journal.jsonl: the durable record of a continuation run, from which --resume continues.
 * Each accepted point is one line, written with a single write(2) and fsync'ed, so a SIGKILL at any
 * moment leaves at worst a torn final line, which the reader ignores. */
#include "rths/continuation.h"

#include <errno.h>
#include <fcntl.h>
#include <json-c/json.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Formats (docs/journal.md): 2 kept the corrector's fields flat in each point record; 3 stores
 * the corrector's saved record (rths_corrector_save) as one list. Both are read. */
enum { JOURNAL_FORMAT = RTHS_JOURNAL_FORMAT, JOURNAL_FORMAT_FLAT_CORRECTOR = 2 };

struct rths_journal {
    int fd;
    char path[4096];
};

static void set_exact_doubles(void) {
    /* %.17g round-trips every double, so a resumed run continues from bit-identical state */
    json_c_set_serialization_double_format("%.17g", JSON_C_OPTION_GLOBAL);
}

static int write_line(rths_journal *j, json_object *obj, rths_error *err) {
    const char *text = json_object_to_json_string_ext(obj, JSON_C_TO_STRING_PLAIN);
    size_t len = strlen(text);
    char *line = malloc(len + 2);
    if (!line) return rths_error_set(err, RTHS_EFAIL, "out of memory writing the journal");
    memcpy(line, text, len);
    line[len] = '\n';
    /* one write(2) per record; a short one (the disk or the file size limit reached mid-record)
     * is continued, which either completes the record or fails with the errno that names the
     * cause (ENOSPC, EFBIG); the reader ignores the torn last line that leaves */
    size_t done = 0;
    int e = 0;
    while (done < len + 1) {
        ssize_t w = write(j->fd, line + done, len + 1 - done);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) {
            e = w < 0 ? errno : EIO;
            break;
        }
        done += (size_t)w;
    }
    free(line);
    if (!e && fsync(j->fd) != 0) e = errno;
    if (e && done > 0 && done < len + 1)
        return rths_error_set(err, RTHS_EFAIL,
                              "cannot write journal %s: %s (the record was cut after %zu of %zu "
                              "bytes)",
                              j->path, strerror(e), done, len + 1);
    if (e)
        return rths_error_set(err, RTHS_EFAIL, "cannot write journal %s: %s", j->path, strerror(e));
    return RTHS_OK;
}

int rths_journal_open(const char *path, const char *strategy, rths_journal **out, rths_error *err) {
    return rths_journal_open_seeded(path, strategy, NULL, out, err);
}

int rths_journal_open_seeded(const char *path, const char *strategy, const char *seed,
                             rths_journal **out, rths_error *err) {
    return rths_journal_open_run(path, strategy, seed, NULL, out, err);
}

int rths_journal_open_run(const char *path, const char *strategy, const char *seed, const char *rig,
                          rths_journal **out, rths_error *err) {
    set_exact_doubles();
    rths_journal *j = calloc(1, sizeof *j);
    if (!j) return rths_error_set(err, RTHS_EFAIL, "out of memory opening the journal");
    snprintf(j->path, sizeof j->path, "%s", path);
    int existed = access(path, F_OK) == 0;
    j->fd = open(path, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (j->fd < 0) {
        int e = errno;
        free(j);
        return rths_error_set(err, RTHS_EFAIL, "cannot open journal %s: %s", path, strerror(e));
    }
    if (!existed) {
        json_object *h = json_object_new_object();
        json_object_object_add(h, "type", json_object_new_string("header"));
        json_object_object_add(h, "format", json_object_new_int(JOURNAL_FORMAT));
        json_object_object_add(h, "strategy", json_object_new_string(strategy));
        json_object_object_add(h, "version", json_object_new_string(RTHS_VERSION));
        json_object_object_add(h, "seed", seed ? json_object_new_string(seed) : NULL);
        if (rig) json_object_object_add(h, "rig", json_object_new_string(rig));
        int rc = write_line(j, h, err);
        json_object_put(h);
        if (rc) {
            rths_journal_close(j);
            return rc;
        }
    }
    *out = j;
    return RTHS_OK;
}

void rths_journal_close(rths_journal *j) {
    if (!j) return;
    if (j->fd >= 0) close(j->fd);
    free(j);
}

static json_object *dbl_array(const double *v, int n) {
    json_object *a = json_object_new_array();
    for (int i = 0; i < n; i++)
        json_object_array_add(a, json_object_new_double(v[i]));
    return a;
}

static void add_fourier(json_object *o, const char *name, const rths_fourier *f, int harmonics) {
    char key[64];
    snprintf(key, sizeof key, "%s_a", name);
    json_object_object_add(o, key, dbl_array(f->a, harmonics + 1));
    snprintf(key, sizeof key, "%s_b", name);
    json_object_object_add(o, key, dbl_array(f->b, harmonics + 1));
}

/* Several interface DoFs' fields of a point (dofs > 1): every DoF's coefficients one after
 * another (RTHS_MAX_HARMONICS + 1 per DoF) and the reported amplitudes. */
static void add_dof_fouriers(json_object *o, const char *name, const rths_fourier *f, int dofs) {
    enum { H = RTHS_MAX_HARMONICS + 1 };
    double a[RTHS_MAX_INTERFACE_DOFS * H], b[RTHS_MAX_INTERFACE_DOFS * H];
    for (int d = 0; d < dofs; d++) {
        memcpy(a + d * H, f[d].a, sizeof(double) * H);
        memcpy(b + d * H, f[d].b, sizeof(double) * H);
    }
    char key[64];
    snprintf(key, sizeof key, "%s_a", name);
    json_object_object_add(o, key, dbl_array(a, dofs * H));
    snprintf(key, sizeof key, "%s_b", name);
    json_object_object_add(o, key, dbl_array(b, dofs * H));
}

static void add_interface_dofs(json_object *o, const rths_solution *s) {
    const rths_evaluation *e = &s->eval;
    int dofs = e->interface_dofs;
    if (dofs <= 1 || dofs > RTHS_MAX_INTERFACE_DOFS) return;
    json_object_object_add(o, "interface_dofs", json_object_new_int(dofs));
    add_dof_fouriers(o, "phys_dof", e->phys_dof, dofs);
    add_dof_fouriers(o, "num_dof", e->num_dof, dofs);
    add_dof_fouriers(o, "phys_dof_se", e->phys_dof_se, dofs);
    add_dof_fouriers(o, "num_dof_se", e->num_dof_se, dofs);
    if (s->interface_dofs == dofs) {
        json_object_object_add(o, "dof_amplitude_m", dbl_array(s->dof_amplitude_m, dofs));
        json_object_object_add(o, "dof_amplitude_se_m", dbl_array(s->dof_amplitude_se_m, dofs));
    }
}

int rths_journal_append(rths_journal *j, const rths_point *pt, int is_update, rths_error *err) {
    const rths_solution *s = &pt->sol;
    const rths_evaluation *e = &s->eval;
    int N = s->harmonics;
    json_object *o = json_object_new_object();
    json_object_object_add(o, "type", json_object_new_string(is_update ? "update" : "point"));
    json_object_object_add(o, "index", json_object_new_int(pt->index));
    json_object_object_add(o, "harmonics", json_object_new_int(N));
    json_object_object_add(o, "omega_rad_s", json_object_new_double(s->omega_rad_s));
    json_object_object_add(o, "frequency_hz", json_object_new_double(e->frequency_hz));
    json_object_object_add(o, "target_a_m", dbl_array(s->target_a, N));
    json_object_object_add(o, "target_b_m", dbl_array(s->target_b, N));
    add_fourier(o, "phys", &e->phys, RTHS_MAX_HARMONICS);
    add_fourier(o, "num", &e->num, RTHS_MAX_HARMONICS);
    add_fourier(o, "phys_se", &e->phys_se, RTHS_MAX_HARMONICS);
    add_fourier(o, "num_se", &e->num_se, RTHS_MAX_HARMONICS);
    json_object_object_add(o, "eval_rig_time_s", json_object_new_double(e->rig_time_s));
    json_object_object_add(o, "wait_periods", json_object_new_int(e->wait_periods));
    json_object_object_add(o, "average_periods", json_object_new_int(e->average_periods));
    json_object_object_add(o, "steady", json_object_new_int(e->steady));
    json_object_object_add(o, "residual_norm_m", json_object_new_double(s->residual_norm_m));
    json_object_object_add(o, "tolerance_m", json_object_new_double(s->tolerance_m));
    json_object_object_add(o, "converged", json_object_new_int(s->converged));
    json_object_object_add(o, "evaluations", json_object_new_int(pt->evaluations));
    json_object_object_add(o, "iterations", json_object_new_int(pt->iterations));
    json_object_object_add(o, "rig_time_s", json_object_new_double(pt->rig_time_s));
    json_object_object_add(o, "fold", json_object_new_int(pt->fold));
    json_object_object_add(o, "segment", json_object_new_int(pt->segment));
    json_object_object_add(o, "step", json_object_new_double(pt->step));
    json_object_object_add(o, "secant_omega", json_object_new_double(pt->secant_omega));
    json_object_object_add(o, "corrector_format", json_object_new_int(pt->corrector.format));
    json_object_object_add(o, "corrector_state",
                           dbl_array(pt->corrector.data, pt->corrector.length));
    json_object_object_add(o, "have_matched", json_object_new_int(s->have_matched));
    json_object_object_add(o, "matched_a_m", dbl_array(s->matched_a, N));
    json_object_object_add(o, "matched_b_m", dbl_array(s->matched_b, N));
    json_object_object_add(o, "matched_amplitude_m",
                           json_object_new_double(s->matched_amplitude_m));
    json_object_object_add(o, "matched_amplitude_se_m",
                           json_object_new_double(s->matched_amplitude_se_m));
    json_object_object_add(o, "matched_omega_rad_s",
                           json_object_new_double(s->matched_omega_rad_s));
    json_object_object_add(o, "reported_frequency_hz", json_object_new_double(s->frequency_hz));
    json_object_object_add(o, "amplitude_m", json_object_new_double(s->amplitude_m));
    json_object_object_add(o, "amplitude_se_m", json_object_new_double(s->amplitude_se_m));
    json_object_object_add(o, "amplitude_se_honest", json_object_new_int(s->amplitude_se_honest));
    add_interface_dofs(o, s);
    /* the accepted evaluation's integrity counts (iterate.h), and the resume mark (optional on
     * reading: docs/journal.md) */
    const rths_evaluation *acc = &pt->residual.eval;
    json_object_object_add(o, "late_samples", json_object_new_int64(acc->late_samples));
    json_object_object_add(o, "clipped_demand_samples",
                           json_object_new_int64(acc->clipped_demand_samples));
    json_object_object_add(o, "saturated_sensor_samples",
                           json_object_new_int64(acc->saturated_sensor_samples));
    json_object_object_add(o, "samples_read", json_object_new_int64(acc->samples_read));
    if (pt->resumed) json_object_object_add(o, "resumed", json_object_new_int(1));
    /* how the accepted evaluation reached steady state, and the point's evaluations all
     * together (rths_point.settle; optional on reading: docs/journal.md) */
    json_object_object_add(o, "eval_fitted", json_object_new_int(e->fitted));
    json_object_object_add(o, "eval_fit_fallback", json_object_new_int(e->fit_fallback));
    json_object_object_add(o, "eval_fit_order", json_object_new_int(e->fit_order));
    json_object_object_add(o, "eval_fit_max_pole", json_object_new_double(e->fit_max_pole));
    json_object_object_add(o, "eval_amplitude_rel_se", json_object_new_double(e->amplitude_rel_se));
    json_object_object_add(o, "eval_se_target_missed", json_object_new_int(e->se_target_missed));
    const rths_settle_tally *t = &pt->settle;
    json_object_object_add(o, "settle_evaluations", json_object_new_int(t->evaluations));
    json_object_object_add(o, "fitted_evaluations", json_object_new_int(t->fitted));
    json_object_object_add(o, "fit_fallback_evaluations", json_object_new_int(t->fit_fallbacks));
    json_object_object_add(o, "se_target_missed_evaluations",
                           json_object_new_int(t->se_target_missed));
    json_object_object_add(o, "settle_rig_time_s", json_object_new_double(t->rig_time_s));
    if (t->fallback_reason[0])
        json_object_object_add(o, "fit_fallback_reason",
                               json_object_new_string(t->fallback_reason));
    if (pt->sol.below_noise_floor)
        json_object_object_add(o, "below_noise_floor", json_object_new_int(1));
    int rc = write_line(j, o, err);
    json_object_put(o);
    return rc;
}

int rths_journal_append_resume(rths_journal *j, int n_points, const char *const *changes,
                               int n_changes, rths_error *err) {
    json_object *o = json_object_new_object(), *list = json_object_new_array();
    json_object_object_add(o, "type", json_object_new_string("resume"));
    json_object_object_add(o, "after_points", json_object_new_int(n_points));
    for (int i = 0; i < n_changes; i++)
        json_object_array_add(list, json_object_new_string(changes[i]));
    json_object_object_add(o, "changed", list);
    int rc = write_line(j, o, err);
    json_object_put(o);
    return rc;
}

/* ---- reading ---- */

/* What a record's key holds, for messages: "absent", "null", "a number", ... */
static const char *json_type_text(json_object *o, const char *key) {
    json_object *v;
    if (!json_object_object_get_ex(o, key, &v)) return "absent";
    switch (json_object_get_type(v)) {
    case json_type_null:
        return "null";
    case json_type_boolean:
        return "a boolean";
    case json_type_double:
    case json_type_int:
        return "a number";
    case json_type_object:
        return "an object";
    case json_type_array:
        return "a list";
    case json_type_string:
        return "a string";
    }
    return "of an unknown type";
}

int rths_journal_read_seed(const char *path, int *known, char **seed, rths_error *err) {
    return rths_journal_read_header_text(path, "seed", known, seed, err);
}

int rths_journal_read_header_text(const char *path, const char *key, int *known, char **seed,
                                  rths_error *err) {
    *known = 0;
    *seed = NULL;
    FILE *f = fopen(path, "r");
    if (!f)
        return rths_error_set(err, RTHS_EINPUT, "cannot read journal %s: %s", path,
                              strerror(errno));
    char *line = NULL;
    size_t cap = 0;
    json_object *h = getline(&line, &cap, f) > 0 ? json_tokener_parse(line) : NULL, *v;
    free(line);
    fclose(f);
    int rc = RTHS_OK;
    if (h && json_object_object_get_ex(h, key, &v)) {
        *known = 1;
        if (v && !json_object_is_type(v, json_type_string))
            rc = rths_error_set(err, RTHS_EINPUT,
                                "%s:1: header key '%s' is %s; expected a string or null", path, key,
                                json_type_text(h, key));
        else if (v && !(*seed = strdup(json_object_get_string(v))))
            rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    if (h) json_object_put(h);
    return rc;
}

/* The key a field reader last refused (absent, null or of the wrong type), for the message
 * naming it; per thread, as several runs may read journals at once (the C API). A copy: a key
 * may be composed in a reader's stack buffer ("phys_a") that is gone when the message is made. */
static _Thread_local char bad_key[64];

static int refuse(const char *key) {
    if (key != bad_key) snprintf(bad_key, sizeof bad_key, "%s", key);
    return -1;
}

static int get_dbl(json_object *o, const char *key, double *out) {
    json_object *v;
    if (!json_object_object_get_ex(o, key, &v)) return refuse(key);
    if (!json_object_is_type(v, json_type_double) && !json_object_is_type(v, json_type_int))
        return refuse(key);
    *out = json_object_get_double(v);
    return 0;
}

static int get_int(json_object *o, const char *key, int *out) {
    json_object *v;
    if (!json_object_object_get_ex(o, key, &v) || !json_object_is_type(v, json_type_int))
        return refuse(key);
    *out = json_object_get_int(v);
    return 0;
}

/* An optional integer count (added within format 3): absent reads as 0; present, it must be a
 * non-negative integer. */
static int get_count(json_object *o, const char *key, long *out) {
    json_object *v;
    *out = 0;
    if (!json_object_object_get_ex(o, key, &v)) return 0;
    if (!json_object_is_type(v, json_type_int) || json_object_get_int64(v) < 0) return refuse(key);
    *out = (long)json_object_get_int64(v);
    return 0;
}

static int get_arr(json_object *o, const char *key, double *out, int n) {
    json_object *v;
    if (!json_object_object_get_ex(o, key, &v) || !json_object_is_type(v, json_type_array) ||
        (int)json_object_array_length(v) != n)
        return refuse(key);
    for (int i = 0; i < n; i++) {
        json_object *x = json_object_array_get_idx(v, (size_t)i);
        if (!json_object_is_type(x, json_type_double) && !json_object_is_type(x, json_type_int))
            return refuse(key);
        out[i] = json_object_get_double(x);
    }
    return 0;
}

static int get_fourier(json_object *o, const char *name, rths_fourier *f, int harmonics) {
    char key[64];
    snprintf(key, sizeof key, "%s_a", name);
    if (get_arr(o, key, f->a, harmonics + 1)) return -1;
    snprintf(key, sizeof key, "%s_b", name);
    return get_arr(o, key, f->b, harmonics + 1);
}

static int get_dof_fouriers(json_object *o, const char *name, rths_fourier *f, int dofs) {
    enum { H = RTHS_MAX_HARMONICS + 1 };
    double a[RTHS_MAX_INTERFACE_DOFS * H], b[RTHS_MAX_INTERFACE_DOFS * H];
    char key[64];
    snprintf(key, sizeof key, "%s_a", name);
    if (get_arr(o, key, a, dofs * H)) return -1;
    snprintf(key, sizeof key, "%s_b", name);
    if (get_arr(o, key, b, dofs * H)) return -1;
    for (int d = 0; d < dofs; d++) {
        memcpy(f[d].a, a + d * H, sizeof(double) * H);
        memcpy(f[d].b, b + d * H, sizeof(double) * H);
    }
    return 0;
}

/* Added within format 3: several interface DoFs' fields; a record without them has one. */
static int get_interface_dofs(json_object *o, rths_solution *s) {
    rths_evaluation *e = &s->eval;
    json_object *v;
    if (!json_object_object_get_ex(o, "interface_dofs", &v)) return 0;
    int dofs = 0;
    if (get_int(o, "interface_dofs", &dofs) || dofs < 2 || dofs > RTHS_MAX_INTERFACE_DOFS ||
        get_dof_fouriers(o, "phys_dof", e->phys_dof, dofs) ||
        get_dof_fouriers(o, "num_dof", e->num_dof, dofs) ||
        get_dof_fouriers(o, "phys_dof_se", e->phys_dof_se, dofs) ||
        get_dof_fouriers(o, "num_dof_se", e->num_dof_se, dofs))
        return -1;
    if (s->harmonics % dofs) return -1;
    e->interface_dofs = dofs;
    e->harmonics = s->harmonics / dofs; /* the solution's harmonics count (DoF, harmonic) pairs */
    if (!json_object_object_get_ex(o, "dof_amplitude_m", &v)) return 0;
    s->interface_dofs = dofs;
    return get_arr(o, "dof_amplitude_m", s->dof_amplitude_m, dofs) ||
                   get_arr(o, "dof_amplitude_se_m", s->dof_amplitude_se_m, dofs)
               ? -1
               : 0;
}

/* Format 3: the corrector's saved record as written. */
static int get_corrector(json_object *o, rths_corrector_saved *c) {
    json_object *v;
    if (get_int(o, "corrector_format", &c->format) ||
        !json_object_object_get_ex(o, "corrector_state", &v) ||
        !json_object_is_type(v, json_type_array))
        return -1;
    c->length = (int)json_object_array_length(v);
    if (c->length > RTHS_CORRECTOR_SAVED_MAX) return -1;
    return get_arr(o, "corrector_state", c->data, c->length);
}

/* Format 2: the same numbers as flat keys of the point record, gathered into the saved record's
 * layout (format 1 of the corrector state, docs/journal.md). */
enum { W = 2 * RTHS_MAX_HARMONICS, LD2 = RTHS_MAX_UNKNOWNS * RTHS_MAX_UNKNOWNS };
static int get_flat_corrector(json_object *o, int harmonics, rths_corrector_saved *c) {
    int have = 0, lti = 0, count = 0, next = 0;
    double *d = c->data, omega[RTHS_LTI_HISTORY], hist[3][RTHS_LTI_HISTORY * W];
    if (get_int(o, "have_jacobian", &have) || get_int(o, "lti", &lti) ||
        get_arr(o, "jacobian", d + 4, LD2) || get_arr(o, "response_jacobian", d + 4 + LD2, LD2) ||
        get_arr(o, "noise_ss_phys", d + 4 + 2 * LD2, RTHS_MAX_UNKNOWNS) ||
        get_arr(o, "noise_ss_num", d + 4 + 2 * LD2 + RTHS_MAX_UNKNOWNS, RTHS_MAX_UNKNOWNS) ||
        get_dbl(o, "noise_dof", d + 4 + 2 * LD2 + 2 * RTHS_MAX_UNKNOWNS) ||
        get_int(o, "history_count", &count) || get_int(o, "history_next", &next) ||
        get_arr(o, "history_omega_rad_s", omega, RTHS_LTI_HISTORY) ||
        get_arr(o, "history_target_m", hist[0], RTHS_LTI_HISTORY * W) ||
        get_arr(o, "history_phi_m", hist[1], RTHS_LTI_HISTORY * W) ||
        get_arr(o, "history_response_m", hist[2], RTHS_LTI_HISTORY * W))
        return -1;
    double head[4] = {have, lti, 2 * harmonics, harmonics};
    memcpy(d, head, sizeof head);
    double *ring = d + 4 + 2 * LD2 + 2 * RTHS_MAX_UNKNOWNS + 1;
    ring[0] = count;
    ring[1] = next;
    for (int e = 0; e < RTHS_LTI_HISTORY; e++) {
        double *h = ring + 2 + e * (1 + 3 * W);
        h[0] = omega[e];
        for (int q = 0; q < 3; q++)
            memcpy(h + 1 + q * W, hist[q] + e * W, sizeof(double) * W);
    }
    c->format = RTHS_CORRECTOR_SAVED_FORMAT;
    c->length = (int)(ring + 2 + RTHS_LTI_HISTORY * (1 + 3 * W) - d);
    return 0;
}

/* An optional number (added within format 3): absent reads as 0. */
static int get_opt_dbl(json_object *o, const char *key, double *out) {
    json_object *v;
    *out = 0;
    return json_object_object_get_ex(o, key, &v) ? get_dbl(o, key, out) : 0;
}

/* Added within format 3, optional (absent: 0, a journal that said nothing of it): how the
 * accepted evaluation and the point's evaluations reached steady state. */
static int get_settle(json_object *o, rths_point *pt) {
    rths_evaluation *e = &pt->sol.eval;
    rths_settle_tally *t = &pt->settle;
    long v[9];
    static const char *const keys[9] = {"eval_fitted",
                                        "eval_fit_fallback",
                                        "eval_se_target_missed",
                                        "eval_fit_order",
                                        "settle_evaluations",
                                        "fitted_evaluations",
                                        "fit_fallback_evaluations",
                                        "se_target_missed_evaluations",
                                        NULL};
    for (int i = 0; keys[i]; i++)
        if (get_count(o, keys[i], &v[i]) || v[i] > 1000000 || (i < 3 && v[i] > 1))
            return refuse(keys[i]);
    e->fitted = (int)v[0], e->fit_fallback = (int)v[1], e->se_target_missed = (int)v[2];
    e->fit_order = (int)v[3];
    t->evaluations = (int)v[4], t->fitted = (int)v[5], t->fit_fallbacks = (int)v[6];
    t->se_target_missed = (int)v[7];
    if (get_opt_dbl(o, "eval_fit_max_pole", &e->fit_max_pole) ||
        get_opt_dbl(o, "eval_amplitude_rel_se", &e->amplitude_rel_se) ||
        get_opt_dbl(o, "settle_rig_time_s", &t->rig_time_s))
        return -1;
    json_object *r;
    if (json_object_object_get_ex(o, "fit_fallback_reason", &r)) {
        if (!json_object_is_type(r, json_type_string)) return refuse("fit_fallback_reason");
        snprintf(t->fallback_reason, sizeof t->fallback_reason, "%s", json_object_get_string(r));
    }
    return 0;
}

static int parse_point(json_object *o, int format, rths_point *pt) {
    memset(pt, 0, sizeof *pt);
    rths_solution *s = &pt->sol;
    rths_evaluation *e = &s->eval;
    int N;
    if (get_int(o, "index", &pt->index) || get_int(o, "harmonics", &N) || N < 1 ||
        N > RTHS_MAX_HARMONICS)
        return -1;
    s->harmonics = e->harmonics = N;
    if (get_dbl(o, "omega_rad_s", &s->omega_rad_s) ||
        get_dbl(o, "frequency_hz", &e->frequency_hz) || get_arr(o, "target_a_m", s->target_a, N) ||
        get_arr(o, "target_b_m", s->target_b, N) ||
        get_fourier(o, "phys", &e->phys, RTHS_MAX_HARMONICS) ||
        get_fourier(o, "num", &e->num, RTHS_MAX_HARMONICS) ||
        get_fourier(o, "phys_se", &e->phys_se, RTHS_MAX_HARMONICS) ||
        get_fourier(o, "num_se", &e->num_se, RTHS_MAX_HARMONICS) ||
        get_dbl(o, "eval_rig_time_s", &e->rig_time_s) ||
        get_int(o, "wait_periods", &e->wait_periods) ||
        get_int(o, "average_periods", &e->average_periods) || get_int(o, "steady", &e->steady) ||
        get_dbl(o, "residual_norm_m", &s->residual_norm_m) ||
        get_dbl(o, "tolerance_m", &s->tolerance_m) || get_int(o, "converged", &s->converged) ||
        get_int(o, "evaluations", &pt->evaluations) || get_int(o, "iterations", &pt->iterations) ||
        get_dbl(o, "rig_time_s", &pt->rig_time_s) || get_int(o, "fold", &pt->fold) ||
        get_int(o, "segment", &pt->segment) || get_dbl(o, "step", &pt->step) ||
        get_dbl(o, "secant_omega", &pt->secant_omega) ||
        (format == JOURNAL_FORMAT_FLAT_CORRECTOR ? get_flat_corrector(o, N, &pt->corrector)
                                                 : get_corrector(o, &pt->corrector)) ||
        get_int(o, "have_matched", &s->have_matched) ||
        get_arr(o, "matched_a_m", s->matched_a, N) || get_arr(o, "matched_b_m", s->matched_b, N) ||
        get_dbl(o, "matched_amplitude_m", &s->matched_amplitude_m) ||
        get_dbl(o, "matched_amplitude_se_m", &s->matched_amplitude_se_m) ||
        get_dbl(o, "matched_omega_rad_s", &s->matched_omega_rad_s) ||
        get_dbl(o, "reported_frequency_hz", &s->frequency_hz) ||
        get_dbl(o, "amplitude_m", &s->amplitude_m) ||
        get_dbl(o, "amplitude_se_m", &s->amplitude_se_m) || get_interface_dofs(o, s))
        return -1;
    /* added within format 3, optional (absent: 0): a journal without amplitude_se_honest makes
     * no claim for its standard errors; the integrity counts of the accepted evaluation; whether
     * a resumed run measured the point; whether it was accepted below the noise floor (--force) */
    long honest = 0, resumed = 0, below = 0;
    if (get_count(o, "below_noise_floor", &below) || below > 1)
        return refuse(below > 1 ? "below_noise_floor" : bad_key);
    s->below_noise_floor = (int)below;
    if (get_count(o, "amplitude_se_honest", &honest) || honest > 1 ||
        get_count(o, "late_samples", &e->late_samples) ||
        get_count(o, "clipped_demand_samples", &e->clipped_demand_samples) ||
        get_count(o, "saturated_sensor_samples", &e->saturated_sensor_samples) ||
        get_count(o, "samples_read", &e->samples_read) || get_count(o, "resumed", &resumed) ||
        resumed > 1)
        return refuse(honest > 1 ? "amplitude_se_honest" : resumed > 1 ? "resumed" : bad_key);
    s->amplitude_se_honest = (int)honest;
    pt->resumed = (int)resumed;
    if (get_settle(o, pt)) return -1;
    rths_residual_from_evaluation(e, &pt->residual);
    return 0;
}

/* Reading state: where we are, the format from the header, the points so far. */
typedef struct {
    const char *path;
    int lineno;
    int complete; /* the line ends in a newline (else: a torn final record) */
    int format;   /* from the header; 0 before it */
    rths_point *pts;
    int n, alloc;
    char **strategy;
} journal_reader;

enum { READ_ON = 0, READ_TORN = -1 }; /* or an error code */

static int read_header(journal_reader *r, json_object *o, rths_error *err) {
    json_object *s;
    int format = 0;
    if (get_int(o, "format", &format) ||
        (format != JOURNAL_FORMAT && format != JOURNAL_FORMAT_FLAT_CORRECTOR))
        return rths_error_set(err, RTHS_EINPUT,
                              "%s:%d: journal format %d, this rths reads formats %d and %d: "
                              "start a new run in another folder",
                              r->path, r->lineno, format, JOURNAL_FORMAT_FLAT_CORRECTOR,
                              JOURNAL_FORMAT);
    r->format = format;
    /* the strategy names the run's kind: a header without it as a string (absent, null, a
     * number) is refused, as a resume or a view could not tell what the points mean */
    if (!json_object_object_get_ex(o, "strategy", &s) || !json_object_is_type(s, json_type_string))
        return rths_error_set(err, RTHS_EINPUT,
                              "%s:%d: header key 'strategy' is %s; expected \"default\" or "
                              "\"paper\"",
                              r->path, r->lineno, json_type_text(o, "strategy"));
    if (r->strategy) {
        free(*r->strategy);
        *r->strategy = strdup(json_object_get_string(s));
        if (!*r->strategy) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    return READ_ON;
}

static int read_point(journal_reader *r, json_object *o, int is_update, rths_error *err) {
    rths_point pt;
    if (r->format == 0)
        return rths_error_set(err, RTHS_EINPUT, "%s:%d: point record before the header", r->path,
                              r->lineno);
    bad_key[0] = '\0';
    if (parse_point(o, r->format, &pt)) {
        if (!r->complete) return READ_TORN;
        if (bad_key[0])
            return rths_error_set(err, RTHS_EINPUT,
                                  "%s:%d: malformed point record: key '%s' is %s or out of range",
                                  r->path, r->lineno, bad_key, json_type_text(o, bad_key));
        return rths_error_set(err, RTHS_EINPUT, "%s:%d: malformed point record", r->path,
                              r->lineno);
    }
    if ((!is_update && pt.index != r->n) || (is_update && (pt.index < 0 || pt.index >= r->n)))
        return rths_error_set(err, RTHS_EINPUT,
                              "%s:%d: point %d out of sequence (expected %d): the journal has "
                              "gaps or duplicates",
                              r->path, r->lineno, pt.index, r->n);
    if (is_update) {
        r->pts[pt.index] = pt;
        return READ_ON;
    }
    if (r->n == r->alloc) {
        int alloc = r->alloc ? 2 * r->alloc : 64;
        rths_point *grown = realloc(r->pts, (size_t)alloc * sizeof *grown);
        if (!grown) return rths_error_set(err, RTHS_EFAIL, "out of memory reading the journal");
        r->pts = grown;
        r->alloc = alloc;
    }
    r->pts[r->n++] = pt;
    return READ_ON;
}

static int read_record(journal_reader *r, const char *line, rths_error *err) {
    json_object *o = json_tokener_parse(line), *t;
    const char *type = NULL;
    if (o && json_object_object_get_ex(o, "type", &t) && json_object_is_type(t, json_type_string))
        type = json_object_get_string(t);
    int rc = READ_ON;
    if (!o || !type) /* a torn final record: the kill came mid-write */
        rc = !r->complete ? READ_TORN
                          : rths_error_set(err, RTHS_EINPUT,
                                           "%s:%d: not a journal record (key 'type' is %s; "
                                           "expected a string)",
                                           r->path, r->lineno,
                                           o && json_object_is_type(o, json_type_object)
                                               ? json_type_text(o, "type")
                                               : "absent");
    else if (!strcmp(type, "header"))
        rc = read_header(r, o, err);
    else if (!strcmp(type, "point") || !strcmp(type, "update"))
        rc = read_point(r, o, !strcmp(type, "update"), err);
    if (o) json_object_put(o);
    return rc;
}

int rths_journal_read(const char *path, rths_point **points, int *n_points, char **strategy,
                      rths_error *err) {
    *points = NULL;
    *n_points = 0;
    if (strategy) *strategy = NULL;
    FILE *f = fopen(path, "r");
    if (!f)
        return rths_error_set(err, RTHS_EINPUT, "cannot read journal %s: %s", path,
                              strerror(errno));
    journal_reader r = {.path = path, .strategy = strategy};
    char *line = NULL;
    size_t cap = 0;
    ssize_t len;
    int rc = READ_ON;
    while (rc == READ_ON && (len = getline(&line, &cap, f)) > 0) {
        r.lineno++;
        r.complete = line[len - 1] == '\n';
        rc = read_record(&r, line, err);
    }
    free(line);
    fclose(f);
    if (rc > 0) {
        free(r.pts);
        if (strategy) free(*strategy), *strategy = NULL;
        return rc;
    }
    *points = r.pts;
    *n_points = r.n;
    return RTHS_OK;
}
