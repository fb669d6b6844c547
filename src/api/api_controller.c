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
#include <json-c/json.h>
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

/* --latency-test: the configuration (optional) gives the server section and the rate. The
 * result's summary holds the numbers, its text the line the command prints. */
static int latency_test(const rths_api_controller_options *args, double seconds,
                        rths_server_options *opt, rths_result **out, rths_error *err) {
    *out = NULL;
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
    rths_result *res;
    if ((rc = rths_result_new(&res, err))) return rc;
    char p50[32], p90[32], p99[32], p999[32];
    rths_result_printf(
        res,
        "samples %llu at %g Hz: wake-up lateness p50 %s, p90 %s, p99 %s, p99.9 %s, worst %.0f "
        "us; %llu overruns (lateness of a whole sample period or more, %.3g %%); SCHED_FIFO "
        "%s, memory locked %s, pinned %s\n",
        (unsigned long long)st.samples, rate_hz, lateness_us(st.lateness_p50_s, p50, 32),
        lateness_us(st.lateness_p90_s, p90, 32), lateness_us(st.lateness_p99_s, p99, 32),
        lateness_us(st.lateness_p999_s, p999, 32), st.worst_lateness_s * 1e6,
        (unsigned long long)st.overruns,
        st.samples ? 100.0 * (double)st.overruns / (double)st.samples : 0.0,
        st.rt_fifo ? "yes" : "no", st.rt_mlock ? "yes" : "no", st.rt_pinned ? "yes" : "no");
    json_object *summary =
        rths_api_summary_new("controller", args->config_path, args->overrides, args->n_overrides);
    if (summary) {
        json_object_object_add(summary, "latency_test_s", json_object_new_double(seconds));
        json_object_object_add(summary, "sample_rate_hz", json_object_new_double(rate_hz));
        json_object_object_add(summary, "samples", json_object_new_uint64(st.samples));
        json_object_object_add(summary, "overruns", json_object_new_uint64(st.overruns));
        json_object_object_add(summary, "lateness_p50_s",
                               json_object_new_double(st.lateness_p50_s));
        json_object_object_add(summary, "lateness_p90_s",
                               json_object_new_double(st.lateness_p90_s));
        json_object_object_add(summary, "lateness_p99_s",
                               json_object_new_double(st.lateness_p99_s));
        json_object_object_add(summary, "lateness_p999_s",
                               json_object_new_double(st.lateness_p999_s));
        json_object_object_add(summary, "worst_lateness_s",
                               json_object_new_double(st.worst_lateness_s));
        json_object_object_add(summary, "sched_fifo", json_object_new_boolean(st.rt_fifo));
        json_object_object_add(summary, "memory_locked", json_object_new_boolean(st.rt_mlock));
        json_object_object_add(summary, "pinned", json_object_new_boolean(st.rt_pinned));
    }
    rc = summary ? rths_result_set_summary(res, summary, err)
                 : rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (rc) {
        rths_result_free(res);
        return rc;
    }
    *out = res;
    return RTHS_OK;
}

static void print_stats(const rths_server_stats *st) {
    char p50[32], p99[32], p999[32];
    fprintf(stderr,
            "rths controller: stopped after %llu samples; lateness p50 %s, p99 %s, p99.9 %s, "
            "worst %.0f us; %llu overruns; step mean %.2f us, max %.1f us\n",
            (unsigned long long)st->samples, lateness_us(st->lateness_p50_s, p50, 32),
            lateness_us(st->lateness_p99_s, p99, 32), lateness_us(st->lateness_p999_s, p999, 32),
            st->worst_lateness_s * 1e6, (unsigned long long)st->overruns, st->step_mean_s * 1e6,
            st->step_max_s * 1e6);
}

/* A controller built and serving (rths.h): the one path of `rths controller` and of
 * rths_api_controller_start. */
struct rths_api_controller {
    rths_config *cfg;
    rths_server *srv;
    rths_server_view *view;
    rths_server_options opt;
    int quiet;
};

static void controller_free(rths_api_controller *c) {
    if (!c) return;
    rths_server_destroy(c->srv);
    rths_config_free(c->cfg);
    free(c);
}

/* Starts the page (view_listen) and the server of c, built already. The threads both start
 * inherit the calling thread's signal mask: the caller blocks what they must not take. */
