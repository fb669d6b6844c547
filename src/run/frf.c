/* The FRF test as one call: configuration -> rig -> continuation -> journal -> outputs. Input is
 * checked before anything is written; once started, everything accepted goes to journal.jsonl as
 * it happens, and frf.csv, summary.json and the figures are written at the end however the run
 * ended, so nothing accepted is ever lost. */
#include "run/frf_internal.h"
#include "run/frf_hb_numerical.h"
#include "run/frf_sites.h"

#include "rths/reduce.h"
#include "rths/rig_remote.h"
#include "rths/rig_virtual.h"

#include <errno.h>
#include <fcntl.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

/* The seed's implicit Euler numerical substructure and its grounding damping (Table 2). */
const char *const rths_run_paper_overrides[] = {"controller.scheme=implicit_euler",
                                                "controller.transition_periods=0",
                                                "controller.grounding_kd_n_s_per_m=200", NULL};
/* the count run.h gives its users (array sizes, loops) is this list's: a third override once went
 * unapplied while the count still said 2 */
_Static_assert(sizeof rths_run_paper_overrides / sizeof rths_run_paper_overrides[0] ==
                   RTHS_RUN_PAPER_OVERRIDES + 1,
               "RTHS_RUN_PAPER_OVERRIDES must count rths_run_paper_overrides");

/* A private status the point handler returns to end the continuation on cancellation. */
enum { FRF_CANCELLED = 100 };

/* The sweep lies where the controller accepts a forcing: from controller.min_frequency_hz to
 * below a quarter of controller.sample_rate_hz (what the rigs refuse at run time, src/rig), so a
 * range the controller would refuse is bad input (exit 2) before anything is written. With a
 * controller process the host's configuration stands for the controller's. */
static int check_sweep_range(frf_state *st, rths_error *err) {
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    int rc = rths_controller_config_read(st->opt->cfg, &copt, err);
    static const char *const keys[2] = {"continuation.start_hz", "continuation.end_hz"};
    double f[2] = {st->cont.start_hz, st->cont.end_hz}, high = 0.25 * copt.sample_rate_hz;
    for (int i = 0; i < 2 && !rc; i++) {
        if (f[i] < copt.min_frequency_hz)
            rc = rths_config_error_at(st->opt->cfg, keys[i], err,
                                      "%g Hz is below controller.min_frequency_hz (%g Hz), the "
                                      "lowest forcing frequency the controller accepts",
                                      f[i], copt.min_frequency_hz);
        else if (f[i] >= high)
            rc = rths_config_error_at(st->opt->cfg, keys[i], err,
                                      "%g Hz is not below a quarter of controller.sample_rate_hz "
                                      "(%g Hz), the highest forcing frequency the controller "
                                      "accepts",
                                      f[i], high);
    }
    return rc;
}

/* Strategy defaults, then the iteration, continuation and output sections over them. */
/* The evaluation's notes (a fitted steady state falling back to waiting, a standard-error target
 * missed: docs/method.md, "The fitted evaluation") and the continuation's (a failed correction)
 * go to run.log once it is open. */
static void run_log_note(void *user, const char *line) {
    frf_state *st = user;
    if (st->rep) rths_report_log(st->rep, "%s", line);
}

static int read_options(frf_state *st, rths_error *err) {
    const rths_run_frf_options *opt = st->opt;
    st->strategy = opt->strategy ? opt->strategy : "default";
    if (strcmp(st->strategy, "default") && strcmp(st->strategy, "paper"))
        return rths_error_set(err, RTHS_EINPUT, "strategy '%s' is neither 'default' nor 'paper'",
                              st->strategy);
    st->paper = !strcmp(st->strategy, "paper");
    if (opt->harmonics < 0 || opt->harmonics > RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT, "harmonics %d is not in 1..%d", opt->harmonics,
                              RTHS_MAX_HARMONICS);
    if (opt->rig_uri && opt->rig)
        return rths_error_set(err, RTHS_EINPUT,
                              "both a rig and a rig URI (%s) given: measure on one", opt->rig_uri);
    if (opt->rig_uri && strncmp(opt->rig_uri, "tcp://", 6))
        return rths_error_set(err, RTHS_EINPUT, "rig '%s' is not tcp://HOST:PORT", opt->rig_uri);
    st->harmonics = 1;
    rths_settle_defaults(&st->settle, st->paper);
    rths_newton_defaults(&st->newton, st->paper);
    rths_continuation_defaults(&st->cont);
    st->cont.model_predictor = !st->paper;
    int rc = rths_iterate_config_read(opt->cfg, &st->settle, &st->newton, &st->harmonics, err);
    st->settle.note = run_log_note;
    st->settle.note_user = st;
    /* --force also accepts a point below the measured noise floor, flagged in frf.csv */
    st->newton.accept_below_noise = opt->force;
    st->newton.on_evaluation = frf_on_evaluation;
    st->newton.on_evaluation_user = st;
    if (!rc && opt->harmonics) st->harmonics = opt->harmonics;
    if (!rc) rc = rths_continuation_config_read(opt->cfg, &st->cont, err);
    st->cont.note = run_log_note;
    st->cont.note_user = st;
    if (!rc) rc = check_sweep_range(st, err);
    /* the virtual rig of a linear structure has a branch without folds (a real rig's physical
     * part may be nonlinear whatever the model says) */
    st->cont.monotonic = !opt->rig_uri && !opt->rig && !st->setup->has_bilinear;
    st->newton.rig_lti = st->cont.monotonic;
    if (!rc)
        rc = rths_config_get_double(opt->cfg, "output.trace_frequency_hz", 0, 0, 0, 1e5,
                                    &st->trace_hz, err);
    rths_controller_options copt; /* output.dofs, as the rig's controller reads it */
    rths_controller_defaults(&copt);
    if (!rc) rc = rths_controller_config_read(opt->cfg, &copt, err);
    if (!rc) frf_dof_columns_init(&st->dof_cols, &copt);
    rths_floquet_measure_defaults(&st->floquet);
    if (!rc) rc = rths_floquet_measure_config_read(opt->cfg, &st->floquet, err);
    if (!rc && st->floquet.enabled && (opt->rig_uri || opt->rig))
        rc = rths_config_error_at(opt->cfg, "stability.experimental_floquet", err,
                                  "needs the virtual rig: the remote rig's protocol cannot inject "
                                  "a demand perturbation");
    /* the series map is identified between one physical and one numerical interface signal,
     * and the controller must integrate the numerical substructure to produce the latter */
    if (!rc && st->floquet.enabled &&
        (st->setup->split.n_int > 1 || st->setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY))
        rc = rths_config_error_at(opt->cfg, "stability.experimental_floquet", err,
                                  "needs one interface DoF and the real-time numerical "
                                  "substructure (split.numerical_solver: realtime)");
    return rc;
}

