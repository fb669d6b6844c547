/* `rths controller` behind the C API: the real-time controller process (docs/protocol.md,
 * include/rths/server.h) built from the configuration and served until a signal or the duration,
 * the machine's latency test, and the command's usage text with this build's defaults. The
 * command (src/cli/cmd_controller.c) parses the options and calls these. */
#include "api/api_internal.h"
#include "rths/protocol.h"
#include "rths/run.h"
#include "rths/server.h"
#include "rths/view.h"

#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* The usage text, with the defaults this build really has (rths_server_options_defaults). */
void rths_api_controller_usage(char *out, size_t cap, int max_overrides) {
    rths_server_options d;
    rths_server_options_defaults(&d);
    snprintf(
        out, cap,
        "Usage: rths controller --config CONFIG [--listen ADDR:PORT] [--io PLUGIN.so]\n"
        "                       [--set key=value]... [--view ADDR:PORT] [--duration SECONDS]\n"
        "                       [--site N] [--quiet]\n"
        "       rths controller CONFIG [options]\n"
        "       rths controller --latency-test SECONDS [--config CONFIG] [--set key=value]...\n\n"
        "Runs the real-time controller: the per-sample step of the hybrid test (numerical\n"
        "substructure, PD control of every interface DoF's actuator, Fourier sums, safety\n"
        "limits) on a device behind the per-sample I/O seam (an I/O plug-in,\n"
        "docs/io-plugins.md; by default the simulated plant), paced by the wall clock, and\n"
        "serves one host over TCP with rths protocol version %d (docs/protocol.md; 1 to %d\n"
        "interface DoFs, one actuator each, as split.interface says). The host runs e.g.\n"
        "  rths frf CONFIG --rig tcp://HOST:PORT\n\n"
        "Options (a value may also be given as --option=VALUE):\n"
        "  --config CONFIG     the test configuration (YAML), required (or as the one\n"
        "                      positional argument); its server section sets the watchdog\n"
        "                      and real-time options (docs/config/server.md), defaults:\n"
        "                      server.watchdog_s %g, server.realtime %s, server.priority %d,\n"
        "                      server.cpu %d (the last CPU), server.max_frequency_hz %g,\n"
        "                      server.max_amplitude_n %g\n"
        "  --listen ADDR:PORT  address to listen on (default %s:%d, loopback only);\n"
        "                      port 0 picks a free port. [IPv6]:PORT accepted.\n"
        "  --io PLUGIN.so      the I/O plug-in driving the lab's hardware (the same as\n"
        "                      io.plugin in the configuration; its settings are the io\n"
        "                      section; default: the simulated plant). A path with a '/'\n"
        "                      (e.g. ./lab.so), never searched in the system's library\n"
        "                      path; an empty one is refused. Refused before anything\n"
        "                      runs when its ABI version differs or a symbol is missing.\n"
        "  --set key=value     override a configuration key (repeatable, at most %d)\n"
        "  --site N            be site N of a multi-site test (rig.sites, docs/method.md)\n"
        "  --view ADDR:PORT    serve a web page of the process (docs/view.md): the interface\n"
        "                      signals as an oscilloscope, limit state, watchdog, the loop's\n"
        "                      lateness histogram and overruns, read without disturbing the\n"
        "                      loop. Loopback unless asked (another address: a warning); port\n"
        "                      0 picks a free one. Prints 'view at http://ADDR:PORT/'.\n"
        "                      Default: no page.\n"
        "  --duration SECONDS  stop after this long, 0 < SECONDS <= 1e7 (default: until\n"
        "                      SIGINT/SIGTERM)\n"
        "  --latency-test SECONDS\n"
        "                      qualify this machine: run the paced loop alone (no device,\n"
        "                      no step, no network) for SECONDS (0 < SECONDS <= 3600) at\n"
        "                      controller.sample_rate_hz (default 10000) with the server\n"
        "                      section's real-time set-up, and print its wake-up lateness\n"
        "                      (p50, p90, p99, p99.9, worst) and overruns, like cyclictest\n"
        "  --quiet, -q         no notices on stderr\n"
        "  --help, -h          this text\n\n"
        "On start it prints 'listening on ADDR:PORT' on stdout. The controller starts\n"
        "disarmed; only the host's ARM starts excitation. Limits latch a fault and ramp the\n"
        "demand to zero; a host silent for longer than server.watchdog_s, or a lost\n"
        "connection, disarms with the same ramp. A host of another protocol version is\n"
        "refused, naming both versions. On SIGINT/SIGTERM (or after --duration) it disarms,\n"
        "ramps down, prints loop statistics on stderr and exits 0. A loop stuck in the\n"
        "device for longer than a sample plus server.stall_margin_s has the device's safe\n"
        "state driven by a supervisor and a fault latched naming the stall; the process\n"
        "then still stops on SIGINT/SIGTERM, and exits 1.\n\n"
        "Exit status: 0 stopped normally; 1 cannot listen or run (e.g. the port is in use),\n"
        "or the loop stalled; 2 bad usage or configuration (nothing started).\n",
        RTHS_PROTO_VERSION, RTHS_PROTO_MAX_DOFS, d.watchdog_s, d.realtime ? "true" : "false",
        d.priority, d.cpu, d.max_frequency_hz, d.max_amplitude_n, d.host, d.port, max_overrides);
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

/* The configuration with the overrides, the server section, and the server built from it
 * (step, plant or plug-in, listening socket): everything that can refuse input. */
/* --site N: the configuration restricted to site N (rths_run_site_overrides: its interface and
 * physical DoFs, every other DoF numerical, its mass ratios), the overrides after the command
 * line's. */
static int load_site(const rths_api_controller_options *args, rths_config **cfg, rths_error *err) {
    rths_setup setup = {0};
    rths_run_sites sites;
    rths_run_site_sets site_sets;
    int have_setup = 0;
    int rc = rths_setup_read(*cfg, &setup, err);
    if (!rc) have_setup = 1;
    if (!rc) rc = rths_run_sites_read(*cfg, &setup, &sites, err);
    if (!rc && sites.n == 0)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "--site %ld: %s lists no rig.sites (a multi-site test lists every "
                            "site's interface DoFs there)",
                            args->site, args->config_path);
    if (!rc) rc = rths_run_site_overrides(&setup, &sites, (int)args->site - 1, &site_sets, err);
    if (have_setup) rths_setup_free(&setup);
    if (rc) return rc;
    const char **sets = calloc((size_t)args->n_overrides + 5, sizeof *sets);
    if (!sets) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int n = 0;
    for (int i = 0; i < args->n_overrides; i++)
        sets[n++] = args->overrides[i];
    for (int i = 0; i < site_sets.n; i++)
        sets[n++] = site_sets.text[i];
    rths_config_free(*cfg);
    *cfg = NULL;
    rc = rths_config_load(args->config_path, sets, n, cfg, err);
    free(sets);
    /* the host's list of the sites: this process is one of them */
    if (!rc) rths_config_mark_known(*cfg, "rig.sites");
    if (!rc && !args->quiet)
        fprintf(stderr, "rths controller: site %ld: %s %s %s\n", args->site, site_sets.text[0],
                site_sets.text[1], site_sets.text[2]);
    return rc;
}

