/* --resume must continue the same test: the configuration the run started with (DIR/config.yaml,
 * as resolved then) and the one given now may differ only where the physics and the measurement
 * cannot change: the end of the range, the point limit, the outputs. */
#include "run/frf_internal.h"

#include <libfyaml.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct {
    char *key, *value;
} flat_entry;

/* A YAML document as dotted.key = flow text of each leaf (sequences whole). */
typedef struct {
    flat_entry *e;
    int n, cap;
} flat_config;

static int flat_add(flat_config *f, const char *key, char *value) {
    if (f->n == f->cap) {
        int cap = f->cap ? 2 * f->cap : 64;
        flat_entry *e = realloc(f->e, (size_t)cap * sizeof *e);
        if (!e) return -1;
        f->e = e;
        f->cap = cap;
    }
    f->e[f->n].key = strdup(key);
    f->e[f->n].value = value;
    return f->e[f->n++].key ? 0 : -1;
}

static void flat_free(flat_config *f) {
    for (int i = 0; i < f->n; i++) {
        free(f->e[i].key);
        free(f->e[i].value);
    }
    free(f->e);
    memset(f, 0, sizeof *f);
}

static int flatten(struct fy_node *node, const char *prefix, flat_config *out) {
    if (!node) return 0;
    if (fy_node_get_type(node) != FYNT_MAPPING) {
        char *text = fy_emit_node_to_string(node, FYECF_MODE_FLOW_ONELINE | FYECF_WIDTH_INF);
        if (!text) return -1;
        text[strcspn(text, "\n")] = 0;
        return flat_add(out, prefix, text);
    }
    void *iter = NULL;
    struct fy_node_pair *pair;
    while ((pair = fy_node_mapping_iterate(node, &iter))) {
        size_t len = 0;
        const char *k = fy_node_get_scalar(fy_node_pair_key(pair), &len);
        if (!k) return -1;
        size_t plen = strlen(prefix), total = plen + len + 2;
        char *key = malloc(total);
        if (!key) return -1;
        snprintf(key, total, "%s%s%.*s", prefix, plen ? "." : "", (int)len, k);
        int rc = flatten(fy_node_pair_value(pair), key, out);
        free(key);
        if (rc) return rc;
    }
    return 0;
}

static int load_flat(const char *path, flat_config *out) {
    if (access(path, R_OK) != 0) return -1; /* before libfyaml, which would print its own error */
    struct fy_document *doc = fy_document_build_from_file(NULL, path);
    if (!doc) return -1;
    int rc = flatten(fy_document_root(doc), "", out);
    fy_document_destroy(doc);
    return rc;
}

static const char *lookup(const flat_config *f, const char *key) {
    for (int i = 0; i < f->n; i++)
        if (!strcmp(f->e[i].key, key)) return f->e[i].value;
    return NULL;
}

/* Equal text, or equal numbers written differently (0.5, 5e-1). */
static int same_value(const char *a, const char *b) {
    if (!a || !b) return a == b;
    if (!strcmp(a, b)) return 1;
    char *ea, *eb;
    double x = strtod(a, &ea), y = strtod(b, &eb);
    return ea != a && eb != b && !*ea && !*eb && x == y;
}

static int may_change(const char *key) {
    /* rig.pace only sleeps: the virtual rig's results are the same at any pace */
    return !strcmp(key, "continuation.end_hz") || !strcmp(key, "continuation.max_points") ||
           !strcmp(key, "rig.pace") || !strncmp(key, "output.", 7);
}

/* The first key of a that b lacks or holds otherwise; allowed ones are noted in *changes. */
static const char *first_change(const flat_config *a, const flat_config *b, int a_is_old,
                                frf_state *st) {
    for (int i = 0; i < a->n; i++) {
        const char *other = lookup(b, a->e[i].key);
        if (same_value(a->e[i].value, other)) continue;
        if (!may_change(a->e[i].key)) return a->e[i].key;
        if (!a_is_old && lookup(b, a->e[i].key)) continue; /* noted from the old side */
        if (st->n_changes < FRF_MAX_CHANGES)
            snprintf(st->changes[st->n_changes++], sizeof st->changes[0], "%s: %s -> %s",
                     a->e[i].key, a_is_old ? a->e[i].value : (other ? other : "(unset)"),
                     a_is_old ? (other ? other : "(unset)") : a->e[i].value);
    }
    return NULL;
}

static int refuse(const char *key, const flat_config *old, const flat_config *now,
                  rths_error *err) {
    const char *was = lookup(old, key), *is = lookup(now, key);
    return rths_error_set(err, RTHS_EINPUT,
                          "--resume: key '%s' was %s when the run started and is %s now: a "
                          "resumed run keeps the physics and the measurement (only "
                          "continuation.end_hz, continuation.max_points, rig.pace and output.* may "
                          "change); start a new run in another folder",
                          key, was ? was : "unset", is ? is : "unset");
}

/* The noise seed given for the run (--seed) is part of the measurement too. */
static int check_seed(const frf_state *st, rths_error *err) {
    int known = 0;
    char *was = NULL;
    int rc = rths_journal_read_seed(st->journal_path, &known, &was, err);
    const char *now = st->seed_text;
    if (!rc && known && (was ? !now || strcmp(was, now) : now != NULL))
        rc = rths_error_set(err, RTHS_EINPUT,
                            "--resume: the run started with %s%s and is resumed with %s%s: a "
                            "resumed run keeps the measurement's noise seed; start a new run in "
                            "another folder",
                            was ? "--seed " : "no --seed", was ? was : "",
                            now ? "--seed " : "no --seed", now ? now : "");
    free(was);
    return rc;
}

/* And so is the rig: a virtual-rig branch does not continue on a controller process. */
static int check_rig(const frf_state *st, rths_error *err) {
    int known = 0;
    char *was = NULL;
    int rc = rths_journal_read_header_text(st->journal_path, "rig", &known, &was, err);
    const char *now = frf_rig_text(st);
    if (!rc && known && was && strcmp(was, now))
        rc = rths_error_set(err, RTHS_EINPUT,
                            "--resume: the run measured on the %s rig and is resumed on %s: a "
                            "resumed run keeps its rig; start a new run in another folder",
                            was, now);
    free(was);
    return rc;
}

int frf_check_resume_config(frf_state *st, rths_error *err) {
    int seed_rc = check_seed(st, err);
    if (!seed_rc) seed_rc = check_rig(st, err);
    if (seed_rc) return seed_rc;
    size_t len = strlen(st->opt->out_dir) + 16;
    char *old_path = malloc(len), tmp[] = "/tmp/rths_resume_XXXXXX";
    if (!old_path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    snprintf(old_path, len, "%s/config.yaml", st->opt->out_dir);
    flat_config old = {0}, now = {0};
    int rc = RTHS_OK, fd = mkstemp(tmp);
    if (load_flat(old_path, &old))
        rc = rths_error_set(err, RTHS_EINPUT,
                            "--resume: cannot read %s, the configuration the run started with",
                            old_path);
    else if (fd < 0 || rths_config_write(st->opt->cfg, tmp, err) || load_flat(tmp, &now))
        rc = rths_error_set(err, RTHS_EFAIL, "--resume: cannot compare the configurations");
    const char *key = NULL;
    if (!rc) key = first_change(&old, &now, 1, st);
    if (!rc && !key) key = first_change(&now, &old, 0, st);
    if (!rc && key) rc = refuse(key, &old, &now, err);
    if (fd >= 0) {
        close(fd);
        unlink(tmp);
    }
    flat_free(&old);
    flat_free(&now);
    free(old_path);
    return rc;
}
