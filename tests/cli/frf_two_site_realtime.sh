#!/usr/bin/env bash
# A multi-site test in the real-time numerical form on loopback (examples/two_site_realtime.yaml;
# docs/method.md, "Multi-site tests", "Which numerical form"): two chains that share no element,
# one per site, each site's numerical storey integrated in real time by its own
# `rths controller --site N` process (split.numerical_solver: realtime, the default), the host
# joining the two with --rig once per site.
# 1. noise off: every point converges; site A's interface DoF (1) is within 0.5 % of the
#    assembly's analytic FRF (numpy's complex solve of (K - w^2 M + i w C) x = f over the file's
#    own matrices); site B's interface DoF (3), on the unforced chain whose analytic response is
#    exactly zero, stays below iteration.abs_tolerance_m (1e-9 m, against site A's ~1e-5 m);
#    summary.json names both sites with their interface DoFs and some rig time each, and each
#    site's controller says it runs its own split (the other chain whole on its numerical side);
# 2. the same file in one process (no URIs: the virtual rig runs both sites' physical parts)
#    meets the same truths, and agrees with the two-site run within 0.1 % on DoF 1 (both are
#    converged to rel_tolerance 1e-4 of the same fixed point).
# Late samples are tolerated (controller.max_overrun_share=1): the simulated plant's samples do
# not depend on when they run, and a test machine is not real-time.
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
cfg="$src/examples/two_site_realtime.yaml"
# every controller and host started here is stopped whatever the outcome; start_site starts one
source "$src/tests/cli/lib/servers.sh"

host=(--set rig.noise=false --set controller.max_overrun_share=1 --quiet)

check_truth() { # out_dir label sites
    /usr/bin/python3 - "$cfg" "$1" "$2" "$3" <<'PY'
import csv, json, re, sys
import numpy as np
cfg, d, label, n_sites = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
# the file's own matrices (rows "- [a, b, c, d]" under each key of structure.matrices)
text = open(cfg).read()
def matrix(key):
    block = text.split(f"    {key}:")[1]
    rows = re.findall(r"^\s+- \[([^\]]*)\]", block, re.M)[:4]
    return np.array([[float(v) for v in r.split(",")] for r in rows])
M, C, K = matrix("mass_kg"), matrix("damping_n_s_per_m"), matrix("stiffness_n_per_m")
f = np.array([0, 1.0, 0, 0])  # forcing.dof 2, amplitude 1 N
rows = list(csv.DictReader(open(f"{d}/frf.csv")))
worst, still = 0.0, 0.0
for r in rows:
    w = 2 * np.pi * float(r["frequency_hz"])
    x = np.abs(np.linalg.solve(K - w * w * M + 1j * w * C, f))
    assert x[2] == 0.0  # chain B is unforced and shares no element with chain A
    worst = max(worst, abs(float(r["dof1_amplitude_m"]) / x[0] - 1))
    still = max(still, abs(float(r["dof2_amplitude_m"])))
print(f"{label}: {len(rows)} points, DoF 1 worst error {100 * worst:.4f} %, "
      f"DoF 3 largest amplitude {still:.3g} m (analytic 0), site A's DoF 1 "
      f"{min(float(r['dof1_amplitude_m']) for r in rows):.3g} m or more")
ok = len(rows) >= 3 and all(r["converged"] == "1" for r in rows) and worst < 0.005 and still <= 1e-9
if n_sites:
    sites = json.load(open(f"{d}/summary.json")).get("sites", [])
    ok = ok and len(sites) == 2 and all(s["rig_time_s"] > 0 for s in sites)
    ok = ok and [s["interface_dofs"] for s in sites] == [[1], [3]]
sys.exit(0 if ok else 1)
PY
}

# 1. two controller processes, one per site
start_site 1 a --set rig.noise=false
rig_a=$port
start_site 2 b --set rig.noise=false
rig_b=$port
"$bin" frf "$cfg" --rig "tcp://127.0.0.1:$rig_a" --rig "tcp://127.0.0.1:$rig_b" --out "$work/two" \
    "${host[@]}" 2>"$work/two.err" || fail "two sites: rths frf exited $? ($(cat "$work/two.err"))"
# each site's controller runs its own split: the other chain whole on its numerical side
grep -q "site 1: split.interface=\[1\] split.physical=\[\] split.numerical=\[2, 3, 4\]" "$work/a.err" ||
    fail "site 1's split: $(cat "$work/a.err")"
grep -q "site 2: split.interface=\[3\] split.physical=\[\] split.numerical=\[1, 2, 4\]" "$work/b.err" ||
    fail "site 2's split: $(cat "$work/b.err")"
check_truth "$work/two" "two sites" 2 || fail "two sites: convergence, accuracy or sites"
[ "$failures" -eq 0 ] && echo "ok   two sites, real-time numerical form: within 0.5 % of the analytic FRF"

# 2. the same file in one process
"$bin" frf "$cfg" --out "$work/one" "${host[@]}" 2>"$work/one.err" ||
    fail "single process: rths frf exited $? ($(cat "$work/one.err"))"
check_truth "$work/one" "single process" 0 || fail "single process: convergence or accuracy"
/usr/bin/python3 - "$work" <<'PY' || fail "the two-site run differs from the single-process run"
import csv, sys
w = sys.argv[1]
two = list(csv.DictReader(open(f"{w}/two/frf.csv")))
one = {round(float(r["frequency_hz"]), 6): r for r in csv.DictReader(open(f"{w}/one/frf.csv"))}
worst, n = 0.0, 0
for r in two:
    s = one.get(round(float(r["frequency_hz"]), 6))
    if s is None:
        continue
    worst = max(worst, abs(float(r["dof1_amplitude_m"]) / float(s["dof1_amplitude_m"]) - 1))
    n += 1
print(f"{n} points compared, worst |two-site / single - 1| on DoF 1 = {100 * worst:.4f} %")
sys.exit(0 if n >= 3 and worst <= 1e-3 else 1)
PY
[ "$failures" -eq 0 ] && echo "ok   the single-process run meets the same truths and equals the two-site run"
exit $((failures > 0))