static int create_server(const rths_api_controller_options *args, rths_server_options *opt,
                         rths_config **cfg, rths_server **srv, rths_error *err) {
    int rc = rths_config_load(args->config_path, args->overrides, args->n_overrides, cfg, err);
    if (!rc && args->site > 0) rc = load_site(args, cfg, err);
    /* without --site the process runs the whole configuration (a one-site test): the sites'
     * list is the host's */
    if (!rc && args->site == 0) rths_config_mark_known(*cfg, "rig.sites");
    if (!rc) rc = rths_server_config_read(*cfg, opt, err);
    /* Everything a command run does not read (iteration, continuation, output...) is fine in a
     * test configuration shared with the host; only typos within read sections are refused. */
    if (!rc) {
        static const char *const host_sections[] = {"iteration", "continuation", "output",
                                                    "stability", "fidelity",     "simulate",
                                                    "model",     "report",       NULL};
        for (int i = 0; host_sections[i]; i++)
            rths_config_mark_known(*cfg, host_sections[i]);
        rths_config_mark_known(*cfg, "rig.pace"); /* paces the host's in-process rig only */
        rc = rths_server_create(*cfg, opt, srv, err);
    }
    if (!rc) rc = rths_config_check_unknown(*cfg, err);
    return rc;
}

/* Waits for SIGINT/SIGTERM, or for duration_s when positive. */
static void wait_for_stop(const sigset_t *sigs, double duration_s) {
    int sig;
    if (duration_s > 0) {
        struct timespec ts = {(time_t)duration_s,
                              (long)((duration_s - (double)(time_t)duration_s) * 1e9)};
        siginfo_t info;
        while ((sig = sigtimedwait(sigs, &info, &ts)) < 0 && errno == EINTR) {
        }
    } else {
        sigwait(sigs, &sig);
    }
}

