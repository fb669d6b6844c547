/* What the view reads from a campaign folder (`rths campaign --out DIR`, docs/campaign.md):
 * campaign.csv (one row per run, rewritten atomically after every run), runs.csv (the index, the
 * only table before campaign.csv exists), plan.txt, and whether a campaign process holds
 * campaign.lock. Read only, through view_file_open like every file of a run (view_files.c). */
#include "view/view_internal.h"

#include <ctype.h>
#include <errno.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int view_is_campaign_dir(const char *dir) {
    return view_file_exists(dir, "campaign.csv") ||
           (view_file_exists(dir, "runs.csv") && view_file_exists(dir, "plan.txt"));
}

/* A run folder of the campaign: run_ and digits only (so never "..", a slash or a hidden name),
 * a folder itself (not a symbolic link) directly inside the campaign folder. */
int view_campaign_run_name(const char *name) {
    if (strncmp(name, "run_", 4) || !name[4] || strlen(name) > 16) return 0;
    for (const char *c = name + 4; *c; c++)
        if (!isdigit((unsigned char)*c)) return 0;
    return 1;
}

int view_campaign_run_dir(const char *campaign_dir, const char *name) {
    if (!view_campaign_run_name(name)) return 0;
    char *path = rths_path_join(campaign_dir, name);
    struct stat st;
    int ok = path && lstat(path, &st) == 0 && S_ISDIR(st.st_mode);
    free(path);
    return ok;
}

/* One CSV record (the campaign's writer quotes a field holding a comma, quote or line break,
 * doubling its quotes): fields appended to *fields (malloc'ed each). Returns the number of
 * fields, 0 at the end of the text, -1 out of memory. */
static int csv_record(const char **text, char ***fields, int *cap) {
    const char *s = *text;
    if (!*s) return 0;
    int n = 0;
    for (;;) {
        size_t len = 0, size = 64;
        char *f = malloc(size);
        if (!f) return -1;
        int quoted = *s == '"';
        if (quoted) s++;
        while (*s) {
            if (quoted && *s == '"' && s[1] == '"') {
                s++;
            } else if (quoted && *s == '"') {
                s++;
                quoted = 0;
                continue;
            } else if (!quoted && (*s == ',' || *s == '\n' || *s == '\r')) {
                break;
            }
            if (len + 2 > size) {
                char *g = realloc(f, size *= 2);
                if (!g) return free(f), -1;
                f = g;
            }
            f[len++] = *s++;
        }
        f[len] = 0;
        if (n == *cap) {
            int c = *cap ? 2 * *cap : 16;
            char **g = realloc(*fields, (size_t)c * sizeof *g);
            if (!g) return free(f), -1;
            *fields = g;
            *cap = c;
        }
        (*fields)[n++] = f;
        if (*s == ',') {
            s++;
            continue;
        }
        if (*s == '\r') s++;
        if (*s == '\n') s++;
        break;
    }
    *text = s;
    return n;
}

/* A field as JSON: empty is null (a run not finished yet), a number is a number, anything else
 * (a grid value such as "shaker", a run's name) is text. */
static json_object *field_value(const char *f) {
    if (!*f) return NULL;
    char *end;
    errno = 0;
    double x = strtod(f, &end);
    if (!*end && end != f && !errno && isfinite(x) && !isspace((unsigned char)*f)) {
        /* written as an integer (a seed, a count, an exit status): sent as one, every digit of
         * a 64-bit seed kept */
        if (!strpbrk(f, ".eEnN")) {
            errno = 0;
            long long i = strtoll(f, &end, 10);
            if (!*end && !errno) return json_object_new_int64(i);
            unsigned long long u = strtoull(f, &end, 10);
            if (!*end && !errno && *f != '-') return json_object_new_uint64(u);
        }
        return json_object_new_double(x);
    }
    if (!strcmp(f, "nan")) return NULL;
    return json_object_new_string(f);
}

