#!/usr/bin/env bash
# `rths frf` on a sparse model in the real-time form (issue 26; docs/architecture.md, "Sparse
# algebra"): the 482-DoF frame of tools/gen_frame3d.py (4 x 4 x 5 column lines, nodes numbered at
# random) forced onto the sparse path, the two-storey 2 kg / 2000 N/m specimen on the rig tied to
# ux of a roof node, the force on the opposite roof node, split.numerical_solver: realtime, noise
# off. The controller integrates the band-exact Krylov reduction of the sparse numerical side
# (krylov_reduce.h), no dense matrix of its order. Asserted:
#  - every point converged and its interface amplitude within 0.5 % (the issue's bound; measured
#    2e-4, the evaluations' settling) of numpy's dense complex solve of the assembly,
#    (K - w^2 M + i w C) x = f, independent of rths;
#  - a reduction worse than controller.reduction.max_error in the band is refused, exit 2, the
#    message naming the key, the error and the band; a sweep not given (no band) is refused
#    naming continuation.start_hz.
# Rayleigh alpha 0.5 1/s (zeta ~4 % near 1.1 Hz) rather than the generator's 0.05: at 0.4 % the
# frame's transients take minutes of rig time per evaluation to settle, which is the evaluation's
# matter, not the reduction's. Given interface shares as in frf_sparse.sh.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
/usr/bin/python3 "$src/tools/gen_frame3d.py" --nx 4 --ny 4 --nz 5 --seed 1 --specimen 2 2e3 \
    --rayleigh-alpha 0.5 "$work/m" >"$work/gen.log" 2>&1 || { fail "gen_frame3d.py"; cat "$work/gen.log"; }
sed -e '/^split:/a\  numerical_solver: realtime' \
    -e 's/mass_ratio: 0.5/mass_ratio: 0.999\n  interface_stiffness_physical_n_per_m: [[2.0e3]]\n  interface_damping_physical_n_s_per_m: [[0.2]]/' \
    -e 's/amplitude_n: 1.0/amplitude_n: 100.0/' "$work/m/frame.yaml" >"$work/m/base.yaml"
cat >>"$work/m/base.yaml" <<'EOF'
model:
  solver: sparse
  frf: {points: 11}
rig:
  interface_mass: physical_share
EOF
cp "$work/m/base.yaml" "$work/m/rt.yaml"
cat >>"$work/m/rt.yaml" <<'EOF'
continuation:
  start_hz: 1.0
  end_hz: 1.12
  method: natural
  initial_step_hz: 0.03
  max_step_hz: 0.03
EOF
"$bin" frf "$work/m/rt.yaml" --out "$work/f" --set rig.noise=false --quiet \
    >"$work/stdout" 2>"$work/stderr"
rc=$?
[ "$rc" -eq 0 ] || { fail "noise off: exit $rc"; cat "$work/stderr"; }
PYTHONPATH="$src/tests/cli/lib" /usr/bin/python3 - "$work/m" "$work/f" <<'PY' || fail "noise off: not within 0.5 % of the assembly"
import csv, sys
import numpy as np
from mtx import read_mtx
m_dir, out = sys.argv[1], sys.argv[2]
m, c, k = (read_mtx(m_dir + "/" + name + ".mtx")
           for name in ("mass_kg", "damping_n_s_per_m", "stiffness_n_per_m"))
f = np.zeros(m.shape[0])
f[283 - 1] = 100.0
rows = list(csv.DictReader(open(out + "/frf.csv")))
assert len(rows) >= 4, len(rows)
worst = 0
for r in rows:
    assert r["converged"] == "1", r
    w = 2 * np.pi * float(r["frequency_hz"])
    x = abs(np.linalg.solve(k - w * w * m + 1j * w * c, f)[301 - 1])
    worst = max(worst, abs(float(r["amplitude_m"]) / x - 1))
print("ok   sparse frame, real-time form, noise off: %d points, at most %.2e from the assembly"
      % (len(rows), worst))
assert worst < 5e-3, worst
PY
grep -q "numerical substructure: sparse, 480 DoFs, reduced in real time to [0-9]* DoFs" "$work/f/run.log" ||
    fail "run.log does not report the real-time reduction: $(grep -m1 -i reduc "$work/f/run.log")"
refused frf "a reduction worse than controller.reduction.max_error" \
    "controller.reduction.max_error 1e-14 %.*over 31 check points of 0.994-1.126 Hz" \
    "$work/m/rt.yaml" --set controller.reduction.max_error=1e-16
refused frf "the real-time form on a sparse model without a sweep" \
    "no band is given: set continuation.start_hz and continuation.end_hz" "$work/m/base.yaml"
[ "$failures" -eq 0 ] || exit 1
echo "frf_sparse_realtime: all passed"