/* A lateness percentile in whole microseconds; the loop's histogram ends at 50 ms, beyond which
 * only ">= 50000 us" is known. */
static const char *lateness_us(double s, char *buf, size_t cap) {
    if (s > 0.05)
        snprintf(buf, cap, ">= 50000 us");
    else
        snprintf(buf, cap, "%.0f us", s * 1e6);
    return buf;
}

/* --latency-test: the configuration (optional) gives the server section and the rate. */
static int latency_test(const rths_api_controller_options *args, double seconds,
                        rths_server_options *opt, rths_error *err) {
    rths_config *cfg = NULL;
    double rate_hz = 10000.0;
    int rc = rths_config_load(args->config_path, args->overrides, args->n_overrides, &cfg, err);
    if (!rc) rc = rths_server_config_read(cfg, opt, err);
    if (!rc)
        rc = rths_config_get_double(cfg, "controller.sample_rate_hz", 0, rate_hz, 100, 1e6,
                                    &rate_hz, err);
    rths_config_free(cfg);
    if (rc) return rc;
    opt->quiet = args->quiet;
    if (!args->quiet)
        fprintf(stderr, "rths controller: latency test: %g s at %g Hz (the paced loop alone)\n",
                seconds, rate_hz);
    rths_server_stats st;
    if ((rc = rths_server_latency_test(opt, rate_hz, seconds, &st, err))) return rc;
    char p50[32], p90[32], p99[32], p999[32];
    printf("samples %llu at %g Hz: wake-up lateness p50 %s, p90 %s, p99 %s, p99.9 %s, worst %.0f "
           "us; %llu overruns (lateness of a whole sample period or more, %.3g %%); SCHED_FIFO "
           "%s, memory locked %s, pinned %s\n",
           (unsigned long long)st.samples, rate_hz, lateness_us(st.lateness_p50_s, p50, 32),
           lateness_us(st.lateness_p90_s, p90, 32), lateness_us(st.lateness_p99_s, p99, 32),
           lateness_us(st.lateness_p999_s, p999, 32), st.worst_lateness_s * 1e6,
           (unsigned long long)st.overruns,
           st.samples ? 100.0 * (double)st.overruns / (double)st.samples : 0.0,
           st.rt_fifo ? "yes" : "no", st.rt_mlock ? "yes" : "no", st.rt_pinned ? "yes" : "no");
    return RTHS_OK;
}

static void print_stats(rths_server *srv) {
    rths_server_stats st;
    rths_server_get_stats(srv, &st);
    char p50[32], p99[32], p999[32];
    fprintf(stderr,
            "rths controller: stopped after %llu samples; lateness p50 %s, p99 %s, p99.9 %s, "
            "worst %.0f us; %llu overruns; step mean %.2f us, max %.1f us\n",
            (unsigned long long)st.samples, lateness_us(st.lateness_p50_s, p50, 32),
            lateness_us(st.lateness_p99_s, p99, 32), lateness_us(st.lateness_p999_s, p999, 32),
            st.worst_lateness_s * 1e6, (unsigned long long)st.overruns, st.step_mean_s * 1e6,
            st.step_max_s * 1e6);
}

