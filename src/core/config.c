/* YAML configuration through libfyaml's event parser.
 *
 * The document is read into a small tree of our own that keeps every node's line and column (the
 * document API of libfyaml 0.8 exposes positions only for scalars), whether a scalar was quoted,
 * and which nodes came from --set. Getters mark what they read; check_unknown refuses the rest.
 *
 * This file: reading (the file checked, parsed into the tree, --set applied) and locating (a
 * dotted key looked up, a node's place named in messages). The tree is in config_internal.h. */
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

/* ---- tree ---- */

cnode *config_node_new(node_type type, int line, int column, const char *origin) {
    cnode *n = calloc(1, sizeof *n);
    if (!n) return NULL;
    n->type = type;
    n->line = line;
    n->column = column;
    n->origin = origin;
    return n;
}

void config_node_free(cnode *n) {
    if (!n) return;
    for (int i = 0; i < n->count; i++) {
        config_node_free(n->items[i]);
        if (n->keys) free(n->keys[i]);
    }
    free(n->items);
    free(n->keys);
    free(n->key_line);
    free(n->key_column);
    free(n->text);
    free(n);
}

int config_node_grow(cnode *n) {
    if (n->count < n->cap) return 0;
    int cap = n->cap ? 2 * n->cap : 8;
    cnode **items = realloc(n->items, (size_t)cap * sizeof *items);
    if (!items) return -1;
    n->items = items;
    if (n->type == NODE_MAPPING) {
        char **keys = realloc(n->keys, (size_t)cap * sizeof *keys);
        if (!keys) return -1;
        n->keys = keys;
        int *kl = realloc(n->key_line, (size_t)cap * sizeof *kl);
        if (!kl) return -1;
        n->key_line = kl;
        int *kc = realloc(n->key_column, (size_t)cap * sizeof *kc);
        if (!kc) return -1;
        n->key_column = kc;
    }
    n->cap = cap;
    return 0;
}

/* "split:" with nothing after it: an empty section, not a value */
int config_is_empty(const cnode *n) {
    return n && n->type == NODE_SCALAR && !n->quoted &&
           (!n->text[0] || !strcmp(n->text, "~") || !strcasecmp(n->text, "null"));
}

int config_map_find(const cnode *map, const char *key, size_t len) {
    for (int i = 0; i < map->count; i++)
        if (strlen(map->keys[i]) == len && !memcmp(map->keys[i], key, len)) return i;
    return -1;
}

const char *config_short_text(const char *text, char *buf, size_t size) {
    size_t len = strlen(text);
    if (len < size) return text;
    size_t head = (size - 4) / 2, tail = size - 4 - head;
    snprintf(buf, size, "%.*s...%s", (int)head, text, text + len - tail);
    return buf;
}

/* A key is quoted in a message up to this length (keys can be as long as the file). */
static int shown_len(size_t len) {
    return len > 200 ? 200 : (int)len;
}

/* Open-addressing hash of a mapping's keys while it is read: the duplicate-key check costs O(1)
 * per key instead of a scan of the keys before it (80 000 keys took 14.5 s that way). */
typedef struct {
    int *slot;  /* key index + 1; 0 = empty */
    size_t cap; /* a power of two, at least twice the keys */
} key_index;

static size_t key_hash(const char *key, size_t len) {
    uint64_t h = 1469598103934665603ULL; /* FNV-1a */
    for (size_t i = 0; i < len; i++)
        h = (h ^ (unsigned char)key[i]) * 1099511628211ULL;
    return (size_t)(h ^ (h >> 32));
}

static size_t key_index_probe(const key_index *ix, const cnode *map, const char *key, size_t len) {
    size_t i = key_hash(key, len) & (ix->cap - 1);
    while (ix->slot[i]) {
        const char *k = map->keys[ix->slot[i] - 1];
        if (strlen(k) == len && !memcmp(k, key, len)) break;
        i = (i + 1) & (ix->cap - 1);
    }
    return i;
}

