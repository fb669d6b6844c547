#!/usr/bin/env bash
# The fitted evaluation's least record (iteration.settle.fit_min_periods; docs/method.md, "The
# fitted evaluation"): a value below 4 (the plain mean's n + 3 residual degrees of freedom) is
# refused by key with exit 2 before anything is written, and so is a residual margin
# (iteration.settle.fit_residual_margin) outside 1..3; on the linear seed (p = 0.5, noise off,
# 12.6-12.8 Hz) the default least record (8 after the skip) has every accepted evaluation read at
# least 13 periods, while 4 leaves the length to the fit: some accepted evaluations read fewer, the
# run takes less rig time, and every point stays within 0.1 % of the analytic FRF.
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
cfg="$src/examples/four_storey_linear.yaml"
opts=(--quiet --set continuation.start_hz=12.6 --set continuation.end_hz=12.8
      --set split.mass_ratio=0.5 --set rig.noise=off --set iteration.settle.strategy=fit)

"$bin" frf "$cfg" --out "$work/bad" "${opts[@]}" --set iteration.settle.fit_min_periods=3 \
    >"$work/bad.txt" 2>&1
rc=$?
[ "$rc" -eq 2 ] || fail "fit_min_periods=3: exit $rc, expected 2: $(cat "$work/bad.txt")"
grep -q 'iteration.settle.fit_min_periods' "$work/bad.txt" || fail "the key is not named: $(cat "$work/bad.txt")"
[ ! -e "$work/bad/journal.jsonl" ] || fail "a refused run wrote a journal"

"$bin" frf "$cfg" --out "$work/bad_margin" "${opts[@]}" --set iteration.settle.fit_residual_margin=0 \
    >"$work/bad_margin.txt" 2>&1
rc=$?
[ "$rc" -eq 2 ] || fail "fit_residual_margin=0: exit $rc, expected 2: $(cat "$work/bad_margin.txt")"
grep -q 'iteration.settle.fit_residual_margin' "$work/bad_margin.txt" \
    || fail "the key is not named: $(cat "$work/bad_margin.txt")"

"$bin" frf "$cfg" --out "$work/eight" "${opts[@]}" >"$work/e.txt" 2>&1 || fail "default: $(cat "$work/e.txt")"
"$bin" frf "$cfg" --out "$work/four" "${opts[@]}" --set iteration.settle.fit_min_periods=4 \
    >"$work/f.txt" 2>&1 || fail "fit_min_periods=4: $(cat "$work/f.txt")"

PYTHONPATH="$src/tests/cli/lib" python3 - "$work" <<'PY' || fail "least record (above)"
import csv, json, sys
from checks import check, exit_status
w = sys.argv[1]
least, rig = {}, {}
for run in ("eight", "four"):
    points = [json.loads(l) for l in open(f"{w}/{run}/journal.jsonl")][1:]
    read = [p["wait_periods"] + p["average_periods"] for p in points if p.get("eval_fitted")]
    least[run] = min(read)
    rig[run] = json.load(open(f"{w}/{run}/summary.json"))["rig_time_s"]
    for r in csv.DictReader(open(f"{w}/{run}/frf.csv")):
        err = abs(float(r["amplitude_m"]) - float(r["true_amplitude_m"])) / float(r["true_amplitude_m"])
        check(err < 1e-3, f"{run} {r['frequency_hz']} Hz within 0.1 % ({err:.2e})")
    print(run, "least periods", least[run], "rig s", rig[run])
check(least["eight"] >= 13, "default: every accepted evaluation read at least 13 periods")
check(least["four"] < 13, "fit_min_periods=4: an accepted evaluation read fewer than 13")
check(rig["four"] < rig["eight"], "fit_min_periods=4: less rig time")
sys.exit(exit_status())
PY
