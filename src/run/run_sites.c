/* Multi-site tests (run.h, rths_run_sites_read; docs/method.md, "Multi-site tests"): which site
 * drives which interface DoFs (rig.sites), which physical DoFs each site's substructure holds,
 * whether the numerical side couples sites, and the split a site's own controller runs
 * (`rths controller CONFIG --site N`), as configuration overrides over the shared file. */
#include "rths/run.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* 1 when assembly DoFs i and j share an element: a non-zero coupling in M, C or K. */
static int coupled(const rths_assembly *a, int i, int j) {
    size_t at = (size_t)i + (size_t)j * (size_t)a->n;
    return a->mass[at] != 0 || a->damping[at] != 0 || a->stiffness[at] != 0;
}

/* Index of assembly DoF dof in the split's interface order, or -1. */
static int interface_index(const rths_split *s, int dof) {
    for (int d = 0; d < s->n_int; d++)
        if (s->int_dofs[d] == dof) return d;
    return -1;
}

/* Every physical DoF to the site whose interface it is joined to through physical elements;
 * refuses an element between two sites and a physical part joined to no site. */
static int assign_physical(rths_config *cfg, const rths_setup *setup, rths_run_sites *out,
                           const int *site_of_interface, rths_error *err) {
    const rths_split *s = &setup->split;
    const rths_assembly *a = &setup->assembly;
    int n = a->n, rc = RTHS_OK;
    int *site_of = malloc(sizeof(int) * (size_t)n), *stack = malloc(sizeof(int) * (size_t)n);
    if (!site_of || !stack) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < n && !rc; i++)
        site_of[i] = setup->roles[i] == RTHS_DOF_NUMERICAL ? -2 : -1;
    for (int d = 0; d < s->n_int && !rc; d++)
        site_of[s->int_dofs[d]] = site_of_interface[d];
    /* flood each site's interface DoFs through the physical side */
    for (int d = 0; d < s->n_int && !rc; d++) {
        int top = 0;
        stack[top++] = s->int_dofs[d];
        while (top && !rc) {
            int i = stack[--top];
            for (int j = 0; j < n && !rc; j++) {
                if (j == i || site_of[j] == -2 || !coupled(a, i, j)) continue;
                if (site_of[j] == -1) {
                    site_of[j] = site_of[i];
                    stack[top++] = j;
                } else if (site_of[j] != site_of[i]) {
                    rc = rths_config_error_at(
                        cfg, "rig.sites", err,
                        "DoFs %d (site %d) and %d (site %d) share an element of the physical side: "
                        "every physical element belongs to one site's substructure (put the DoFs "
                        "between the sites on the numerical side)",
                        i + 1, site_of[i] + 1, j + 1, site_of[j] + 1);
                }
            }
        }
    }
    for (int i = 0; i < n && !rc; i++)
        if (site_of[i] == -1)
            rc =
                rths_config_error_at(cfg, "rig.sites", err,
                                     "physical DoF %d is joined to no site's interface DoF", i + 1);
    for (int i = 0; i < n && !rc; i++)
        if (site_of[i] >= 0 && setup->roles[i] == RTHS_DOF_PHYSICAL) {
            rths_run_site *site = &out->site[site_of[i]];
            if (site->n_phys >= RTHS_RUN_SITE_MAX_PHYSICAL)
                rc = rths_config_error_at(cfg, "rig.sites", err,
                                          "site %d holds more than %d physical DoFs",
                                          site_of[i] + 1, RTHS_RUN_SITE_MAX_PHYSICAL);
            else
                site->phys_dofs[site->n_phys++] = i;
        }
    /* the numerical side couples sites when a group of numerical DoFs joined to each other
     * touches interface DoFs of two sites (or a numerical element joins two sites' interfaces) */
    int *group = rc ? NULL : calloc((size_t)n, sizeof(int));
    if (!rc && !group) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int start = 0, groups = 0; start < n && !rc && !out->numerical_couples_sites; start++) {
        if (setup->roles[start] != RTHS_DOF_NUMERICAL || group[start]) continue;
        int top = 0, touched = -1;
        group[start] = ++groups;
        stack[top++] = start;
        while (top) {
            int i = stack[--top];
            for (int j = 0; j < n; j++) {
                if (j == i || !coupled(a, i, j)) continue;
                if (setup->roles[j] == RTHS_DOF_NUMERICAL && !group[j]) {
                    group[j] = groups;
                    stack[top++] = j;
                } else if (setup->roles[j] == RTHS_DOF_INTERFACE) {
                    int k = site_of[j];
                    if (touched < 0) touched = k;
                    if (k != touched && !out->numerical_couples_sites) {
                        out->numerical_couples_sites = 1;
                        out->coupling_dof = start;
                    }
                }
            }
        }
    }
    free(group);
    free(site_of);
    free(stack);
    return rc;
}

