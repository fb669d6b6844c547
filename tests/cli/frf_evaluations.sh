#!/usr/bin/env bash
# evaluations.csv (docs/method.md, "Outputs"): every evaluation the corrector made, a row each,
# with what it was for. The rows account for every evaluation and every rig second the points
# report (frf.csv, summary.json), each row has exactly one role, each correction begins with its
# prediction, every accepted point has a row within tolerance, and a resumed run appends to the
# file (one header) with its rows marked resumed.
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
cfg="$src/examples/four_storey_linear.yaml"
opts=(--quiet --set continuation.start_hz=12.6 --set continuation.end_hz=13.0)

"$bin" frf "$cfg" --out "$work/run" "${opts[@]}" --set continuation.max_points=3 >"$work/1.txt" 2>&1 \
    || fail "first run: $(cat "$work/1.txt")"
first_rows=$(($(wc -l <"$work/run/evaluations.csv") - 1))
"$bin" frf "$cfg" --out "$work/run" "${opts[@]}" --resume >"$work/2.txt" 2>&1 \
    || fail "resumed run: $(cat "$work/2.txt")"
[ -f "$work/run/results.mat" ] || fail "no results.mat (evaluations.csv must stay a numeric table)"

python3 - "$work/run" "$first_rows" <<'PY' || fail "evaluations.csv wrong (above)"
import csv, json, math, sys
d, first_rows = sys.argv[1], int(sys.argv[2])
ok = True
def check(cond, what):
    global ok
    if not cond:
        print("wrong:", what); ok = False
roles = ["prediction", "jacobian", "step", "damped_step", "gain_probe", "accuracy_step"]
header = ("point,correction," + ",".join(roles) + ",iteration,frequency_hz,mismatch_m,tolerance_m,"
          "mismatch_to_tolerance,within_tolerance,damping,rig_time_s,wait_periods,average_periods,"
          "steady,fitted,fit_fallback,refused,resumed")
lines = open(f"{d}/evaluations.csv").read().splitlines()
check(lines[0] == header, f"header {lines[0]}")
check(lines.count(header) == 1, "the resumed run wrote a second header")
rows = list(csv.DictReader(open(f"{d}/evaluations.csv")))
pts = list(csv.DictReader(open(f"{d}/frf.csv")))
summary = json.load(open(f"{d}/summary.json"))
check(len(pts) >= 5, f"{len(pts)} points")
check(len(rows) == summary["evaluations_total"], f"{len(rows)} rows, {summary['evaluations_total']} evaluations")
rig = sum(float(r["rig_time_s"]) for r in rows)
rig_pts = sum(float(p["rig_time_s"]) for p in pts)
check(abs(rig - rig_pts) <= 1e-9 * rig_pts, f"rows' rig time {rig} s, the points' {rig_pts} s")
check(0 < first_rows < len(rows), f"{first_rows} rows before the resume of {len(rows)}")
correction = 0
for i, r in enumerate(rows):
    flags = [int(r[k]) for k in roles]
    check(sum(flags) == 1, f"row {i}: roles {flags}")
    check(int(r["resumed"]) == (i >= first_rows), f"row {i}: resumed {r['resumed']}")
    if int(r["prediction"]):
        # corrections count per run: the resumed run begins again at 1
        correction = 1 if i == first_rows else correction + 1
    check(int(r["correction"]) == correction, f"row {i}: correction {r['correction']}, expected {correction}")
    m, t, q = float(r["mismatch_m"]), float(r["tolerance_m"]), float(r["mismatch_to_tolerance"])
    check(math.isfinite(m) and t > 0 and abs(q - m / t) <= 1e-9 * q, f"row {i}: mismatch {m} / {t} != {q}")
    check(int(r["within_tolerance"]) == (q < 1), f"row {i}: within {r['within_tolerance']} at {q} tolerances")
    step = int(r["step"]) or int(r["damped_step"])
    check((float(r["damping"]) > 0) == bool(step), f"row {i}: damping {r['damping']}")
    check(float(r["rig_time_s"]) > 0 and int(r["wait_periods"]) + int(r["average_periods"]) > 0, f"row {i}: no rig time")
check(rows[0]["prediction"] == "1" and rows[first_rows]["prediction"] == "1", "a run does not begin with a prediction")
check(any(int(r["jacobian"]) for r in rows), "no finite-difference column (the first point measures its Jacobian)")
for p in pts:
    mine = [r for r in rows if r["point"] == p["point"]]
    check(len(mine) == int(p["evaluations"]), f"point {p['point']}: {len(mine)} rows, {p['evaluations']} evaluations")
    check(any(int(r["within_tolerance"]) for r in mine), f"point {p['point']}: no row within tolerance")
    check(all(abs(float(r["frequency_hz"]) - float(p["frequency_hz"])) < 0.2 for r in mine), f"point {p['point']}: a row's frequency far off")
sys.exit(0 if ok else 1)
PY
echo "evaluations.csv: rows and rig time account for every point"