/* Starts the page (--view) and the server, prints where they listen, runs until stopped. */
static int serve(const rths_api_controller_options *args, const rths_server_options *opt,
                 rths_server *srv, rths_error *err) {
    const int quiet = args->quiet;
    /* Signals are taken synchronously by this thread; the loop and network threads inherit the
     * blocked mask, so a signal never interrupts the loop. */
    sigset_t sigs;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGINT);
    sigaddset(&sigs, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);
    /* the page's threads inherit the blocked signals; a bad --view stops before the loop runs */
    rths_server_view *view = NULL;
    int rc;
    if (args->view_listen && (rc = rths_server_view_start(srv, args->view_listen, &view, err)))
        return rc;
    if (view && !quiet && !rths_view_host_is_loopback(rths_server_view_host(view)))
        fprintf(stderr,
                "rths controller: warning: the page on %s is reachable from other machines; it "
                "has no authentication\n",
                rths_server_view_host(view));
    if ((rc = rths_server_start(srv, err))) {
        rths_server_view_stop(view);
        return rc;
    }
    printf("listening on %s%s%s:%d\n", strchr(opt->host, ':') ? "[" : "", opt->host,
           strchr(opt->host, ':') ? "]" : "", rths_server_port(srv));
    if (view) {
        const char *vh = rths_server_view_host(view);
        int v6 = strchr(vh, ':') != NULL;
        printf("view at http://%s%s%s:%d/\n", v6 ? "[" : "", vh, v6 ? "]" : "",
               rths_server_view_port(view));
    }
    fflush(stdout);
    wait_for_stop(&sigs, args->duration_s);
    rths_server_view_stop(view);
    rths_server_stop(srv);
    if (!quiet) print_stats(srv);
    double ran_s = 0;
    if (rths_server_loop_stalled(srv, &ran_s))
        return rths_error_set(err, RTHS_EFAIL,
                              "the loop stalled in the I/O device (a sample ran %.3g s, beyond "
                              "server.stall_margin_s = %g s); its safe state was driven and the "
                              "device was left open (the stuck thread ends with the process)",
                              ran_s, opt->stall_margin_s);
    return RTHS_OK;
}

/* The server options as the command line sets them: the defaults, quiet, --listen. */
static int start_options(const rths_api_controller_options *o, rths_server_options *opt,
                         rths_error *err) {
    rths_server_options_defaults(opt);
    opt->quiet = o->quiet;
    if (o->listen && parse_listen(o->listen, opt->host, sizeof opt->host, &opt->port))
        return rths_error_set(err, RTHS_EINPUT, "--listen '%s': expected ADDR:PORT (port 0..65535)",
                              o->listen);
    return RTHS_OK;
}

int rths_api_controller_check_listen(const char *listen, rths_error *err) {
    rths_server_options opt;
    rths_api_controller_options o = {.listen = listen};
    return start_options(&o, &opt, err);
}

int rths_api_controller_latency_test(const rths_api_controller_options *o, double seconds,
                                     rths_error *err) {
    rths_server_options opt;
    int rc = start_options(o, &opt, err);
    return rc ? rc : latency_test(o, seconds, &opt, err);
}

int rths_api_controller_serve(const rths_api_controller_options *o, rths_error *err) {
    rths_server_options opt;
    rths_config *cfg = NULL;
    rths_server *srv = NULL;
    int rc = start_options(o, &opt, err);
    if (!rc) rc = create_server(o, &opt, &cfg, &srv, err);
    if (!rc) rc = serve(o, &opt, srv, err);
    rths_server_destroy(srv);
    rths_config_free(cfg);
    return rc;
}