/* Index of key in map, or -1 after recording it as map's key number `index` (-2: out of memory). */
static int key_index_add(key_index *ix, const cnode *map, const char *key, size_t len, int index) {
    if ((size_t)(index + 1) * 2 > ix->cap) {
        size_t cap = ix->cap ? 2 * ix->cap : 16;
        int *slot = calloc(cap, sizeof *slot);
        if (!slot) return -2;
        free(ix->slot);
        ix->slot = slot;
        ix->cap = cap;
        for (int j = 0; j < index; j++)
            ix->slot[key_index_probe(ix, map, map->keys[j], strlen(map->keys[j]))] = j + 1;
    }
    size_t i = key_index_probe(ix, map, key, len);
    if (ix->slot[i]) return ix->slot[i] - 1;
    ix->slot[i] = index + 1;
    return -1;
}

/* ---- parsing (events -> tree) ---- */

typedef struct {
    struct fy_parser *parser;
    char diag_text[512]; /* libfyaml's first error: "LINE:COL: error: what" (file name cut off) */
    const char *where;   /* file name or "--set ..." for messages (shortened) */
    const char *origin;
    int depth; /* collections open around the current event (--set: plus the key's) */
    rths_error *err;
} parse_ctx;

static void event_position(struct fy_event *ev, int *line, int *column) {
    const struct fy_mark *m = fy_event_start_mark(ev);
    *line = m ? m->line + 1 : 0;
    *column = m ? m->column + 1 : 0;
}

/* The parser's own diagnosis when it stops on a syntax error. */
static int parse_error(parse_ctx *ctx) {
    const char *text = ctx->diag_text, *sep = strstr(text, ": error: ");
    if (sep && !ctx->origin && sep > text)
        return rths_error_set(ctx->err, RTHS_EINPUT, "%s:%.*s: not valid YAML: %s", ctx->where,
                              (int)(sep - text), text, sep + 9);
    if (sep)
        return rths_error_set(ctx->err, RTHS_EINPUT, "%s: not valid YAML: %s", ctx->where, sep + 9);
    return rths_error_set(ctx->err, RTHS_EINPUT, "%s: not valid YAML", ctx->where);
}

/* Keeps libfyaml's first error as "LINE:COL: error: what": the file name in front of it (which may
 * be longer than the whole buffer) is replaced by ctx->where when the message is made. */
static void capture_diag(struct fy_diag *diag, void *user, const char *buf, size_t len) {
    (void)diag;
    parse_ctx *ctx = user;
    const char *sep = memmem(buf, len, ": error: ", 9);
    if (ctx->diag_text[0] || !sep) return;
    while (len && (buf[len - 1] == '\n' || buf[len - 1] == ' '))
        len--;
    /* "FILE:LINE:COL: error: ..." -> start at LINE: the two numbers before sep */
    const char *start = sep;
    for (int colons = 0; start > buf && colons < 2; start--)
        if (start[-1] == ':' && ++colons == 2) break;
    if (start == buf || !isdigit((unsigned char)*start)) start = sep;
    len -= (size_t)(start - buf);
    if (len >= sizeof ctx->diag_text) len = sizeof ctx->diag_text - 1;
    memcpy(ctx->diag_text, start, len);
    ctx->diag_text[len] = 0;
}

static int parse_node(parse_ctx *ctx, struct fy_event *ev, cnode **out);

