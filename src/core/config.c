/* YAML configuration through libfyaml's event parser.
 *
 * The document is read into a small tree of our own that keeps every node's line and column (the
 * document API of libfyaml 0.8 exposes positions only for scalars), whether a scalar was quoted,
 * and which nodes came from --set. Getters mark what they read; check_unknown refuses the rest. */
#include "rths/config.h"

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

typedef enum { NODE_SCALAR, NODE_SEQUENCE, NODE_MAPPING } node_type;

typedef struct cnode cnode;
struct cnode {
    node_type type;
    int line, column;   /* 1-based; 0 when unknown */
    const char *origin; /* the --set text this node came from, or NULL (the file) */
    int known;          /* a getter read it (or an ancestor of something read) */
    int known_subtree;  /* mark_known: everything below is known */
    char *text;         /* scalar */
    int quoted;         /* scalar was quoted: a string, never a number */
    int count, cap;
    cnode **items; /* sequence items, or mapping values */
    char **keys;   /* mapping keys */
    int *key_line, *key_column;
};

struct rths_config {
    char *path;
    cnode *root;
    char **overrides; /* owned copies of the --set texts (nodes point into them) */
    int n_overrides;
    char **asked; /* every key a getter asked for, present or not: "did you mean" candidates */
    int n_asked, cap_asked;
};

/* ---- tree ---- */

static cnode *node_new(node_type type, int line, int column, const char *origin) {
    cnode *n = calloc(1, sizeof *n);
    if (!n) return NULL;
    n->type = type;
    n->line = line;
    n->column = column;
    n->origin = origin;
    return n;
}

static void node_free(cnode *n) {
    if (!n) return;
    for (int i = 0; i < n->count; i++) {
        node_free(n->items[i]);
        if (n->keys) free(n->keys[i]);
    }
    free(n->items);
    free(n->keys);
    free(n->key_line);
    free(n->key_column);
    free(n->text);
    free(n);
}

