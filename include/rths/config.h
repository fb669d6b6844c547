/* rths configuration: one YAML file per test (libfyaml), with --set dotted.key=value overrides.
 *
 * Every getter takes a dotted key ("split.mass_ratio", "structure.masses") and marks it as known.
 * A missing optional key leaves the default; a present key of the wrong type or out of range fails
 * with RTHS_EINPUT and a message "FILE:LINE:COL: key 'a.b': what is wrong" (for a value that came
 * from --set, the location reads "--set a.b=..."). After all section readers have run,
 * rths_config_check_unknown() refuses any key nobody asked for, so typos never pass silently. */
#ifndef RTHS_CONFIG_H
#define RTHS_CONFIG_H

#include "rths/core.h"

typedef struct rths_config rths_config;

/* Mappings and lists nest at most this deep (a configuration needs about five levels); deeper
 * input, from the file or a --set, is refused with its location instead of exhausting the stack. */
#define RTHS_CONFIG_MAX_DEPTH 64

/* Loads path (NULL: an empty document, so everything takes defaults), then applies each override
 * "dotted.key=value" in order; value is parsed as a YAML flow scalar/sequence ("0.33", "[1, 2]").
 */
int rths_config_load(const char *path, const char *const *overrides, int n_overrides,
                     rths_config **out, rths_error *err);
void rths_config_free(rths_config *cfg);
const char *rths_config_path(const rths_config *cfg);

int rths_config_has(const rths_config *cfg, const char *key);

/* Inclusive range [lo, hi]; pass -INFINITY / INFINITY for no bound. NaN and inf are refused. */
int rths_config_get_double(rths_config *cfg, const char *key, int required, double def, double lo,
                           double hi, double *out, rths_error *err);
/* The same with open bounds where flagged: RTHS_CONFIG_LO_OPEN gives lo < x ("must be > 0"). */
enum { RTHS_CONFIG_LO_OPEN = 1, RTHS_CONFIG_HI_OPEN = 2 };
int rths_config_get_double_ex(rths_config *cfg, const char *key, int required, double def,
                              double lo, double hi, unsigned flags, double *out, rths_error *err);
/* The range [lo, hi] (with flags' open ends) as the getters word it, one style for every message:
 * "in [0, 1]", "in (0, 1)", ">= 0", "> 0", "<= 100000", "< 1". Returns buf. */
const char *rths_config_range_text(double lo, double hi, unsigned flags, char *buf, size_t size);
int rths_config_get_int(rths_config *cfg, const char *key, int required, long def, long lo, long hi,
                        long *out, rths_error *err);
int rths_config_get_bool(rths_config *cfg, const char *key, int required, int def, int *out,
                         rths_error *err);
/* *out points into the config (valid until rths_config_free). */
int rths_config_get_string(rths_config *cfg, const char *key, int required, const char *def,
                           const char **out, rths_error *err);
/* choices is NULL-terminated; *out_index is the index of the match (def_index when absent). */
int rths_config_get_choice(rths_config *cfg, const char *key, int required, int def_index,
                           const char *const *choices, int *out_index, rths_error *err);
/* Sequence of numbers; *out is malloc'ed (caller frees), *count its length (0 when absent). */
int rths_config_get_double_list(rths_config *cfg, const char *key, int required, double **out,
                                int *count, rths_error *err);
int rths_config_get_int_list(rths_config *cfg, const char *key, int required, int **out, int *count,
                             rths_error *err);
/* Sequence of equal-length rows of numbers -> column-major matrix (caller frees). */
int rths_config_get_matrix(rths_config *cfg, const char *key, int required, double **out, int *rows,
                           int *cols, rths_error *err);
/* Marks a whole subtree as known (for sections read by a component not linked in this command);
 * NULL or "" marks the whole document. */
/* Lists of mappings (rig.sites, structure.nonlinear): *count items (0 when the key is absent or
 * empty), read one by one through keys with the item's index, "rig.sites.0.uri"; an index is a
 * key part everywhere (getters, rths_config_error_at, --set). Not a list: a located error. */
int rths_config_get_count(rths_config *cfg, const char *key, int *count, rths_error *err);
void rths_config_mark_known(rths_config *cfg, const char *key_prefix);

/* A semantic error about a key that exists (e.g. "matrix is not symmetric"): the message is
 * prefixed with the key's location exactly like the getters' errors. Returns RTHS_EINPUT. */
int rths_config_error_at(const rths_config *cfg, const char *key, rths_error *err, const char *fmt,
                         ...) __attribute__((format(printf, 4, 5)));

/* Whether some getter asked for a key under section (e.g. "rig": any "rig.*"), present or not:
 * the section's reader ran in this program. */
int rths_config_section_read(const rths_config *cfg, const char *section);

/* Fails on the first key in the document that no getter asked for. */
int rths_config_check_unknown(const rths_config *cfg, rths_error *err);

/* The check every command and API entry runs after its readers: rths_config_check_unknown, with
 * each of the project's optional sections (rig, controller, iteration, continuation, stability,
 * fidelity, output, server, io) accepted whole only when no reader in this program asked for any of
 * its keys and it is not listed in own (NULL-terminated, may be NULL). Once a reader asked for
 * one of a section's keys, a key it did not ask for is a typo that would otherwise change
 * nothing, silently. */
int rths_config_check_sections(rths_config *cfg, const char *const *own, rths_error *err);

/* Writes the document as resolved (overrides applied) as YAML, to a temp file then rename. */
int rths_config_write(const rths_config *cfg, const char *path, rths_error *err);

#endif