static int parse_children(parse_ctx *ctx, cnode *n, key_index *ix) {
    for (;;) {
        struct fy_event *ev = fy_parser_parse(ctx->parser);
        if (!ev) return parse_error(ctx);
        enum fy_event_type t = ev->type;
        if (t == FYET_SEQUENCE_END || t == FYET_MAPPING_END) {
            fy_parser_event_free(ctx->parser, ev);
            return RTHS_OK;
        }
        if (n->type == NODE_MAPPING) {
            /* key: must be a scalar */
            int kl, kc;
            event_position(ev, &kl, &kc);
            if (t != FYET_SCALAR) {
                fy_parser_event_free(ctx->parser, ev);
                return rths_error_set(ctx->err, RTHS_EINPUT,
                                      "%s:%d:%d: mapping keys must be "
                                      "plain names",
                                      ctx->where, kl, kc);
            }
            size_t len = 0;
            const char *text = fy_token_get_text(ev->scalar.value, &len);
            if (!text) text = "";
            int first = key_index_add(ix, n, text, len, n->count);
            if (first == -2) {
                fy_parser_event_free(ctx->parser, ev);
                return rths_error_set(ctx->err, RTHS_EFAIL, "out of memory");
            }
            if (first >= 0) {
                int rc =
                    rths_error_set(ctx->err, RTHS_EINPUT,
                                   "%s:%d:%d: duplicate key '%.*s' in this mapping (first "
                                   "at line %d)",
                                   ctx->where, kl, kc, shown_len(len), text, n->key_line[first]);
                fy_parser_event_free(ctx->parser, ev);
                return rc;
            }
            if (memchr(text, '.', len) || !len) {
                /* a dotted key could never be read: dots separate the levels of a key */
                int rc = rths_error_set(ctx->err, RTHS_EINPUT,
                                        "%s:%d:%d: key '%.*s': keys may not be empty or contain "
                                        "'.'; write nested mappings instead",
                                        ctx->where, kl, kc, shown_len(len), text);
                fy_parser_event_free(ctx->parser, ev);
                return rc;
            }
            if (config_node_grow(n)) {
                fy_parser_event_free(ctx->parser, ev);
                return rths_error_set(ctx->err, RTHS_EFAIL, "out of memory");
            }
            n->keys[n->count] = strndup(text, len);
            n->key_line[n->count] = kl;
            n->key_column[n->count] = kc;
            fy_parser_event_free(ctx->parser, ev);
            if (!n->keys[n->count]) return rths_error_set(ctx->err, RTHS_EFAIL, "out of memory");
            n->items[n->count] = NULL;
            n->count++;
            ev = fy_parser_parse(ctx->parser);
            if (!ev) return parse_error(ctx);
            int rc = parse_node(ctx, ev, &n->items[n->count - 1]);
            if (rc) return rc;
            cnode *v = n->items[n->count - 1];
            if (!v->line && !v->origin) { /* an empty value has no mark of its own */
                v->line = kl;
                v->column = kc;
            }
        } else {
            if (config_node_grow(n)) {
                fy_parser_event_free(ctx->parser, ev);
                return rths_error_set(ctx->err, RTHS_EFAIL, "out of memory");
            }
            n->items[n->count] = NULL;
            n->count++;
            int rc = parse_node(ctx, ev, &n->items[n->count - 1]);
            if (rc) return rc;
        }
    }
}

/* Consumes ev (and, for collections, everything up to the matching end). */
static int parse_node(parse_ctx *ctx, struct fy_event *ev, cnode **out) {
    int line, column;
    event_position(ev, &line, &column);
    enum fy_event_type t = ev->type;
    int rc = RTHS_OK;
    if (t == FYET_SCALAR) {
        size_t len = 0;
        const char *text = fy_token_get_text(ev->scalar.value, &len);
        cnode *n = config_node_new(NODE_SCALAR, line, column, ctx->origin);
        if (n) {
            n->text = strndup(text ? text : "", text ? len : 0);
            enum fy_scalar_style style =
                ev->scalar.value ? fy_token_scalar_style(ev->scalar.value) : FYSS_PLAIN;
            n->quoted = style != FYSS_PLAIN;
            /* libfyaml marks a quoted scalar after its opening quote; point at the quote */
            if ((style == FYSS_SINGLE_QUOTED || style == FYSS_DOUBLE_QUOTED) && n->column > 1)
                n->column--;
            if (ev->scalar.tag) { /* "!!str 1.5" is text, like a quoted scalar */
                const char *tag = fy_token_get_text0(ev->scalar.tag);
                size_t tl = tag ? strlen(tag) : 0;
                if (tl >= 4 && !strcmp(tag + tl - 4, ":str")) n->quoted = 1;
            }
        }
        fy_parser_event_free(ctx->parser, ev);
        if (!n || !n->text) {
            config_node_free(n);
            return rths_error_set(ctx->err, RTHS_EFAIL, "out of memory");
        }
        *out = n;
        return RTHS_OK;
    }
    if (t == FYET_SEQUENCE_START || t == FYET_MAPPING_START) {
        fy_parser_event_free(ctx->parser, ev);
        /* the tree is built, freed, checked and written by recursion: bound its depth */
        if (ctx->depth >= RTHS_CONFIG_MAX_DEPTH)
            return rths_error_set(ctx->err, RTHS_EINPUT,
                                  "%s:%d:%d: nested deeper than %d levels (a configuration needs "
                                  "a handful)",
                                  ctx->where, line, column, RTHS_CONFIG_MAX_DEPTH);
        cnode *n = config_node_new(t == FYET_SEQUENCE_START ? NODE_SEQUENCE : NODE_MAPPING, line,
                                   column, ctx->origin);
        if (!n) return rths_error_set(ctx->err, RTHS_EFAIL, "out of memory");
        *out = n;
        key_index ix = {0};
        ctx->depth++;
        rc = parse_children(ctx, n, &ix);
        ctx->depth--;
        free(ix.slot);
        return rc;
    }
    fy_parser_event_free(ctx->parser, ev);
    if (t == FYET_ALIAS) /* marked after the '*' */
        return rths_error_set(ctx->err, RTHS_EINPUT,
                              "%s:%d:%d: YAML aliases are not supported "
                              "in rths configurations; write the value out",
                              ctx->where, line, column > 1 ? column - 1 : column);
    return rths_error_set(ctx->err, RTHS_EINPUT, "%s:%d:%d: unexpected YAML structure", ctx->where,
                          line, column);
}