/* A multi-site test (rig.sites; docs/method.md, "Multi-site tests"): the sites' URIs from --rig
 * (one per site) or from rig.sites, and the joined rig over their controllers. *joined = 0 when
 * no site has a URI: the virtual rig then runs the whole physical side in one process (the
 * single-process run of the same test). Refused: URIs for some sites only, a count of --rig
 * that differs from the sites', one --rig with rig.sites, the real-time form when the numerical
 * side couples the sites. */
static int create_sites_rig(frf_state *st, int *joined, rths_error *err) {
    const rths_run_frf_options *opt = st->opt;
    rths_run_sites sites;
    *joined = 0;
    int rc = rths_run_sites_read(opt->cfg, st->setup, &sites, err);
    if (!rc && opt->n_site_uris > 0 && sites.n == 0)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "--rig given %d times: a multi-site test needs rig.sites in the "
                            "configuration (which interface DoFs each site drives)",
                            opt->n_site_uris);
    if (rc || sites.n == 0) return rc;
    if (opt->rig_uri || opt->rig)
        return rths_error_set(err, RTHS_EINPUT,
                              "rig.sites lists %d sites: give --rig once per site (in rig.sites' "
                              "order), or none to take rig.sites.N.uri",
                              sites.n);
    if (opt->n_site_uris > 0 && opt->n_site_uris != sites.n)
        return rths_error_set(err, RTHS_EINPUT,
                              "--rig given %d times; rig.sites lists %d sites (one --rig per "
                              "site, in rig.sites' order)",
                              opt->n_site_uris, sites.n);
    const char *uris[RTHS_MAX_INTERFACE_DOFS];
    const int *maps[RTHS_MAX_INTERFACE_DOFS];
    int have = 0;
    for (int k = 0; k < sites.n; k++) {
        uris[k] = opt->n_site_uris ? opt->site_uris[k] : sites.site[k].uri;
        maps[k] = sites.site[k].map;
        have += uris[k][0] != 0;
    }
    if (have == 0) return RTHS_OK; /* the single-process run */
    for (int k = 0; k < sites.n; k++)
        if (!uris[k][0]) {
            char key[64];
            snprintf(key, sizeof key, "rig.sites.%d", k);
            return rths_config_error_at(opt->cfg, key, err,
                                        "has no uri while other sites have one: give every "
                                        "site's tcp://HOST:PORT (or --rig once per site)");
        }
    rc = rths_run_sites_check_solver(opt->cfg, st->setup, &sites, err);
    /* the sites' controllers read the rig section (as with one --rig, whose run reads none of
     * it): the host has read rig.sites only */
    if (!rc) rths_config_mark_known(opt->cfg, "rig");
    if (!rc) rc = rths_config_check_sections(opt->cfg, NULL, err);
    if (!rc)
        rc =
            rths_sites_rig_create(sites.n, uris, maps, st->setup->split.n_int, NULL, &st->rig, err);
    if (rc) return rc;
    *joined = 1;
    /* real rigs: the physical parts may be nonlinear whatever the model says */
    st->cont.monotonic = 0;
    st->newton.rig_lti = 0;
    for (int k = 0; k < sites.n; k++) {
        rths_site_info info;
        rths_sites_rig_site(st->rig, k, &info);
        /* each site's controller announces the DoFs its own split gives it */
        if (info.interface_dofs != sites.site[k].n_int)
            return rths_error_set(err, RTHS_EINPUT,
                                  "site %d (%s) drives %d interface DoF(s); rig.sites.%d."
                                  "interface_dofs lists %d (start its controller with --site %d)",
                                  k + 1, uris[k], info.interface_dofs, k, sites.site[k].n_int,
                                  k + 1);
    }
    return RTHS_OK;
}

/* The rig, created before anything is written: its configuration errors are input errors. The
 * run's own sections are checked key by key; the controller process reads rig and controller
 * itself. */
static int create_rig(frf_state *st, rths_error *err) {
    const rths_run_frf_options *opt = st->opt;
    int joined = 0;
    int rc = create_sites_rig(st, &joined, err);
    if (!rc && !joined && !opt->rig_uri && !opt->rig)
        rc = rths_virtual_rig_create(opt->cfg, st->setup, opt->has_seed, opt->seed, &st->rig, err);
    if (!rc && !joined && !opt->rig_uri && !opt->rig) st->virtual_rig = st->rig;
    if (!rc && !joined) rc = rths_config_check_sections(opt->cfg, NULL, err);
    if (!rc && opt->rig_uri) rc = rths_remote_rig_create(opt->rig_uri, NULL, &st->rig, err);
    st->inner_rig = st->rig;
    if (!rc && opt->reset_fault && !opt->rig_uri && !joined)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "--reset-fault needs --rig tcp://HOST:PORT: a virtual rig starts "
                            "without a fault");
    if (!rc && opt->reset_fault)
        rc = rths_rig_clear_fault(st->rig, st->reset_note, sizeof st->reset_note, err);
    if (!rc && !st->virtual_rig && rths_rig_interface_dofs(st->rig) != st->setup->split.n_int)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s drives %d interface DoF(s); this configuration's split.interface "
                            "has %d",
                            opt->rig_uri ? opt->rig_uri : rths_rig_description(st->rig),
                            rths_rig_interface_dofs(st->rig), st->setup->split.n_int);
    int dofs = st->setup->split.n_int;
    if (!rc && dofs > 1 && 2 * st->harmonics * dofs > 2 * RTHS_MAX_HARMONICS)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%d harmonic(s) on %d interface DoFs are %d unknowns; the corrector "
                            "takes at most %d: lower iteration.harmonics",
                            st->harmonics, dofs, 2 * st->harmonics * dofs, 2 * RTHS_MAX_HARMONICS);
    return rc;
}

/* Fills the run's memory with a point (the journal's on resume, already durable). */
static int remember(frf_state *st, const rths_point *pt) {
    if (pt->index >= st->cap) {
        int cap = st->cap ? 2 * st->cap : 64;
        while (cap <= pt->index)
            cap *= 2;
        rths_point *p = realloc(st->pts, (size_t)cap * sizeof *p);
        if (!p) return RTHS_EFAIL;
        st->pts = p;
        if (st->floquet.enabled) { /* the experimental Floquet estimates, by the same index */
            frf_floquet_point *f = realloc(st->floquet_pts, (size_t)cap * sizeof *f);
            if (!f) return RTHS_EFAIL;
            for (int i = st->cap; i < cap; i++)
                f[i] = (frf_floquet_point){0};
            st->floquet_pts = f;
        }
        st->cap = cap;
    }
    st->pts[pt->index] = *pt;
    if (pt->index >= st->n) st->n = pt->index + 1;
    return RTHS_OK;
}

