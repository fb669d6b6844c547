/* rths controller: the real-time controller process (docs/protocol.md, include/rths/server.h). */
#include "cli/commands.h"
#include "rths/config.h"
#include "rths/server.h"
#include "rths/view.h"

#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static void usage(FILE *to) {
    fprintf(
        to,
        "Usage: rths controller --config CONFIG [--listen ADDR:PORT] [--io PLUGIN.so]\n"
        "                       [--set key=value]... [--view ADDR:PORT] [--duration SECONDS]\n"
        "                       [--quiet]\n"
        "       rths controller CONFIG [options]\n\n"
        "Runs the real-time controller: the per-sample step of the hybrid test (numerical\n"
        "substructure, PD control of the physical interface, Fourier sums, safety limits) on\n"
        "a device behind the per-sample I/O seam (an I/O plug-in, docs/io-plugins.md; by\n"
        "default the simulated plant), paced by the wall clock, and serves one host over\n"
        "TCP (docs/protocol.md). The host runs e.g.\n"
        "  rths frf CONFIG --rig tcp://HOST:PORT\n\n"
        "Options:\n"
        "  --listen ADDR:PORT  address to listen on (default 127.0.0.1:7400, loopback only);\n"
        "                      port 0 picks a free port. [IPv6]:PORT accepted.\n"
        "  --config CONFIG     the test configuration (YAML); the server section sets the\n"
        "                      watchdog and real-time options (docs/config/server.md)\n"
        "  --io PLUGIN.so      the I/O plug-in driving the lab's hardware (the same as\n"
        "                      io.plugin in the configuration; its settings are the io\n"
        "                      section). Refused before anything runs when its ABI version\n"
        "                      differs or a symbol is missing.\n"
        "  --set key=value     override a configuration key (repeatable)\n"
        "  --view ADDR:PORT    serve a web page of the process (docs/view.md): the interface\n"
        "                      signals as an oscilloscope, limit state, watchdog, the loop's\n"
        "                      lateness histogram and overruns, read without disturbing the\n"
        "                      loop. Loopback unless asked (another address: a warning); port\n"
        "                      0 picks a free one. Prints 'view at http://ADDR:PORT/'.\n"
        "  --duration SECONDS  stop after this long (default: until SIGINT/SIGTERM)\n"
        "  --quiet             no notices on stderr\n\n"
        "On start it prints 'listening on ADDR:PORT' on stdout. The controller starts\n"
        "disarmed; only the host's ARM starts excitation. Limits latch a fault and ramp the\n"
        "demand to zero; a host silent for longer than server.watchdog_s, or a lost\n"
        "connection, disarms with the same ramp. On SIGINT/SIGTERM it disarms, ramps down,\n"
        "prints loop statistics on stderr and exits 0.\n\n"
        "Exit status: 0 stopped normally; 1 cannot listen or run; 2 bad usage or configuration.\n");
}

/* "HOST:PORT" or "[V6]:PORT", PORT 0..65535. */
static int parse_listen(const char *arg, char *host, size_t cap, int *port) {
    const char *colon;
    size_t hl;
    const char *h = arg;
    if (*arg == '[') {
        const char *close = strchr(arg, ']');
        if (!close || close[1] != ':') return -1;
        h = arg + 1;
        hl = (size_t)(close - h);
        colon = close + 1;
    } else {
        colon = strrchr(arg, ':');
        if (!colon) return -1;
        hl = (size_t)(colon - arg);
        if (memchr(arg, ':', hl)) return -1;
    }
    if (hl == 0 || hl >= cap) return -1;
    char *end;
    errno = 0;
    long v = strtol(colon + 1, &end, 10);
    if (errno || end == colon + 1 || *end || v < 0 || v > 65535) return -1;
    memcpy(host, h, hl);
    host[hl] = '\0';
    *port = (int)v;
    return 0;
}

