/* rths view DIR [--listen ADDR:PORT]: the live web page of a run folder or of a campaign folder
 * (src/view/, through the C API's rths_api_view_*). */
#include "cli/cli_common.h"
#include "cli/commands.h"
#include "rths/rths.h"

#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

static const char usage[] =
    "Usage: rths view RUN_DIR|CAMPAIGN_DIR [--listen ADDR:PORT] [--quiet]\n"
    "\n"
    "Serves a web page that watches the run folder RUN_DIR (the --out of 'rths frf'), finished\n"
    "or still being written, here or on a shared disk: the frequency response so far over the\n"
    "true one, progress and health, and from live.json (when the run writes one) the current\n"
    "point's residual and the interface signals. It only reads the folder (journal.jsonl,\n"
    "frf.csv, truth.csv, live.json, summary.json, config.yaml); the test itself serves nothing\n"
    "and is not slowed. The page updates itself (server-sent events), no reload.\n"
    "\n"
    "CAMPAIGN_DIR (the --out of 'rths campaign'), finished or still running: campaign.csv as\n"
    "a table (sortable; each run links to its own page, /runs/run_K/) and any result column\n"
    "plotted against a grid column, updated after every run.\n"
    "Runs until interrupted (Ctrl-C).\n"
    "\n"
    "Options:\n"
    "  --listen ADDR:PORT   address to serve on (default 127.0.0.1:8080; port 0: a free one,\n"
    "                       printed). Loopback unless you ask: any other address serves the\n"
    "                       page to the network, without authentication, with a warning\n"
    "  --quiet              print nothing but errors\n"
    "  --help               this text\n"
    "\n"
    "JSON behind the page: /api/points (frf.csv's fields, every accepted point), /api/truth,\n"
    "/api/live (live.json), /api/summary (once the run has ended), /api/status, /api/events;\n"
    "for a campaign /api/campaign (campaign.csv), /api/status, /api/events.\n"
    "\n"
    "Exit status: 0 stopped by a signal; 1 cannot listen; 2 bad usage, or the folder missing or\n"
    "neither a run nor a campaign folder.\n";

/* RUN_DIR is the one argument that is neither an option nor an option's value. */
static int split_run_dir(int argc, char **argv, char **rest, int *n_rest, const char **run_dir) {
    *n_rest = 0;
    *run_dir = NULL;
    for (int i = 0; i < argc; i++) {
        if (i > 0 && argv[i][0] != '-' && strcmp(argv[i - 1], "--listen") && !*run_dir)
            *run_dir = argv[i];
        else
            rest[(*n_rest)++] = argv[i];
    }
    return *run_dir != NULL;
}

int rths_cmd_view(int argc, char **argv) {
    enum { OPT_LISTEN, N_OPTS };
    rths_cli_opt opts[N_OPTS] = {[OPT_LISTEN] = {"--listen", "ADDR:PORT", NULL}};
    char *rest[argc + 1];
    int n_rest;
    const char *run_dir;
    int have_dir = split_run_dir(argc, argv, rest, &n_rest, &run_dir);
    rths_cli cli;
    int rc = rths_cli_parse(&cli, n_rest, rest, 0, usage, opts, N_OPTS);
    if (rc || cli.help) return rc;
    rths_error err = {0};
    if (!have_dir)
        return rths_cli_fail(&cli,
                             rths_error_set(&err, RTHS_EINPUT,
                                            "missing RUN_DIR (the folder of a run, e.g. "
                                            "out/demo/linear_p0.5, or of a campaign)"),
                             &err);
    rths_api_view *view;
    if ((rc = rths_api_view_open(run_dir, opts[OPT_LISTEN].value, &view, &err)))
        return rths_cli_fail(&cli, rc, &err);
    const char *host = rths_api_view_host(view);
    if (!rths_api_view_host_is_loopback(view))
        fprintf(stderr,
                "rths view: warning: serving on %s, reachable from other machines; the page "
                "has no authentication and shows the run folder's files\n",
                host);
    /* SIGINT and SIGTERM are blocked before the server's threads exist (they inherit the mask)
     * and taken here by sigwait: the stop never depends on which thread a signal lands on */
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, NULL);
    if ((rc = rths_api_view_serve(view, &err))) {
        rths_api_view_stop(view);
        return rths_cli_fail(&cli, rc, &err);
    }
    int v6 = strchr(host, ':') != NULL;
    rths_cli_print(&cli, "rths view: %s at http://%s%s%s:%d/ (Ctrl-C to stop)\n", run_dir,
                   v6 ? "[" : "", host, v6 ? "]" : "", rths_api_view_port(view));
    int sig;
    sigwait(&stop_signals, &sig);
    rths_api_view_stop(view);
    return RTHS_OK;
}