int rths_run_sites_read(rths_config *cfg, const rths_setup *setup, rths_run_sites *out,
                        rths_error *err) {
    memset(out, 0, sizeof *out);
    /* asking for an absent key would count the rig section as read by this program, which a run
     * on one controller (whose rig section is the controller's) must not */
    if (!rths_config_has(cfg, "rig.sites")) return RTHS_OK;
    int count = 0, rc = rths_config_get_count(cfg, "rig.sites", &count, err);
    if (rc || count == 0) return rc;
    const rths_split *s = &setup->split;
    if (count < 2 || count > RTHS_MAX_INTERFACE_DOFS)
        return rths_config_error_at(cfg, "rig.sites", err,
                                    "lists %d site(s); a multi-site test has 2 to %d", count,
                                    RTHS_MAX_INTERFACE_DOFS);
    static const char *const unsupported[] = {"rig.actuators",
                                              "rig.lasers",
                                              "split.interface_damping_physical_n_s_per_m",
                                              "split.interface_stiffness_physical_n_per_m",
                                              "output.dofs",
                                              NULL};
    for (int i = 0; unsupported[i]; i++)
        if (rths_config_has(cfg, unsupported[i]))
            return rths_config_error_at(cfg, unsupported[i], err,
                                        "is not supported with rig.sites (each site's controller "
                                        "reads the shared file over its own interface DoFs)");
    if (setup->base_excitation)
        return rths_config_error_at(cfg, "forcing.type", err,
                                    "base excitation is not supported with rig.sites");
    out->n = count;
    int site_of_interface[RTHS_MAX_INTERFACE_DOFS];
    for (int d = 0; d < RTHS_MAX_INTERFACE_DOFS; d++)
        site_of_interface[d] = -1;
    for (int k = 0; k < count && !rc; k++) {
        rths_run_site *site = &out->site[k];
        char key[96];
        const char *uri = NULL;
        snprintf(key, sizeof key, "rig.sites.%d.uri", k);
        rc = rths_config_get_string(cfg, key, 0, NULL, &uri, err);
        if (!rc && uri && strncmp(uri, "tcp://", 6))
            rc = rths_config_error_at(cfg, key, err, "'%s' is not tcp://HOST:PORT", uri);
        if (!rc && uri) snprintf(site->uri, sizeof site->uri, "%s", uri);
        int *dofs = NULL, n_dofs = 0;
        snprintf(key, sizeof key, "rig.sites.%d.interface_dofs", k);
        if (!rc) rc = rths_config_get_int_list(cfg, key, 1, &dofs, &n_dofs, err);
        if (!rc && (n_dofs < 1 || n_dofs > RTHS_MAX_INTERFACE_DOFS))
            rc = rths_config_error_at(cfg, key, err, "lists %d DoFs; a site drives 1 to %d", n_dofs,
                                      RTHS_MAX_INTERFACE_DOFS);
        for (int j = 0; j < n_dofs && !rc; j++) {
            int d =
                dofs[j] >= 1 && dofs[j] <= setup->assembly.n ? interface_index(s, dofs[j] - 1) : -1;
            if (d < 0)
                rc = rths_config_error_at(cfg, key, err, "DoF %d is not in split.interface",
                                          dofs[j]);
            else if (site_of_interface[d] >= 0)
                rc = rths_config_error_at(cfg, key, err,
                                          "DoF %d is driven by site %d already: each interface "
                                          "DoF belongs to one site",
                                          dofs[j], site_of_interface[d] + 1);
            else
                site_of_interface[d] = k;
        }
        free(dofs);
    }
    for (int d = 0; d < s->n_int && !rc; d++)
        if (site_of_interface[d] < 0)
            rc = rths_config_error_at(cfg, "rig.sites", err,
                                      "interface DoF %d (split.interface) is driven by no site",
                                      s->int_dofs[d] + 1);
    /* each site's DoFs in the split's (ascending) order, as its own controller orders them */
    for (int d = 0; d < s->n_int && !rc; d++) {
        rths_run_site *site = &out->site[site_of_interface[d]];
        site->int_dofs[site->n_int] = s->int_dofs[d];
        site->map[site->n_int++] = d;
    }
    if (!rc) rc = assign_physical(cfg, setup, out, site_of_interface, err);
    return rc;
}

