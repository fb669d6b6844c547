/* rths: iterative real-time hybrid testing toolkit — command dispatcher. */
#include "cli/commands.h"
#include "rths/rths.h"

#include <signal.h>
#include <stdio.h>
#include <string.h>

typedef struct {
    const char *name;
    rths_command_fn fn;
    const char *summary;
} command_entry;

static void print_usage(FILE *to, const command_entry *cmds, int n) {
    fprintf(to,
            "Usage: rths <command> [options]\n"
            "       rths --help | --version\n"
            "       rths <command> --help\n\n"
            "Iterative real-time hybrid testing: a physical substructure on a rig (or the virtual\n"
            "rig), a numerical substructure simulated in real time, and a host that iterates the\n"
            "actuator target's Fourier coefficients until both sides of the interface agree.\n\n"
            "Commands:\n");
    for (int i = 0; i < n; i++)
        if (cmds[i].fn) fprintf(to, "  %-11s %s\n", cmds[i].name, cmds[i].summary);
    fprintf(to,
            "\nEvery command that takes CONFIG accepts --set dotted.key=value (repeatable) to\n"
            "override any configuration key, e.g. --set split.mass_ratio=0.33.\n\n"
            "Exit status: 0 success; 1 failure (numerics, I/O, rig fault); 2 bad usage or input\n"
            "(configuration, command line, values out of range). Nothing is written on exit 2.\n");
}

int main(int argc, char **argv) {
    const command_entry cmds[] = {
        {"model", rths_cmd_model, "modes and analytic FRF of the true assembly"},
        {"simulate", rths_cmd_simulate, "run the hybrid test on the virtual rig at a fixed target"},
        {"fidelity", rths_cmd_fidelity, "integration-scheme error of the numerical substructure"},
        {"frf", rths_cmd_frf, "iterative hybrid test with continuation: the frequency response"},
        {"chart", rths_cmd_chart, "stability chart of the delayed-feedback hybrid test"},
        {"tune", rths_cmd_tune, "PD and grounding gains from the model, with their margins"},
        {"controller", rths_cmd_controller, "the real-time controller process"},
        {"view", rths_cmd_view, "live web page of a run folder, finished or in progress"},
        {"campaign", rths_cmd_campaign, "many frf runs over a grid of values and seeds (MPI)"},
    };
    const int n = (int)(sizeof cmds / sizeof cmds[0]);
    /* a file size limit (ulimit -f) makes write() fail with EFBIG, which every writer reports by
     * name, instead of killing the process mid-output */
    signal(SIGXFSZ, SIG_IGN);
    if (argc < 2) {
        print_usage(stderr, cmds, n);
        return RTHS_EINPUT;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        print_usage(stdout, cmds, n);
        return RTHS_OK;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("rths %s\n", RTHS_VERSION);
#ifdef RTHS_HAVE_MPI
        printf("MPI: built in (rths campaign under mpirun shares its runs between the ranks)\n");
#else
        printf("MPI: not built in (rths campaign runs serially or with --jobs)\n");
#endif
        return RTHS_OK;
    }
    for (int i = 0; i < n; i++)
        if (cmds[i].fn && !strcmp(argv[1], cmds[i].name)) return cmds[i].fn(argc - 1, argv + 1);
    fprintf(stderr, "rths: unknown command '%s' (see 'rths --help')\n", argv[1]);
    return RTHS_EINPUT;
}
