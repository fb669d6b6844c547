/* The configuration's typed getters for one value (number with its range, integer, boolean,
 * string, choice) and what they share: finding the key, marking it read, "did you mean" for a
 * missing one, and messages that name the key, its place and the limit. */
#include "core/config_internal.h"

#include <ctype.h>
#include <errno.h>
#include <libfyaml.h>
#include <limits.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- getters ---- */

int config_edit_distance(const char *a, const char *b) {
    size_t la = strlen(a), lb = strlen(b);
    if (la > 63 || lb > 63) return 99;
    int d[64][64];
    for (size_t i = 0; i <= la; i++)
        d[i][0] = (int)i;
    for (size_t j = 0; j <= lb; j++)
        d[0][j] = (int)j;
    for (size_t i = 1; i <= la; i++)
        for (size_t j = 1; j <= lb; j++) {
            int best = d[i - 1][j - 1] + (a[i - 1] != b[j - 1]);
            if (d[i - 1][j] + 1 < best) best = d[i - 1][j] + 1;
            if (d[i][j - 1] + 1 < best) best = d[i][j - 1] + 1;
            d[i][j] = best;
        }
    return d[la][lb];
}

const char *config_describe(const cnode *n) {
    return n->type == NODE_MAPPING    ? "a mapping"
           : n->type == NODE_SEQUENCE ? "a list"
           : config_is_empty(n)       ? "an empty value"
                                      : "text";
}

static void remember(rths_config *cfg, const char *key) {
    if (!key || !*key) return;
    for (int i = 0; i < cfg->n_asked; i++)
        if (!strcmp(cfg->asked[i], key)) return;
    if (cfg->n_asked == cfg->cap_asked) {
        int cap = cfg->cap_asked ? 2 * cfg->cap_asked : 32;
        char **a = realloc(cfg->asked, (size_t)cap * sizeof *a);
        if (!a) return; /* costs a spelling hint only */
        cfg->asked = a;
        cfg->cap_asked = cap;
    }
    char *copy = strdup(key);
    if (copy) cfg->asked[cfg->n_asked++] = copy;
}

/* Finds key for a getter: RTHS_OK with *n (NULL when absent and optional). */
int config_get_node(rths_config *cfg, const char *key, int required, cnode **n, rths_error *err) {
    cnode *deepest = NULL;
    remember(cfg, key);
    *n = config_lookup(cfg, key, 1, &deepest);
    if (*n) return RTHS_OK;
    /* "split: 0.5" when split.mass_ratio is asked for: refused even for an optional key, or the
     * value would silently be ignored */
    if (deepest && deepest->type != NODE_MAPPING && !config_is_empty(deepest))
        return config_key_error(
            cfg, key, deepest, err, "%s its parent is %s, not a mapping",
            required ? "is required but" : "cannot be read:", config_describe(deepest));
    if (!required) return RTHS_OK;
    /* a missing top-level key has no better place than the file itself */
    cnode *where = deepest == cfg->root ? NULL : deepest;
    /* a present key one or two letters off is most likely the user's spelling of this one */
    const char *last = strrchr(key, '.');
    last = last ? last + 1 : key;
    if (deepest && deepest->type == NODE_MAPPING)
        for (int i = 0; i < deepest->count; i++)
            if (config_edit_distance(deepest->keys[i], last) <= 2)
                return config_key_error(cfg, key, where, err,
                                        "is required but missing (line %d has '%s': misspelt?)",
                                        deepest->key_line[i], deepest->keys[i]);
    return config_key_error(cfg, key, where, err, "is required but missing");
}

/* YAML 1.2 core-schema decimal numbers: [-+]? (digits [. digits?] | . digits) ([eE] [-+]? digits)?
 * (strtod alone would also take hex floats, "infinity" and leading blanks) */
static int number_syntax(const char *p) {
    int digits = 0;
    if (*p == '+' || *p == '-') p++;
    while (isdigit((unsigned char)*p))
        p++, digits++;
    if (*p == '.') {
        p++;
        while (isdigit((unsigned char)*p))
            p++, digits++;
    }
    if (!digits) return 0;
    if (*p == 'e' || *p == 'E') {
        p++;
        if (*p == '+' || *p == '-') p++;
        if (!isdigit((unsigned char)*p)) return 0;
        while (isdigit((unsigned char)*p))
            p++;
    }
    return *p == 0;
}

