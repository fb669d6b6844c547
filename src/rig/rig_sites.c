/* The multi-site rig: one rig over several sites' rigs (rig_remote.h, rths_sites_rig_create;
 * docs/method.md, "Multi-site tests"). Each site drives a subset of the interface DoFs with its
 * own controller, actuators, sample rate and clock; this rig maps the host's interface order onto
 * the sites and joins their per-period records period by period: the i-th period every site
 * delivers after the last setting forms the host's i-th record. The host above it is unchanged.
 *
 * Every operation goes to all sites at once (one thread per further site), so a slow link costs
 * its latency once per request, not once per site. A fault or a lost link at any site disarms
 * every other site at once (excitation and target ramped to zero) and is the joined rig's
 * fault. This is host-side code: it may allocate, block and start threads. */
#include "rths/rig_remote.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct site {
    rths_rig *rig;
    char uri[300];
    int dofs;                         /* interface DoFs this site drives */
    int map[RTHS_MAX_INTERFACE_DOFS]; /* host interface index of the site's DoF j */
    double time0_s;                   /* the site's rig time when the joined rig was made */
    int behind;         /* OP_ALIGN: its first period is dropped and its next one fetched */
    double last_time_s; /* its rig time when last read */
    rths_period *buf;   /* its periods of the current run_periods */
    int buf_cap;
    /* the operation's arguments and outcome (one thread per site) */
    int rc;
    rths_error err;
} site;

typedef struct sites_rig {
    int n;
    site s[RTHS_MAX_INTERFACE_DOFS];
    int dofs; /* host interface DoFs, every one driven by exactly one site */
    /* the current operation */
    enum { OP_FORCING, OP_TARGET, OP_PERIODS, OP_ALIGN, OP_TRACE, OP_RESET, OP_DISARM } op;
    double frequency_hz, amplitude_n;
    int harmonics;
    const double *a, *b; /* host-order targets */
    int count;
    double trace_s;
    int trace_max;
    rths_trace_sample *trace[RTHS_MAX_INTERFACE_DOFS];
    int trace_n[RTHS_MAX_INTERFACE_DOFS];
    rths_rig_fault fault;
    int fault_site;
    int changed; /* a forcing was set since the last run_periods: the sites' periods to line up */
} sites_rig;

typedef struct job {
    sites_rig *r;
    int i;
} job;

/* One site's part of the current operation. */
static void run_site(sites_rig *r, int i) {
    site *s = &r->s[i];
    s->rc = RTHS_OK;
    s->err.msg[0] = '\0';
    switch (r->op) {
    case OP_FORCING:
        s->rc = rths_rig_set_forcing(s->rig, r->frequency_hz, r->amplitude_n, &s->err);
        break;
    case OP_TARGET: {
        double a[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_HARMONICS] = {0};
        double b[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_HARMONICS] = {0};
        for (int j = 0; j < s->dofs; j++)
            for (int k = 0; k < r->harmonics; k++) {
                a[j * r->harmonics + k] = r->a[s->map[j] * r->harmonics + k];
                b[j * r->harmonics + k] = r->b[s->map[j] * r->harmonics + k];
            }
        s->rc = rths_rig_set_target_dofs(s->rig, s->dofs, r->harmonics, a, b, &s->err);
        break;
    }
    case OP_PERIODS:
        s->rc = rths_rig_run_periods(s->rig, r->count, s->buf, &s->err);
        if (!s->rc && r->count > 0) s->last_time_s = s->buf[r->count - 1].end_time_s;
        break;
    case OP_ALIGN:
        if (!s->behind) break;
        memmove(s->buf, s->buf + 1, sizeof *s->buf * (size_t)(r->count - 1));
        s->rc = rths_rig_run_periods(s->rig, 1, &s->buf[r->count - 1], &s->err);
        if (!s->rc) s->last_time_s = s->buf[r->count - 1].end_time_s;
        break;
    case OP_TRACE:
        s->rc = rths_rig_record_trace(s->rig, r->trace_s, r->trace_max, r->trace[i], &r->trace_n[i],
                                      &s->err);
        break;
    case OP_RESET:
        s->rc = rths_rig_reset_fault(s->rig, &s->err);
        break;
    case OP_DISARM:
        s->rc = rths_rig_disarm(s->rig, &s->err);
        break;
    }
}

