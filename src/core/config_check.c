/* Unknown keys refused: after the getters have read what a command needs, every key of the file
 * or of --set that none read is named (with a "did you mean"), and sections that belong to other
 * commands are checked against what those commands read. */
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

/* ---- unknown keys ---- */

static int check_node(const rths_config *cfg, const cnode *n, char *path, size_t plen,
                      rths_error *err) {
    if (n->known_subtree) return RTHS_OK;
    if (n->type == NODE_SEQUENCE) { /* a list of mappings: each item's keys are checked */
        for (int i = 0; i < n->count; i++) {
            if (n->items[i]->type != NODE_MAPPING) continue;
            if (plen + 16 >= 1024) return RTHS_OK;
            size_t at = plen + (size_t)snprintf(path + plen, 1024 - plen, ".%d", i);
            int rc = check_node(cfg, n->items[i], path, at, err);
            path[plen] = 0;
            if (rc) return rc;
        }
        return RTHS_OK;
    }
    if (n->type != NODE_MAPPING) return RTHS_OK;
    for (int i = 0; i < n->count; i++) {
        size_t len = strlen(n->keys[i]);
        if (plen + len + 2 >= 1024) { /* no reader asks for such a key: it is unknown */
            char loc[MESSAGE_TEXT_MAX + 64];
            config_location(cfg, n->items[i], n->key_line[i], n->key_column[i], loc, sizeof loc);
            return rths_error_set(err, RTHS_EINPUT, "%s: unknown key '%.*s%s%.200s...'", loc,
                                  (int)(plen > 200 ? 200 : plen), path, plen ? "." : "",
                                  n->keys[i]);
        }
        size_t at = plen;
        if (plen) path[at++] = '.';
        memcpy(path + at, n->keys[i], len + 1);
        const cnode *child = n->items[i];
        if (!child->known) {
            /* a misspelling of a key that was asked for at the same level? */
            const char *suggest = NULL;
            size_t suggest_len = 0;
            for (int j = 0; j < n->count; j++)
                if (j != i && n->items[j]->known &&
                    config_edit_distance(n->keys[i], n->keys[j]) <= 2) {
                    suggest = n->keys[j];
                    suggest_len = strlen(suggest);
                }
            /* or a key some reader asked for at this level that is absent (an optional key) */
            for (int j = 0; j < cfg->n_asked && !suggest; j++) {
                const char *a = cfg->asked[j];
                if (plen && (strncmp(a, path, plen) != 0 || a[plen] != '.')) continue;
                const char *c = plen ? a + plen + 1 : a, *dot = strchr(c, '.');
                size_t cl = dot ? (size_t)(dot - c) : strlen(c);
                char comp[64];
                if (cl >= sizeof comp) continue;
                memcpy(comp, c, cl);
                comp[cl] = 0;
                if (strcmp(comp, n->keys[i]) && config_edit_distance(n->keys[i], comp) <= 2) {
                    suggest = c;
                    suggest_len = cl;
                }
            }
            char loc[MESSAGE_TEXT_MAX + 64];
            config_location(cfg, child, n->key_line[i] ? n->key_line[i] : child->line,
                            n->key_line[i] ? n->key_column[i] : child->column, loc, sizeof loc);
            if (suggest)
                return rths_error_set(err, RTHS_EINPUT,
                                      "%s: unknown key '%s' (did you mean "
                                      "'%.*s%.*s'?)",
                                      loc, path, (int)(plen ? plen + 1 : 0), path, (int)suggest_len,
                                      suggest);
            return rths_error_set(err, RTHS_EINPUT,
                                  "%s: unknown key '%s' (see docs/config.md for the keys)", loc,
                                  path);
        }
        int rc = check_node(cfg, child, path, at + len, err);
        if (rc) return rc;
    }
    return RTHS_OK;
}

int rths_config_check_unknown(const rths_config *cfg, rths_error *err) {
    char path[1024] = "";
    return check_node(cfg, cfg->root, path, 0, err);
}

/* Sub-sections every command's setup reads (rths_setup_read: the actuator and sensor transforms,
 * docs/config/rig.md; rths_controller_config_read: the sweep, the band of a sparse model's
 * real-time reduction): reading them does not make a command the owner of their section, so
 * `rths model` still ignores the rest of `rig` and `rths fidelity` the rest of `continuation`. */
static const char *const setup_subsections[] = {"rig.actuators.",      "rig.lasers.",
                                                "rig.interface_mass",  "continuation.start_hz",
                                                "continuation.end_hz", NULL};

/* Whether a key of section was asked for, not counting the setup's sub-sections. */
static int section_read_by_command(const rths_config *cfg, const char *section) {
    size_t len = strlen(section);
    for (int i = 0; i < cfg->n_asked; i++) {
        if (strncmp(cfg->asked[i], section, len) || cfg->asked[i][len] != '.') continue;
        int shared = 0;
        for (int j = 0; setup_subsections[j] && !shared; j++)
            shared = !strncmp(cfg->asked[i], setup_subsections[j], strlen(setup_subsections[j]));
        if (!shared) return 1;
    }
    return 0;
}

int rths_config_check_sections(rths_config *cfg, const char *const *own, rths_error *err) {
    /* io: a plug-in's own keys, read by the controller process that loads it */
    static const char *const sections[] = {"rig",          "controller", "iteration",
                                           "continuation", "stability",  "fidelity",
                                           "output",       "server",     "io"};
    enum { N_SECTIONS = sizeof sections / sizeof sections[0] };
    int read[N_SECTIONS];
    for (int k = 0; k < N_SECTIONS; k++) /* before any marking: marks count as reads */
        read[k] = section_read_by_command(cfg, sections[k]);
    for (int k = 0; k < N_SECTIONS; k++) {
        int mine = read[k];
        for (int j = 0; own && own[j] && !mine; j++)
            mine = !strcmp(own[j], sections[k]);
        if (!mine) rths_config_mark_known(cfg, sections[k]);
    }
    return rths_config_check_unknown(cfg, err);
}