static int controller_run(rths_api_controller *c, const char *view_listen, rths_error *err) {
    /* the page's threads inherit the blocked signals; a bad --view stops before the loop runs */
    int rc;
    if (view_listen && (rc = rths_server_view_start(c->srv, view_listen, &c->view, err))) return rc;
    if (c->view && !c->quiet && !rths_view_host_is_loopback(rths_server_view_host(c->view)))
        fprintf(stderr,
                "rths controller: warning: the page on %s is reachable from other machines; it "
                "has no authentication\n",
                rths_server_view_host(c->view));
    if ((rc = rths_server_start(c->srv, err))) {
        rths_server_view_stop(c->view);
        c->view = NULL;
        return rc;
    }
    return RTHS_OK;
}

/* Stops the page and the loop (the server disarms first); st receives the loop's statistics.
 * RTHS_EFAIL when the loop had stalled in the I/O device. */
static int controller_halt(rths_api_controller *c, rths_server_stats *st, rths_error *err) {
    rths_server_view_stop(c->view);
    c->view = NULL;
    rths_server_stop(c->srv);
    rths_server_get_stats(c->srv, st);
    double ran_s = 0;
    if (rths_server_loop_stalled(c->srv, &ran_s))
        return rths_error_set(err, RTHS_EFAIL,
                              "the loop stalled in the I/O device (a sample ran %.3g s, beyond "
                              "server.stall_margin_s = %g s); its safe state was driven and the "
                              "device was left open (the stuck thread ends with the process)",
                              ran_s, c->opt.stall_margin_s);
    return RTHS_OK;
}

/* Starts the page (--view) and the server, prints where they listen, runs until stopped. */
static int serve(const rths_api_controller_options *args, rths_api_controller *c, rths_error *err) {
    /* Signals are taken synchronously by this thread; the loop and network threads inherit the
     * blocked mask, so a signal never interrupts the loop. */
    sigset_t sigs;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGINT);
    sigaddset(&sigs, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);
    int rc = controller_run(c, args->view_listen, err);
    if (rc) return rc;
    const rths_server_options *opt = &c->opt;
    printf("listening on %s%s%s:%d\n", strchr(opt->host, ':') ? "[" : "", opt->host,
           strchr(opt->host, ':') ? "]" : "", rths_server_port(c->srv));
    if (c->view) {
        const char *vh = rths_server_view_host(c->view);
        int v6 = strchr(vh, ':') != NULL;
        printf("view at http://%s%s%s:%d/\n", v6 ? "[" : "", vh, v6 ? "]" : "",
               rths_server_view_port(c->view));
    }
    fflush(stdout);
    wait_for_stop(&sigs, args->duration_s);
    rths_server_stats st;
    rc = controller_halt(c, &st, err);
    if (!args->quiet) print_stats(&st);
    return rc;
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
    rths_result *res = NULL;
    int rc = start_options(o, &opt, err);
    if (!rc) rc = latency_test(o, seconds, &opt, &res, err);
    if (!rc) fputs(rths_result_text(res), stdout);
    rths_result_free(res);
    return rc;
}

/* The server built from the configuration with the options: everything that can refuse input. */
static int controller_create(const rths_api_controller_options *o, rths_api_controller **out,
                             rths_error *err) {
    *out = NULL;
    rths_api_controller *c = calloc(1, sizeof *c);
    if (!c) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    c->quiet = o->quiet;
    int rc = start_options(o, &c->opt, err);
    if (!rc) rc = create_server(o, &c->opt, &c->cfg, &c->srv, err);
    if (rc) {
        controller_free(c);
        return rc;
    }
    *out = c;
    return RTHS_OK;
}

int rths_api_controller_serve(const rths_api_controller_options *o, rths_error *err) {
    rths_api_controller *c;
    int rc = controller_create(o, &c, err);
    if (!rc) rc = serve(o, c, err);
    controller_free(c);
    return rc;
}

/* ---- the controller for a program (rths.h, "the controller process") ---- */