/* --resume: the journal's points, after checking they belong to this kind of run. The journal is
 * rewritten without a torn last line (atomically), in the current format, so appending continues
 * on a clean record. */
static int load_resume(frf_state *st, rths_error *err) {
    char *jstrategy = NULL;
    int rc = rths_journal_read(st->journal_path, &st->resume_pts, &st->n_resume, &jstrategy, err);
    if (rc) return rc;
    const rths_point *pts = st->resume_pts;
    int dofs = st->setup->split.n_int > 1 ? st->setup->split.n_int : 1;
    if (!jstrategy)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s has no header record (the run was killed before it started): "
                            "start a new run in another folder",
                            st->journal_path);
    else if (strcmp(jstrategy, st->strategy))
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s was written by a '%s' run; resume it with --strategy %s",
                            st->journal_path, jstrategy, jstrategy);
    else if (st->n_resume > 0 && pts[0].sol.harmonics != st->harmonics * dofs)
        /* with several interface DoFs a solution's harmonics counts the (DoF, harmonic) pairs */
        rc = rths_error_set(
            err, RTHS_EINPUT, "%s matched %d harmonic(s); resume it with --harmonics %d",
            st->journal_path, pts[0].sol.harmonics / dofs, pts[0].sol.harmonics / dofs);
    free(jstrategy);
    if (rc) return rc;
    size_t len = strlen(st->journal_path) + 16;
    char *tmp = malloc(len);
    if (!tmp) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    snprintf(tmp, len, "%s.rewrite", st->journal_path);
    remove(tmp);
    rths_journal *j = NULL;
    rc = rths_journal_open_run(tmp, st->strategy, st->seed_text, frf_rig_text(st), &j, err);
    for (int i = 0; i < st->n_resume && !rc; i++)
        rc = rths_journal_append(j, &pts[i], 0, err);
    if (j) rths_journal_close(j);
    if (!rc && rename(tmp, st->journal_path))
        rc = rths_error_set(err, RTHS_EFAIL, "cannot replace %s", st->journal_path);
    if (rc) remove(tmp);
    free(tmp);
    return rc;
}

/* The output folder holds no run (or, to resume, holds one). */
static int check_journal(frf_state *st, rths_error *err) {
    const rths_run_frf_options *opt = st->opt;
    size_t len = strlen(opt->out_dir) + 32;
    st->journal_path = malloc(len);
    if (!st->journal_path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    snprintf(st->journal_path, len, "%s/journal.jsonl", opt->out_dir);
    struct stat sb;
    int exists = stat(st->journal_path, &sb) == 0;
    if (!opt->resume && exists)
        return rths_error_set(err, RTHS_EINPUT,
                              "%s already holds a run (journal.jsonl): continue it with --resume, "
                              "or choose another --out",
                              opt->out_dir);
    if (opt->resume && !exists)
        return rths_error_set(err, RTHS_EINPUT, "--resume: %s has no journal.jsonl to resume",
                              opt->out_dir);
    return RTHS_OK;
}

/* Two runs must never write one folder: an exclusive flock on DIR/run.lock, held until the run
 * ends (the kernel drops it if the process dies), which holds the holder's pid. An existing
 * folder is locked before its journal is looked at (create 0: a missing one is left alone); a new
 * one is created and locked once the input is checked (create 1), so a refused run leaves
 * nothing, and its journal check is repeated under the lock because another run may have started
 * the folder meanwhile.
 *
 * The run removes run.lock when it releases the folder (release_folder: unlink while still
 * holding the lock, then close), so a finished folder holds no stale lock file. A run that
 * opened the old file just before the unlink may then lock an inode no longer in the folder,
 * while a third run creates and locks a new run.lock: both would own the folder. So a lock
 * counts only while the path still names the locked inode; otherwise it is dropped and taken
 * again on the new file. */
static int lock_folder(frf_state *st, int create, rths_error *err) {
    const char *dir = st->opt->out_dir;
    struct stat sb;
    if (st->lock_fd >= 0 || (!create && stat(dir, &sb) != 0)) return RTHS_OK;
    if (create && mkdir(dir, 0755) != 0 && errno != EEXIST)
        return rths_error_set(err, RTHS_EFAIL, "cannot create %s: %s", dir, strerror(errno));
    size_t len = strlen(dir) + 16;
    char *path = malloc(len);
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    snprintf(path, len, "%s/run.lock", dir);
    int rc = RTHS_OK;
    for (int attempt = 0; attempt < 100 && st->lock_fd < 0 && !rc; attempt++) {
        int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        struct stat held, named;
        if (fd < 0) {
            rc = rths_error_set(err, RTHS_EFAIL, "cannot open %s: %s", path, strerror(errno));
        } else if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
            char pid[32] = "?";
            ssize_t n = pread(fd, pid, sizeof pid - 1, 0);
            pid[n > 0 ? n : 1] = 0;
            pid[strcspn(pid, "\n")] = 0;
            rc = rths_error_set(err, RTHS_EINPUT, "%s is in use by another rths run (pid %s)", dir,
                                pid);
            close(fd);
        } else if (fstat(fd, &held) != 0 || stat(path, &named) != 0 ||
                   held.st_dev != named.st_dev || held.st_ino != named.st_ino) {
            close(fd); /* the run that held it removed it meanwhile: lock the new file */
        } else {
            st->lock_fd = fd;
            st->lock_path = path;
            path = NULL;
        }
    }
    if (!rc && st->lock_fd < 0)
        rc = rths_error_set(err, RTHS_EFAIL, "cannot lock %s: it keeps being replaced", path);
    if (!rc) {
        char pid[32];
        int n = snprintf(pid, sizeof pid, "%ld\n", (long)getpid());
        if (ftruncate(st->lock_fd, 0) != 0 || pwrite(st->lock_fd, pid, (size_t)n, 0) != n)
            rc = rths_error_set(err, RTHS_EFAIL, "cannot write %s: %s", st->lock_path,
                                strerror(errno));
    }
    free(path);
    if (!rc && !st->opt->resume && st->journal_path && stat(st->journal_path, &sb) == 0)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%s already holds a run (journal.jsonl): continue it with --resume, "
                            "or choose another --out",
                            dir);
    return rc;
}

/* Gives the folder up: run.lock removed while still locked (see lock_folder), then unlocked. */
static void release_folder(frf_state *st) {
    if (st->lock_fd < 0) return;
    if (st->lock_path) unlink(st->lock_path);
    close(st->lock_fd);
    st->lock_fd = -1;
    free(st->lock_path);
    st->lock_path = NULL;
}