static int node_grow(cnode *n) {
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
static int is_empty(const cnode *n) {
    return n && n->type == NODE_SCALAR && !n->quoted &&
           (!n->text[0] || !strcmp(n->text, "~") || !strcasecmp(n->text, "null"));
}

static int map_find(const cnode *map, const char *key, size_t len) {
    for (int i = 0; i < map->count; i++)
        if (strlen(map->keys[i]) == len && !memcmp(map->keys[i], key, len)) return i;
    return -1;
}

/* Paths and --set texts can be as long as the system allows; in a message they are shortened in
 * the middle so the reason after them always fits (rths_error holds RTHS_ERROR_MSG_LEN bytes). */
#define MESSAGE_TEXT_MAX 1024

static const char *short_text(const char *text, char *buf, size_t size) {
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
            if (node_grow(n)) {
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
            if (node_grow(n)) {
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
        cnode *n = node_new(NODE_SCALAR, line, column, ctx->origin);
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
            node_free(n);
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
        cnode *n = node_new(t == FYET_SEQUENCE_START ? NODE_SEQUENCE : NODE_MAPPING, line, column,
                            ctx->origin);
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
                node_free(*root);
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
                node_free(*root);
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
            node_free(*root);
            *root = NULL;
            return rc;
        }
    }
}

/* depth: the levels of mapping the parsed value will sit under (the parts of a --set key). */
static int parse_source(const char *path, const char *text, const char *where, const char *origin,
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

/* UTF-8 validation a byte at a time, with the position of the character being read. */
typedef struct {
    long line, column; /* of the byte just stepped over (1-based) */
    int continuation;  /* continuation bytes still due */
    unsigned lo, hi;   /* the range of the next continuation byte */
    unsigned lead;     /* the last multi-byte lead byte, and where it was */
    long lead_line, lead_column;
} utf8_scan;

enum { UTF8_OK, UTF8_BAD, UTF8_NUL };

static int utf8_step(utf8_scan *u, unsigned char c) {
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
            int status = utf8_step(&u, buf[i]);
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

static void location(const rths_config *cfg, const cnode *n, int line, int column, char *buf,
                     size_t size) {
    char cut[MESSAGE_TEXT_MAX];
    const char *file = cfg->path ? short_text(cfg->path, cut, sizeof cut) : NULL;
    if (n && n->origin)
        snprintf(buf, size, "--set %s", short_text(n->origin, cut, sizeof cut));
    else if (line > 0)
        snprintf(buf, size, "%s:%d:%d", file ? file : "<config>", line, column);
    else
        snprintf(buf, size, "%s", file ? file : "<no config file>");
}

static int key_error(const rths_config *cfg, const char *key, const cnode *at, rths_error *err,
                     const char *fmt, ...) __attribute__((format(printf, 5, 6)));
static int key_error(const rths_config *cfg, const char *key, const cnode *at, rths_error *err,
                     const char *fmt, ...) {
    char loc[MESSAGE_TEXT_MAX + 64], msg[RTHS_ERROR_MSG_LEN];
    location(cfg, at, at ? at->line : 0, at ? at->column : 0, loc, sizeof loc);
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
static int sequence_index(const cnode *n, const char *p, size_t len) {
    if (len == 0 || len > 6) return -1;
    int index = 0;
    for (size_t k = 0; k < len; k++) {
        if (p[k] < '0' || p[k] > '9') return -1;
        index = 10 * index + (p[k] - '0');
    }
    if (len > 1 && p[0] == '0') return -1;
    return index < n->count ? index : -1;
}

static cnode *lookup(const rths_config *cfg, const char *key, int mark, cnode **deepest) {
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
            i = sequence_index(n, p, len);
        else if (n->type == NODE_MAPPING)
            i = map_find(n, p, len);
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

/* ---- loading ---- */

static int apply_override(rths_config *cfg, const char *text, rths_error *err) {
    char cut[MESSAGE_TEXT_MAX];
    const char *shown = short_text(text, cut, sizeof cut);
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
        if (utf8_step(&u, (unsigned char)*c) != UTF8_OK || (!c[1] && u.continuation))
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
    int rc = parse_source(NULL, copy + klen + 1, where, copy, key_depth, &value, err);
    if (rc) return rc;
    if (!value) return rths_error_set(err, RTHS_EINPUT, "%s: no value after '='", where);
    if (!cfg->root) {
        cfg->root = node_new(NODE_MAPPING, 0, 0, NULL);
        if (!cfg->root) {
            node_free(value);
            return rths_error_set(err, RTHS_EFAIL, "out of memory");
        }
    }
    cnode *n = cfg->root;
    const char *p = copy;
    for (;;) {
        const char *dot = memchr(p, '.', (size_t)(copy + klen - p));
        size_t len = dot ? (size_t)(dot - p) : (size_t)(copy + klen - p);
        if (is_empty(n)) { /* "split:" with nothing under it becomes a mapping */
            n->type = NODE_MAPPING;
            free(n->text);
            n->text = NULL;
        }
        if (n->type == NODE_SEQUENCE) { /* "rig.sites.1.uri=..." replaces inside item 1 */
            int item = sequence_index(n, p, len);
            if (item < 0) {
                node_free(value);
                return rths_error_set(err, RTHS_EINPUT,
                                      "%s: '%.*s' is a list of %d item%s, so it has no item '%.*s' "
                                      "(items are numbered from 0)",
                                      where, (int)(p - copy - 1), copy, n->count,
                                      n->count == 1 ? "" : "s", (int)len, p);
            }
            if (!dot) {
                node_free(n->items[item]);
                n->items[item] = value;
                return RTHS_OK;
            }
            n = n->items[item];
            p = dot + 1;
            continue;
        }
        if (n->type != NODE_MAPPING) {
            node_free(value);
            return rths_error_set(err, RTHS_EINPUT,
                                  "%s: '%.*s' is not a mapping in the configuration, so it has no "
                                  "key '%.*s'",
                                  where, (int)(p - copy - 1), copy, (int)len, p);
        }
        int i = map_find(n, p, len);
        if (!dot) {
            if (i >= 0) {
                node_free(n->items[i]);
                n->items[i] = value;
            } else {
                if (node_grow(n)) {
                    node_free(value);
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
            cnode *m = node_new(NODE_MAPPING, 0, 0, copy);
            if (!m || node_grow(n)) {
                node_free(m);
                node_free(value);
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
        const char *shown = short_text(path, cut, sizeof cut);
        if (!rc) rc = check_config_file(path, shown, err);
        if (!rc) rc = parse_source(path, NULL, shown, NULL, 0, &cfg->root, err);
        if (!rc && cfg->root && cfg->root->type != NODE_MAPPING)
            rc = rths_error_set(err, RTHS_EINPUT,
                                "%s:%d:%d: the configuration must be a mapping of sections "
                                "(structure:, split:, ...)",
                                shown, cfg->root->line, cfg->root->column);
    }
    if (!rc && !cfg->root) {
        cfg->root = node_new(NODE_MAPPING, 0, 0, NULL);
        if (!cfg->root) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int i = 0; i < n_overrides && !rc; i++)
        rc = apply_override(cfg, overrides[i], err);
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
    node_free(cfg->root);
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
    return lookup(cfg, key, 0, NULL) != NULL;
}

/* ---- getters ---- */

static int edit_distance(const char *a, const char *b) {
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

static const char *describe(const cnode *n) {
    return n->type == NODE_MAPPING    ? "a mapping"
           : n->type == NODE_SEQUENCE ? "a list"
           : is_empty(n)              ? "an empty value"
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
static int get_node(rths_config *cfg, const char *key, int required, cnode **n, rths_error *err) {
    cnode *deepest = NULL;
    remember(cfg, key);
    *n = lookup(cfg, key, 1, &deepest);
    if (*n) return RTHS_OK;
    /* "split: 0.5" when split.mass_ratio is asked for: refused even for an optional key, or the
     * value would silently be ignored */
    if (deepest && deepest->type != NODE_MAPPING && !is_empty(deepest))
        return key_error(cfg, key, deepest, err, "%s its parent is %s, not a mapping",
                         required ? "is required but" : "cannot be read:", describe(deepest));
    if (!required) return RTHS_OK;
    /* a missing top-level key has no better place than the file itself */
    cnode *where = deepest == cfg->root ? NULL : deepest;
    /* a present key one or two letters off is most likely the user's spelling of this one */
    const char *last = strrchr(key, '.');
    last = last ? last + 1 : key;
    if (deepest && deepest->type == NODE_MAPPING)
        for (int i = 0; i < deepest->count; i++)
            if (edit_distance(deepest->keys[i], last) <= 2)
                return key_error(cfg, key, where, err,
                                 "is required but missing (line %d has '%s': misspelt?)",
                                 deepest->key_line[i], deepest->keys[i]);
    return key_error(cfg, key, where, err, "is required but missing");
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

static int scalar_number(rths_config *cfg, const char *key, const cnode *n, double *out,
                         rths_error *err) {
    if (n->type != NODE_SCALAR)
        return key_error(cfg, key, n, err, "expected a number, got %s", describe(n));
    const char *s = n->text;
    if (is_empty(n)) return key_error(cfg, key, n, err, "has no value (expected a number)");
    if (!n->quoted) {
        const char *t = s + (*s == '-' || *s == '+');
        if (!strcasecmp(t, ".nan") || !strcasecmp(t, ".inf") || !strcasecmp(t, "nan") ||
            !strcasecmp(t, "inf") || !strcasecmp(t, "infinity"))
            return key_error(cfg, key, n, err, "NaN/inf is not allowed (got '%s')", s);
    }
    if (n->quoted)
        return key_error(cfg, key, n, err,
                         "expected a number, got the quoted text '%s' (write numbers without "
                         "quotes)",
                         s);
    if (!number_syntax(s)) return key_error(cfg, key, n, err, "expected a number, got '%s'", s);
    /* '.' is the decimal point whatever locale the process runs in */
    locale_t c = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0);
    if (!c) return rths_error_set(err, RTHS_EFAIL, "cannot create the C locale");
    errno = 0;
    double v = strtod_l(s, NULL, c);
    int range = errno == ERANGE && fabs(v) > 1.0; /* underflow to a subnormal or 0 is fine */
    freelocale(c);
    if (range || !isfinite(v))
        return key_error(cfg, key, n, err, "'%s' is out of range for a double", s);
    *out = v;
    return RTHS_OK;
}

int rths_config_get_double_ex(rths_config *cfg, const char *key, int required, double def,
                              double lo, double hi, unsigned flags, double *out, rths_error *err) {
    cnode *n;
    int rc = get_node(cfg, key, required, &n, err);
    if (rc) return rc;
    if (!n) {
        *out = def;
        return RTHS_OK;
    }
    double v;
    if ((rc = scalar_number(cfg, key, n, &v, err))) return rc;
    int lo_open = (flags & RTHS_CONFIG_LO_OPEN) != 0, hi_open = (flags & RTHS_CONFIG_HI_OPEN) != 0;
    if ((lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi)) {
        *out = v;
        return RTHS_OK;
    }
    char range[128];
    return key_error(cfg, key, n, err, "must be %s (got %s)",
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

static int scalar_int(rths_config *cfg, const char *key, const cnode *n, long *out,
                      rths_error *err) {
    if (n->type != NODE_SCALAR)
        return key_error(cfg, key, n, err, "expected an integer, got %s", describe(n));
    char *end = NULL;
    errno = 0;
    long v = n->quoted ? 0 : strtol(n->text, &end, 10);
    if (n->quoted || !*n->text || end == n->text || *end || isspace((unsigned char)n->text[0]))
        return key_error(cfg, key, n, err, "expected an integer, got %s'%s'",
                         n->quoted ? "the quoted text " : "", n->text);
    if (errno == ERANGE)
        return key_error(cfg, key, n, err, "'%s' is out of range for an integer", n->text);
    *out = v;
    return RTHS_OK;
}

int rths_config_get_int(rths_config *cfg, const char *key, int required, long def, long lo, long hi,
                        long *out, rths_error *err) {
    cnode *n;
    int rc = get_node(cfg, key, required, &n, err);
    if (rc) return rc;
    if (!n) {
        *out = def;
        return RTHS_OK;
    }
    long v;
    if ((rc = scalar_int(cfg, key, n, &v, err))) return rc;
    if (v < lo && hi == LONG_MAX)
        return key_error(cfg, key, n, err, "must be >= %ld (got %ld)", lo, v);
    if (v > hi && lo == LONG_MIN)
        return key_error(cfg, key, n, err, "must be <= %ld (got %ld)", hi, v);
    if (v < lo || v > hi)
        return key_error(cfg, key, n, err, "must be in [%ld, %ld] (got %ld)", lo, hi, v);
    *out = v;
    return RTHS_OK;
}

int rths_config_get_bool(rths_config *cfg, const char *key, int required, int def, int *out,
                         rths_error *err) {
    cnode *n;
    int rc = get_node(cfg, key, required, &n, err);
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
    return key_error(
        cfg, key, n, err, "expected true or false, got %s%s%s", n->type == NODE_SCALAR ? "'" : "",
        n->type == NODE_SCALAR ? n->text : describe(n), n->type == NODE_SCALAR ? "'" : "");
}

int rths_config_get_string(rths_config *cfg, const char *key, int required, const char *def,
                           const char **out, rths_error *err) {
    cnode *n;
    int rc = get_node(cfg, key, required, &n, err);
    if (rc) return rc;
    if (!n) {
        *out = def;
        return RTHS_OK;
    }
    if (n->type != NODE_SCALAR || is_empty(n))
        return key_error(cfg, key, n, err, "expected text, got %s", describe(n));
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
    return key_error(cfg, key, lookup(cfg, key, 0, NULL), err, "'%s' is not one of %s", s, allowed);
}

static int number_list(rths_config *cfg, const char *key, cnode *n, int integers, double **dout,
                       int **iout, int *count, rths_error *err) {
    if (n->type != NODE_SEQUENCE)
        return key_error(cfg, key, n, err, "expected a list of numbers like [1, 2], got %s%s%s",
                         describe(n), n->type == NODE_SCALAR ? " " : "",
                         n->type == NODE_SCALAR ? n->text : "");
    size_t m = (size_t)(n->count ? n->count : 1);
    double *d = integers ? NULL : calloc(m, sizeof *d);
    int *iv = integers ? calloc(m, sizeof *iv) : NULL;
    if (!d && !iv) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < n->count; i++) {
        cnode *item = n->items[i];
        int rc;
        if (integers) {
            long v = 0;
            rc = scalar_int(cfg, key, item, &v, err);
            if (!rc && (v < -2147483647L || v > 2147483647L))
                rc = key_error(cfg, key, item, err, "entry %d is out of range", i + 1);
            if (!rc) iv[i] = (int)v;
        } else {
            rc = scalar_number(cfg, key, item, &d[i], err);
        }
        if (rc) {
            free(d);
            free(iv);
            return rc;
        }
    }
    if (dout) *dout = d;
    if (iout) *iout = iv;
    *count = n->count;
    return RTHS_OK;
}

int rths_config_get_double_list(rths_config *cfg, const char *key, int required, double **out,
                                int *count, rths_error *err) {
    cnode *n;
    *out = NULL;
    *count = 0;
    int rc = get_node(cfg, key, required, &n, err);
    if (rc || !n) return rc;
    return number_list(cfg, key, n, 0, out, NULL, count, err);
}

int rths_config_get_int_list(rths_config *cfg, const char *key, int required, int **out, int *count,
                             rths_error *err) {
    cnode *n;
    *out = NULL;
    *count = 0;
    int rc = get_node(cfg, key, required, &n, err);
    if (rc || !n) return rc;
    return number_list(cfg, key, n, 1, NULL, out, count, err);
}

int rths_config_get_matrix(rths_config *cfg, const char *key, int required, double **out, int *rows,
                           int *cols, rths_error *err) {
    cnode *n;
    *out = NULL;
    *rows = *cols = 0;
    int rc = get_node(cfg, key, required, &n, err);
    if (rc || !n) return rc;
    if (n->type != NODE_SEQUENCE || n->count == 0)
        return key_error(cfg, key, n, err,
                         "expected a matrix as a list of rows, e.g. [[1, 0], [0, 1]]");
    int r = n->count, c = -1;
    for (int i = 0; i < r; i++) {
        cnode *row = n->items[i];
        if (row->type != NODE_SEQUENCE)
            return key_error(cfg, key, row, err, "row %d is not a list of numbers", i + 1);
        if (c < 0) c = row->count;
        if (row->count != c)
            return key_error(cfg, key, row, err, "row %d has %d entries, row 1 has %d", i + 1,
                             row->count, c);
    }
    if (c < 1) return key_error(cfg, key, n, err, "the matrix has empty rows");
    double *m = calloc((size_t)r * (size_t)c, sizeof *m);
    if (!m) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < r; i++)
        for (int j = 0; j < c; j++) {
            rc = scalar_number(cfg, key, n->items[i]->items[j], &RTHS_AT(m, r, i, j), err);
            if (rc) {
                free(m);
                return rc;
            }
        }
    *out = m;
    *rows = r;
    *cols = c;
    return RTHS_OK;
}

int rths_config_get_count(rths_config *cfg, const char *key, int *count, rths_error *err) {
    *count = 0;
    cnode *n;
    int rc = get_node(cfg, key, 0, &n, err);
    if (rc || !n || is_empty(n)) return rc;
    if (n->type != NODE_SEQUENCE)
        return key_error(cfg, key, n, err, "must be a list ([...] or '- ' items), not %s",
                         describe(n));
    *count = n->count;
    return RTHS_OK;
}

void rths_config_mark_known(rths_config *cfg, const char *key_prefix) {
    if (!cfg) return;
    if (!key_prefix) key_prefix = "";
    remember(cfg, key_prefix);
    cnode *n = lookup(cfg, key_prefix, 1, NULL);
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
    cnode *n = lookup(cfg, key, 0, &deepest);
    if (!n && deepest == cfg->root) deepest = NULL;
    return key_error(cfg, key, n ? n : deepest, err, "%s", msg);
}

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
            location(cfg, n->items[i], n->key_line[i], n->key_column[i], loc, sizeof loc);
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
                if (j != i && n->items[j]->known && edit_distance(n->keys[i], n->keys[j]) <= 2) {
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
                if (strcmp(comp, n->keys[i]) && edit_distance(n->keys[i], comp) <= 2) {
                    suggest = c;
                    suggest_len = cl;
                }
            }
            char loc[MESSAGE_TEXT_MAX + 64];
            location(cfg, child, n->key_line[i] ? n->key_line[i] : child->line,
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

/* ---- writing the resolved document ---- */

static int needs_quotes(const char *s) {
    if (!*s) return 1;
    if (strchr("?:-", s[0]) && (s[1] == ' ' || !s[1])) return 1; /* "-1.5" stays a number */
    if (strchr(",[]{}#&*!|>'\"%@` ", s[0])) return 1;
    for (const char *p = s; *p; p++)
        if (strchr("#:,[]{}\"\\\n", *p) || (unsigned char)*p < 0x20) return 1;
    return s[strlen(s) - 1] == ' ';
}

/* text as a plain scalar when it reads back as itself, else double-quoted with escapes */
static void emit_text(FILE *f, const char *text, int quoted) {
    if (!quoted && !needs_quotes(text)) {
        fputs(text, f);
        return;
    }
    fputc('"', f);
    for (const char *p = text; *p; p++) {
        if (*p == '"' || *p == '\\')
            fprintf(f, "\\%c", *p);
        else if (*p == '\n')
            fputs("\\n", f);
        else if ((unsigned char)*p < 0x20)
            fprintf(f, "\\x%02x", (unsigned char)*p);
        else
            fputc(*p, f);
    }
    fputc('"', f);
}

static void emit_scalar(FILE *f, const cnode *n) {
    if (!n->quoted && !n->text[0])
        fputc('~', f); /* an empty value stays empty (null), not the text "" */
    else
        emit_text(f, n->text, n->quoted);
}

static void emit_flow(FILE *f, const cnode *n) {
    if (n->type == NODE_SCALAR) {
        emit_scalar(f, n);
    } else if (n->type == NODE_SEQUENCE) {
        fputc('[', f);
        for (int i = 0; i < n->count; i++) {
            if (i) fputs(", ", f);
            emit_flow(f, n->items[i]);
        }
        fputc(']', f);
    } else {
        fputc('{', f);
        for (int i = 0; i < n->count; i++) {
            fputs(i ? ", " : "", f);
            emit_text(f, n->keys[i], 0);
            fputs(": ", f);
            emit_flow(f, n->items[i]);
        }
        fputc('}', f);
    }
}

static void emit_block(FILE *f, const cnode *map, int indent) {
    for (int i = 0; i < map->count; i++) {
        const cnode *v = map->items[i];
        fprintf(f, "%*s", indent, "");
        emit_text(f, map->keys[i], 0);
        fputc(':', f);
        if (v->type == NODE_MAPPING && v->count > 0) {
            fputc('\n', f);
            emit_block(f, v, indent + 2);
        } else {
            fputc(' ', f);
            emit_flow(f, v);
            fputc('\n', f);
        }
    }
}

int rths_config_write(const rths_config *cfg, const char *path, rths_error *err) {
    size_t len = strlen(path) + 32;
    char *tmp = malloc(len);
    if (!tmp) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    snprintf(tmp, len, "%s.tmp.%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f) {
        int e = errno;
        free(tmp);
        return rths_error_set(err, RTHS_EFAIL, "cannot write %s: %s", path, strerror(e));
    }
    fprintf(f, "# configuration as resolved (file %s, --set overrides applied)\n",
            cfg->path ? cfg->path : "none");
    emit_block(f, cfg->root, 0);
    int bad = fflush(f) != 0 || fsync(fileno(f)) != 0;
    bad |= fclose(f) != 0;
    if (bad || rename(tmp, path) != 0) {
        int e = errno;
        remove(tmp);
        free(tmp);
        return rths_error_set(err, RTHS_EFAIL, "cannot write %s: %s", path, strerror(e));
    }
    free(tmp);
    return RTHS_OK;
}

/* Sub-sections every command's setup reads (rths_setup_read: the actuator and sensor transforms,
 * docs/config/rig.md): reading them does not make a command the owner of their section, so
 * `rths model` still ignores the rest of `rig`. */
static const char *const setup_subsections[] = {"rig.actuators.", "rig.lasers.",
                                                "rig.interface_mass", NULL};

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