int config_scalar_number(rths_config *cfg, const char *key, const cnode *n, double *out,
                         rths_error *err) {
    if (n->type != NODE_SCALAR)
        return config_key_error(cfg, key, n, err, "expected a number, got %s", config_describe(n));
    const char *s = n->text;
    if (config_is_empty(n))
        return config_key_error(cfg, key, n, err, "has no value (expected a number)");
    if (!n->quoted) {
        const char *t = s + (*s == '-' || *s == '+');
        if (!strcasecmp(t, ".nan") || !strcasecmp(t, ".inf") || !strcasecmp(t, "nan") ||
            !strcasecmp(t, "inf") || !strcasecmp(t, "infinity"))
            return config_key_error(cfg, key, n, err, "NaN/inf is not allowed (got '%s')", s);
    }
    if (n->quoted)
        return config_key_error(
            cfg, key, n, err,
            "expected a number, got the quoted text '%s' (write numbers without "
            "quotes)",
            s);
    if (!number_syntax(s))
        return config_key_error(cfg, key, n, err, "expected a number, got '%s'", s);
    /* '.' is the decimal point whatever locale the process runs in */
    locale_t c = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
    if (!c) return rths_error_set(err, RTHS_EFAIL, "cannot create the C locale");
    errno = 0;
    double v = strtod_l(s, NULL, c);
    int range = errno == ERANGE && fabs(v) > 1.0; /* underflow to a subnormal or 0 is fine */
    freelocale(c);
    if (range || !isfinite(v))
        return config_key_error(cfg, key, n, err, "'%s' is out of range for a double", s);
    *out = v;
    return RTHS_OK;
}

int rths_config_get_double_ex(rths_config *cfg, const char *key, int required, double def,
                              double lo, double hi, unsigned flags, double *out, rths_error *err) {
    cnode *n;
    int rc = config_get_node(cfg, key, required, &n, err);
    if (rc) return rc;
    if (!n) {
        *out = def;
        return RTHS_OK;
    }
    double v;
    if ((rc = config_scalar_number(cfg, key, n, &v, err))) return rc;
    int lo_open = (flags & RTHS_CONFIG_LO_OPEN) != 0, hi_open = (flags & RTHS_CONFIG_HI_OPEN) != 0;
    if ((lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi)) {
        *out = v;
        return RTHS_OK;
    }
    char range[128];
    return config_key_error(cfg, key, n, err, "must be %s (got %s)",
                            rths_config_range_text(lo, hi, flags, range, sizeof range), n->text);
}

const char *rths_config_range_text(double lo, double hi, unsigned flags, char *buf, size_t size) {
    int lo_open = (flags & RTHS_CONFIG_LO_OPEN) != 0, hi_open = (flags & RTHS_CONFIG_HI_OPEN) != 0;
    if (isinf(lo) && isinf(hi))
        snprintf(buf, size, "finite");
    else if (isinf(hi)) /* one-sided: no "[-inf, 100000]" */
        snprintf(buf, size, "%s %g", lo_open ? ">" : ">=", lo);
    else if (isinf(lo))
        snprintf(buf, size, "%s %g", hi_open ? "<" : "<=", hi);
    else
        snprintf(buf, size, "in %c%g, %g%c", lo_open ? '(' : '[', lo, hi, hi_open ? ')' : ']');
    return buf;
}

int rths_config_get_double(rths_config *cfg, const char *key, int required, double def, double lo,
                           double hi, double *out, rths_error *err) {
    return rths_config_get_double_ex(cfg, key, required, def, lo, hi, 0, out, err);
}

int config_scalar_int(rths_config *cfg, const char *key, const cnode *n, long *out,
                      rths_error *err) {
    if (n->type != NODE_SCALAR)
        return config_key_error(cfg, key, n, err, "expected an integer, got %s",
                                config_describe(n));
    char *end = NULL;
    errno = 0;
    long v = n->quoted ? 0 : strtol(n->text, &end, 10);
    if (n->quoted || !*n->text || end == n->text || *end || isspace((unsigned char)n->text[0]))
        return config_key_error(cfg, key, n, err, "expected an integer, got %s'%s'",
                                n->quoted ? "the quoted text " : "", n->text);
    if (errno == ERANGE)
        return config_key_error(cfg, key, n, err, "'%s' is out of range for an integer", n->text);
    *out = v;
    return RTHS_OK;
}