/* Opens the output folder (run.log, config.yaml) and writes the truth curve. */
static int open_outputs(frf_state *st, rths_error *err) {
    const rths_run_frf_options *opt = st->opt;
    int rc = rths_report_open(opt->out_dir, "frf", opt->argc, opt->argv, &st->rep, err);
    if (rc) return rc;
    if (st->reset_note[0]) rths_report_log(st->rep, "%s", st->reset_note);
    if (st->virtual_rig) { /* a sparse model's real-time reduction (controller.h) */
        char reduction[768];
        rths_controller_krylov_text(rths_virtual_rig_controller(st->virtual_rig), reduction,
                                    sizeof reduction);
        if (reduction[0]) rths_report_log(st->rep, "%s", reduction);
    }
    char *path = rths_report_path(st->rep, "config.yaml");
    rc = path ? rths_config_write(opt->cfg, path, err)
              : rths_error_set(err, RTHS_EFAIL, "out of memory");
    free(path);
    if (!rc) rc = frf_write_truth_csv(st->rep, st, &st->truth, err);
    if (!rc)
        rc = rths_journal_open_run(st->journal_path, st->strategy, st->seed_text, frf_rig_text(st),
                                   &st->journal, err);
    if (!rc) rc = frf_evaluations_open(st, err);
    /* the observing rig reports every evaluation to live.json; it forwards every call unchanged
     * (tests/test_live.c: a watched run equals an unwatched one bit for bit) */
    if (!rc) rc = rths_live_open(opt->out_dir, &st->live, err);
    if (!rc) rc = rths_live_wrap_rig(st->live, st->rig, &st->rig, err);
    if (!rc && st->opt->resume) {
        const char *changes[FRF_MAX_CHANGES];
        for (int i = 0; i < st->n_changes; i++)
            changes[i] = st->changes[i];
        rc = rths_journal_append_resume(st->journal, st->n_resume, changes, st->n_changes, err);
    }
    for (int i = 0; i < st->n_resume && !rc; i++)
        if (remember(st, &st->resume_pts[i])) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    return rc;
}

/* stability.experimental_floquet: the multipliers at the point just accepted, while the rig still
 * holds its orbit (docs/method.md, "Experimental Floquet multipliers"). A failed estimate is
 * logged and leaves the point unmeasured; a rig fault stops the run. */
static int measure_floquet(frf_state *st, const rths_point *pt) {
    rths_floquet_estimate e;
    rths_error err = {0};
    double rig_s = 0;
    int rc = rths_floquet_measure(st->virtual_rig, pt->sol.frequency_hz, &st->floquet,
                                  st->floquet.seed + (uint64_t)pt->index, &e, &rig_s, &err);
    st->floquet_rig_time_s += rig_s;
    if (rc) {
        rths_report_log(st->rep, "point %d: no Floquet estimate: %s", pt->index, err.msg);
        if (rths_rig_get_fault(st->virtual_rig) == RTHS_RIG_OK) return RTHS_OK;
        st->point_err = err;
        return RTHS_EFAIL;
    }
    st->floquet_pts[pt->index] =
        (frf_floquet_point){1, e.max_abs, e.max_abs_se, e.label, e.trustworthy};
    char dominant[160] = "";
    for (int i = 0, len = 0; i < e.n_multipliers && i < 4 && len < (int)sizeof dominant; i++)
        len += snprintf(dominant + len, sizeof dominant - (size_t)len, "%s%.4f%+.4fi",
                        i ? ", " : "", e.multiplier_re[i], e.multiplier_im[i]);
    static const char *const label[] = {"undetermined", "unstable", "stable"};
    rths_report_log(st->rep,
                    "point %d: Floquet |mu|max %.5f +- %.2g (standard error: bootstrap %.2g, "
                    "order %.2g): %s; dominant %s (order %d, residual %.3g, condition %.3g%s%s)",
                    pt->index, e.max_abs, e.max_abs_se, e.max_abs_se_bootstrap, e.max_abs_se_order,
                    label[e.label + 1], dominant, e.order, e.relative_residual, e.condition,
                    e.trustworthy ? "" : "; not trustworthy: ", e.note);
    return RTHS_OK;
}

/* How a point's evaluations reached steady state, for its run.log line: "waited", or with
 * iteration.settle.strategy fit how many were fitted and how many fell back (and the last
 * reason), and with iteration.target_rel_se whether the point's accepted evaluation met it
 * within the point's iteration.max_rig_s_per_point (docs/method.md, "The fitted evaluation"). */
static void settle_text(const frf_state *st, const rths_point *pt, char *buf, size_t size) {
    const rths_settle_tally *t = &pt->settle;
    const rths_evaluation *e = &pt->sol.eval;
    int len;
    if (st->settle.strategy == RTHS_SETTLE_FIT)
        len = snprintf(buf, size, "%s; of %d evaluations %d fitted, %d fell back to waiting%s%s",
                       e->fitted ? "fitted" : "waited", t->evaluations, t->fitted, t->fit_fallbacks,
                       t->fallback_reason[0] ? " (last: " : "",
                       t->fallback_reason[0] ? t->fallback_reason : "");
    else
        len = snprintf(buf, size, "waited");
    if (len > 0 && (size_t)len < size && t->fallback_reason[0] &&
        st->settle.strategy == RTHS_SETTLE_FIT)
        len += snprintf(buf + len, size - (size_t)len, ")");
    if (len > 0 && (size_t)len < size && st->settle.target_rel_se > 0)
        snprintf(buf + len, size - (size_t)len,
                 e->se_target_missed
                     ? "; iteration.target_rel_se %.3g NOT met (relative standard error %.3g "
                       "after %.3g of the point's %.3g rig s)"
                     : "; iteration.target_rel_se %.3g met (relative standard error %.3g, %.3g of "
                       "the point's %.3g rig s)",
                 st->settle.target_rel_se, e->amplitude_rel_se, t->rig_time_s,
                 st->settle.max_rig_s_per_point > 0 ? st->settle.max_rig_s_per_point
                                                    : RTHS_SETTLE_MAX_RIG_S_PER_POINT);
}

/* One run.log line per accepted point, written (and flushed) as it is accepted, so a run under
 * nohup shows its progress with tail -f: frequency, amplitude and its standard error, the
 * evaluations and rig time the point took; with several interface DoFs every DoF's amplitude; in
 * a multi-site test every site's rig time so far. */
