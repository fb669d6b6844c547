#!/usr/bin/env bash
# rths model on a one-DoF structure given inline (issue 24.8: M = [[5]], C = [[1]], K = [[40000]]
# reported mode 1 at 0 Hz and an all-zero FRF with exit 0): exit 0, mode 1 at sqrt(K/M) / 2 pi =
# 14.2353 Hz, the static response 1 / K and the peak near 1 / (C w) in true_frf.csv; a storey or
# a diagonal mass entry of 1e-300 kg (issue 24.12: a mode at 5e151 Hz and NaN output with exit 0)
# is refused with the key and the value, exit 2, nothing written.
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
  amplitude_n: 1
YAML
"$bin" model "$work/one.yaml" --out "$work/m" --quiet >"$work/stdout" 2>"$work/stderr"
rc=$?
[ "$rc" -eq 0 ] || { fail "one DoF: exit status $rc"; cat "$work/stderr"; }
/usr/bin/python3 - "$work/m" <<'PY' || fail "one DoF: modes.csv or true_frf.csv wrong"
import csv, math, sys
out = sys.argv[1]
modes = list(csv.DictReader(open(out + "/modes.csv")))
f1 = float(modes[0]["frequency_hz"])
truth = math.sqrt(40000 / 5) / (2 * math.pi)
assert len(modes) == 1 and abs(f1 - truth) < 1e-9 * truth, (f1, truth)
rows = list(csv.DictReader(open(out + "/true_frf.csv")))
amp = [(float(r["frequency_hz"]), float(r["x1_amplitude_m"])) for r in rows]
assert all(math.isfinite(a) for _, a in amp)
f0, a0 = amp[0]
assert f0 == 0 and abs(a0 - 1 / 40000) < 1e-12, amp[0]
# the grid's largest: within 0.1 % of the closed form's peak near 1 / (c w) = 0.01118 m
w = 2 * math.pi * truth
peak = max(a for _, a in amp)
assert abs(peak - 1 / w) < 1e-3 / w, (peak, 1 / w)
print("ok   one DoF: mode %.6f Hz (truth %.6f), peak %.6g m" % (f1, truth, peak))
PY
sed 's/\[\[5\]\]/[[1e-300]]/' "$work/one.yaml" >"$work/tiny.yaml"
refused model "1e-300 kg mass matrix" "key 'structure.matrices.mass_kg': diagonal entry \(1, 1\) = 1e-300 is below 1e-12" "$work/tiny.yaml"
refused model "1e-300 kg storey" "key 'structure.storeys.mass_kg': storey 1: must be > 0 and <= 1e\\+15 kg, at least 1e-06 kg \\(got 1e-300\\)" \
    "$src/examples/four_storey_linear.yaml" --set 'structure.storeys.mass_kg=[1e-300,1000,1000,1000]'
[ "$failures" -eq 0 ] || exit 1
echo "model_one_dof: all passed"
