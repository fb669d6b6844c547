/* The multi-site rig (rig_remote.h, rths_sites_rig_join; docs/method.md, "Multi-site tests") over
 * scripted site rigs whose every call is recorded: targets reach each site in its own DoF order,
 * periods are joined DoF by DoF from their sites with the samples and integrity counts summed, the
 * joined time is the longest any site ran, a site's fault disarms every other site, and a DoF
 * driven by two sites or by none is refused. */
#include "testlib.h"

#include "rths/rig_remote.h"

#include <math.h>
#include <string.h>

typedef struct scripted {
    int dofs;
    double site_value; /* every coefficient the site reports is site_value + DoF + k / 10 */
    double time_s;
    int samples, late;
    rths_rig_fault fault_after_periods; /* latched once run_periods is called */
    rths_rig_fault fault;
    int disarmed;
    int harmonics;
    double a[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_HARMONICS];
    double frequency_hz;
    /* a glide of glide_periods periods after each forcing change (period g of it at from +
     * (f - from) (g + 1) / (glide_periods + 1)); the site's first period after a change is the
     * glide's period first_kept (1: its target came late, the glide's first was dropped) */
    int glide_periods, first_kept, next_glide;
    double from_hz;
    int runs; /* run_periods calls */
} scripted;

static int sc_forcing(void *self, double f, double amp, rths_error *err) {
    (void)amp, (void)err;
    scripted *s = self;
    s->from_hz = s->frequency_hz;
    s->next_glide = s->first_kept;
    s->frequency_hz = f;
    return RTHS_OK;
}
static int sc_target_dofs(void *self, int dofs, int harmonics, const double *a, const double *b,
                          rths_error *err) {
    scripted *s = self;
    (void)b;
    if (dofs != s->dofs) return rths_error_set(err, RTHS_EINPUT, "wrong DoF count");
    s->harmonics = harmonics;
    memcpy(s->a, a, sizeof(double) * (size_t)(dofs * harmonics));
    return RTHS_OK;
}
static int sc_target(void *self, int harmonics, const double *a, const double *b, rths_error *err) {
    return sc_target_dofs(self, 1, harmonics, a, b, err);
}
static int sc_run(void *self, int count, rths_period *out, rths_error *err) {
    scripted *s = self;
    if (s->fault_after_periods) {
        s->fault = s->fault_after_periods;
        return rths_error_set(err, RTHS_EFAIL, "scripted fault");
    }
    s->runs++;
    for (int i = 0; i < count; i++) {
        rths_period *p = &out[i];
        memset(p, 0, sizeof *p);
        s->time_s += 1.0 / s->frequency_hz;
        p->frequency_hz = s->frequency_hz;
        if (s->next_glide < s->glide_periods)
            p->frequency_hz = s->from_hz + (s->frequency_hz - s->from_hz) * (s->next_glide + 1) /
                                               (s->glide_periods + 1);
        s->next_glide++;
        p->end_time_s = s->time_s;
        p->samples = s->samples;
        p->late_samples = s->late;
        p->interface_dofs = s->dofs;
        for (int d = 0; d < s->dofs; d++)
            for (int k = 0; k <= RTHS_MAX_HARMONICS; k++) {
                p->phys_dof[d].a[k] = s->site_value + d + k / 10.0;
                p->num_dof[d].a[k] = -(s->site_value + d + k / 10.0);
            }
        p->phys = p->phys_dof[0];
        p->num = p->num_dof[0];
    }
    return RTHS_OK;
}
static double sc_time(void *self) {
    return ((scripted *)self)->time_s;
}
static rths_rig_fault sc_fault(void *self) {
    return ((scripted *)self)->fault;
}
static int sc_disarm(void *self, rths_error *err) {
    (void)err;
    ((scripted *)self)->disarmed++;
    return RTHS_OK;
}
static int sc_dofs(void *self) {
    return ((scripted *)self)->dofs;
}
static const rths_rig_ops scripted_ops = {.set_forcing = sc_forcing,
                                          .set_target = sc_target,
                                          .run_periods = sc_run,
                                          .time_s = sc_time,
                                          .fault = sc_fault,
                                          .disarm = sc_disarm,
                                          .set_target_dofs = sc_target_dofs,
                                          .interface_dofs = sc_dofs};

/* Site 1 drives the host's interface DoF 1 (0-based), site 2 DoFs 0 and 2. */
static rths_rig *join(scripted *one, scripted *two, rths_error *err, int *rc) {
    rths_rig *rigs[2] = {rths_rig_create(&scripted_ops, one, "one"),
                         rths_rig_create(&scripted_ops, two, "two")};
    static const int map_one[] = {1}, map_two[] = {0, 2};
    const int *maps[2] = {map_one, map_two};
    const char *names[2] = {"tcp://a:1", "tcp://b:2"};
    rths_rig *joined = NULL;
    *rc = rths_sites_rig_join(2, rigs, names, maps, 3, &joined, err);
    return joined;
}