static void log_point(frf_state *st, const rths_point *pt) {
    const rths_solution *sol = &pt->sol;
    char extra[600] = "";
    int len = 0;
    for (int d = 1; d < sol->interface_dofs && len < (int)sizeof extra; d++)
        len += snprintf(extra + len, sizeof extra - (size_t)len, "; DoF %d %.6g m +- %.2g",
                        st->setup->split.int_dofs[d] + 1, sol->dof_amplitude_m[d],
                        sol->dof_amplitude_se_m[d]);
    int sites = rths_sites_rig_count(st->inner_rig);
    for (int k = 0; k < sites && len < (int)sizeof extra; k++) {
        rths_site_info info;
        rths_sites_rig_site(st->inner_rig, k, &info);
        len += snprintf(extra + len, sizeof extra - (size_t)len, "%s%.1f s",
                        k ? ", " : "; sites' rig time ", info.rig_time_s);
    }
    char how[RTHS_SETTLE_REASON_LEN + 200];
    settle_text(st, pt, how, sizeof how);
    rths_report_log(st->rep,
                    "point %d accepted: %.6f Hz, amplitude %.6g m +- %.2g (SE), %d evaluation%s, "
                    "%.2f s rig%s; %s%s",
                    pt->index, sol->frequency_hz, sol->amplitude_m, sol->amplitude_se_m,
                    pt->evaluations, pt->evaluations == 1 ? "" : "s", pt->rig_time_s,
                    sol->converged ? "" : ", not converged", how, extra);
}

/* A multi-site test's sites as run.log and summary.json report them: URI, interface DoFs, rig
 * time (each site's controller clock since the run joined it), latched fault, integrity. */
static void log_sites(frf_state *st) {
    int sites = st->inner_rig ? rths_sites_rig_count(st->inner_rig) : 0;
    for (int k = 0; k < sites; k++) {
        rths_site_info info;
        rths_sites_rig_site(st->inner_rig, k, &info);
        char dofs[64] = "";
        for (int j = 0, len = 0; j < info.interface_dofs; j++)
            len += snprintf(dofs + len, sizeof dofs - (size_t)len, "%s%d", j ? ", " : "",
                            st->setup->split.int_dofs[info.map[j]] + 1);
        rths_report_log(st->rep,
                        "site %d %s (%s): interface DoFs [%s], rig time %.2f s, fault %s, %ld "
                        "periods, %ld late samples",
                        k + 1, info.uri, info.description, dofs, info.rig_time_s,
                        rths_rig_fault_name(info.fault), info.integrity.periods,
                        info.integrity.late_samples);
    }
}

/* summary.json's "sites" (a multi-site test only), added to the summary frf_write_summary wrote
 * (replaced atomically) before results.mat reads it. */
static int add_sites_summary(frf_state *st, rths_error *err) {
    int sites = st->inner_rig ? rths_sites_rig_count(st->inner_rig) : 0;
    if (!sites) return RTHS_OK;
    char *path = rths_report_path(st->rep, "summary.json");
    if (!path) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    json_object *root = json_object_from_file(path);
    int rc = root ? RTHS_OK
                  : rths_error_set(err, RTHS_EFAIL, "cannot read back %s to add the sites", path);
    json_object *list = rc ? NULL : json_object_new_array();
    for (int k = 0; k < sites && list; k++) {
        rths_site_info info;
        rths_sites_rig_site(st->inner_rig, k, &info);
        json_object *o = json_object_new_object(), *dofs = json_object_new_array();
        for (int j = 0; j < info.interface_dofs; j++)
            json_object_array_add(dofs,
                                  json_object_new_int(st->setup->split.int_dofs[info.map[j]] + 1));
        json_object_object_add(o, "uri", json_object_new_string(info.uri));
        json_object_object_add(o, "controller", json_object_new_string(info.description));
        json_object_object_add(o, "interface_dofs", dofs);
        json_object_object_add(o, "rig_time_s", json_object_new_double(info.rig_time_s));
        json_object_object_add(o, "fault", json_object_new_string(rths_rig_fault_name(info.fault)));
        json_object_object_add(o, "periods", json_object_new_int64(info.integrity.periods));
        json_object_object_add(o, "late_samples",
                               json_object_new_int64(info.integrity.late_samples));
        json_object_array_add(list, o);
    }
    if (list) {
        json_object_object_add(root, "sites", list);
        rc = rths_json_write(path, root, err);
    }
    if (root) json_object_put(root);
    free(path);
    return rc;
}

static int on_point(void *user, const rths_point *given, int is_update) {
    frf_state *st = user;
    rths_error err;
    /* how its evaluations reached steady state: the tally kept over the point (a fold's update
     * re-reports a point already remembered with it) */
    rths_point with_settle = *given, *pt = &with_settle;
    if (!is_update && st->settle.tally) {
        pt->settle = *st->settle.tally;
        memset(st->settle.tally, 0, sizeof *st->settle.tally);
    } else if (is_update && given->index < st->n) {
        pt->settle = st->pts[given->index].settle;
    }
    if (rths_journal_append(st->journal, pt, is_update, &err)) {
        rths_report_log(st->rep, "%s", err.msg);
        st->point_err = err;
        return RTHS_EFAIL;
    }
    if (!is_update) log_point(st, pt);
    if (!is_update && pt->trust_actions > 0)
        rths_report_log(st->rep,
                        "point %d at %.6g Hz: the targets' trust region acted %d time(s) "
                        "(iteration.trust_growth; docs/method.md, \"Iteration and continuation\")",
                        pt->index, pt->sol.frequency_hz, pt->trust_actions);
    if (remember(st, pt))
        return rths_error_set(&st->point_err, RTHS_EFAIL, "out of memory keeping the points");
    if (st->floquet.enabled && !is_update && measure_floquet(st, pt)) return RTHS_EFAIL;
    const rths_run_callbacks *cb = st->cb;
    int rc = cb && cb->on_point ? cb->on_point(cb->user, pt, is_update) : RTHS_OK;
    if (rc)
        rths_error_set(&st->point_err, rc, "the point callback stopped the run (status %d)", rc);
    /* only after a new point: a fold's re-reported points come before the point that found it */
    if (!rc && !is_update && cb && cb->should_cancel && cb->should_cancel(cb->user)) {
        st->cancelled = 1;
        return FRF_CANCELLED;
    }
    return rc;
}

static void on_progress(void *user, int points, double frequency_hz, double residual_m,
                        int evaluations, int accepted) {
    frf_state *st = user;
    rths_live_progress(st->live, points, frequency_hz, residual_m, accepted);
    const rths_run_callbacks *cb = st->cb;
    if (cb && cb->on_progress)
        cb->on_progress(cb->user, points, frequency_hz, residual_m, evaluations, accepted);
}

/* Offset of point i's log amplitude (a[i]) from the chord through its neighbours in frequency,
 * when the three lie on one branch segment in monotonic frequency; 0 with *ok = 0 otherwise. */
