/* The YAML configuration: every getter's value and every refusal, with the exact FILE:LINE:COL a
 * user would be sent to. The positions asserted here were counted by hand in the inline YAML
 * (1-based lines and columns), so a shifted location fails the test. */
#include "testlib.h"

#include "rths/config.h"

#include <limits.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char path[64];

/* Writes yaml to a fresh temporary file (its name goes into every message) and loads it. */
static int load(const char *yaml, const char *const *ov, int n, rths_config **cfg,
                rths_error *err) {
    snprintf(path, sizeof path, "/tmp/rths_test_config_XXXXXX");
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    FILE *f = fdopen(fd, "w");
    assert_non_null(f);
    fputs(yaml, f);
    fclose(f);
    return rths_config_load(path, ov, n, cfg, err);
}

static void done(rths_config *cfg) {
    rths_config_free(cfg);
    unlink(path);
}

/* err->msg must contain fmt (formatted; "%F" style is not used: pass path explicitly). */
__attribute__((format(printf, 2, 3))) static void msg_has(const rths_error *err, const char *fmt,
                                                          ...) {
    char want[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(want, sizeof want, fmt, ap);
    va_end(ap);
    if (!strstr(err->msg, want)) fail_msg("message\n  '%s'\nlacks\n  '%s'", err->msg, want);
}

/* Line numbers are in the comments; columns are 1-based. */
static const char *const main_yaml = "# getter test\n"                      /* 1 */
                                     "split:\n"                             /* 2 */
                                     "  mass_ratio: 0.5\n"                  /* 3: value col 15 */
                                     "  name: abc\n"                        /* 4: col 9 */
                                     "  neg: -1\n"                          /* 5: col 8 */
                                     "  big: 1.5\n"                         /* 6: col 8 */
                                     "  nan: .nan\n"                        /* 7 */
                                     "  inf: -.inf\n"                       /* 8 */
                                     "  sci: 1e-4\n"                        /* 9 */
                                     "  quoted: \"0.25\"\n"                 /* 10: col 11 */
                                     "  flag: yes\n"                        /* 11 */
                                     "  badflag: maybe\n"                   /* 12: col 12 */
                                     "  count: 7\n"                         /* 13: col 10 */
                                     "  frac: 2.5\n"                        /* 14: col 9 */
                                     "  list: [1, 2.5, -3e2]\n"             /* 15: 2.5 at 13 */
                                     "  badlist: [1, x, 3]\n"               /* 16: x at 16 */
                                     "  ints: [1, 2, 3]\n"                  /* 17 */
                                     "  matrix: [[1, 2], [3, 4], [5, 6]]\n" /* 18 */
                                     "  ragged: [[1, 2], [3]]\n"            /* 19: row 2 at 20 */
                                     "  method: zoh\n"                      /* 20: col 11 */
                                     "  empty:\n"                           /* 21: key col 3 */
                                     "  nested:\n"                          /* 22 */
                                     "    deep: 3\n"                        /* 23 */
                                     "top: 1\n"                             /* 24: value col 6 */
                                     "hexa: 0x10\n"                         /* 25: col 7 */
                                     "huge: 1e999\n"                        /* 26: col 7 */
                                     "tiny: 4.9e-324\n"                     /* 27 */
                                     "off: Off\n"                           /* 28 */
                                     "text: !!str 12\n";                    /* 29 */

static void test_doubles(void **state) {
    (void)state;
    rths_config *cfg;
    rths_error err;
    assert_int_equal(load(main_yaml, NULL, 0, &cfg, &err), RTHS_OK);
    double v = -7;
    assert_int_equal(rths_config_get_double(cfg, "split.mass_ratio", 1, 0, 0, 1, &v, &err),
                     RTHS_OK);
    assert_true(v == 0.5);
    assert_int_equal(rths_config_get_double(cfg, "split.sci", 1, 0, 0, 1, &v, &err), RTHS_OK);
    assert_true(v == 1e-4); /* the same double the compiler makes of 1e-4 */
    assert_int_equal(rths_config_get_double(cfg, "tiny", 1, 0, 0, 1, &v, &err), RTHS_OK);
    assert_true(v == 4.9e-324);
    assert_int_equal(rths_config_get_double(cfg, "split.nested.deep", 1, 0, 0, 10, &v, &err),
                     RTHS_OK);
    assert_true(v == 3);
    /* absent optional: the default; absent required: located at the parent section */
    assert_int_equal(rths_config_get_double(cfg, "split.absent", 0, 42.5, 0, 100, &v, &err),
                     RTHS_OK);
    assert_true(v == 42.5);
    assert_int_equal(rths_config_get_double(cfg, "split.absent", 1, 0, 0, 1, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:3:3: key 'split.absent': is required but missing", path);
    assert_int_equal(rths_config_get_double(cfg, "nosection.x", 1, 0, 0, 1, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s: key 'nosection.x': is required but missing", path);

    v = -7;
    assert_int_equal(rths_config_get_double(cfg, "split.name", 1, 0, 0, 1, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s:4:9: key 'split.name': expected a number, got 'abc'", path);
    assert_true(v == -7); /* untouched on error */
    assert_int_equal(rths_config_get_double(cfg, "split.neg", 1, 0, 0, INFINITY, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:5:8: key 'split.neg': must be >= 0 (got -1)", path);
    assert_int_equal(rths_config_get_double_ex(cfg, "split.neg", 1, 0, 0, INFINITY,
                                               RTHS_CONFIG_LO_OPEN, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:5:8: key 'split.neg': must be > 0 (got -1)", path);
    assert_int_equal(rths_config_get_double(cfg, "split.neg", 1, 0, -INFINITY, -2, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "key 'split.neg': must be <= -2 (got -1)");
    assert_int_equal(rths_config_get_double(cfg, "split.big", 1, 0, 0, 1, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s:6:8: key 'split.big': must be in [0, 1] (got 1.5)", path);
    assert_int_equal(rths_config_get_double_ex(cfg, "split.mass_ratio", 1, 0, 0, 0.5,
                                               RTHS_CONFIG_LO_OPEN | RTHS_CONFIG_HI_OPEN, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:3:15: key 'split.mass_ratio': must be in (0, 0.5) (got 0.5)", path);
    assert_int_equal(rths_config_get_double(cfg, "split.nan", 1, 0, -INFINITY, INFINITY, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:7:8: key 'split.nan': NaN/inf is not allowed", path);
    assert_int_equal(rths_config_get_double(cfg, "split.inf", 1, 0, -INFINITY, INFINITY, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:8:8: key 'split.inf': NaN/inf is not allowed", path);
    assert_int_equal(rths_config_get_double(cfg, "split.quoted", 1, 0, 0, 1, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:10:11: key 'split.quoted': expected a number, got the quoted text '0.25'",
            path);
    assert_int_equal(rths_config_get_double(cfg, "hexa", 1, 0, 0, 100, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s:25:7: key 'hexa': expected a number, got '0x10'", path);
    assert_int_equal(rths_config_get_double(cfg, "huge", 1, 0, 0, INFINITY, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s:26:7: key 'huge': '1e999' is out of range", path);
    assert_int_equal(rths_config_get_double(cfg, "text", 1, 0, 0, INFINITY, &v, &err), RTHS_EINPUT);
    msg_has(&err, "key 'text': expected a number, got the quoted text '12'");
    /* an empty value is located at its key */
    assert_int_equal(rths_config_get_double(cfg, "split.empty", 0, 1, 0, 2, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s:21:3: key 'split.empty': has no value", path);
    /* below a scalar: refused even when optional, else the value would be silently ignored */
    assert_int_equal(rths_config_get_double(cfg, "top.x", 0, 1, 0, 2, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s:24:6: key 'top.x': cannot be read: its parent is text, not a mapping", path);
    /* a list where a number belongs */
    assert_int_equal(rths_config_get_double(cfg, "split.list", 1, 0, -INFINITY, INFINITY, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:15:9: key 'split.list': expected a number, got a list", path);
    done(cfg);
}

static void test_ints_bools_strings_choices(void **state) {
    (void)state;
    rths_config *cfg;
    rths_error err;
    assert_int_equal(load(main_yaml, NULL, 0, &cfg, &err), RTHS_OK);
    long i = -1;
    assert_int_equal(rths_config_get_int(cfg, "split.count", 1, 0, 0, 10, &i, &err), RTHS_OK);
    assert_int_equal(i, 7);
    assert_int_equal(rths_config_get_int(cfg, "split.count", 1, 0, 8, 10, &i, &err), RTHS_EINPUT);
    msg_has(&err, "%s:13:10: key 'split.count': must be in [8, 10] (got 7)", path);
    assert_int_equal(rths_config_get_int(cfg, "split.count", 1, 0, 8, LONG_MAX, &i, &err),
                     RTHS_EINPUT);
    msg_has(&err, "key 'split.count': must be >= 8 (got 7)");
    assert_int_equal(rths_config_get_int(cfg, "split.frac", 1, 0, 0, 10, &i, &err), RTHS_EINPUT);
    msg_has(&err, "%s:14:9: key 'split.frac': expected an integer, got '2.5'", path);
    assert_int_equal(rths_config_get_int(cfg, "split.absent", 0, 5, 0, 10, &i, &err), RTHS_OK);
    assert_int_equal(i, 5);

    int b = -1;
    assert_int_equal(rths_config_get_bool(cfg, "split.flag", 1, 0, &b, &err), RTHS_OK);
    assert_int_equal(b, 1);
    assert_int_equal(rths_config_get_bool(cfg, "off", 1, 1, &b, &err), RTHS_OK);
    assert_int_equal(b, 0);
    assert_int_equal(rths_config_get_bool(cfg, "split.absent", 0, 1, &b, &err), RTHS_OK);
    assert_int_equal(b, 1);
    assert_int_equal(rths_config_get_bool(cfg, "split.badflag", 1, 0, &b, &err), RTHS_EINPUT);
    msg_has(&err, "%s:12:12: key 'split.badflag': expected true or false, got 'maybe'", path);

    const char *s = NULL;
    assert_int_equal(rths_config_get_string(cfg, "split.name", 1, NULL, &s, &err), RTHS_OK);
    assert_string_equal(s, "abc");
    assert_int_equal(rths_config_get_string(cfg, "split.quoted", 1, NULL, &s, &err), RTHS_OK);
    assert_string_equal(s, "0.25");
    assert_int_equal(rths_config_get_string(cfg, "text", 1, NULL, &s, &err), RTHS_OK);
    assert_string_equal(s, "12");
    assert_int_equal(rths_config_get_string(cfg, "split.absent", 0, "dflt", &s, &err), RTHS_OK);
    assert_string_equal(s, "dflt");
    assert_int_equal(rths_config_get_string(cfg, "split.nested", 1, NULL, &s, &err), RTHS_EINPUT);
    msg_has(&err, "key 'split.nested': expected text, got a mapping");

    static const char *const methods[] = {"ieuler", "zoh", NULL};
    static const char *const other[] = {"a", "b", NULL};
    int idx = -1;
    assert_int_equal(rths_config_get_choice(cfg, "split.method", 1, 0, methods, &idx, &err),
                     RTHS_OK);
    assert_int_equal(idx, 1);
    assert_int_equal(rths_config_get_choice(cfg, "split.absent", 0, 0, methods, &idx, &err),
                     RTHS_OK);
    assert_int_equal(idx, 0);
    assert_int_equal(rths_config_get_choice(cfg, "split.method", 1, 0, other, &idx, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:20:11: key 'split.method': 'zoh' is not one of 'a', 'b'", path);
    done(cfg);
}

static void test_lists_and_matrices(void **state) {
    (void)state;
    rths_config *cfg;
    rths_error err;
    assert_int_equal(load(main_yaml, NULL, 0, &cfg, &err), RTHS_OK);
    double *d = NULL;
    int count = -1;
    assert_int_equal(rths_config_get_double_list(cfg, "split.list", 1, &d, &count, &err), RTHS_OK);
    assert_int_equal(count, 3);
    assert_true(d[0] == 1 && d[1] == 2.5 && d[2] == -300);
    free(d);
    assert_int_equal(rths_config_get_double_list(cfg, "split.badlist", 1, &d, &count, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:16:16: key 'split.badlist': expected a number, got 'x'", path);
    assert_null(d);
    assert_int_equal(rths_config_get_double_list(cfg, "split.name", 1, &d, &count, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:4:9: key 'split.name': expected a list of numbers", path);
    assert_int_equal(rths_config_get_double_list(cfg, "split.absent", 0, &d, &count, &err),
                     RTHS_OK);
    assert_null(d);
    assert_int_equal(count, 0);

    int *iv = NULL;
    assert_int_equal(rths_config_get_int_list(cfg, "split.ints", 1, &iv, &count, &err), RTHS_OK);
    assert_int_equal(count, 3);
    assert_true(iv[0] == 1 && iv[1] == 2 && iv[2] == 3);
    free(iv);
    assert_int_equal(rths_config_get_int_list(cfg, "split.list", 1, &iv, &count, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:15:13: key 'split.list': expected an integer, got '2.5'", path);

    double *m = NULL;
    int rows = -1, cols = -1;
    assert_int_equal(rths_config_get_matrix(cfg, "split.matrix", 1, &m, &rows, &cols, &err),
                     RTHS_OK);
    assert_int_equal(rows, 3);
    assert_int_equal(cols, 2);
    /* column-major: (i, j) at m[i + 3 j] */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 2; j++)
            assert_true(RTHS_AT(m, 3, i, j) == 2 * i + j + 1);
    free(m);
    assert_int_equal(rths_config_get_matrix(cfg, "split.ragged", 1, &m, &rows, &cols, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:19:20: key 'split.ragged': row 2 has 1 entries, row 1 has 2", path);
    assert_null(m);
    assert_int_equal(rths_config_get_matrix(cfg, "split.list", 1, &m, &rows, &cols, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:15:10: key 'split.list': row 1 is not a list of numbers", path);
    done(cfg);
}

static void test_overrides(void **state) {
    (void)state;
    rths_config *cfg;
    rths_error err;
    const char *ok[] = {"split.mass_ratio=0.25", "new.section.values=[1, 2.5]",
                        "split.empty.child=on"};
    assert_int_equal(load(main_yaml, ok, 3, &cfg, &err), RTHS_OK);
    double v;
    assert_int_equal(rths_config_get_double(cfg, "split.mass_ratio", 1, 0, 0, 1, &v, &err),
                     RTHS_OK);
    assert_true(v == 0.25);
    double *d;
    int count;
    assert_int_equal(rths_config_get_double_list(cfg, "new.section.values", 1, &d, &count, &err),
                     RTHS_OK);
    assert_int_equal(count, 2);
    assert_true(d[0] == 1 && d[1] == 2.5);
    free(d);
    int b = 0;
    assert_int_equal(rths_config_get_bool(cfg, "split.empty.child", 1, 0, &b, &err), RTHS_OK);
    assert_int_equal(b, 1);
    /* the replaced value is still under its file key, the untouched ones too */
    assert_int_equal(rths_config_get_double(cfg, "split.big", 1, 0, 0, 1, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s:6:8:", path);
    done(cfg);

    /* a value of the wrong type from --set is located at the --set text */
    const char *bad_type[] = {"split.mass_ratio=abc"};
    assert_int_equal(load(main_yaml, bad_type, 1, &cfg, &err), RTHS_OK);
    assert_int_equal(rths_config_get_double(cfg, "split.mass_ratio", 1, 0, 0, 1, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "--set split.mass_ratio=abc: key 'split.mass_ratio': expected a number, got "
                  "'abc'");
    done(cfg);

    struct {
        const char *ov, *want;
    } bad[] = {
        {"noequals", "--set noequals: expected dotted.key=value"},
        {"=5", "--set =5: expected dotted.key=value"},
        {"a..b=1", "--set a..b=1: the key has an empty part"},
        {"split.=1", "--set split.=1: the key has an empty part"},
        {"top.x=1", "--set top.x=1: 'top' is not a mapping"},
        {"split.list=[1, 2", "--set split.list=[1, 2: not valid YAML"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        const char *one[] = {bad[k].ov};
        cfg = (rths_config *)&err; /* must be reset to NULL on failure */
        assert_int_equal(load(main_yaml, one, 1, &cfg, &err), RTHS_EINPUT);
        assert_null(cfg);
        msg_has(&err, "%s", bad[k].want);
        unlink(path);
    }
}

static void test_unknown_keys(void **state) {
    (void)state;
    const char *yaml = "split:\n"
                       "  mass_ratio: 0.5\n"
                       "  mas_ratio: 0.4\n"
                       "other:\n"
                       "  x: 1\n"
                       "forcing:\n"
                       "  amplitud_n: 2\n";
    rths_config *cfg;
    rths_error err;
    assert_int_equal(load(yaml, NULL, 0, &cfg, &err), RTHS_OK);
    double v;
    assert_int_equal(rths_config_get_double(cfg, "split.mass_ratio", 1, 0, 0, 1, &v, &err),
                     RTHS_OK);
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:3:3: unknown key 'split.mas_ratio' (did you mean 'split.mass_ratio'?)", path);
    rths_config_mark_known(cfg, "split");
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:4:1: unknown key 'other'", path);
    /* has() does not count as reading */
    assert_true(rths_config_has(cfg, "other.x"));
    assert_false(rths_config_has(cfg, "other.y"));
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_EINPUT);
    msg_has(&err, "unknown key 'other'");
    assert_int_equal(rths_config_get_double(cfg, "other.x", 1, 0, 0, 1, &v, &err), RTHS_OK);
    /* an optional key that was asked for but is absent is still a spelling candidate */
    assert_int_equal(rths_config_get_double(cfg, "forcing.amplitude_n", 0, 1, 0, 9, &v, &err),
                     RTHS_OK);
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:7:3: unknown key 'forcing.amplitud_n' (did you mean 'forcing.amplitude_n'?)",
            path);
    rths_config_mark_known(cfg, NULL);
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_OK);
    done(cfg);

    /* a key created by --set that nobody reads is located at the --set */
    const char *ov[] = {"extra.thing=1"};
    assert_int_equal(load("a: 1\n", ov, 1, &cfg, &err), RTHS_OK);
    long i;
    assert_int_equal(rths_config_get_int(cfg, "a", 1, 0, 0, 9, &i, &err), RTHS_OK);
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_EINPUT);
    msg_has(&err, "--set extra.thing=1: unknown key 'extra'");
    done(cfg);
}

static void test_document_errors(void **state) {
    (void)state;
    rths_config *cfg = NULL;
    rths_error err;
    assert_int_equal(load("a:\n  b: 1\n  b: 2\n", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:3:3: duplicate key 'b' in this mapping (first at line 2)", path);
    assert_null(cfg);
    unlink(path);
    assert_int_equal(load("a: 1\nb: [1, 2\nc: 3\n", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:", path);
    msg_has(&err, "not valid YAML");
    msg_has(&err, "bracket");
    unlink(path);
    assert_int_equal(load("a:\n\tb: 1\n", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:2:", path);
    unlink(path);
    assert_int_equal(load("- 1\n- 2\n", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:1:1: the configuration must be a mapping", path);
    unlink(path);
    assert_int_equal(load("a: &x 1\nb: *x\n", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:2:4: YAML aliases are not supported", path);
    unlink(path);
    assert_int_equal(load("split:\n  mass.ratio: 1\n", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:2:3: key 'mass.ratio': keys may not be empty or contain '.'", path);
    unlink(path);
    assert_int_equal(load("a: 1\n---\nb: 2\n", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:2:1: a configuration is one YAML document", path);
    unlink(path);
    assert_int_equal(rths_config_load("/nonexistent/rths.yaml", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "/nonexistent/rths.yaml: cannot read the configuration");
    /* an empty file and no file at all: everything takes defaults */
    assert_int_equal(load("# nothing\n", NULL, 0, &cfg, &err), RTHS_OK);
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_OK);
    done(cfg);
    assert_int_equal(rths_config_load(NULL, NULL, 0, &cfg, &err), RTHS_OK);
    assert_null(rths_config_path(cfg));
    double v = 0;
    assert_int_equal(rths_config_get_double(cfg, "x.y", 0, 2.5, 0, 9, &v, &err), RTHS_OK);
    assert_true(v == 2.5);
    assert_int_equal(rths_config_get_double(cfg, "x.y", 1, 2.5, 0, 9, &v, &err), RTHS_EINPUT);
    msg_has(&err, "key 'x.y': is required but missing");
    rths_config_free(cfg);
}

static void test_error_at(void **state) {
    (void)state;
    rths_config *cfg;
    rths_error err;
    assert_int_equal(load(main_yaml, NULL, 0, &cfg, &err), RTHS_OK);
    assert_int_equal(rths_config_error_at(cfg, "split.matrix", &err, "must be %s", "square"),
                     RTHS_EINPUT);
    assert_int_equal(err.code, RTHS_EINPUT);
    msg_has(&err, "%s:18:11: key 'split.matrix': must be square", path);
    assert_int_equal(rths_config_error_at(cfg, "split.nothing", &err, "needed"), RTHS_EINPUT);
    msg_has(&err, "%s:3:3: key 'split.nothing': needed", path);
    done(cfg);
}

/* Written out, the resolved document reads back to the same values (negative numbers stay
 * numbers, quoted text stays text, empty stays empty), and no temporary is left. */
static void test_write_round_trip(void **state) {
    (void)state;
    rths_config *cfg, *back;
    rths_error err;
    const char *ov[] = {"split.mass_ratio=0.125", "x.y=\"a, b: c\""};
    assert_int_equal(load(main_yaml, ov, 2, &cfg, &err), RTHS_OK);
    char out[96];
    snprintf(out, sizeof out, "%s.resolved.yaml", path);
    assert_int_equal(rths_config_write(cfg, out, &err), RTHS_OK);
    char tmp[128];
    snprintf(tmp, sizeof tmp, "%s.tmp.%ld", out, (long)getpid());
    assert_int_equal(access(tmp, F_OK), -1);
    assert_int_equal(rths_config_load(out, NULL, 0, &back, &err), RTHS_OK);
    double a, b;
    const char *sa, *sb;
    assert_int_equal(rths_config_get_double(back, "split.mass_ratio", 1, 0, 0, 1, &b, &err),
                     RTHS_OK);
    assert_true(b == 0.125);
    const char *num[] = {"split.neg", "split.sci", "tiny", "split.nested.deep"};
    for (int k = 0; k < 4; k++) {
        assert_int_equal(rths_config_get_double(cfg, num[k], 1, 0, -9, 9, &a, &err), RTHS_OK);
        assert_int_equal(rths_config_get_double(back, num[k], 1, 0, -9, 9, &b, &err), RTHS_OK);
        assert_true(a == b);
    }
    const char *str[] = {"split.quoted", "x.y", "text", "split.name"};
    for (int k = 0; k < 4; k++) {
        assert_int_equal(rths_config_get_string(cfg, str[k], 1, NULL, &sa, &err), RTHS_OK);
        assert_int_equal(rths_config_get_string(back, str[k], 1, NULL, &sb, &err), RTHS_OK);
        assert_string_equal(sa, sb);
    }
    assert_int_equal(rths_config_get_double(back, "split.quoted", 1, 0, 0, 1, &b, &err),
                     RTHS_EINPUT);
    assert_int_equal(rths_config_get_double(back, "split.empty", 0, 0, 0, 1, &b, &err),
                     RTHS_EINPUT);
    msg_has(&err, "has no value");
    double *m1, *m2;
    int r1, c1, r2, c2;
    assert_int_equal(rths_config_get_matrix(cfg, "split.matrix", 1, &m1, &r1, &c1, &err), RTHS_OK);
    assert_int_equal(rths_config_get_matrix(back, "split.matrix", 1, &m2, &r2, &c2, &err), RTHS_OK);
    assert_int_equal(r1, r2);
    assert_int_equal(c1, c2);
    assert_memory_equal(m1, m2, sizeof(double) * (size_t)(r1 * c1));
    free(m1);
    free(m2);
    rths_config_free(back);
    unlink(out);
    done(cfg);
}

/* Writes len raw bytes (NULs, byte-order marks) to a fresh temporary file and loads it. */
static int load_bytes(const char *bytes, size_t len, rths_config **cfg, rths_error *err) {
    snprintf(path, sizeof path, "/tmp/rths_test_config_XXXXXX");
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, bytes, len), (ssize_t)len);
    close(fd);
    return rths_config_load(path, NULL, 0, cfg, err);
}

/* "x: [[...]]" with `levels` brackets (the root mapping is one more level). */
static char *nested_list(const char *prefix, int levels) {
    size_t pl = strlen(prefix);
    char *t = malloc(pl + 2 * (size_t)levels + 2);
    assert_non_null(t);
    memcpy(t, prefix, pl);
    memset(t + pl, '[', (size_t)levels);
    memset(t + pl + levels, ']', (size_t)levels);
    strcpy(t + pl + 2 * (size_t)levels, "\n");
    return t;
}

/* Nesting is bounded (the tree is built, checked, written and freed by recursion: 60 000 levels
 * overflowed the stack): RTHS_CONFIG_MAX_DEPTH levels pass, one more is refused where it opens. */
static void test_depth_limit(void **state) {
    (void)state;
    rths_config *cfg = NULL;
    rths_error err;
    char *ok = nested_list("x: ", RTHS_CONFIG_MAX_DEPTH - 1);
    assert_int_equal(load(ok, NULL, 0, &cfg, &err), RTHS_OK);
    done(cfg);
    free(ok);
    const int too_deep[] = {RTHS_CONFIG_MAX_DEPTH, 60000};
    for (int k = 0; k < 2; k++) {
        char *deep = nested_list("x: ", too_deep[k]);
        assert_int_equal(load(deep, NULL, 0, &cfg, &err), RTHS_EINPUT);
        assert_null(cfg);
        /* the 64th '[' opens level 65: column 3 + 64 */
        msg_has(&err, "%s:1:%d: nested deeper than %d levels", path, 3 + RTHS_CONFIG_MAX_DEPTH,
                RTHS_CONFIG_MAX_DEPTH);
        unlink(path);
        free(deep);
    }
    /* flow mappings under a key nobody reads are bounded alike */
    char flow[8192] = "zz: ";
    for (int i = 0; i < 1000; i++)
        strcat(flow, "{a: ");
    assert_int_equal(load(flow, NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:1:%d: nested deeper than", path, 5 + 4 * (RTHS_CONFIG_MAX_DEPTH - 1));
    unlink(path);
    /* --set: the key's levels count (root, a, b: the value's list is level 3) */
    char *set_ok = nested_list("a.b=", RTHS_CONFIG_MAX_DEPTH - 2);
    set_ok[strlen(set_ok) - 1] = 0;
    const char *ov[] = {set_ok};
    assert_int_equal(load("a: {}\n", ov, 1, &cfg, &err), RTHS_OK);
    done(cfg);
    char *set_deep = nested_list("a.b=", RTHS_CONFIG_MAX_DEPTH - 1);
    set_deep[strlen(set_deep) - 1] = 0;
    ov[0] = set_deep;
    assert_int_equal(load("a: {}\n", ov, 1, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "nested deeper than %d levels", RTHS_CONFIG_MAX_DEPTH);
    assert_true(strncmp(err.msg, "--set a.b=[[[", 13) == 0);
    unlink(path);
    free(set_ok);
    free(set_deep);
    /* a dotted key alone deeper than the limit */
    char key[4 * RTHS_CONFIG_MAX_DEPTH + 8] = "";
    for (int i = 0; i < RTHS_CONFIG_MAX_DEPTH; i++)
        strcat(key, "a.");
    strcat(key, "b=1");
    ov[0] = key;
    assert_int_equal(load("a: {}\n", ov, 1, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "the key is nested deeper than %d levels", RTHS_CONFIG_MAX_DEPTH);
    unlink(path);
}

/* A mapping of many keys: every key readable, and a duplicate found however far apart (the
 * keys' hash grows from 16 slots to 262 144 on the way, so every rehash is crossed). */
static void test_many_keys(void **state) {
    (void)state;
    enum { KEYS = 80000 };
    size_t cap = (size_t)KEYS * 24 + 64, len = 0;
    char *yaml = malloc(cap);
    assert_non_null(yaml);
    len += (size_t)snprintf(yaml + len, cap - len, "big:\n");
    for (int i = 0; i < KEYS; i++)
        len += (size_t)snprintf(yaml + len, cap - len, "  k%d: %d\n", i, i);
    rths_config *cfg = NULL;
    rths_error err;
    assert_int_equal(load(yaml, NULL, 0, &cfg, &err), RTHS_OK);
    long v;
    for (int i = 0; i < KEYS; i += 7919) {
        char key[32];
        snprintf(key, sizeof key, "big.k%d", i);
        assert_int_equal(rths_config_get_int(cfg, key, 1, -1, 0, KEYS, &v, &err), RTHS_OK);
        assert_int_equal(v, i);
    }
    done(cfg);
    /* the first key again at the end: line 2 first, line KEYS + 2 the duplicate */
    snprintf(yaml + len, cap - len, "  k0: 1\n");
    assert_int_equal(load(yaml, NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:%d:3: duplicate key 'k0' in this mapping (first at line 2)", path, KEYS + 2);
    unlink(path);
    free(yaml);
}

/* What libfyaml reads as an empty document (a folder, a UTF-16 file, a lone byte-order mark) or
 * as text (NUL, bytes that are not UTF-8) is named for what it is, not "structure missing". */
static void test_not_utf8_text(void **state) {
    (void)state;
    rths_config *cfg = NULL;
    rths_error err;
    assert_int_equal(load_bytes("\xff\xfe", 2, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s: starts with a UTF-16/UTF-32 byte-order mark (FF FE)", path);
    unlink(path);
    /* "a: 1\n" in UTF-16 big-endian with its mark */
    assert_int_equal(load_bytes("\xfe\xff\0a\0:\0 \0"
                                "1\0\n",
                                12, &cfg, &err),
                     RTHS_EINPUT);
    msg_has(&err, "byte-order mark (FE FF)");
    unlink(path);
    /* UTF-16 little-endian without a mark: a NUL after the first character */
    assert_int_equal(load_bytes("a\0:\0 \0"
                                "1\0\n\0",
                                10, &cfg, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:1:2: a NUL byte: the configuration must be UTF-8 text", path);
    unlink(path);
    assert_int_equal(load_bytes("a: 1\nb: caf\xe9\n", 13, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:2:7: byte 0xE9 does not start a UTF-8 character here", path);
    assert_int_equal(load_bytes("a: 1\nb: \xff\n", 9, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:2:4: byte 0xFF does not start a UTF-8 character here", path);
    unlink(path);
    /* overlong (E0 96 ...), a surrogate (ED A0 80), beyond U+10FFFF (F4 90 ...): not UTF-8 either
     * (an overlong one reached config.yaml through a --set and failed to reload: make fuzz) */
    const char *not_utf8[] = {"a: \xe0\x96\x91\n", "a: \xed\xa0\x80\n", "a: \xf4\x90\x80\x80\n"};
    for (int k = 0; k < 3; k++) {
        assert_int_equal(load_bytes(not_utf8[k], strlen(not_utf8[k]), &cfg, &err), RTHS_EINPUT);
        msg_has(&err, "%s:1:4: byte 0x", path);
        unlink(path);
    }
    assert_int_equal(load_bytes("a: caf\xc3", 7, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s: ends inside a UTF-8 character", path);
    unlink(path);
    /* libfyaml 0.7 loops forever in its directive scanner on '%' followed by a byte that is not
     * UTF-8 (libfyaml issue 101, fixed upstream in 2023): refused before libfyaml sees it, from a
     * file and from a --set */
    assert_int_equal(load_bytes("%\"\xa6", 3, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s:1:3: byte 0xA6 does not start a UTF-8 character here", path);
    unlink(path);
    const char *directive[] = {"a=%\"\xa6"};
    assert_int_equal(rths_config_load(NULL, directive, 1, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "not UTF-8 text");
    /* valid UTF-8 (a BOM included) passes */
    assert_int_equal(load_bytes("\xef\xbb\xbf"
                                "a: caf\xc3\xa9\n",
                                12, &cfg, &err),
                     RTHS_OK);
    const char *text;
    assert_int_equal(rths_config_get_string(cfg, "a", 1, NULL, &text, &err), RTHS_OK);
    assert_string_equal(text, "caf\xc3\xa9");
    done(cfg);
    assert_int_equal(rths_config_load("/tmp", NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "/tmp: is a folder; the configuration is a YAML file");
}

/* A path of any length keeps the reason at the end of the message. */
static void test_long_paths(void **state) {
    (void)state;
    rths_config *cfg = NULL;
    rths_error err;
    size_t len = 6000;
    char *p = malloc(len + 1);
    assert_non_null(p);
    memset(p, 'a', len);
    memcpy(p, "/tmp/", 5);
    for (size_t i = 100; i < len; i += 100)
        p[i] = '/'; /* names within NAME_MAX, the whole beyond PATH_MAX */
    p[len] = 0;
    assert_int_equal(rths_config_load(p, NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "cannot read the configuration: File name too long");
    assert_true(strlen(err.msg) < 1200);
    memset(p + 5, 'a', 295); /* one name of 295 bytes */
    p[300] = 0;
    assert_int_equal(rths_config_load(p, NULL, 0, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "%s: cannot read the configuration: File name too long", p);
    free(p);
    /* a --set text of any length, too */
    char *ov_text = malloc(20000);
    assert_non_null(ov_text);
    strcpy(ov_text, "a=");
    memset(ov_text + 2, 'x', 19990);
    strcpy(ov_text + 19992, ": [");
    const char *ov[] = {ov_text};
    assert_int_equal(load("a: 1\n", ov, 1, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "not valid YAML");
    unlink(path);
    free(ov_text);
}

/* Keys that are not plain names (quoted in the file, or any text in a --set key) are written back
 * quoted, so config.yaml stays a configuration the reader accepts (found by make fuzz: a --set key
 * with '#' and a line break was written raw). */
static void test_write_odd_keys(void **state) {
    (void)state;
    rths_config *cfg = NULL, *back = NULL;
    rths_error err;
    const char *ov[] = {"k# x\n y: z=1", "[a]=2"};
    assert_int_equal(load("\"odd: key\": 1\n'#k': {'- x': 3}\n", ov, 2, &cfg, &err), RTHS_OK);
    char out[] = "/tmp/rths_test_config_odd_XXXXXX";
    int fd = mkstemp(out);
    assert_true(fd >= 0);
    close(fd);
    assert_int_equal(rths_config_write(cfg, out, &err), RTHS_OK);
    assert_int_equal(rths_config_load(out, NULL, 0, &back, &err), RTHS_OK);
    const char *keys[] = {"odd: key", "#k.- x", "k# x\n y: z", "[a]"};
    const long want[] = {1, 3, 1, 2};
    for (int k = 0; k < 4; k++) {
        long v = 0;
        assert_int_equal(rths_config_get_int(back, keys[k], 1, 0, 0, 9, &v, &err), RTHS_OK);
        assert_int_equal(v, want[k]);
    }
    assert_int_equal(rths_config_check_unknown(back, &err), RTHS_OK);
    /* and a --set that is not UTF-8 is refused like such a file */
    const char *bad[] = {"a=caf\xe9"};
    rths_config_free(back);
    assert_int_equal(rths_config_load(NULL, bad, 1, &back, &err), RTHS_EINPUT);
    msg_has(&err, "not UTF-8 text");
    unlink(out);
    done(cfg);
}

/* One wording for every range: two-sided with its brackets, one-sided without an infinity. */
static void test_range_text(void **state) {
    (void)state;
    char b[128];
    assert_string_equal(rths_config_range_text(0, 1, 0, b, sizeof b), "in [0, 1]");
    assert_string_equal(
        rths_config_range_text(0, 1, RTHS_CONFIG_LO_OPEN | RTHS_CONFIG_HI_OPEN, b, sizeof b),
        "in (0, 1)");
    assert_string_equal(rths_config_range_text(0, 1e5, RTHS_CONFIG_LO_OPEN, b, sizeof b),
                        "in (0, 100000]");
    assert_string_equal(rths_config_range_text(-INFINITY, 1e5, 0, b, sizeof b), "<= 100000");
    assert_string_equal(rths_config_range_text(-INFINITY, 1, RTHS_CONFIG_HI_OPEN, b, sizeof b),
                        "< 1");
    assert_string_equal(rths_config_range_text(0, INFINITY, RTHS_CONFIG_LO_OPEN, b, sizeof b),
                        "> 0");
    rths_config *cfg = NULL;
    rths_error err;
    double v;
    assert_int_equal(load("p: 1\nf: 2e5\n", NULL, 0, &cfg, &err), RTHS_OK);
    assert_int_equal(rths_config_get_double_ex(cfg, "p", 1, 0.5, 0, 1,
                                               RTHS_CONFIG_LO_OPEN | RTHS_CONFIG_HI_OPEN, &v, &err),
                     RTHS_EINPUT);
    msg_has(&err, "%s:1:4: key 'p': must be in (0, 1) (got 1)", path);
    assert_int_equal(rths_config_get_double(cfg, "f", 1, 0, -INFINITY, 1e5, &v, &err), RTHS_EINPUT);
    msg_has(&err, "%s:2:4: key 'f': must be <= 100000 (got 2e5)", path);
    done(cfg);
}

/* A section counts as read once a getter asked for one of its keys, present or not. */
static void test_section_read(void **state) {
    (void)state;
    rths_config *cfg = NULL;
    rths_error err;
    assert_int_equal(load("rig:\n  nosie: false\nrigging: 1\n", NULL, 0, &cfg, &err), RTHS_OK);
    assert_false(rths_config_section_read(cfg, "rig"));
    int b;
    assert_int_equal(rths_config_get_bool(cfg, "rigging2.x", 0, 1, &b, &err), RTHS_OK);
    assert_false(rths_config_section_read(cfg, "rig"));
    rths_config_mark_known(cfg, "rig"); /* accepting a section whole is not reading it */
    assert_false(rths_config_section_read(cfg, "rig"));
    assert_int_equal(rths_config_get_bool(cfg, "rig.noise", 0, 1, &b, &err), RTHS_OK);
    assert_true(rths_config_section_read(cfg, "rig"));
    assert_false(rths_config_section_read(cfg, "ri"));
    done(cfg);
}

/* '.' is the decimal point whatever LC_NUMERIC the process runs in. */
/* Lists of mappings (rig.sites, structure.nonlinear): counted, read by index, overridden by
 * index, their unknown keys located, and a count asked of a non-list refused. */
static void test_lists_of_mappings(void **state) {
    (void)state;
    static const char *const yaml = "rig:\n"                       /* 1 */
                                    "  sites:\n"                   /* 2 */
                                    "    - uri: tcp://a:1\n"       /* 3 */
                                    "      interface_dofs: [1]\n"  /* 4 */
                                    "    - uri: tcp://b:2\n"       /* 5 */
                                    "      interface_dofss: [2]\n" /* 6: key col 7 */
                                    "  name: x\n";                 /* 7 */
    rths_config *cfg;
    rths_error err = {0};
    const char *const ov[] = {"rig.sites.0.uri=tcp://c:3"};
    assert_int_equal(load(yaml, ov, 1, &cfg, &err), RTHS_OK);
    int count = -1;
    assert_int_equal(rths_config_get_count(cfg, "rig.sites", &count, &err), RTHS_OK);
    assert_int_equal(count, 2);
    const char *uri = NULL;
    assert_int_equal(rths_config_get_string(cfg, "rig.sites.0.uri", 1, NULL, &uri, &err), RTHS_OK);
    assert_string_equal(uri, "tcp://c:3");
    assert_int_equal(rths_config_get_string(cfg, "rig.sites.1.uri", 1, NULL, &uri, &err), RTHS_OK);
    assert_string_equal(uri, "tcp://b:2");
    int *dofs = NULL, n = 0;
    assert_int_equal(
        rths_config_get_int_list(cfg, "rig.sites.0.interface_dofs", 1, &dofs, &n, &err), RTHS_OK);
    assert_int_equal(n, 1);
    assert_int_equal(dofs[0], 1);
    free(dofs);
    assert_int_equal(
        rths_config_get_int_list(cfg, "rig.sites.1.interface_dofs", 0, &dofs, &n, &err), RTHS_OK);
    assert_int_equal(n, 0);
    free(dofs);
    assert_int_equal(rths_config_has(cfg, "rig.sites.2.uri"), 0);
    assert_int_equal(rths_config_has(cfg, "rig.sites.01.uri"), 0);
    const char *name = NULL;
    assert_int_equal(rths_config_get_string(cfg, "rig.name", 1, NULL, &name, &err), RTHS_OK);
    assert_int_equal(rths_config_check_unknown(cfg, &err), RTHS_EINPUT);
    msg_has(&err,
            "%s:6:7: unknown key 'rig.sites.1.interface_dofss' (did you mean "
            "'rig.sites.1.interface_dofs'?)",
            path);
    assert_int_equal(rths_config_get_count(cfg, "rig.name", &count, &err), RTHS_EINPUT);
    msg_has(&err, "%s:7:9: key 'rig.name': must be a list", path);
    assert_int_equal(rths_config_get_count(cfg, "rig.absent", &count, &err), RTHS_OK);
    assert_int_equal(count, 0);
    done(cfg);

    const char *const beyond[] = {"rig.sites.2.uri=tcp://d:4"};
    assert_int_equal(load(yaml, beyond, 1, &cfg, &err), RTHS_EINPUT);
    msg_has(&err, "'rig.sites' is a list of 2 items, so it has no item '2'");
    done(cfg);
}

static void test_locale_independent(void **state) {
    (void)state;
    const char *locales[] = {"de_DE.UTF-8", "de_DE.utf8", "fr_FR.UTF-8", NULL};
    int switched = 0;
    for (int k = 0; locales[k] && !switched; k++)
        switched = setlocale(LC_NUMERIC, locales[k]) != NULL;
    rths_config *cfg;
    rths_error err;
    assert_int_equal(load("v: 0.5\nw: 1,5\n", NULL, 0, &cfg, &err), RTHS_OK);
    double v;
    assert_int_equal(rths_config_get_double(cfg, "v", 1, 0, 0, 1, &v, &err), RTHS_OK);
    assert_true(v == 0.5);
    assert_int_equal(rths_config_get_double(cfg, "w", 1, 0, 0, 9, &v, &err), RTHS_EINPUT);
    msg_has(&err, "expected a number, got '1,5'");
    done(cfg);
    setlocale(LC_NUMERIC, "C");
    if (!switched) print_message("(no comma locale installed: checked in the C locale only)\n");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_doubles),
        cmocka_unit_test(test_ints_bools_strings_choices),
        cmocka_unit_test(test_lists_and_matrices),
        cmocka_unit_test(test_lists_of_mappings),
        cmocka_unit_test(test_overrides),
        cmocka_unit_test(test_unknown_keys),
        cmocka_unit_test(test_document_errors),
        cmocka_unit_test(test_error_at),
        cmocka_unit_test(test_write_round_trip),
        cmocka_unit_test(test_locale_independent),
        cmocka_unit_test(test_depth_limit),
        cmocka_unit_test(test_many_keys),
        cmocka_unit_test(test_not_utf8_text),
        cmocka_unit_test(test_long_paths),
        cmocka_unit_test(test_range_text),
        cmocka_unit_test(test_section_read),
        cmocka_unit_test(test_write_odd_keys),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