/* The stable API's arguments as the command's options (quiet: a library prints nothing). */
static int api_options(const rths_api_config *cfg, const char *listen, int site,
                       const char *view_listen, rths_api_controller_options *o, rths_error *err) {
    memset(o, 0, sizeof *o);
    if (site < 0 || site > RTHS_API_MAX_INTERFACE_DOFS)
        return rths_error_set(err, RTHS_EINPUT, "site %d: must be in [0, %d] (0: the whole test)",
                              site, RTHS_API_MAX_INTERFACE_DOFS);
    if (cfg) {
        o->config_path = cfg->path;
        o->overrides = (const char *const *)cfg->overrides;
        o->n_overrides = cfg->n_overrides;
    }
    o->listen = listen;
    o->site = site;
    o->view_listen = view_listen;
    o->quiet = 1;
    return RTHS_OK;
}

int rths_api_controller_start(const rths_api_config *cfg, const char *listen, int site,
                              const char *view_listen, rths_api_controller **out, rths_error *err) {
    *out = NULL;
    if (!cfg) return rths_error_set(err, RTHS_EINPUT, "no configuration given");
    rths_server_options probe; /* the address named as this call's argument, not --listen */
    int probe_port;
    if (listen && parse_listen(listen, probe.host, sizeof probe.host, &probe_port))
        return rths_error_set(err, RTHS_EINPUT, "listen '%s': expected ADDR:PORT (port 0..65535)",
                              listen);
    rths_api_controller_options o;
    int rc = api_options(cfg, listen, site, view_listen, &o, err);
    rths_api_controller *c = NULL;
    if (!rc) rc = controller_create(&o, &c, err);
    if (rc) return rc;
    /* the loop, network and page threads never take the caller's signals (a Ctrl-C meant for
     * the program): they start with SIGINT and SIGTERM blocked, the caller's mask restored */
    sigset_t sigs, old;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGINT);
    sigaddset(&sigs, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &sigs, &old);
    rc = controller_run(c, view_listen, err);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (rc) {
        controller_free(c);
        return rc;
    }
    *out = c;
    return RTHS_OK;
}

int rths_api_controller_port(const rths_api_controller *c) {
    return c ? rths_server_port(c->srv) : -1;
}

int rths_api_controller_view_port(const rths_api_controller *c) {
    return c && c->view ? rths_server_view_port(c->view) : -1;
}

int rths_api_controller_stop(rths_api_controller *c, rths_result **stats, rths_error *err) {
    if (stats) *stats = NULL;
    if (!c) return RTHS_OK;
    rths_server_stats st;
    int rc = controller_halt(c, &st, err);
    json_object *summary = NULL;
    rths_result *res = NULL;
    if (!rc && stats && !(rc = rths_result_new(&res, err))) {
        summary = rths_api_summary_new("controller", NULL, NULL, 0);
        if (summary) {
            json_object_object_add(summary, "samples", json_object_new_uint64(st.samples));
            json_object_object_add(summary, "overruns", json_object_new_uint64(st.overruns));
            json_object_object_add(summary, "lateness_p50_s",
                                   json_object_new_double(st.lateness_p50_s));
            json_object_object_add(summary, "lateness_p99_s",
                                   json_object_new_double(st.lateness_p99_s));
            json_object_object_add(summary, "lateness_p999_s",
                                   json_object_new_double(st.lateness_p999_s));
            json_object_object_add(summary, "worst_lateness_s",
                                   json_object_new_double(st.worst_lateness_s));
            json_object_object_add(summary, "step_mean_s", json_object_new_double(st.step_mean_s));
            json_object_object_add(summary, "step_max_s", json_object_new_double(st.step_max_s));
            json_object_object_add(summary, "fault", json_object_new_int(st.fault));
        }
        rc = summary ? rths_result_set_summary(res, summary, err)
                     : rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    controller_free(c);
    if (rc) {
        rths_result_free(res);
        return rc;
    }
    if (stats) *stats = res;
    return RTHS_OK;
}

int rths_api_controller_latency(const rths_api_config *cfg, double seconds, rths_result **out,
                                rths_error *err) {
    *out = NULL;
    if (!(seconds > 0 && seconds <= 3600))
        return rths_error_set(err, RTHS_EINPUT, "seconds %g: must be in (0, 3600]", seconds);
    rths_api_controller_options o;
    rths_server_options opt;
    int rc = api_options(cfg, NULL, 0, NULL, &o, err);
    if (!rc) rc = start_options(&o, &opt, err);
    return rc ? rc : latency_test(&o, seconds, &opt, out, err);
}