static double branch_offset(const frf_state *st, const double *a, int i, int *ok) {
    const rths_point *p = st->pts;
    double f0 = p[i - 1].sol.frequency_hz, f1 = p[i].sol.frequency_hz,
           f2 = p[i + 1].sol.frequency_hz;
    *ok = p[i - 1].segment == p[i].segment && p[i + 1].segment == p[i].segment &&
          (f1 - f0) * (f2 - f1) > 0 && a[i - 1] > 0 && a[i] > 0 && a[i + 1] > 0;
    if (!*ok) return 0.0;
    double b = (f1 - f0) / (f2 - f0);
    return log(a[i]) - ((1 - b) * log(a[i - 1]) + b * log(a[i + 1]));
}

/* Points whose offsets from their neighbours' chords join a point's branch scatter, each side. */
enum { BRANCH_SCATTER_HALF_WINDOW = 4 };

/* The frequency form with nonlinear elements: each point's amplitude standard error is at least
 * the scatter of the points about the branch near it (docs/method.md, "Nonlinear elements in
 * the frequency form"). On the Duffing example with noise the points lay 0.15-0.4 % off with
 * standard errors of 0.03-0.1 %: an error correlated over more than 16 periods, which the
 * periods' scatter cannot see and, without a fitted model, nothing else measures. The offsets
 * r_i of log amplitudes from the chords through their neighbours (var r >= 1.5 sigma^2 for
 * independent errors; the branch's curvature only adds) over the points within the window give
 * sigma, relative; the larger of it and the point's own standard error is reported. */
static void frf_branch_scatter_floor(frf_state *st) {
    int n = st->n, dofs = st->setup->split.n_int, raised = 0;
    double *a = malloc((size_t)(n > 0 ? n : 1) * sizeof *a);
    double *r = malloc((size_t)(n > 0 ? n : 1) * sizeof *r);
    int *ok = malloc((size_t)(n > 0 ? n : 1) * sizeof *ok);
    for (int d = -1; a && r && ok && d < (dofs > 1 ? dofs : 0); d++) {
        for (int i = 0; i < n; i++) {
            const rths_solution *s = &st->pts[i].sol;
            a[i] = d < 0 ? s->amplitude_m : s->dof_amplitude_m[d];
            ok[i] = 0;
        }
        for (int i = 1; i + 1 < n; i++)
            r[i] = branch_offset(st, a, i, &ok[i]);
        for (int i = 0; i < n; i++) {
            double sum = 0;
            int count = 0;
            for (int j = i - BRANCH_SCATTER_HALF_WINDOW; j <= i + BRANCH_SCATTER_HALF_WINDOW; j++)
                if (j > 0 && j + 1 < n && ok[j]) sum += r[j] * r[j], count++;
            if (count < 3) continue;
            double floor_m = a[i] * sqrt(sum / count / 1.5);
            rths_solution *s = &st->pts[i].sol;
            double *se = d < 0 ? &s->amplitude_se_m : &s->dof_amplitude_se_m[d];
            if (!(isfinite(*se) && floor_m > *se)) continue;
            *se = floor_m;
            raised++;
            /* the accuracy-on-demand flag follows the standard error now reported */
            double rel = a[i] > 0 ? floor_m / a[i] : INFINITY;
            if (st->settle.target_rel_se > 0 && rel > st->settle.target_rel_se) {
                s->eval.se_target_missed = 1;
                if (!(s->eval.amplitude_rel_se >= rel)) s->eval.amplitude_rel_se = rel;
            }
        }
    }
    free(a);
    free(r);
    free(ok);
    /* the journal, the run.log point lines and the callbacks had the corrector's own */
    if (raised)
        rths_report_log(st->rep,
                        "standard errors raised to the branch's local scatter after the run: %d "
                        "(point, DoF) values in frf.csv and summary.json (docs/method.md, "
                        "\"Nonlinear elements in the frequency form\")",
                        raised);
}

/* split.numerical_solver: frequency with nonlinear elements on the numerical side: the zero
 * problem reads the rig through the view that solves the numerical substructure by harmonic
 * balance, motion-to-force, every period (frf_hb_numerical.h; docs/method.md, "Nonlinear
 * elements in the frequency form"); one interface DoF or several. */
static int run_frequency_form_nonlinear(frf_state *st, rths_error *err) {
    frf_hb_numerical *hb = NULL;
    rths_rig *view = NULL;
    /* the grounding gains the real-time form would use (controller.grounding_*) */
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    int rc = rths_controller_config_read(st->opt->cfg, &copt, err);
    double kp[RTHS_MAX_INTERFACE_DOFS], kd[RTHS_MAX_INTERFACE_DOFS];
    for (int d = 0; d < RTHS_MAX_INTERFACE_DOFS; d++) {
        kp[d] = copt.grounding_kp_dof[d] > 0 ? copt.grounding_kp_dof[d] : copt.grounding_kp_n_per_m;
        kd[d] =
            copt.grounding_kd_dof[d] > 0 ? copt.grounding_kd_dof[d] : copt.grounding_kd_n_s_per_m;
    }
    if (!rc) rc = frf_hb_numerical_create(st->setup, st->rig, kp, kd, &hb, &view, err);
    rths_zero_problem problem;
    rths_rig_problem ctx;
    if (!rc && st->setup->split.n_int > 1)
        rc = rths_rig_problem_init_dofs(&problem, &ctx, view, &st->settle, st->harmonics,
                                        st->setup->forcing_amplitude_n, err);
    else if (!rc)
        rths_rig_problem_init(&problem, &ctx, view, &st->settle, st->harmonics,
                              st->setup->forcing_amplitude_n);
    char text[512];
    if (!rc) {
        frf_hb_numerical_describe(hb, 0, text, sizeof text);
        rths_report_log(st->rep, "numerical substructure on the host: %s", text);
    }
    if (!rc)
        rc = rths_continuation_run_problem(&problem, view, &st->cont, &st->newton,
                                           problem.harmonics, st->resume_pts, st->n_resume,
                                           on_point, on_progress, st, &st->result, err);
    frf_branch_scatter_floor(st);
    if (hb) {
        frf_hb_numerical_describe(hb, 1, text, sizeof text);
        rths_report_log(st->rep, "numerical substructure on the host: %s", text);
    }
    frf_hb_numerical_destroy(hb, view);
    return rc;
}

/* split.numerical_solver: frequency: the same continuation on the zero problem whose numerical
 * side the host solves per harmonic (docs/method.md, "Numerical substructure integration"). */