static void targets_and_periods_follow_the_map(void **state) {
    (void)state;
    scripted one = {.dofs = 1, .site_value = 10, .samples = 500, .late = 1};
    scripted two = {.dofs = 2, .site_value = 20, .time_s = 5.0, .samples = 250, .late = 2};
    rths_error err;
    int rc;
    rths_rig *rig = join(&one, &two, &err, &rc);
    assert_int_equal(rc, RTHS_OK);
    assert_int_equal(rths_rig_interface_dofs(rig), 3);
    assert_int_equal(rths_sites_rig_count(rig), 2);
    assert_int_equal(rths_rig_set_forcing(rig, 18.0, 1.0, &err), RTHS_OK);
    /* two harmonics per DoF, host DoF d's at a[d * 2 + k] = 100 d + k */
    double a[6] = {0, 1, 100, 101, 200, 201}, b[6] = {0};
    assert_int_equal(rths_rig_set_target_dofs(rig, 3, 2, a, b, &err), RTHS_OK);
    assert_int_equal(one.harmonics, 2);
    assert_true(one.a[0] == 100 && one.a[1] == 101); /* host DoF 1 */
    assert_true(two.a[0] == 0 && two.a[1] == 1 && two.a[2] == 200 && two.a[3] == 201);
    rths_period p[3];
    assert_int_equal(rths_rig_run_periods(rig, 3, p, &err), RTHS_OK);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(p[i].interface_dofs, 3);
        assert_int_equal(p[i].samples, 750);
        assert_int_equal(p[i].late_samples, 3);
        for (int k = 0; k <= RTHS_MAX_HARMONICS; k++) {
            assert_close(p[i].phys_dof[1].a[k], 10 + k / 10.0, 1e-15); /* site 1's DoF 0 */
            assert_close(p[i].phys_dof[0].a[k], 20 + k / 10.0, 1e-15); /* site 2's DoF 0 */
            assert_close(p[i].phys_dof[2].a[k], 21 + k / 10.0, 1e-15); /* site 2's DoF 1 */
            assert_close(p[i].num_dof[2].a[k], -(21 + k / 10.0), 1e-15);
        }
        assert_close(p[i].phys.a[1], p[i].phys_dof[0].a[1], 0);
    }
    /* each site ran 3 periods of 1/18 s since the join; the joined time is the longest */
    rths_site_info info;
    assert_int_equal(rths_sites_rig_site(rig, 1, &info), RTHS_OK);
    assert_close(info.rig_time_s, 3.0 / 18.0, 1e-12);
    assert_int_equal(info.interface_dofs, 2);
    assert_int_equal(info.map[1], 2);
    assert_close(rths_rig_time_s(rig), 3.0 / 18.0, 1e-12);
    rths_rig_destroy(rig);
}

static void a_site_fault_disarms_every_site(void **state) {
    (void)state;
    scripted one = {.dofs = 1, .samples = 10};
    scripted two = {.dofs = 2, .samples = 10, .fault_after_periods = RTHS_RIG_FAULT_LINK};
    rths_error err;
    int rc;
    rths_rig *rig = join(&one, &two, &err, &rc);
    assert_int_equal(rc, RTHS_OK);
    assert_int_equal(rths_rig_set_forcing(rig, 10.0, 1.0, &err), RTHS_OK);
    rths_period p[2];
    assert_int_equal(rths_rig_run_periods(rig, 2, p, &err), RTHS_EFAIL);
    assert_non_null(strstr(err.msg, "site 2 (tcp://b:2)"));
    assert_non_null(strstr(err.msg, "every other site was disarmed"));
    assert_int_equal(one.disarmed, 1); /* the healthy site was ramped to zero at once */
    assert_int_equal(rths_rig_get_fault(rig), RTHS_RIG_FAULT_LINK);
    rths_rig_destroy(rig);
}

/* After a forcing change a site whose target came late keeps its periods from the glide's second
 * (docs/protocol.md, "Which periods follow a change"): the other site's glide period before it is
 * dropped and its next one fetched, so every joined period has one forcing, whichever site is
 * behind and however many periods the host asks for at once. A site whose forcing is another
 * is still reported out of step. */