/* The campaign's file NAME, whole, as text (NUL-terminated, malloc'ed): the HTTP status. */
static int read_text(const char *dir, const char *name, char **text, rths_error *err) {
    *text = NULL;
    view_file f;
    int status = view_file_open(dir, name, &f, err);
    if (status == 200) status = view_file_parse_check(&f, name, err);
    if (status == 200) {
        size_t size = (size_t)f.st.st_size, got = 0;
        char *buf = malloc(size + 1);
        while (buf && got < size) {
            ssize_t n = read(f.fd, buf + got, size - got);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) break; /* replaced meanwhile: what was there */
            got += (size_t)n;
        }
        if (!buf)
            status = (rths_error_set(err, RTHS_EFAIL, "out of memory"), 500);
        else {
            buf[got] = 0;
            *text = buf;
        }
    }
    view_file_close(&f);
    return status;
}

static void free_fields(char **fields, int n) {
    for (int i = 0; i < n; i++)
        free(fields[i]);
}

/* Whether a process holds an flock on the folder's campaign.lock (a campaign runs into it):
 * /proc/locks lists every lock on this machine by device and inode. Read only (the view takes no
 * lock, which could make a starting campaign find the folder in use); a campaign on another
 * machine of a shared disk does not show. */
static int campaign_locked(const char *dir) {
    char *path = rths_path_join(dir, "campaign.lock");
    struct stat st;
    int ok = path && lstat(path, &st) == 0 && S_ISREG(st.st_mode);
    free(path);
    if (!ok) return 0;
    FILE *f = fopen("/proc/locks", "r");
    if (!f) return 0;
    char line[256];
    int held = 0;
    while (!held && fgets(line, sizeof line, f)) {
        unsigned maj, min;
        unsigned long long ino;
        /* "1: FLOCK  ADVISORY  WRITE 1234 08:01:123456 0 EOF" (device numbers in hex) */
        if (!strstr(line, "FLOCK")) continue;
        const char *p = line;
        for (int field = 0; field < 5 && p; field++) {
            p = strchr(p, ' ');
            while (p && *p == ' ')
                p++;
        }
        /* the inode decides: on an overlay file system the lock is on the underlying file,
         * whose device differs from the one stat gives (its inode number does not) */
        if (p && sscanf(p, "%x:%x:%llu", &maj, &min, &ino) == 3)
            held = ino == (unsigned long long)st.st_ino;
    }
    fclose(f);
    return held;
}

int view_campaign_json(const char *dir, char **json, rths_error *err) {
    *json = NULL;
    const char *source = view_file_present(dir, "campaign.csv") ? "campaign.csv"
                         : view_file_present(dir, "runs.csv")   ? "runs.csv"
                                                                : NULL;
    char *text = NULL;
    int status = 200;
    if (source) status = read_text(dir, source, &text, err);
    if (status != 200) return status;
    json_object *root = json_object_new_object(), *columns = json_object_new_array(),
                *grid = json_object_new_array(), *outputs = json_object_new_array(),
                *runs = json_object_new_array(), *folders = json_object_new_array();
    char **fields = NULL, **header = NULL;
    int cap = 0, n_header = 0, n, seed_column = -1, exit_column = -1;
    int finished = 0, failed = 0;
    const char *p = text ? text : "";
    n = csv_record(&p, &fields, &cap);
    if (n > 0) {
        header = fields;
        n_header = n;
        fields = NULL;
        cap = 0;
        for (int c = 0; c < n_header; c++) {
            json_object_array_add(columns, json_object_new_string(header[c]));
            if (!strcmp(header[c], "seed") && seed_column < 0) seed_column = c;
            if (!strcmp(header[c], "exit_status")) exit_column = c;
        }
        /* run, the grid keys, seed, then the results (docs/campaign.md) */
        for (int c = 1; c < n_header; c++)
            if (c != seed_column)
                json_object_array_add(c < seed_column || seed_column < 0 ? grid : outputs,
                                      json_object_new_string(header[c]));
    }
    while (n >= 0 && (n = csv_record(&p, &fields, &cap)) > 0) {
        json_object *row = json_object_new_object();
        for (int c = 0; c < n_header; c++)
            json_object_object_add(row, header[c],
                                   c >= n   ? NULL
                                   : c == 0 ? json_object_new_string(fields[c])
                                            : field_value(fields[c]));
        int started = n > 0 && view_campaign_run_dir(dir, fields[0]);
        if (started) {
            char *run = rths_path_join(dir, fields[0]);
            rths_error ignored;
            started = run && !rths_view_check_run_dir(run, &ignored);
            free(run);
        }
        json_object_array_add(folders, json_object_new_boolean(started));
        if (exit_column >= 0 && exit_column < n && fields[exit_column][0]) {
            finished++;
            if (strcmp(fields[exit_column], "0")) failed++;
        }
        json_object_array_add(runs, row);
        free_fields(fields, n);
    }
    free(fields);
    if (n < 0) {
        status = (rths_error_set(err, RTHS_EFAIL, "out of memory"), 500);
    } else {
        int total = (int)json_object_array_length(runs);
        json_object_object_add(root, "kind", json_object_new_string("campaign"));
        json_object_object_add(root, "source", json_object_new_string(source ? source : "none"));
        json_object_object_add(root, "columns", columns);
        json_object_object_add(root, "grid", grid);
        json_object_object_add(root, "outputs", outputs);
        json_object_object_add(root, "runs", runs);
        json_object_object_add(root, "run_folders", folders);
        json_object_object_add(root, "total", json_object_new_int(total));
        json_object_object_add(root, "finished", json_object_new_int(finished));
        json_object_object_add(root, "failed", json_object_new_int(failed));
        columns = grid = outputs = runs = folders = NULL;
        if (!(*json = view_json_text(root)))
            status = (rths_error_set(err, RTHS_EFAIL, "out of memory"), 500);
    }
    json_object_put(columns);
    json_object_put(grid);
    json_object_put(outputs);
    json_object_put(runs);
    json_object_put(folders);
    json_object_put(root);
    free_fields(header, n_header);
    free(header);
    free(text);
    return status;
}