static int run_frequency_form(frf_state *st, rths_error *err) {
    if (rths_setup_nonlinear_count(st->setup, 1) > 0) return run_frequency_form_nonlinear(st, err);
    rths_numerical_receptance *rec = NULL;
    rths_sparse_model_receptance *sparse_rec = NULL;
    /* a sparse model: one sparse complex LDL^T per harmonic on one symbolic analysis (model.h) */
    int rc = st->setup->sparse
                 ? rths_sparse_model_receptance_create(st->setup->sparse, &sparse_rec, err)
                 : rths_numerical_receptance_create(&st->setup->split, st->setup->forcing_dof, &rec,
                                                    err);
    if (rc) return rc;
    rths_zero_problem problem;
    rths_frequency_problem ctx;
    rc = rths_frequency_problem_init(
        &problem, &ctx, st->rig, &st->settle, st->harmonics, st->setup->forcing_amplitude_n,
        sparse_rec ? rths_sparse_model_receptance_eval : rths_numerical_receptance_eval,
        sparse_rec ? (void *)sparse_rec : (void *)rec, err);
    if (!rc)
        rc = rths_continuation_run_problem(&problem, st->rig, &st->cont, &st->newton, st->harmonics,
                                           st->resume_pts, st->n_resume, on_point, on_progress, st,
                                           &st->result, err);
    rths_frequency_problem_release(&ctx);
    if (sparse_rec) {
        int analyses = 0;
        double s = rths_sparse_model_receptance_s(sparse_rec, &analyses);
        rths_report_log(st->rep,
                        "numerical substructure: sparse, %d DoFs, %.3g s in factorisations and "
                        "solves on %d symbolic analysis(es)",
                        st->setup->split.nn, s, analyses);
    }
    rths_sparse_model_receptance_destroy(sparse_rec);
    rths_numerical_receptance_destroy(rec);
    return rc;
}

/* Several interface DoFs: the continuation on the zero problem over all of them (iterate.h,
 * rths_rig_problem_init_dofs), whose solutions carry every DoF's targets. With the numerical
 * substructure on the host (split.numerical_solver: frequency, e.g. a multi-site test whose
 * numerical side couples the sites) the problem reads the rig through the view that turns the
 * measured interface forces into the numerical interface displacements (frf_sites.h). */
static int run_interface_dofs(frf_state *st, rths_error *err) {
    rths_zero_problem problem;
    rths_rig_problem ctx;
    frf_host_numerical *host = NULL;
    rths_rig *rig = st->rig;
    int rc = RTHS_OK;
    if (st->setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY &&
        rths_setup_nonlinear_count(st->setup, 1) > 0)
        return run_frequency_form_nonlinear(st, err);
    if (st->setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY)
        rc = frf_host_numerical_create(st->setup, st->rig, &host, &rig, err);
    if (!rc)
        rc = rths_rig_problem_init_dofs(&problem, &ctx, rig, &st->settle, st->harmonics,
                                        st->setup->forcing_amplitude_n, err);
    if (!rc)
        rc = rths_continuation_run_problem(&problem, rig, &st->cont, &st->newton, problem.harmonics,
                                           st->resume_pts, st->n_resume, on_point, on_progress, st,
                                           &st->result, err);
    if (host) frf_host_numerical_destroy(host, rig);
    return rc;
}

/* The continuation itself; returns its status (RTHS_OK also when cancelled). */
static int run_continuation(frf_state *st, rths_error *run_err) {
    if (st->limit_warning[0]) rths_report_log(st->rep, "warning: %s", st->limit_warning);
    rths_report_log(st->rep, "start: strategy %s, %d harmonic(s), %s continuation %g -> %g Hz%s",
                    st->strategy, st->harmonics,
                    st->cont.method == RTHS_CONT_ARCLENGTH ? "pseudo-arclength" : "natural",
                    st->cont.start_hz, st->cont.end_hz, st->opt->resume ? ", resumed" : "");
    if (st->cb && st->cb->should_cancel && st->cb->should_cancel(st->cb->user)) st->cancelled = 1;
    int run_rc = RTHS_OK;
    if (!st->cancelled && st->setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY &&
        st->setup->split.n_int == 1)
        run_rc = run_frequency_form(st, run_err);
    else if (!st->cancelled && st->setup->split.n_int > 1)
        run_rc = run_interface_dofs(st, run_err);
    else if (!st->cancelled)
        run_rc = rths_continuation_run(st->rig, &st->cont, &st->settle, &st->newton, st->harmonics,
                                       st->setup->forcing_amplitude_n, st->resume_pts, st->n_resume,
                                       on_point, on_progress, st, &st->result, run_err);
    /* the point handler stopped the run: say what failed (the journal write, with its errno
     * text, or the caller's callback), not only that the handler stopped it */
    if (run_rc && st->point_err.msg[0]) {
        *run_err = st->point_err;
        snprintf(st->result.stop_reason, sizeof st->result.stop_reason, "%s", st->point_err.msg);
    }
    rths_live_close(st->live); /* "state": "ended"; the rig now only forwards */
    st->live = NULL;
    if (st->cancelled) {
        run_rc = RTHS_OK;
        snprintf(st->result.stop_reason, sizeof st->result.stop_reason,
                 "stopped by the user after %d points", st->n);
    }
    int same = !strcmp(run_err->msg, st->result.stop_reason); /* said once */
    rths_report_log(st->rep, "continuation ended: %s%s%s", st->result.stop_reason,
                    run_rc && !same ? "; " : "", run_rc && !same ? run_err->msg : "");
    return run_rc;
}

/* The rig's safe state as soon as measuring is over (issue 24.3: it stayed armed while the
 * figures were drawn, long enough for the controller's watchdog to latch): excitation and target
 * ramped to zero before anything is written. A failed disarm is logged; the controller also
 * disarms itself when the host disconnects. */
static void disarm_rig(frf_state *st) {
    rths_error err = {0};
    if (!st->inner_rig) return;
    if (rths_rig_disarm(st->inner_rig, &err))
        rths_report_log(st->rep, "warning: disarming the rig failed: %s", err.msg);
    else if (st->opt->rig_uri || rths_sites_rig_count(st->inner_rig))
        rths_report_log(st->rep, "rig disarmed (excitation ramped to zero) before the outputs");
    st->disarmed = 1;
}

/* The Lissajous trace (not after a rig fault or a cancellation) is recorded while the rig still
 * runs; then the rig is disarmed; then frf.csv, trace.csv, summary.json, the figures. */
