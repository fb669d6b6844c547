#!/usr/bin/env bash
# Smooth transitions (controller.transition_periods; docs/method.md, "Smooth transitions"). A value
# out of range is refused by key with exit 2 before anything is written; `--strategy paper` puts
# the seed's changes at once (0) among its overrides. On the two-shaker cantilever (noise off,
# 2.96-3.04 Hz, 5 points) the tip held at the cut rings in its 6.55 Hz mode (0.77 % damping, a
# 3.2 s time constant) after every change made at once, and the wait for steady state lasts 41 to
# 50 periods (measured); moved over 3 periods instead, the mode 3.55 Hz from the forcing is hardly
# excited: the points after the first wait 10 to 33 periods, the run takes 0.63 of the rig time,
# and both stay within 0.05 % of the analytic FRF (measured 0.016 and 0.014 %).
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
cfg="$src/examples/cantilever_two_shakers.yaml"
opts=(--quiet --set rig.noise=off --set continuation.start_hz=2.96 --set continuation.end_hz=3.04)

refused frf "transition_periods=-1" 'controller\.transition_periods' "$cfg" "${opts[@]}" \
    --set controller.transition_periods=-1

"$bin" frf "$cfg" --out "$work/paper" "${opts[@]}" --strategy paper --set continuation.max_points=2 \
    >"$work/paper.txt" 2>&1 || fail "paper: $(cat "$work/paper.txt")"
grep -q '"controller.transition_periods=0"' "$work/paper/summary.json" \
    || fail "--strategy paper does not list controller.transition_periods=0 among its overrides"
grep -q '"controller.grounding_kd_n_s_per_m=200"' "$work/paper/summary.json" \
    || fail "--strategy paper lost its grounding damping override"

"$bin" frf "$cfg" --out "$work/abrupt" "${opts[@]}" --set controller.transition_periods=0 \
    >"$work/a.txt" 2>&1 || fail "transition_periods=0: $(cat "$work/a.txt")"
"$bin" frf "$cfg" --out "$work/smooth" "${opts[@]}" >"$work/s.txt" 2>&1 \
    || fail "default: $(cat "$work/s.txt")"

PYTHONPATH="$src/tests/cli/lib" python3 - "$work" <<'PY' || fail "transitions (above)"
import json, statistics, sys
from checks import check, exit_status
w = sys.argv[1]
rig, waits = {}, {}
for run in ("abrupt", "smooth"):
    s = json.load(open(f"{w}/{run}/summary.json"))
    rig[run] = s["rig_time_s"]
    check(s["converged_points"] == s["points"] == 5, f"{run}: 5 points converged")
    for d in s["interface_dofs"]:
        err = d["max_relative_error_vs_truth"]
        check(err < 5e-4, f"{run}: interface DoF {d['dof']} within 0.05 % of the truth ({err:.2e})")
    points = [json.loads(l) for l in open(f"{w}/{run}/journal.jsonl")][1:]
    waits[run] = statistics.median(p["wait_periods"] for p in points[1:])
    print(run, "rig s", round(rig[run], 1), "median wait after the first point", waits[run])
check(rig["smooth"] < 0.75 * rig["abrupt"], "smooth transitions: under 0.75 of the rig time")
check(waits["smooth"] < 0.6 * waits["abrupt"], "smooth transitions: the wait under 0.6 of it")
sys.exit(exit_status())
PY
exit $((failures > 0))
