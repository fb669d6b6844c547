/* The resolved configuration written back as YAML (every value as read, --set applied), quoting
 * what a reader would otherwise take for another type. */
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