/* Parses a whole stream with exactly one document (or none: NULL root). */
static int parse_stream(parse_ctx *ctx, cnode **root) {
    *root = NULL;
    int docs = 0;
    for (;;) {
        struct fy_event *ev = fy_parser_parse(ctx->parser);
        if (!ev) {
            if (fy_parser_get_stream_error(ctx->parser)) {
                config_node_free(*root);
                *root = NULL;
                return parse_error(ctx);
            }
            return RTHS_OK;
        }
        enum fy_event_type t = ev->type;
        if (t == FYET_STREAM_START || t == FYET_DOCUMENT_END || t == FYET_STREAM_END) {
            fy_parser_event_free(ctx->parser, ev);
            if (t == FYET_STREAM_END) return RTHS_OK;
            continue;
        }
        if (t == FYET_DOCUMENT_START) {
            int line, column;
            event_position(ev, &line, &column);
            fy_parser_event_free(ctx->parser, ev);
            if (++docs > 1) {
                config_node_free(*root);
                *root = NULL;
                return rths_error_set(ctx->err, RTHS_EINPUT,
                                      "%s:%d:%d: a configuration is one YAML document, found a "
                                      "second",
                                      ctx->where, line, column);
            }
            continue;
        }
        int rc = parse_node(ctx, ev, root);
        if (rc) {
            config_node_free(*root);
            *root = NULL;
            return rc;
        }
    }
}

/* depth: the levels of mapping the parsed value will sit under (the parts of a --set key). */
int config_parse_source(const char *path, const char *text, const char *where, const char *origin,
                        int depth, cnode **root, rths_error *err) {
    parse_ctx ctx = {.where = where, .origin = origin, .depth = depth, .err = err};
    struct fy_diag_cfg dcfg;
    fy_diag_cfg_default(&dcfg);
    dcfg.fp = NULL;
    dcfg.output_fn = capture_diag;
    dcfg.user = &ctx;
    dcfg.colorize = false;
    struct fy_diag *diag = fy_diag_create(&dcfg);
    if (!diag) return rths_error_set(err, RTHS_EFAIL, "out of memory creating the YAML parser");
    struct fy_parse_cfg pcfg = {.flags = FYPCF_QUIET, .diag = diag};
    ctx.parser = fy_parser_create(&pcfg);
    int rc = RTHS_OK;
    if (!ctx.parser) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory creating the YAML parser");
    } else if (path ? fy_parser_set_input_file(ctx.parser, path)
                    : fy_parser_set_string(ctx.parser, text, strlen(text))) {
        rc = path ? rths_error_set(err, RTHS_EINPUT, "%s: cannot read: %s", where,
                                   strerror(errno ? errno : ENOENT))
                  : rths_error_set(err, RTHS_EFAIL, "cannot parse %s", where);
    } else {
        rc = parse_stream(&ctx, root);
    }
    if (ctx.parser) fy_parser_destroy(ctx.parser);
    fy_diag_destroy(diag);
    return rc;
}