int rths_cmd_controller(int argc, char **argv) {
    const char *config_path = NULL, *listen = NULL, *io_path = NULL, *view_listen = NULL;
    double duration = -1.0;
    int quiet = 0;
    const char **sets = calloc((size_t)argc + 1, sizeof *sets);
    int n_sets = 0;
    if (!sets) return RTHS_EFAIL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout);
            free(sets);
            return RTHS_OK;
        }
        int has_value = i + 1 < argc;
        if (!strcmp(a, "--listen") && has_value) {
            listen = argv[++i];
        } else if (!strcmp(a, "--view") && has_value) {
            view_listen = argv[++i];
        } else if (!strcmp(a, "--io") && has_value) {
            io_path = argv[++i];
        } else if (!strcmp(a, "--config") && has_value) {
            config_path = argv[++i];
        } else if (!strcmp(a, "--set") && has_value) {
            sets[n_sets++] = argv[++i];
        } else if (!strcmp(a, "--duration") && has_value) {
            char *end;
            duration = strtod(argv[++i], &end);
            if (*end || !(duration > 0) || duration > 1e7) {
                fprintf(stderr, "rths controller: --duration '%s': expected seconds > 0\n",
                        argv[i]);
                free(sets);
                return RTHS_EINPUT;
            }
        } else if (!strcmp(a, "--quiet")) {
            quiet = 1;
        } else if (a[0] != '-' && !config_path) {
            config_path = a;
        } else {
            fprintf(stderr, "rths controller: unexpected argument '%s'%s (see --help)\n", a,
                    has_value ? "" : " or missing value");
            free(sets);
            return RTHS_EINPUT;
        }
    }
    if (!config_path) {
        fprintf(stderr, "rths controller: --config CONFIG is required (see --help)\n");
        free(sets);
        return RTHS_EINPUT;
    }
    rths_server_options opt;
    rths_server_options_defaults(&opt);
    opt.quiet = quiet;
    if (listen && parse_listen(listen, opt.host, sizeof opt.host, &opt.port)) {
        fprintf(stderr, "rths controller: --listen '%s': expected ADDR:PORT (port 0..65535)\n",
                listen);
        free(sets);
        return RTHS_EINPUT;
    }
    /* --io is the override io.plugin, single-quoted for YAML (a quote doubled) */
    char *io_set = io_path ? malloc(2 * strlen(io_path) + 16) : NULL;
    if (io_path) {
        if (!io_set) {
            free(sets);
            return RTHS_EFAIL;
        }
        char *w = io_set + sprintf(io_set, "io.plugin='");
        for (const char *r = io_path; *r; r++) {
            if (*r == '\'') *w++ = '\'';
            *w++ = *r;
        }
        strcpy(w, "'");
        sets[n_sets++] = io_set;
    }
    rths_error err;
    rths_error_clear(&err);
    rths_config *cfg = NULL;
    rths_server *srv = NULL;
    int rc = rths_config_load(config_path, sets, n_sets, &cfg, &err);
    free(sets);
    free(io_set);
    if (!rc) rc = rths_server_config_read(cfg, &opt, &err);
    /* Everything a command run does not read (iteration, continuation, output...) is fine in a
     * test configuration shared with the host; only typos within read sections are refused. */
    if (!rc) {
        static const char *const host_sections[] = {"iteration", "continuation", "output",
                                                    "stability", "fidelity",     "simulate",
                                                    "model",     "report",       NULL};
        for (int i = 0; host_sections[i]; i++)
            rths_config_mark_known(cfg, host_sections[i]);
        rths_config_mark_known(cfg, "rig.pace"); /* paces the host's in-process rig only */
        rc = rths_server_create(cfg, &opt, &srv, &err);
    }
    if (!rc) rc = rths_config_check_unknown(cfg, &err);
    if (rc) {
        fprintf(stderr, "rths controller: %s\n", err.msg);
        rths_server_destroy(srv);
        rths_config_free(cfg);
        return rc;
    }
    /* Signals are taken synchronously by this thread; the loop and network threads inherit the
     * blocked mask, so a signal never interrupts the loop. */
    sigset_t sigs;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGINT);
    sigaddset(&sigs, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);
    /* the page's threads inherit the blocked signals; a bad --view stops before the loop runs */
    rths_server_view *view = NULL;
    if (view_listen && (rc = rths_server_view_start(srv, view_listen, &view, &err))) {
        fprintf(stderr, "rths controller: %s\n", err.msg);
        rths_server_destroy(srv);
        rths_config_free(cfg);
        return rc;
    }
    if (view && !quiet && !rths_view_host_is_loopback(rths_server_view_host(view)))
        fprintf(stderr,
                "rths controller: warning: the page on %s is reachable from other machines; it "
                "has no authentication\n",
                rths_server_view_host(view));
    if ((rc = rths_server_start(srv, &err))) {
        fprintf(stderr, "rths controller: %s\n", err.msg);
        rths_server_view_stop(view);
        rths_server_destroy(srv);
        rths_config_free(cfg);
        return rc;
    }
    printf("listening on %s%s%s:%d\n", strchr(opt.host, ':') ? "[" : "", opt.host,
           strchr(opt.host, ':') ? "]" : "", rths_server_port(srv));
    if (view) {
        const char *vh = rths_server_view_host(view);
        int v6 = strchr(vh, ':') != NULL;
        printf("view at http://%s%s%s:%d/\n", v6 ? "[" : "", vh, v6 ? "]" : "",
               rths_server_view_port(view));
    }
    fflush(stdout);
    if (duration > 0) {
        struct timespec ts = {(time_t)duration,
                              (long)((duration - (double)(time_t)duration) * 1e9)};
        int sig;
        siginfo_t info;
        while ((sig = sigtimedwait(&sigs, &info, &ts)) < 0 && errno == EINTR) {
        }
    } else {
        int sig;
        sigwait(&sigs, &sig);
    }
    rths_server_view_stop(view);
    rths_server_stop(srv);
    rths_server_stats st;
    rths_server_get_stats(srv, &st);
    if (!quiet)
        fprintf(stderr,
                "rths controller: stopped after %llu samples; lateness p50 %.0f us, p99 %.0f us, "
                "p99.9 %.0f us, worst %.0f us; %llu overruns; step mean %.2f us, max %.1f us\n",
                (unsigned long long)st.samples, st.lateness_p50_s * 1e6, st.lateness_p99_s * 1e6,
                st.lateness_p999_s * 1e6, st.worst_lateness_s * 1e6,
                (unsigned long long)st.overruns, st.step_mean_s * 1e6, st.step_max_s * 1e6);
    rths_server_destroy(srv);
    rths_config_free(cfg);
    return RTHS_OK;
}