static void *site_thread(void *arg) {
    job *j = arg;
    run_site(j->r, j->i);
    return NULL;
}

/* Runs the current operation on every site at once; the first site's failure (in site order) is
 * the result. A site that failed with a fault latched (limits, watchdog, a lost link) has every
 * other site disarmed at once. */
static int all_sites(sites_rig *r, rths_error *err) {
    pthread_t th[RTHS_MAX_INTERFACE_DOFS];
    job jobs[RTHS_MAX_INTERFACE_DOFS];
    int started[RTHS_MAX_INTERFACE_DOFS] = {0};
    for (int i = 1; i < r->n; i++) {
        jobs[i] = (job){r, i};
        started[i] = pthread_create(&th[i], NULL, site_thread, &jobs[i]) == 0;
        if (!started[i]) run_site(r, i); /* no thread: in turn */
    }
    run_site(r, 0);
    for (int i = 1; i < r->n; i++)
        if (started[i]) pthread_join(th[i], NULL);
    int rc = RTHS_OK;
    for (int i = 0; i < r->n && !rc; i++)
        if (r->s[i].rc) {
            rc = r->s[i].rc;
            rths_error_set(err, rc, "site %d (%s): %s", i + 1, r->s[i].uri, r->s[i].err.msg);
        }
    if (r->op == OP_DISARM || r->op == OP_RESET) return rc;
    /* only a site that failed is asked (asking a remote site costs a round trip) */
    for (int i = 0; i < r->n; i++) {
        if (!r->s[i].rc) continue;
        rths_rig_fault f = rths_rig_get_fault(r->s[i].rig);
        if (f == RTHS_RIG_OK || r->fault != RTHS_RIG_OK) continue;
        r->fault = f;
        r->fault_site = i;
        /* every site to its safe state now, not when the host gets to it */
        for (int k = 0; k < r->n; k++) {
            rths_error ignored;
            if (k != i) rths_rig_disarm(r->s[k].rig, &ignored);
        }
        if (!rc)
            rc = rths_error_set(err, RTHS_EFAIL, "site %d (%s) latched a %s fault", i + 1,
                                r->s[i].uri, rths_rig_fault_name(f));
        size_t len = strlen(err->msg);
        snprintf(err->msg + len, sizeof err->msg - len,
                 "; every other site was disarmed (excitation and target ramped to zero)");
    }
    return rc;
}

static int s_set_forcing(void *self, double frequency_hz, double amplitude_n, rths_error *err) {
    sites_rig *r = self;
    r->op = OP_FORCING;
    r->frequency_hz = frequency_hz;
    r->amplitude_n = amplitude_n;
    r->changed = 1;
    return all_sites(r, err);
}

static int s_set_target_dofs(void *self, int dofs, int harmonics, const double *a, const double *b,
                             rths_error *err) {
    sites_rig *r = self;
    if (dofs != r->dofs)
        return rths_error_set(err, RTHS_EINPUT,
                              "target for %d interface DoF(s); the sites drive %d", dofs, r->dofs);
    r->op = OP_TARGET;
    r->harmonics = harmonics;
    r->a = a;
    r->b = b;
    return all_sites(r, err);
}

static int s_set_target(void *self, int harmonics, const double *a, const double *b,
                        rths_error *err) {
    return s_set_target_dofs(self, 1, harmonics, a, b, err);
}

static void copy_fourier_dof(const rths_period *from, int j, rths_period *to, int d) {
    to->phys_dof[d] = from->interface_dofs > 1 || j > 0 ? from->phys_dof[j] : from->phys;
    to->num_dof[d] = from->interface_dofs > 1 || j > 0 ? from->num_dof[j] : from->num;
    to->force_dof[d] = from->interface_dofs > 1 || j > 0 ? from->force_dof[j] : from->force;
}

