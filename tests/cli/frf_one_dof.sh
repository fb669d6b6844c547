#!/usr/bin/env bash
# The numerical substructure of a one-DoF split is the free mass p M with an all-zero stiffness,
# which is not indefinite (it was refused as such).
# Issue 24.8: a single-DoF structure (M = [[5]], C = [[1]], K = [[40000]]) as a hybrid test:
# `rths frf` said "K indefinite" (exit 2). With the change it runs, exit 0, and every point lies
# within 1 % of 1 / (K - M w^2 + i C w) away from the 14.24 Hz resonance (the sweep's 10 .. 13 Hz
# part; numpy-free closed form).
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cat >"$work/one.yaml" <<'YAML'
structure:
  matrices:
    mass_kg: [[5]]
    damping_n_s_per_m: [[1]]
    stiffness_n_per_m: [[40000]]
split:
  interface: [1]
  mass_ratio: 0.5
forcing:
  dof: 1
  amplitude_n: 0.2
continuation:
  start_hz: 10
  end_hz: 13
YAML
"$bin" frf "$work/one.yaml" --set rig.noise=false --out "$work/f" --quiet >"$work/stdout" 2>"$work/stderr"
rc=$?
[ "$rc" -eq 0 ] || { fail "one DoF frf: exit $rc"; cat "$work/stderr"; }
/usr/bin/python3 - "$work/f" <<'PY' || fail "one DoF frf: points off the closed form"
import csv, math, sys
rows = list(csv.DictReader(open(sys.argv[1] + "/frf.csv")))
assert len(rows) > 3
worst = 0
for r in rows:
    w = 2 * math.pi * float(r["frequency_hz"])
    truth = 0.2 / abs(complex(40000 - 5 * w * w, w))
    worst = max(worst, abs(float(r["amplitude_m"]) / truth - 1))
print("ok   one DoF frf: %d points, at most %.3f %% off" % (len(rows), 100 * worst))
assert worst < 0.01, worst
PY
[ "$failures" -eq 0 ] || exit 1
echo "frf_one_dof: all passed"
