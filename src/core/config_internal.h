/* Private to src/core/config*.c: the configuration's tree (every node's line and column, whether a
 * scalar was quoted, which nodes came from --set) and the functions one of its files calls in
 * another. config.c reads and locates, config_override.c applies --set, config_get.c and
 * config_list.c are the typed getters, config_check.c refuses unknown keys and config_write.c
 * writes the resolved document. */
#ifndef RTHS_CONFIG_INTERNAL_H
#define RTHS_CONFIG_INTERNAL_H

#include "rths/config.h"

#include <stddef.h>

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

/* Paths and --set texts can be as long as the system allows; in a message they are shortened in
 * the middle so the reason after them always fits (rths_error holds RTHS_ERROR_MSG_LEN bytes). */
#define MESSAGE_TEXT_MAX 1024

/* config.c */
/* UTF-8 validation a byte at a time, with the position of the character being read. */
typedef struct {
    long line, column; /* of the byte just stepped over (1-based) */
    int continuation;  /* continuation bytes still due */
    unsigned lo, hi;   /* the range of the next continuation byte */
    unsigned lead;     /* the last multi-byte lead byte, and where it was */
    long lead_line, lead_column;
} utf8_scan;

enum { UTF8_OK, UTF8_BAD, UTF8_NUL };

cnode *config_node_new(node_type type, int line, int column, const char *origin);
void config_node_free(cnode *n);
int config_node_grow(cnode *n);
int config_is_empty(const cnode *n);
int config_map_find(const cnode *map, const char *key, size_t len);
const char *config_short_text(const char *text, char *buf, size_t size);
int config_parse_source(const char *path, const char *text, const char *where, const char *origin,
                        int depth, cnode **root, rths_error *err);
int config_utf8_step(utf8_scan *u, unsigned char c);
void config_location(const rths_config *cfg, const cnode *n, int line, int column, char *buf,
                     size_t size);
int config_key_error(const rths_config *cfg, const char *key, const cnode *at, rths_error *err,
                     const char *fmt, ...) __attribute__((format(printf, 5, 6)));
int config_sequence_index(const cnode *n, const char *p, size_t len);
cnode *config_lookup(const rths_config *cfg, const char *key, int mark, cnode **deepest);

/* config_override.c */
int config_apply_override(rths_config *cfg, const char *text, rths_error *err);

/* config_get.c */
int config_edit_distance(const char *a, const char *b);
const char *config_describe(const cnode *n);
int config_get_node(rths_config *cfg, const char *key, int required, cnode **n, rths_error *err);
int config_scalar_number(rths_config *cfg, const char *key, const cnode *n, double *out,
                         rths_error *err);
int config_scalar_int(rths_config *cfg, const char *key, const cnode *n, long *out,
                      rths_error *err);

#endif