static void sites_line_up_after_a_change(void **state) {
    (void)state;
    for (int late = 0; late < 2; late++)
        for (int count = 1; count <= 4; count += 3) {
            scripted one = {.dofs = 1, .samples = 10, .glide_periods = 3};
            scripted two = {.dofs = 2, .samples = 10, .glide_periods = 3};
            (late ? &two : &one)->first_kept = 1;
            rths_error err;
            int rc;
            rths_rig *rig = join(&one, &two, &err, &rc);
            assert_int_equal(rc, RTHS_OK);
            rths_period p[4];
            assert_int_equal(rths_rig_set_forcing(rig, 10.0, 1.0, &err), RTHS_OK);
            assert_int_equal(rths_rig_run_periods(rig, count, p, &err), RTHS_OK);
            one.first_kept = two.first_kept = 0;
            (late ? &one : &two)->first_kept = 1;
            assert_int_equal(rths_rig_set_forcing(rig, 14.0, 1.0, &err), RTHS_OK);
            for (int i = 0; i < 4; i += count) {
                rc = rths_rig_run_periods(rig, count, p + i, &err);
                if (rc) fail_msg("late %d, count %d: %s", late, count, err.msg);
            }
            /* the joined periods are the glide's second and third, then the new forcing */
            assert_close(p[0].frequency_hz, 12.0, 1e-12);
            assert_close(p[1].frequency_hz, 13.0, 1e-12);
            assert_close(p[2].frequency_hz, 14.0, 1e-12);
            assert_close(p[3].frequency_hz, 14.0, 1e-12);
            rths_rig_destroy(rig);
        }
    /* another forcing at one site: no dropping lines it up */
    scripted one = {.dofs = 1, .samples = 10}, two = {.dofs = 2, .samples = 10};
    rths_error err;
    int rc;
    rths_rig *rig = join(&one, &two, &err, &rc);
    assert_int_equal(rths_rig_set_forcing(rig, 10.0, 1.0, &err), RTHS_OK);
    two.frequency_hz = 10.5;
    rths_period p[2];
    assert_int_equal(rths_rig_run_periods(rig, 2, p, &err), RTHS_EFAIL);
    assert_non_null(strstr(err.msg, "out of step"));
    /* with what the host set and every site's periods of the call, for the lab to tell which
     * site missed the change */
    assert_non_null(strstr(err.msg, "forcing set 10 Hz"));
    assert_non_null(strstr(err.msg, "site 1: 10 Hz to "));
    assert_non_null(strstr(err.msg, "site 2: 10.5 Hz to "));
    rths_rig_destroy(rig);
}

/* A site still gliding from an earlier change when the next one comes (a correction that failed
 * at its first periods, retried at once) glides from another frequency: site 1 from 11 Hz, site 2
 * from 10 Hz, both to 14 Hz over three periods (11.75, 12.5, 13.25 against 11, 12, 13). No
 * dropping matches site 1's glide; once site 2 reaches 14 Hz itself, site 1 drops its glide too
 * and every joined period runs 14 Hz (before, site 2 dropped 8 periods past its glide and the
 * call failed out of step, and so did every retry). */
static void sites_line_up_after_glides_from_different_forcings(void **state) {
    (void)state;
    for (int count = 1; count <= 4; count += 3) {
        scripted one = {.dofs = 1, .samples = 10, .glide_periods = 3};
        scripted two = {.dofs = 2, .samples = 10, .glide_periods = 3};
        rths_error err;
        int rc;
        rths_rig *rig = join(&one, &two, &err, &rc);
        assert_int_equal(rc, RTHS_OK);
        rths_period p[8];
        assert_int_equal(rths_rig_set_forcing(rig, 10.0, 1.0, &err), RTHS_OK);
        assert_int_equal(rths_rig_run_periods(rig, 4, p, &err), RTHS_OK);
        one.frequency_hz = 11.0; /* site 1 still on its way from an earlier change */
        assert_int_equal(rths_rig_set_forcing(rig, 14.0, 1.0, &err), RTHS_OK);
        for (int i = 0; i < 4; i += count) {
            rc = rths_rig_run_periods(rig, count, p + i, &err);
            if (rc) fail_msg("count %d: %s", count, err.msg);
        }
        for (int i = 0; i < 4; i++)
            assert_close(p[i].frequency_hz, 14.0, 1e-12);
        /* each site dropped only its own glide: site 2 its three, site 1 its three */
        assert_close(one.time_s - two.time_s, 0.0, 1e-12);
        rths_rig_destroy(rig);
    }
}

static void a_dof_in_two_sites_or_none_is_refused(void **state) {
    (void)state;
    scripted one = {.dofs = 1}, two = {.dofs = 2};
    rths_error err;
    rths_rig *rigs[2] = {rths_rig_create(&scripted_ops, &one, "one"),
                         rths_rig_create(&scripted_ops, &two, "two")};
    static const int map_one[] = {0}, map_two[] = {0, 2};
    const int *maps[2] = {map_one, map_two};
    const char *names[2] = {"a", "b"};
    rths_rig *joined = NULL;
    assert_int_equal(rths_sites_rig_join(2, rigs, names, maps, 3, &joined, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "interface DoF 1 is driven by site 1 and by site 2"));
    assert_null(joined);
    rths_rig *again[2] = {rths_rig_create(&scripted_ops, &one, "one"),
                          rths_rig_create(&scripted_ops, &two, "two")};
    static const int map_three[] = {3};
    const int *maps2[2] = {map_three, map_two};
    assert_int_equal(rths_sites_rig_join(2, again, names, maps2, 4, &joined, &err), RTHS_EINPUT);
    assert_non_null(strstr(err.msg, "interface DoF 2 (in the host's interface order) is driven by "
                                    "no site"));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(targets_and_periods_follow_the_map),
        cmocka_unit_test(a_site_fault_disarms_every_site),
        cmocka_unit_test(sites_line_up_after_a_change),
        cmocka_unit_test(sites_line_up_after_glides_from_different_forcings),
        cmocka_unit_test(a_dof_in_two_sites_or_none_is_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