int rths_run_sites_check_solver(rths_config *cfg, const rths_setup *setup,
                                const rths_run_sites *sites, rths_error *err) {
    if (sites->n < 2 || !sites->numerical_couples_sites ||
        setup->numerical_solver == RTHS_NUMERICAL_FREQUENCY)
        return RTHS_OK;
    return rths_config_error_at(
        cfg, "rig.sites", err,
        "the numerical side couples the sites (numerical DoF %d is joined, through numerical "
        "elements, to interface DoFs of two sites): set split.numerical_solver: frequency, so "
        "the host solves the numerical substructure per harmonic and no site needs another "
        "site's motion in real time (docs/method.md, \"Multi-site tests\")",
        sites->coupling_dof + 1);
}

/* "[a, b, c]" of 1-based DoFs into buf. */
static void dof_list(char *buf, size_t cap, const int *dofs, int n) {
    size_t len = (size_t)snprintf(buf, cap, "[");
    for (int i = 0; i < n && len < cap; i++)
        len += (size_t)snprintf(buf + len, cap - len, "%s%d", i ? ", " : "", dofs[i] + 1);
    if (len < cap) snprintf(buf + len, cap - len, "]");
}

int rths_run_site_overrides(const rths_setup *setup, const rths_run_sites *sites, int k,
                            rths_run_site_sets *out, rths_error *err) {
    memset(out, 0, sizeof *out);
    if (k < 0 || k >= sites->n)
        return rths_error_set(err, RTHS_EINPUT,
                              "--site %d: the configuration's rig.sites lists %d site(s)", k + 1,
                              sites->n);
    const rths_run_site *site = &sites->site[k];
    const rths_split *s = &setup->split;
    int n = setup->assembly.n;
    int *num = malloc(sizeof(int) * (size_t)n);
    if (!num) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    int n_num = 0;
    for (int i = 0; i < n; i++) {
        int mine = 0;
        for (int j = 0; j < site->n_int; j++)
            mine |= site->int_dofs[j] == i;
        for (int j = 0; j < site->n_phys; j++)
            mine |= site->phys_dofs[j] == i;
        if (!mine) num[n_num++] = i;
    }
    char list[sizeof out->text[0] - 32];
    dof_list(list, sizeof list, site->int_dofs, site->n_int);
    snprintf(out->text[out->n++], sizeof out->text[0], "split.interface=%s", list);
    dof_list(list, sizeof list, site->phys_dofs, site->n_phys);
    snprintf(out->text[out->n++], sizeof out->text[0], "split.physical=%s", list);
    dof_list(list, sizeof list, num, n_num);
    int fits = strlen(list) + 20 < sizeof out->text[0];
    snprintf(out->text[out->n++], sizeof out->text[0], "split.numerical=%s", list);
    free(num);
    if (!fits)
        return rths_error_set(err, RTHS_EINPUT,
                              "site %d: the numerical DoF list is too long for an override (%d "
                              "DoFs)",
                              k + 1, n_num);
    /* one p per interface DoF: the site's own */
    size_t len = (size_t)snprintf(out->text[out->n], sizeof out->text[0], "split.mass_ratio=[");
    for (int j = 0; j < site->n_int; j++)
        len += (size_t)snprintf(out->text[out->n] + len, sizeof out->text[0] - len, "%s%.17g",
                                j ? ", " : "", s->mass_ratios[site->map[j]]);
    snprintf(out->text[out->n] + len, sizeof out->text[0] - len, "]");
    out->n++;
    return RTHS_OK;
}