int rths_view_campaign_json(const char *dir, char **json, rths_error *err) {
    int status = view_campaign_json(dir, json, err);
    return status == 200 ? RTHS_OK : err->code ? err->code : RTHS_EFAIL;
}

json_object *view_campaign_state(const char *dir) {
    json_object *o = json_object_new_object();
    char *json = NULL;
    rths_error err = {0};
    json_object *table =
        view_campaign_json(dir, &json, &err) == 200 && json ? json_tokener_parse(json) : NULL;
    free(json);
    json_object *v;
    int total = 0, finished = 0, failed = 0;
    if (table && json_object_object_get_ex(table, "total", &v)) total = json_object_get_int(v);
    if (table && json_object_object_get_ex(table, "finished", &v))
        finished = json_object_get_int(v);
    if (table && json_object_object_get_ex(table, "failed", &v)) failed = json_object_get_int(v);
    json_object_put(table);
    int locked = campaign_locked(dir);
    /* running: a campaign process holds the folder; ended: every run has its exit status;
     * stopped: neither (interrupted, resumable; or run from another machine of a shared disk) */
    json_object_object_add(o, "state",
                           json_object_new_string(locked                           ? "running"
                                                  : total > 0 && finished == total ? "ended"
                                                                                   : "stopped"));
    json_object_object_add(o, "runs", json_object_new_int(total));
    json_object_object_add(o, "finished", json_object_new_int(finished));
    json_object_object_add(o, "failed", json_object_new_int(failed));
    /* plan.txt's first line: "config: PATH" */
    char *plan = NULL;
    rths_error ignored;
    if (read_text(dir, "plan.txt", &plan, &ignored) == 200 && !strncmp(plan, "config: ", 8)) {
        plan[8 + strcspn(plan + 8, "\n")] = 0;
        json_object_object_add(o, "config", json_object_new_string(plan + 8));
    }
    free(plan);
    return o;
}

int rths_view_check_folder(const char *dir, rths_error *err) {
    struct stat st;
    if (dir && dir[0] && stat(dir, &st) == 0 && S_ISDIR(st.st_mode) && view_is_campaign_dir(dir))
        return RTHS_OK;
    int rc = rths_view_check_run_dir(dir, err);
    if (rc && strstr(err->msg, "is not a run folder"))
        rths_error_set(err, RTHS_EINPUT,
                       "%s is not a run folder (it holds no journal.jsonl, frf.csv or live.json: "
                       "the folder given to 'rths frf --out') nor a campaign folder (no "
                       "campaign.csv: the folder given to 'rths campaign --out')",
                       dir);
    return rc;
}
