#!/usr/bin/env bash
# rths model on the sparse path (docs/architecture.md, "Sparse algebra"), on a small version of
# issue 26's acceptance case: a 3-D frame from tools/gen_frame3d.py, nodes numbered at random,
# with a two-storey lumped specimen tied to a roof node (physical) and the force on another roof
# node. Independent truths from numpy on the dense matrices read back from the files:
#  - the modes: the generalised eigenvalues by Cholesky + eigvalsh; every sparse mode within
#    1e-9 relative (ARPACK converges to machine precision; the dense solver's own error on the
#    lowest modes is ~1e-12 here), their count the number of dense eigenvalues below the
#    reported Sturm shift (the sparse LDL^T's inertia), the printed residuals below 1e-8;
#  - the FRF: numpy's complex solve of (K - w^2 M + i w C) x = f at every frequency of
#    true_frf.csv, at the interface, the specimen and the forcing DoF: within 1e-4 of the curve's
#    largest amplitude, and within 0.5 % of each frequency's own largest amplitude (the modal FRF
#    with the residual's two moments, every mode below 1.5 x the band computed: its error is
#    ~(w / w_first dropped)^4 of the dropped modes' static share, which near the band's end,
#    where the response is 100 x below its peak, is 0.2 % of the response there, measured);
#  - the path's choice: auto takes sparse above 1000 DoFs with a scattered pattern and says why,
#    dense below; summary.json and run.log carry the stage times and the peak memory.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
gen="$src/tools/gen_frame3d.py"
/usr/bin/python3 "$gen" --nx 3 --ny 2 --nz 3 --elements-per-member 2 --seed 5 \
    --specimen 2000 3e5 "$work/f" >"$work/gen.log" 2>&1 || { fail "gen_frame3d.py"; cat "$work/gen.log"; }

"$bin" model "$work/f/frame.yaml" --out "$work/o" --set model.solver=sparse \
    --set model.frf.end_hz=6 --set model.frf.points=120 --set model.frf.check_points=2 \
    >"$work/o.out" 2>&1 || { fail "rths model (sparse) failed"; cat "$work/o.out"; }
grep -q "^Solver: sparse (model.solver: sparse" "$work/o.out" || fail "no 'Solver: sparse' line"
grep -q "solver: sparse, because model.solver: sparse" "$work/o/run.log" || fail "run.log: no solver line"
grep -Eq "timing: [0-9]+ DoFs; read .* order .* factor .* eigen .* FRF .*peak memory [0-9.]+ MB" \
    "$work/o/run.log" || fail "run.log: no stage times and peak memory"

/usr/bin/python3 - "$work" <<'PY' || fail "sparse model outputs disagree with numpy"
import csv, json, re, sys
import numpy as np

work = sys.argv[1]
bad = 0
def check(ok, what):
    global bad
    print(("ok   " if ok else "FAIL ") + what)
    bad += not ok

def read_mtx(path):
    with open(path) as f:
        f.readline()
        line = f.readline()
        while line.startswith("%"):
            line = f.readline()
        n, _, count = map(int, line.split())
        data = np.loadtxt(f, ndmin=2)
    a = np.zeros((n, n))
    i, j = data[:, 0].astype(int) - 1, data[:, 1].astype(int) - 1
    np.add.at(a, (i, j), data[:, 2])
    np.add.at(a, (j, i), np.where(i != j, data[:, 2], 0))
    return a

d = work + "/f/"
k, m, c = (read_mtx(d + x + ".mtx") for x in ("stiffness_n_per_m", "mass_kg", "damping_n_s_per_m"))
n = k.shape[0]
l = np.linalg.cholesky(m)
li = np.linalg.inv(l)
lam = np.linalg.eigvalsh(li @ k @ li.T)

rows = list(csv.DictReader(open(work + "/o/modes.csv")))
f_sparse = np.array([float(r["frequency_hz"]) for r in rows])
f_dense = np.sqrt(lam[:len(f_sparse)]) / (2 * np.pi)
err = np.max(np.abs(f_sparse / f_dense - 1))
check(err < 1e-9, "%d modes within %.2g of numpy's dense eigenvalues (< 1e-9)" % (len(rows), err))
check(np.sqrt(lam[len(rows)]) / (2 * np.pi) >= 9.0,
      "every mode below 1.5 x model.frf.end_hz = 9 Hz computed (next %.4f Hz)"
      % (np.sqrt(lam[len(rows)]) / (2 * np.pi)))

s = json.load(open(work + "/o/summary.json"))
sol = s["solver"]
shift = None
out = open(work + "/o.out").read()
mt = re.search(r"Sturm count below ([0-9.e+-]+) Hz: (\d+)", out)
check(mt is not None, "Sturm count printed")
if mt:
    below = int(np.sum(lam < sol["sturm_shift_rad2_s2"]))
    check(int(mt.group(2)) == len(rows) and sol["sturm_count"] == len(rows) and below == len(rows),
          "Sturm count %s = modes %d = numpy's eigenvalues below the shift %d"
          % (mt.group(2), len(rows), below))
check(sol["modes_max_relative_residual"] < 1e-8,
      "largest relative residual %.2g < 1e-8" % sol["modes_max_relative_residual"])
check(sol["path"] == "sparse" and sol["frf_direct_checks"] == 2
      and sol["frf_check_max_relative_error"] < 1e-3,
      "summary: sparse path, 2 direct checks, largest difference %.2g < 1e-3"
      % sol["frf_check_max_relative_error"])
check(all(x in s["timing_s"] for x in ("read", "order", "factor", "eigen", "frf"))
      and s["peak_memory_mb"] > 0, "summary: stage times and peak memory %.0f MB" % s["peak_memory_mb"])

