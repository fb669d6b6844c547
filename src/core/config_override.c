/* One --set KEY=VALUE applied to the configuration's tree (config_internal.h): the value parsed
 * as YAML, placed at the dotted key (created, replaced or an item of a list), its origin kept for
 * messages. */
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

/* ---- loading ---- */

int config_apply_override(rths_config *cfg, const char *text, rths_error *err) {
    char cut[MESSAGE_TEXT_MAX];
    const char *shown = config_short_text(text, cut, sizeof cut);
    const char *eq = strchr(text, '=');
    if (!eq || eq == text)
        return rths_error_set(err, RTHS_EINPUT,
                              "--set %s: expected dotted.key=value (e.g. split.mass_ratio=0.33)",
                              shown);
    size_t klen = (size_t)(eq - text);
    if (text[0] == '.' || text[klen - 1] == '.' || memmem(text, klen, "..", 2))
        return rths_error_set(err, RTHS_EINPUT, "--set %s: the key has an empty part", shown);
    if (!eq[1]) return rths_error_set(err, RTHS_EINPUT, "--set %s: no value after '='", shown);
    utf8_scan u = {0};
    for (const char *c = text; *c; c++)
        if (config_utf8_step(&u, (unsigned char)*c) != UTF8_OK || (!c[1] && u.continuation))
            return rths_error_set(err, RTHS_EINPUT, "--set %s: not UTF-8 text", shown);
    int key_depth = 1; /* the root mapping */
    for (size_t i = 0; i < klen; i++)
        key_depth += text[i] == '.';
    if (key_depth >= RTHS_CONFIG_MAX_DEPTH)
        return rths_error_set(err, RTHS_EINPUT, "--set %s: the key is nested deeper than %d levels",
                              shown, RTHS_CONFIG_MAX_DEPTH);
    char *copy = strdup(text);
    char **list = realloc(cfg->overrides, (size_t)(cfg->n_overrides + 1) * sizeof *list);
    if (!copy || !list) {
        free(copy);
        if (list) cfg->overrides = list;
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    cfg->overrides = list;
    cfg->overrides[cfg->n_overrides++] = copy;
    char where[MESSAGE_TEXT_MAX + 8];
    snprintf(where, sizeof where, "--set %s", shown);
    cnode *value = NULL;
    int rc = config_parse_source(NULL, copy + klen + 1, where, copy, key_depth, &value, err);
    if (rc) return rc;
    if (!value) return rths_error_set(err, RTHS_EINPUT, "%s: no value after '='", where);
    if (!cfg->root) {
        cfg->root = config_node_new(NODE_MAPPING, 0, 0, NULL);
        if (!cfg->root) {
            config_node_free(value);
            return rths_error_set(err, RTHS_EFAIL, "out of memory");
        }
    }
    cnode *n = cfg->root;
    const char *p = copy;
    for (;;) {
        const char *dot = memchr(p, '.', (size_t)(copy + klen - p));
        size_t len = dot ? (size_t)(dot - p) : (size_t)(copy + klen - p);
        if (config_is_empty(n)) { /* "split:" with nothing under it becomes a mapping */
            n->type = NODE_MAPPING;
            free(n->text);
            n->text = NULL;
        }
        if (n->type == NODE_SEQUENCE) { /* "rig.sites.1.uri=..." replaces inside item 1 */
            int item = config_sequence_index(n, p, len);
            if (item < 0) {
                config_node_free(value);
                return rths_error_set(err, RTHS_EINPUT,
                                      "%s: '%.*s' is a list of %d item%s, so it has no item '%.*s' "
                                      "(items are numbered from 0)",
                                      where, (int)(p - copy - 1), copy, n->count,
                                      n->count == 1 ? "" : "s", (int)len, p);
            }
            if (!dot) {
                config_node_free(n->items[item]);
                n->items[item] = value;
                return RTHS_OK;
            }
            n = n->items[item];
            p = dot + 1;
            continue;
        }
        if (n->type != NODE_MAPPING) {
            config_node_free(value);
            return rths_error_set(err, RTHS_EINPUT,
                                  "%s: '%.*s' is not a mapping in the configuration, so it has no "
                                  "key '%.*s'",
                                  where, (int)(p - copy - 1), copy, (int)len, p);
        }
        int i = config_map_find(n, p, len);
        if (!dot) {
            if (i >= 0) {
                config_node_free(n->items[i]);
                n->items[i] = value;
            } else {
                if (config_node_grow(n)) {
                    config_node_free(value);
                    return rths_error_set(err, RTHS_EFAIL, "out of memory");
                }
                n->keys[n->count] = strndup(p, len);
                n->key_line[n->count] = 0;
                n->key_column[n->count] = 0;
                n->items[n->count++] = value;
            }
            return RTHS_OK;
        }
        if (i < 0) {
            cnode *m = config_node_new(NODE_MAPPING, 0, 0, copy);
            if (!m || config_node_grow(n)) {
                config_node_free(m);
                config_node_free(value);
                return rths_error_set(err, RTHS_EFAIL, "out of memory");
            }
            n->keys[n->count] = strndup(p, len);
            n->key_line[n->count] = 0;
            n->key_column[n->count] = 0;
            n->items[n->count] = m;
            i = n->count++;
        }
        n = n->items[i];
        p = dot + 1;
    }
}