int config_utf8_step(utf8_scan *u, unsigned char c) {
    if (u->line == 0) u->line = 1;
    u->column++;
    if (u->continuation && (c & 0xc0) == 0x80 && c >= u->lo && c <= u->hi) {
        u->continuation--;
        u->lo = 0x80, u->hi = 0xbf;
        return UTF8_OK;
    }
    int bad = u->continuation > 0; /* the character at lead_* stopped short */
    if (!bad && c >= 0x80) {       /* lead byte: 110xxxxx, 1110xxxx, 11110xxx (<= U+10FFFF) */
        u->continuation = c >= 0xc2 && c <= 0xdf   ? 1
                          : c >= 0xe0 && c <= 0xef ? 2
                          : c >= 0xf0 && c <= 0xf4 ? 3
                                                   : -1;
        bad = u->continuation < 0;
        u->lead = c, u->lead_line = u->line, u->lead_column = u->column;
        /* the second byte's range excludes overlong forms, surrogates and beyond U+10FFFF */
        u->lo = c == 0xe0 ? 0xa0 : c == 0xf0 ? 0x90 : 0x80;
        u->hi = c == 0xed ? 0x9f : c == 0xf4 ? 0x8f : 0xbf;
    }
    if (c == '\n') u->line++, u->column = 0;
    return bad ? UTF8_BAD : c ? UTF8_OK : UTF8_NUL;
}

static int utf8_error(const utf8_scan *u, int status, const char *shown, rths_error *err) {
    if (status == UTF8_NUL)
        return rths_error_set(err, RTHS_EINPUT,
                              "%s:%ld:%ld: a NUL byte: the configuration must be UTF-8 text (is it "
                              "UTF-16?)",
                              shown, u->line, u->column);
    if (status == UTF8_BAD)
        return rths_error_set(err, RTHS_EINPUT,
                              "%s:%ld:%ld: byte 0x%02X does not start a UTF-8 character here: "
                              "save the configuration as UTF-8 text",
                              shown, u->lead_line, u->lead_column, u->lead);
    return rths_error_set(err, RTHS_EINPUT, "%s: ends inside a UTF-8 character", shown);
}

/* What libfyaml would read as an empty or garbled document: a folder, UTF-16 or UTF-32 text (a
 * byte-order mark, or NUL bytes between ASCII characters), bytes that are not UTF-8. shown: path
 * for messages. */
static int check_config_file(const char *path, const char *shown, rths_error *err) {
    struct stat st;
    if (stat(path, &st) != 0)
        return rths_error_set(err, RTHS_EINPUT, "%s: cannot read the configuration: %s", shown,
                              strerror(errno));
    if (S_ISDIR(st.st_mode))
        return rths_error_set(err, RTHS_EINPUT,
                              "%s: is a folder; the configuration is a YAML file (e.g. "
                              "examples/four_storey.yaml)",
                              shown);
    FILE *f = fopen(path, "rb");
    if (!f)
        return rths_error_set(err, RTHS_EINPUT, "%s: cannot read the configuration: %s", shown,
                              strerror(errno));
    if (!S_ISREG(st.st_mode)) { /* a pipe is read once, by the parser */
        fclose(f);
        return RTHS_OK;
    }
    unsigned char buf[4096];
    size_t got;
    utf8_scan u = {0};
    int rc = RTHS_OK, first = 1;
    while (!rc && (got = fread(buf, 1, sizeof buf, f)) > 0) {
        if (first && got >= 2 &&
            ((buf[0] == 0xff && buf[1] == 0xfe) || (buf[0] == 0xfe && buf[1] == 0xff) ||
             (got >= 4 && !buf[0] && !buf[1] && buf[2] == 0xfe)))
            rc = rths_error_set(err, RTHS_EINPUT,
                                "%s: starts with a UTF-16/UTF-32 byte-order mark (%02X %02X): "
                                "save the configuration as UTF-8 text",
                                shown, buf[0], buf[1]);
        first = 0;
        for (size_t i = 0; i < got && !rc; i++) {
            int status = config_utf8_step(&u, buf[i]);
            if (status != UTF8_OK) rc = utf8_error(&u, status, shown, err);
        }
    }
    if (!rc && u.continuation) rc = utf8_error(&u, UTF8_OK, shown, err);
    if (!rc && ferror(f))
        rc = rths_error_set(err, RTHS_EINPUT, "%s: cannot read the configuration: %s", shown,
                            strerror(errno));
    fclose(f);
    return rc;
}

/* ---- locations and messages ---- */

void config_location(const rths_config *cfg, const cnode *n, int line, int column, char *buf,
                     size_t size) {
    char cut[MESSAGE_TEXT_MAX];
    const char *file = cfg->path ? config_short_text(cfg->path, cut, sizeof cut) : NULL;
    if (n && n->origin)
        snprintf(buf, size, "--set %s", config_short_text(n->origin, cut, sizeof cut));
    else if (line > 0)
        snprintf(buf, size, "%s:%d:%d", file ? file : "<config>", line, column);
    else
        snprintf(buf, size, "%s", file ? file : "<no config file>");
}

