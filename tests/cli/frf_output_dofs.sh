#!/usr/bin/env bash
# output.dofs end to end (issue 23): frf.csv and truth.csv of `rths frf` gain x<d>_amplitude_m,
# x<d>_phase_rad and x<d>_amplitude_se_m for every listed DoF, before the integrity columns that
# end every row; noise off, every DoF's amplitude within 0.1 % of numpy's complex solve of the
# seed chain (independent of rths), truth.csv's within 1e-9; without the key no such column.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cfg="$src/examples/four_storey_linear.yaml"
run=(--set rig.noise=false --set continuation.start_hz=13.2 --set continuation.end_hz=13.7 --quiet)
"$bin" frf "$cfg" --out "$work/dofs" "${run[@]}" --set 'output.dofs=[1, 2, 3, 4]' \
    2>"$work/err" || fail "rths frf with output.dofs: $(cat "$work/err")"
"$bin" frf "$cfg" --out "$work/plain" "${run[@]}" 2>"$work/err" || fail "rths frf: $(cat "$work/err")"
grep -q "x1_amplitude_m" "$work/plain/frf.csv" "$work/plain/truth.csv" && fail "columns without output.dofs"
/usr/bin/python3 - "$work/dofs" <<'PY' || fail "output.dofs columns"
import csv, sys
import numpy as np
d = sys.argv[1]
m = np.diag([5.37, 5.37, 5.37, 10.74])
def chain(v):
    a = np.zeros((4, 4))
    for i in range(4):
        a[i, i] += v[i]
        if i > 0:
            a[i - 1, i - 1] += v[i]; a[i - 1, i] -= v[i]; a[i, i - 1] -= v[i]
    return a
c, k = chain([4.4062, 3.7979, 3.7421, 3.7421]), chain([53048, 45724, 45052, 45052])
f = np.array([0, 0, 0, 1.0])
def truth(hz):
    w = 2 * np.pi * hz
    return np.abs(np.linalg.solve(k + 1j * w * c - w * w * m, f))
ok = True
for name, tol in (("frf.csv", 1e-3), ("truth.csv", 1e-9)):
    rows = list(csv.DictReader(open(d + "/" + name)))
    head = list(rows[0].keys())
    want = [f"x{j}_{q}" for j in range(1, 5) for q in ("amplitude_m", "phase_rad", "amplitude_se_m")]
    if name == "frf.csv":
        at = head.index("late_samples")
        ok &= head[at - 12:at] == want
    else:
        ok &= head[-12:] == want
    worst = max(abs(float(r[f"x{j}_amplitude_m"]) / truth(float(r["frequency_hz"]))[j - 1] - 1)
                for r in rows for j in range(1, 5))
    print(f"{name}: {len(rows)} rows, every DoF within {100 * worst:.4f} % of numpy")
    ok &= worst < tol and len(rows) > 5
sys.exit(0 if ok else 1)
PY
exit $((failures > 0))