/* The i-th period of every site, joined: every interface DoF from its site, the frequency and
 * end time of the first site (each site's end time is on its own clock), the samples and the
 * integrity counts summed over the sites (the share of late samples stays a share). */
static void join_period(const sites_rig *r, int i, rths_period *out) {
    memset(out, 0, sizeof *out);
    const rths_period *first = &r->s[0].buf[i];
    out->frequency_hz = first->frequency_hz;
    out->end_time_s = first->end_time_s;
    out->interface_dofs = r->dofs;
    for (int k = 0; k < r->n; k++) {
        const site *s = &r->s[k];
        const rths_period *p = &s->buf[i];
        out->samples += p->samples;
        out->late_samples += p->late_samples;
        out->clipped_demand_samples += p->clipped_demand_samples;
        out->saturated_sensor_samples += p->saturated_sensor_samples;
        for (int j = 0; j < s->dofs; j++)
            copy_fourier_dof(p, j, out, s->map[j]);
    }
    out->phys = out->phys_dof[0];
    out->num = out->num_dof[0];
    out->force = out->force_dof[0];
}

static int same_frequency(double f, double g) {
    return fabs(f - g) <= 1e-9 * fabs(g);
}

/* After a forcing change every site keeps its periods from its glide's first (docs/protocol.md,
 * "Which periods follow a change"), but a site whose target reached it only after that period
 * had closed (the host or the link stalled a whole period between the two commands) keeps them
 * from the glide's second. The glide runs period by period alike at every site, so the sites
 * are lined up again: the site furthest into the glide (its first period nearest the new
 * frequency) sets the first period, and every other site drops its leading periods until its
 * first has that frequency (at most MAX_ALIGN_DROP, each replaced by the site's next). A site
 * that was still gliding from an earlier change when this one came (a correction that failed at
 * its first periods is retried at once) glides from another frequency, and no dropping matches
 * the lead's glide: once a site that did not match reaches the new forcing itself, every site
 * drops its glide periods and they line up on the new forcing's first. Sites that still disagree
 * are reported out of step by the caller. */
#define MAX_ALIGN_DROP 8
static int align_after_change(sites_rig *r, rths_error *err) {
    int lead = 0;
    for (int k = 1; k < r->n; k++)
        if (fabs(r->s[k].buf[0].frequency_hz - r->frequency_hz) <
            fabs(r->s[lead].buf[0].frequency_hz - r->frequency_hz))
            lead = k;
    double first = r->s[lead].buf[0].frequency_hz;
    r->op = OP_ALIGN;
    for (int round = 0; round < MAX_ALIGN_DROP; round++) {
        /* a site at the new forcing itself: its glide has ended, so every site lines up on it
         * (where the glides match, the lead's first is that frequency by then anyway) */
        for (int k = 0; k < r->n; k++)
            if (same_frequency(r->s[k].buf[0].frequency_hz, r->frequency_hz))
                first = r->frequency_hz;
        int any = 0;
        for (int k = 0; k < r->n; k++) {
            r->s[k].behind = !same_frequency(r->s[k].buf[0].frequency_hz, first);
            any |= r->s[k].behind;
        }
        if (!any) return RTHS_OK;
        int rc = all_sites(r, err);
        if (rc) return rc;
    }
    return RTHS_OK;
}

/* The sites' periods disagree at index i: the error names the site and, so that a lab (or a
 * test log) can tell a site that fell behind from one that missed a change, every site's
 * periods of this call (frequency and end time on its own clock, the first few) and the
 * forcing the host set. */