int rths_config_get_int(rths_config *cfg, const char *key, int required, long def, long lo, long hi,
                        long *out, rths_error *err) {
    cnode *n;
    int rc = config_get_node(cfg, key, required, &n, err);
    if (rc) return rc;
    if (!n) {
        *out = def;
        return RTHS_OK;
    }
    long v;
    if ((rc = config_scalar_int(cfg, key, n, &v, err))) return rc;
    if (v < lo && hi == LONG_MAX)
        return config_key_error(cfg, key, n, err, "must be >= %ld (got %ld)", lo, v);
    if (v > hi && lo == LONG_MIN)
        return config_key_error(cfg, key, n, err, "must be <= %ld (got %ld)", hi, v);
    if (v < lo || v > hi)
        return config_key_error(cfg, key, n, err, "must be in [%ld, %ld] (got %ld)", lo, hi, v);
    *out = v;
    return RTHS_OK;
}

int rths_config_get_bool(rths_config *cfg, const char *key, int required, int def, int *out,
                         rths_error *err) {
    cnode *n;
    int rc = config_get_node(cfg, key, required, &n, err);
    if (rc) return rc;
    if (!n) {
        *out = def;
        return RTHS_OK;
    }
    static const char *const yes[] = {"true", "yes", "on"}, *const no[] = {"false", "no", "off"};
    if (n->type == NODE_SCALAR && !n->quoted)
        for (int i = 0; i < 3; i++) {
            if (!strcasecmp(n->text, yes[i])) {
                *out = 1;
                return RTHS_OK;
            }
            if (!strcasecmp(n->text, no[i])) {
                *out = 0;
                return RTHS_OK;
            }
        }
    return config_key_error(
        cfg, key, n, err, "expected true or false, got %s%s%s", n->type == NODE_SCALAR ? "'" : "",
        n->type == NODE_SCALAR ? n->text : config_describe(n), n->type == NODE_SCALAR ? "'" : "");
}

int rths_config_get_string(rths_config *cfg, const char *key, int required, const char *def,
                           const char **out, rths_error *err) {
    cnode *n;
    int rc = config_get_node(cfg, key, required, &n, err);
    if (rc) return rc;
    if (!n) {
        *out = def;
        return RTHS_OK;
    }
    if (n->type != NODE_SCALAR || config_is_empty(n))
        return config_key_error(cfg, key, n, err, "expected text, got %s", config_describe(n));
    *out = n->text;
    return RTHS_OK;
}

int rths_config_get_choice(rths_config *cfg, const char *key, int required, int def_index,
                           const char *const *choices, int *out_index, rths_error *err) {
    const char *s;
    int rc = rths_config_get_string(cfg, key, required, NULL, &s, err);
    if (rc) return rc;
    if (!s) {
        *out_index = def_index;
        return RTHS_OK;
    }
    for (int i = 0; choices[i]; i++)
        if (!strcmp(s, choices[i])) {
            *out_index = i;
            return RTHS_OK;
        }
    char allowed[512] = "";
    size_t len = 0;
    for (int i = 0; choices[i] && len < sizeof allowed; i++)
        len += (size_t)snprintf(allowed + len, sizeof allowed - len, "%s'%s'", i ? ", " : "",
                                choices[i]);
    return config_key_error(cfg, key, config_lookup(cfg, key, 0, NULL), err,
                            "'%s' is not one of %s", s, allowed);
}

void rths_config_mark_known(rths_config *cfg, const char *key_prefix) {
    if (!cfg) return;
    if (!key_prefix) key_prefix = "";
    remember(cfg, key_prefix);
    cnode *n = config_lookup(cfg, key_prefix, 1, NULL);
    if (n) n->known_subtree = 1;
}

int rths_config_section_read(const rths_config *cfg, const char *section) {
    size_t len = strlen(section);
    for (int i = 0; i < cfg->n_asked; i++)
        if (!strncmp(cfg->asked[i], section, len) && cfg->asked[i][len] == '.') return 1;
    return 0;
}

int rths_config_error_at(const rths_config *cfg, const char *key, rths_error *err, const char *fmt,
                         ...) {
    char msg[RTHS_ERROR_MSG_LEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    cnode *deepest = NULL;
    cnode *n = config_lookup(cfg, key, 0, &deepest);
    if (!n && deepest == cfg->root) deepest = NULL;
    return config_key_error(cfg, key, n ? n : deepest, err, "%s", msg);
}