frf = list(csv.DictReader(open(work + "/o/true_frf.csv")))
dofs = [int(x[1:-12]) for x in frf[0] if x.endswith("_amplitude_m")]
check(sorted(dofs) == sorted([s["interface_dof"], s["forcing_dof"], n - 1, n]),
      "true_frf.csv: interface, forcing and the two specimen DoFs %s" % dofs)
force = np.zeros(n)
force[s["forcing_dof"] - 1] = 1.0
worst = worst_curve = curve = 0.0
for r in frf:
    w = 2 * np.pi * float(r["frequency_hz"])
    x = np.linalg.solve(k - w * w * m + 1j * w * c, force)
    scale = np.max(np.abs(x[[d - 1 for d in dofs]]))
    curve = max(curve, scale)
    for d in dofs:
        z = float(r["x%d_amplitude_m" % d]) * np.exp(1j * float(r["x%d_phase_rad" % d]))
        worst = max(worst, abs(z - x[d - 1]) / scale)
        worst_curve = max(worst_curve, abs(z - x[d - 1]))
check(worst_curve / curve < 1e-4, "true_frf.csv within %.2g of the curve's peak of numpy's "
      "complex solves (< 1e-4) at %d frequencies" % (worst_curve / curve, len(frf)))
check(worst < 5e-3, "true_frf.csv within %.2g of each frequency's own amplitude (< 0.5 %%)"
      % worst)
sys.exit(1 if bad else 0)
PY

# the automatic choice: dense at this size, sparse above 1000 DoFs with a scattered pattern
"$bin" model "$work/f/frame.yaml" --out "$work/d" --set model.frf.points=20 >"$work/d.out" 2>&1 ||
    { fail "rths model (dense) failed"; cat "$work/d.out"; }
grep -Eq "^Solver: dense \(n = [0-9]+ <= 1000; half-bandwidth" "$work/d.out" ||
    fail "small model: no 'Solver: dense' line: $(head -n 2 "$work/d.out")"
/usr/bin/python3 "$gen" --nx 4 --ny 3 --nz 5 --elements-per-member 2 --seed 2 \
    --specimen 2000 3e5 "$work/big" >"$work/gen.log" 2>&1 || fail "gen_frame3d.py (big)"
"$bin" model "$work/big/frame.yaml" --out "$work/b" --set model.modes=4 --set model.frf.points=20 \
    >"$work/b.out" 2>&1 || { fail "rths model (auto, 1232 DoFs) failed"; cat "$work/b.out"; }
grep -Eq "^Solver: sparse \(n = 1232 > 1000 and the pattern is not banded \(half-bandwidth [0-9]+ > n / 8 = 154\)\)" \
    "$work/b.out" || fail "1232 DoFs: auto did not take sparse: $(head -n 1 "$work/b.out")"

# the figure (issue 28): at most 8 curves, the interface, forcing and physical DoFs among them,
# subscripts braced (gnuplot's enhanced text sets x_10 as x with subscript 1 and a 0 after it)
/usr/bin/python3 "$gen" --nx 2 --ny 1 --nz 1 --seed 3 --specimen 2000 3e5 "$work/tiny" \
    >"$work/gen.log" 2>&1 || fail "gen_frame3d.py (tiny)"
"$bin" model "$work/tiny/frame.yaml" --out "$work/t" --quiet --set model.frf.points=20 ||
    fail "rths model (14 DoFs) failed"
curves=$(grep -c "title 'x_{" "$work/t/true_frf.gp")
[ "$curves" -eq 16 ] || fail "figure: $curves curves in true_frf.gp (8 per terminal expected)"
grep -q "title 'x_[0-9]" "$work/t/true_frf.gp" && fail "figure: an unbraced subscript"
iface=$(sed -n 's/^  interface: \[\([0-9]*\)\]/\1/p' "$work/tiny/frame.yaml")
forced=$(sed -n 's/^  dof: \([0-9]*\)/\1/p' "$work/tiny/frame.yaml")
for d in "$iface" "$forced" 13 14; do
    grep -q "title 'x_{$d} " "$work/t/true_frf.gp" || fail "figure: DoF $d not drawn"
done
[ "$(head -n 1 "$work/t/true_frf.csv" | tr ',' '\n' | grep -c _amplitude_m)" -eq 14 ] ||
    fail "true_frf.csv: not every DoF of a 14-DoF model"

# a range beyond the computed modes is said, on the console and in run.log
"$bin" model "$work/f/frame.yaml" --out "$work/w" --set model.solver=sparse --set model.modes=4 \
    --set model.frf.end_hz=6 --set model.frf.points=20 --set model.frf.check_points=0 \
    >"$work/w.out" 2>&1 || fail "rths model (4 modes, 6 Hz) failed"
grep -q "^Warning: the FRF range ends at 6 Hz, above the highest mode computed" "$work/w.out" ||
    fail "no warning for a range above the computed modes"
grep -q "warning: FRF range ends at 6 Hz" "$work/w/run.log" || fail "run.log: no range warning"

# bad input
printf 'structure:\n  storeys:\n    mass_kg: [1, 1]\n    damping_n_s_per_m: [1, 1]\n    stiffness_n_per_m: [100, 100]\nsplit:\n  interface: [1]\n  mass_ratio: 0.5\nforcing:\n  dof: 2\n  amplitude_n: 1\nmodel:\n  solver: sparse\n' >"$work/chain.yaml"
refused model "sparse on a storey chain" "model.solver.*Matrix Market" "$work/chain.yaml"
refused model "too many modes below the band" "lower model.frf.end_hz" "$work/f/frame.yaml" \
    --set model.solver=sparse --set model.frf.end_hz=1e6
exit $((failures > 0))