static int out_of_step(const sites_rig *r, int k, int i, int count, rths_error *err) {
    char seq[640];
    size_t at = 0;
    for (int j = 0; j < r->n && at < sizeof seq; j++) {
        at += (size_t)snprintf(seq + at, sizeof seq - at, "%ssite %d:", j ? "; " : "", j + 1);
        for (int q = 0; q < count && q < 4 && at < sizeof seq; q++)
            at += (size_t)snprintf(seq + at, sizeof seq - at, " %.9g Hz to %.6f s",
                                   r->s[j].buf[q].frequency_hz, r->s[j].buf[q].end_time_s);
    }
    return rths_error_set(err, RTHS_EFAIL,
                          "site %d (%s) ran a period at %.9g Hz while site 1 ran it at %.9g Hz: "
                          "the sites' forcing is out of step (forcing set %.9g Hz; %s)",
                          k + 1, r->s[k].uri, r->s[k].buf[i].frequency_hz,
                          r->s[0].buf[i].frequency_hz, r->frequency_hz, seq);
}

static int s_run_periods(void *self, int count, rths_period *out, rths_error *err) {
    sites_rig *r = self;
    for (int k = 0; k < r->n; k++) {
        site *s = &r->s[k];
        if (s->buf_cap < count) {
            rths_period *b = realloc(s->buf, sizeof *b * (size_t)count);
            if (!b) return rths_error_set(err, RTHS_EFAIL, "out of memory");
            s->buf = b;
            s->buf_cap = count;
        }
    }
    r->op = OP_PERIODS;
    r->count = count;
    int rc = all_sites(r, err);
    if (!rc && count > 0 && r->changed) {
        r->changed = 0;
        rc = align_after_change(r, err);
    }
    for (int i = 0; i < count && !rc; i++) {
        join_period(r, i, &out[i]);
        for (int k = 1; k < r->n && !rc; k++)
            if (fabs(r->s[k].buf[i].frequency_hz - out[i].frequency_hz) >
                1e-9 * out[i].frequency_hz)
                rc = out_of_step(r, k, i, count, err);
    }
    return rc;
}

/* Every site records its own trace at once; the joined trace holds each site's DoFs by sample
 * index (the sites' samples fall at their own clocks' times: the Lissajous figure it draws is
 * each DoF's own, their mutual timing within a sample period or so). */