int config_key_error(const rths_config *cfg, const char *key, const cnode *at, rths_error *err,
                     const char *fmt, ...) {
    char loc[MESSAGE_TEXT_MAX + 64], msg[RTHS_ERROR_MSG_LEN];
    config_location(cfg, at, at ? at->line : 0, at ? at->column : 0, loc, sizeof loc);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return rths_error_set(err, RTHS_EINPUT, "%s: key '%s': %s", loc, key, msg);
}

/* Walks the dotted key. Returns the node or NULL; *deepest receives the deepest existing node on
 * the path (for locating "missing" errors). Marks the path as known when mark is set. */
/* A key part naming an item of a list ("rig.sites.1.uri"): its decimal index, or -1 when the
 * part is not a plain index or lies beyond the list. */
int config_sequence_index(const cnode *n, const char *p, size_t len) {
    if (len == 0 || len > 6) return -1;
    int index = 0;
    for (size_t k = 0; k < len; k++) {
        if (p[k] < '0' || p[k] > '9') return -1;
        index = 10 * index + (p[k] - '0');
    }
    if (len > 1 && p[0] == '0') return -1;
    return index < n->count ? index : -1;
}

cnode *config_lookup(const rths_config *cfg, const char *key, int mark, cnode **deepest) {
    cnode *n = cfg->root;
    if (deepest) *deepest = NULL;
    const char *p = key;
    while (n) {
        if (deepest) *deepest = n;
        if (mark) n->known = 1;
        if (!*p) return n;
        const char *dot = strchr(p, '.');
        size_t len = dot ? (size_t)(dot - p) : strlen(p);
        int i;
        if (n->type == NODE_SEQUENCE)
            i = config_sequence_index(n, p, len);
        else if (n->type == NODE_MAPPING)
            i = config_map_find(n, p, len);
        else
            return NULL;
        if (i < 0) return NULL;
        n = n->items[i];
        p += len + (dot ? 1 : 0);
        if (!dot) {
            if (n && mark) n->known = 1;
            if (deepest) *deepest = n;
            return n;
        }
    }
    return NULL;
}

int rths_config_load(const char *path, const char *const *overrides, int n_overrides,
                     rths_config **out, rths_error *err) {
    *out = NULL;
    rths_config *cfg = calloc(1, sizeof *cfg);
    if (!cfg) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int rc = RTHS_OK;
    if (path) {
        cfg->path = strdup(path);
        if (!cfg->path) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        char cut[MESSAGE_TEXT_MAX];
        const char *shown = config_short_text(path, cut, sizeof cut);
        if (!rc) rc = check_config_file(path, shown, err);
        if (!rc) rc = config_parse_source(path, NULL, shown, NULL, 0, &cfg->root, err);
        if (!rc && cfg->root && cfg->root->type != NODE_MAPPING)
            rc = rths_error_set(err, RTHS_EINPUT,
                                "%s:%d:%d: the configuration must be a mapping of sections "
                                "(structure:, split:, ...)",
                                shown, cfg->root->line, cfg->root->column);
    }
    if (!rc && !cfg->root) {
        cfg->root = config_node_new(NODE_MAPPING, 0, 0, NULL);
        if (!cfg->root) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int i = 0; i < n_overrides && !rc; i++)
        rc = config_apply_override(cfg, overrides[i], err);
    if (rc) {
        rths_config_free(cfg);
        return rc;
    }
    cfg->root->known = 1;
    *out = cfg;
    return RTHS_OK;
}

void rths_config_free(rths_config *cfg) {
    if (!cfg) return;
    config_node_free(cfg->root);
    for (int i = 0; i < cfg->n_overrides; i++)
        free(cfg->overrides[i]);
    free(cfg->overrides);
    for (int i = 0; i < cfg->n_asked; i++)
        free(cfg->asked[i]);
    free(cfg->asked);
    free(cfg->path);
    free(cfg);
}

const char *rths_config_path(const rths_config *cfg) {
    return cfg->path;
}

int rths_config_has(const rths_config *cfg, const char *key) {
    return config_lookup(cfg, key, 0, NULL) != NULL;
}