static int write_outputs(frf_state *st, int run_rc, rths_error *err) {
    int pick = run_rc || st->cancelled ? -1 : frf_choose_trace_point(st, st->trace_hz);
    frf_trace trace = {0};
    if (pick >= 0) {
        rths_error trace_err;
        if (frf_trace_record(st->rig, &st->settle, st->harmonics, st->setup->forcing_amplitude_n,
                             &st->pts[pick], &trace, &trace_err)) {
            rths_report_log(st->rep, "no trace figure: %s", trace_err.msg);
            pick = -1;
        }
        st->trace_rig_time_s = trace.rig_time_s;
    }
    disarm_rig(st);
    log_sites(st);
    frf_log_integrity(st);
    int rc = frf_write_frf_csv(st->rep, st, err);
    if (!rc && st->setup->base_excitation) rc = frf_write_absolute_csv(st->rep, st, err);
    if (!rc && pick >= 0) {
        rths_error trace_err;
        if (frf_trace_write(st->rep, st->setup, &trace, &trace_err))
            rths_report_log(st->rep, "no trace figure: %s", trace_err.msg);
    }
    frf_trace_free(&trace);
    if (!rc) rc = frf_write_summary(st, err);
    if (!rc) rc = add_sites_summary(st, err);
    if (!rc && st->n > 0) {
        char title[256];
        snprintf(title, sizeof title, "Hybrid test, %s strategy, p = %g, %d harmonic(s)%s",
                 st->strategy, st->setup->split.mass_ratio, st->harmonics,
                 st->setup->has_bilinear ? ", bilinear leg" : "");
        rc = frf_plot_frf(st->rep, st, &st->truth, title, err);
    }
    /* results.mat last, from the outputs above: a failed write (disk full, file size limit) fails
     * the run with its reason instead of a warning at close */
    if (!rc) rc = rths_report_write_mat(st->rep, err);
    return rc;
}

static void fill_result(const frf_state *st, int run_rc, rths_run_frf_result *r) {
    r->points = st->n;
    r->resumed_points = st->n_resume;
    r->folds = st->result.n_folds;
    r->wall_time_s = st->wall_time_s;
    r->max_relative_error_vs_truth = st->max_truth_error;
    for (int i = 0; i < st->n; i++) {
        r->converged_points += st->pts[i].sol.converged;
        r->evaluations += st->pts[i].evaluations;
        r->rig_time_s += st->pts[i].rig_time_s;
    }
    snprintf(r->stop_reason, sizeof r->stop_reason, "%s", st->result.stop_reason);
    r->outputs_written = 1;
    r->status = st->stopped_short        ? RTHS_RUN_STOPPED
                : run_rc                 ? RTHS_RUN_FAILED
                : st->cancelled          ? RTHS_RUN_CANCELLED
                : st->result.reached_end ? RTHS_RUN_COMPLETED
                                         : RTHS_RUN_STOPPED;
}

static void release(frf_state *st) {
    if (st->journal) rths_journal_close(st->journal);
    rths_live_close(st->live);
    rths_truth_free(&st->truth);
    free(st->pts);
    free(st->floquet_pts);
    free(st->resume_pts);
    free(st->journal_path);
    if (st->rig) rths_rig_destroy(st->rig);
    frf_evaluations_close(st);
    rths_report_close(st->rep);
    release_folder(st);
}

int rths_run_frf(const rths_run_frf_options *opt, const rths_run_callbacks *cb,
                 rths_run_frf_result *result, rths_error *err) {
    /* a caller's rig is the run's from here on, destroyed when it ends however it ends */
    frf_state st = {.opt = opt, .cb = cb, .setup = opt->setup, .lock_fd = -1, .rig = opt->rig};
    if (opt->has_seed)
        snprintf(st.seed_buf, sizeof st.seed_buf, "%llu", (unsigned long long)opt->seed);
    st.seed_text = opt->has_seed ? st.seed_buf : NULL;
    memset(result, 0, sizeof *result);
    result->status = RTHS_RUN_FAILED;
    int rc = read_options(&st, err);
    if (!rc) rc = create_rig(&st, err);
    if (!rc) rc = frf_plan_within_limits(&st, err);
    if (!rc && st.floquet.enabled) /* to judge the experimental multipliers in summary.json */
        rc = frf_floquet_truth_compute(st.setup, &st.floquet_truth, err);
    if (!rc) rc = lock_folder(&st, 0, err);
    if (!rc) rc = check_journal(&st, err);
    if (!rc) rc = lock_folder(&st, 1, err);
    if (!rc && opt->resume) rc = frf_check_resume_config(&st, err);
    if (!rc && opt->resume) rc = load_resume(&st, err);
    if (!rc) rc = open_outputs(&st, err);
    int run_rc = RTHS_OK;
    rths_error run_err = {0};
    double t_start = rths_monotonic_s();
    /* every point's evaluations tallied (cleared as each is accepted): how they reached steady
     * state, and the point's iteration.max_rig_s_per_point (the trace after the run is none) */
    rths_settle_tally tally = {0};
    st.settle.tally = &tally;
    if (!rc) run_rc = run_continuation(&st, &run_err);
    st.settle.tally = NULL;
    st.wall_time_s = rths_monotonic_s() - t_start;
    /* Whatever ended the run, everything accepted is written out. A run that accepted no point
     * (and was not cancelled) measured nothing: a failure, whatever stopped it. */
    if (!rc && !run_rc && st.n == 0 && !st.cancelled)
        run_rc = rths_error_set(&run_err, RTHS_EFAIL, "no point was accepted: %s",
                                st.result.stop_reason);
    /* A sweep that ended short of its end for a reason of its own (failed corrections, the
     * branch leaving the range; not the user, not max_points) did not measure what was asked:
     * a failure naming the cause (issue 24.15), everything accepted still written. */
    else if (!rc && !run_rc && !st.cancelled && st.result.stopped_short) {
        st.stopped_short = 1;
        run_rc = rths_error_set(
            &run_err, RTHS_EFAIL, "the sweep stopped at %.6g Hz, short of its end %.6g Hz: %s",
            st.pts[st.n - 1].sol.frequency_hz, st.cont.end_hz, st.result.stop_reason);
    }
    if (!rc && run_rc) frf_integrity_to_error(&st, &run_err);
    if (!rc) rc = write_outputs(&st, run_rc, err);
    if (!rc) fill_result(&st, run_rc, result);
    if (!rc && run_rc) {
        *err = run_err;
        rc = run_rc;
    }
    /* the status the command exits with: a cancellation is the user's Ctrl-C (130, as the shell
     * reports an interrupt; src/cli/cmd_frf.c) */
    if (st.rep && !rc && st.cancelled)
        rths_report_log(st.rep, "finished: stopped by the user (exit 130)");
    else if (st.rep)
        rths_report_log(st.rep, "finished with status %d%s%s", rc, rc ? ": " : "",
                        rc ? err->msg : "");
    release(&st);
    return rc;
}