static int s_record_trace(void *self, double duration_s, int max_samples, rths_trace_sample *out,
                          int *n_out, rths_error *err) {
    sites_rig *r = self;
    *n_out = 0;
    int rc = RTHS_OK;
    for (int k = 0; k < r->n && !rc; k++) {
        r->trace[k] = calloc((size_t)(max_samples > 0 ? max_samples : 1), sizeof *r->trace[k]);
        r->trace_n[k] = 0;
        if (!r->trace[k]) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    if (!rc) {
        r->op = OP_TRACE;
        r->trace_s = duration_s;
        r->trace_max = max_samples;
        rc = all_sites(r, err);
    }
    int n = max_samples;
    for (int k = 0; k < r->n; k++)
        if (r->trace_n[k] < n) n = r->trace_n[k];
    for (int i = 0; i < n && !rc; i++) {
        rths_trace_sample *t = &out[i];
        *t = r->trace[0][i];
        t->dofs = r->dofs;
        for (int k = 0; k < r->n; k++) {
            const rths_trace_sample *u = &r->trace[k][i];
            for (int j = 0; j < r->s[k].dofs; j++) {
                int d = r->s[k].map[j], many = u->dofs > 1;
                t->x_phys_dof_m[d] = many ? u->x_phys_dof_m[j] : u->x_phys_m;
                t->x_num_dof_m[d] = many ? u->x_num_dof_m[j] : u->x_num_m;
                t->target_dof_m[d] = many ? u->target_dof_m[j] : u->target_m;
                t->force_dof_n[d] = many ? u->force_dof_n[j] : u->force_n;
                t->demand_dof_v[d] = many ? u->demand_dof_v[j] : u->demand;
            }
        }
        t->x_phys_m = t->x_phys_dof_m[0];
        t->x_num_m = t->x_num_dof_m[0];
        t->target_m = t->target_dof_m[0];
        t->force_n = t->force_dof_n[0];
        t->demand = t->demand_dof_v[0];
    }
    if (!rc) *n_out = n;
    for (int k = 0; k < r->n; k++) {
        free(r->trace[k]);
        r->trace[k] = NULL;
    }
    return rc;
}

/* The joined rig's time: the longest any site has run since the rig was made, each site's time
 * its own controller's (samples run times its sample period) at the end of the last period it
 * delivered (or when last asked). Not asked anew here: asking a remote site costs a round trip
 * over its link, twice per evaluation; between evaluations a site's clock runs on while the host
 * is busy, which the next evaluation's last period counts. */
static double s_time_s(void *self) {
    sites_rig *r = self;
    double t = 0;
    for (int k = 0; k < r->n; k++)
        if (r->s[k].last_time_s - r->s[k].time0_s > t) t = r->s[k].last_time_s - r->s[k].time0_s;
    return t;
}

/* A site's fault as known without a round trip when it is remote (rths_remote_rig_known_fault:
 * the host asks after every evaluation, and a slow link would pay twice its latency per site). */
static rths_rig_fault site_fault(const site *s) {
    rths_rig_fault f;
    return rths_remote_rig_known_fault(s->rig, &f) ? f : rths_rig_get_fault(s->rig);
}

static rths_rig_fault s_fault(void *self) {
    sites_rig *r = self;
    for (int k = 0; k < r->n && r->fault == RTHS_RIG_OK; k++) {
        rths_rig_fault f = site_fault(&r->s[k]);
        if (f != RTHS_RIG_OK) r->fault = f, r->fault_site = k;
    }
    return r->fault;
}

static int s_reset_fault(void *self, rths_error *err) {
    sites_rig *r = self;
    r->op = OP_RESET;
    int rc = all_sites(r, err);
    if (!rc) r->fault = RTHS_RIG_OK;
    return rc;
}

static int s_disarm(void *self, rths_error *err) {
    sites_rig *r = self;
    r->op = OP_DISARM;
    return all_sites(r, err);
}

static double s_noise_level_m(void *self) {
    sites_rig *r = self;
    double n = 0;
    for (int k = 0; k < r->n; k++) {
        double v = rths_rig_noise_level_m(r->s[k].rig);
        if (v > n) n = v;
    }
    return n;
}

static int s_interface_dofs(void *self) {
    return ((sites_rig *)self)->dofs;
}

static void s_destroy(void *self) {
    sites_rig *r = self;
    for (int k = 0; k < r->n; k++) {
        if (r->s[k].rig) rths_rig_destroy(r->s[k].rig);
        free(r->s[k].buf);
    }
    free(r);
}

static const rths_rig_ops sites_ops = {
    .set_forcing = s_set_forcing,
    .set_target = s_set_target,
    .run_periods = s_run_periods,
    .record_trace = s_record_trace,
    .time_s = s_time_s,
    .fault = s_fault,
    .reset_fault = s_reset_fault,
    .disarm = s_disarm,
    .noise_level_m = s_noise_level_m,
    .destroy = s_destroy,
    .set_target_dofs = s_set_target_dofs,
    .interface_dofs = s_interface_dofs,
};

int rths_sites_rig_join(int n_sites, rths_rig **rigs, const char *const *names,
                        const int *const *maps, int interface_dofs, rths_rig **out,
                        rths_error *err) {
    *out = NULL;
    int rc = RTHS_OK;
    int owner[RTHS_MAX_INTERFACE_DOFS];
    for (int d = 0; d < RTHS_MAX_INTERFACE_DOFS; d++)
        owner[d] = -1;
    if (n_sites < 1 || n_sites > RTHS_MAX_INTERFACE_DOFS || interface_dofs < 1 ||
        interface_dofs > RTHS_MAX_INTERFACE_DOFS)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "%d site(s) over %d interface DoF(s): 1 to %d of each are supported",
                            n_sites, interface_dofs, RTHS_MAX_INTERFACE_DOFS);
    for (int k = 0; k < n_sites && !rc; k++)
        for (int j = 0; j < rths_rig_interface_dofs(rigs[k]) && !rc; j++) {
            int d = maps[k][j];
            if (d < 0 || d >= interface_dofs)
                rc = rths_error_set(err, RTHS_EINPUT,
                                    "site %d (%s): its interface DoF %d maps to %d, outside the "
                                    "host's %d interface DoFs",
                                    k + 1, names[k], j + 1, d + 1, interface_dofs);
            else if (owner[d] >= 0)
                rc = rths_error_set(err, RTHS_EINPUT,
                                    "interface DoF %d is driven by site %d and by site %d (%s): "
                                    "each interface DoF belongs to one site",
                                    d + 1, owner[d] + 1, k + 1, names[k]);
            else
                owner[d] = k;
        }
    for (int d = 0; d < interface_dofs && !rc; d++)
        if (owner[d] < 0)
            rc = rths_error_set(err, RTHS_EINPUT,
                                "interface DoF %d (in the host's interface order) is driven by no "
                                "site",
                                d + 1);
    sites_rig *r = rc ? NULL : calloc(1, sizeof *r);
    if (!rc && !r) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (rc) {
        for (int k = 0; k < n_sites; k++)
            if (rigs[k]) rths_rig_destroy(rigs[k]);
        return rc;
    }
    r->n = n_sites;
    r->dofs = interface_dofs;
    char desc[256];
    int len = snprintf(desc, sizeof desc, "%d sites:", n_sites);
    for (int k = 0; k < n_sites; k++) {
        site *s = &r->s[k];
        s->rig = rigs[k];
        snprintf(s->uri, sizeof s->uri, "%s", names[k]);
        s->dofs = rths_rig_interface_dofs(rigs[k]);
        for (int j = 0; j < s->dofs; j++)
            s->map[j] = maps[k][j];
        s->time0_s = s->last_time_s = rths_rig_time_s(rigs[k]);
        if (len < (int)sizeof desc)
            len += snprintf(desc + len, sizeof desc - (size_t)len, "%s %.100s", k ? "," : "",
                            names[k]);
    }
    *out = rths_rig_create(&sites_ops, r, desc);
    if (!*out) {
        s_destroy(r);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    return RTHS_OK;
}

int rths_sites_rig_create(int n_sites, const char *const *uris, const int *const *maps,
                          int interface_dofs, const rths_remote_options *opt, rths_rig **out,
                          rths_error *err) {
    *out = NULL;
    if (n_sites < 1 || n_sites > RTHS_MAX_INTERFACE_DOFS)
        return rths_error_set(err, RTHS_EINPUT, "%d sites: 1 to %d are supported", n_sites,
                              RTHS_MAX_INTERFACE_DOFS);
    rths_rig *rigs[RTHS_MAX_INTERFACE_DOFS] = {0};
    int rc = RTHS_OK;
    for (int k = 0; k < n_sites && !rc; k++) {
        rths_error local;
        rc = rths_remote_rig_create(uris[k], opt, &rigs[k], &local);
        if (rc) rths_error_set(err, rc, "site %d: %s", k + 1, local.msg);
    }
    if (rc) {
        for (int k = 0; k < n_sites; k++)
            if (rigs[k]) rths_rig_destroy(rigs[k]);
        return rc;
    }
    return rths_sites_rig_join(n_sites, rigs, uris, maps, interface_dofs, out, err);
}

int rths_sites_rig_count(rths_rig *rig) {
    sites_rig *r = rths_rig_backend(rig, &sites_ops);
    return r ? r->n : 0;
}

int rths_sites_rig_site(rths_rig *rig, int k, rths_site_info *out) {
    sites_rig *r = rths_rig_backend(rig, &sites_ops);
    memset(out, 0, sizeof *out);
    if (!r || k < 0 || k >= r->n) return RTHS_EINPUT;
    const site *s = &r->s[k];
    snprintf(out->uri, sizeof out->uri, "%s", s->uri);
    snprintf(out->description, sizeof out->description, "%s", rths_rig_description(s->rig));
    out->interface_dofs = s->dofs;
    for (int j = 0; j < s->dofs; j++)
        out->map[j] = s->map[j];
    out->rig_time_s = s->last_time_s - s->time0_s;
    out->fault = site_fault(s);
    rths_rig_integrity_totals(s->rig, &out->integrity);
    return RTHS_OK;
}
