/* libFuzzer target for the configuration reader (make fuzz).
 *
 * The input is a configuration file; when it holds a NUL byte, the text after the first NUL is
 * also applied as one --set override (so both the file and the override paths are reached). The
 * reader's contract, checked on every input beyond "no crash, no sanitizer report":
 *  - a load either succeeds with a configuration or fails with no configuration and a message
 *    that starts with where the problem is (the file or the --set);
 *  - an accepted configuration survives every getter on every key it holds (types and ranges are
 *    refused with a message, never a crash), and the unknown-key check either passes or names a
 *    key;
 *  - what rths_config_write writes back is itself a configuration the reader accepts.
 * The depth limit (RTHS_CONFIG_MAX_DEPTH) and the -max_len of the make rule bound the work per
 * input. */
#include "rths/config.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
const char *__lsan_default_suppressions(void);

/* libfyaml 0.8 leaks a scanner buffer when it stops on some malformed flow collections; that is
 * libfyaml's, not the reader's (the reader's own allocations stay checked). */
const char *__lsan_default_suppressions(void) {
    return "leak:libfyaml.so\n";
}

static int input_fd = -1;
static char input_path[64], written_path[256];

static void setup_files(void) {
    if (input_fd >= 0) return;
    input_fd = memfd_create("rths_fuzz_config", 0);
    if (input_fd < 0) abort();
    snprintf(input_path, sizeof input_path, "/proc/self/fd/%d", input_fd);
    char dir[] = "/tmp/rths_fuzz_config_XXXXXX";
    if (!mkdtemp(dir)) abort();
    snprintf(written_path, sizeof written_path, "%s/config.yaml", dir);
}

/* Every getter on key: each returns OK or EINPUT with a message, and frees what it allocates. */
static void read_key(rths_config *cfg, const char *key) {
    rths_error err;
    double d, *list = NULL, *matrix = NULL;
    long l;
    int b, count, rows, cols, *ints = NULL, choice;
    const char *s;
    static const char *const choices[] = {"a", "zoh", NULL};
    int rc[9] = {
        rths_config_get_double(cfg, key, 0, 0, -INFINITY, INFINITY, &d, &err),
        rths_config_get_double_ex(cfg, key, 0, 0.5, 0, 1, RTHS_CONFIG_LO_OPEN, &d, &err),
        rths_config_get_int(cfg, key, 0, 0, -5, 5, &l, &err),
        rths_config_get_bool(cfg, key, 0, 0, &b, &err),
        rths_config_get_string(cfg, key, 0, NULL, &s, &err),
        rths_config_get_choice(cfg, key, 0, 0, choices, &choice, &err),
        rths_config_get_double_list(cfg, key, 0, &list, &count, &err),
        rths_config_get_int_list(cfg, key, 0, &ints, &count, &err),
        rths_config_get_matrix(cfg, key, 0, &matrix, &rows, &cols, &err),
    };
    for (int k = 0; k < 9; k++)
        if (rc[k] != RTHS_OK && (rc[k] != RTHS_EINPUT || !err.msg[0])) abort();
    free(list);
    free(ints);
    free(matrix);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    setup_files();
    const uint8_t *nul = memchr(data, 0, size);
    size_t file_len = nul ? (size_t)(nul - data) : size;
    if (ftruncate(input_fd, 0) || pwrite(input_fd, data, file_len, 0) != (ssize_t)file_len) abort();
    char *override = NULL;
    if (nul) {
        override = strndup((const char *)nul + 1, size - file_len - 1);
        if (!override) abort();
    }
    const char *ov[1] = {override};
    rths_config *cfg = (rths_config *)&input_fd; /* must become NULL on failure */
    rths_error err = {0};
    int rc = rths_config_load(input_path, ov, override ? 1 : 0, &cfg, &err);
    if (rc != RTHS_OK) {
        if (cfg || rc != RTHS_EINPUT || !err.msg[0]) abort();
        if (strncmp(err.msg, input_path, strlen(input_path)) && strncmp(err.msg, "--set ", 6))
            abort();
        free(override);
        return 0;
    }
    /* the keys a reader would ask for: the top-level names and the override's key */
    static const char *const keys[] = {
        "a", "x", "split", "split.mass_ratio", "structure.masses", "rig.noise", "a.b", "x.y.z"};
    for (size_t k = 0; k < sizeof keys / sizeof keys[0]; k++)
        read_key(cfg, keys[k]);
    if (override && strchr(override, '=')) {
        *strchr(override, '=') = 0;
        read_key(cfg, override);
    }
    rths_config_section_read(cfg, "rig");
    rc = rths_config_check_unknown(cfg, &err);
    if (rc != RTHS_OK && (rc != RTHS_EINPUT || !strstr(err.msg, "unknown key"))) abort();
    rths_config_mark_known(cfg, NULL);
    if (rths_config_check_unknown(cfg, &err) != RTHS_OK) abort();
    if (rths_config_write(cfg, written_path, &err) != RTHS_OK) abort();
    rths_config *again = NULL;
    if (rths_config_load(written_path, NULL, 0, &again, &err) != RTHS_OK) {
        fprintf(stderr, "written configuration not accepted: %s\n", err.msg);
        abort();
    }
    rths_config_free(again);
    rths_config_free(cfg);
    free(override);
    return 0;
}
