#!/usr/bin/env bash
# rths model on the 1000-DoF rod chain given as Matrix Market files
# (examples/rod_chain_1000): every natural frequency equals the dense generalised eigenvalues of
# an independent LAPACK path (numpy: Cholesky of M, then eigh, each eigenvalue refined as its
# vector's Rayleigh quotient) to 1e-8 relative, the interface
# FRF equals numpy's dense complex solve to 1e-8 relative at a few frequencies, run.log reports
# the FRF method and the time of each stage (Debian's python3 with python3-numpy); a broken .mtx is refused with its file and line,
# exit 2 and nothing written.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
ex="$src/examples/rod_chain_1000"
out="$work/rod"
"$bin" model "$ex/rod_chain_1000.yaml" --out "$out" --quiet >"$work/stdout" 2>"$work/stderr"
rc=$?
[ "$rc" -eq 0 ] || { fail "rod chain: exit status $rc"; cat "$work/stderr"; }
grep -Eq 'timing: 1000 DoFs; .*modes \(banded, dsbgvd\) [0-9.]+ s, FRF preparation \(banded solves\)' \
    "$out/run.log" || fail "run.log has no timing line: $(cat "$out/run.log")"
[ "$(wc -l <"$out/modes.csv")" -eq 1001 ] || fail "modes.csv: not 1000 modes"
head -n 1 "$out/true_frf.csv" | grep -q '^frequency_hz,x1_amplitude_m,x1_phase_rad,.*x3_amplitude_m,x3_phase_rad,x1000_amplitude_m,x1000_phase_rad$' ||
    fail "true_frf.csv header: $(head -n 1 "$out/true_frf.csv")"
/usr/bin/python3 - "$ex" "$out" <<'PY' || fail "rod chain: modes or FRF differ from the dense LAPACK solution"
import sys
import numpy as np

ex, out = sys.argv[1], sys.argv[2]

def read_mtx(path):  # the generator's files: coordinate real symmetric, lower triangle
    with open(path) as f:
        lines = [l for l in f if not l.startswith("%")]
    n = int(lines[0].split()[0])
    a = np.zeros((n, n))
    for l in lines[1:]:
        i, j, v = l.split()
        i, j = int(i) - 1, int(j) - 1
        a[i, j] += float(v)
        if i != j:
            a[j, i] += float(v)
    return a

m, c, k = (read_mtx("%s/%s.mtx" % (ex, name))
           for name in ("mass_kg", "damping_n_s_per_m", "stiffness_n_per_m"))
# numpy's dense path (LAPACK dpotrf + dsyevd), eigenvalues then refined as the Rayleigh
# quotients of its own eigenvectors: the dense eigenvalues alone carry eps * w_max^2 absolute
# error, 1e-8 relative on this mesh's lowest mode (w_max^2 / w_1^2 = 7e9); the quotients do not
l = np.linalg.cholesky(m)
a = np.linalg.solve(l, np.linalg.solve(l, k).T)
w2_dense, y = np.linalg.eigh(0.5 * (a + a.T))
phi = np.linalg.solve(l.T, y)
w2 = np.einsum("ir,ir->r", phi, k @ phi) / np.einsum("ir,ir->r", phi, m @ phi)
modes = np.loadtxt("%s/modes.csv" % out, delimiter=",", skiprows=1)
rel = np.max(np.abs(modes[:, 2] ** 2 - w2) / w2)
raw = np.max(np.abs(modes[:, 2] ** 2 - w2_dense) / w2_dense)
print("modes: max relative difference of w^2 from the dense solution %.2e (%.2e before the "
      "Rayleigh quotient)" % (rel, raw))
frf = np.loadtxt("%s/true_frf.csv" % out, delimiter=",", skiprows=1)
f = np.zeros(m.shape[0]); f[-1] = 1.0
worst = 0.0
for row in frf[:: max(1, len(frf) // 25)]:
    w = 2 * np.pi * row[0]
    x = np.linalg.solve(k - w * w * m + 1j * w * c, f)
    got = row[5] * np.exp(1j * row[6])  # x3 (the interface): columns 5, 6
    worst = max(worst, abs(got - x[2]) / abs(x[2]))
print("FRF: max relative difference at the interface %.2e" % worst)
sys.exit(0 if rel < 1e-8 and worst < 1e-8 else 1)
PY

# broken files: the key, the file and its line
cp "$ex"/*.mtx "$ex/rod_chain_1000.yaml" "$work/"
sed -i '5s/.*/4 3 oops/' "$work/stiffness_n_per_m.mtx"
refused model "bad .mtx entry" "key 'structure.matrices.stiffness_n_per_m': .*stiffness_n_per_m.mtx:5: expected 3 numbers on this line, found 2" \
    "$work/rod_chain_1000.yaml"
refused model "missing .mtx" "no_such.mtx: cannot open" "$work/rod_chain_1000.yaml" \
    --set structure.matrices.mass_kg=no_such.mtx
refused model "indefinite stiffness" "stiffness_n_per_m': must be positive definite" \
    "$src/tests/data/mtx/seed_matrices.yaml" \
    --set 'structure.matrices.stiffness_n_per_m=[[1, 2, 0, 0], [2, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]'
# issue 18's extreme inputs: refused before anything is written
refused model "1e308 kg storey" "storey 3: must be > 0 and <= 1e\\+15" "$src/examples/four_storey.yaml" \
    --set 'structure.storeys.mass_kg=[5.37, 5.37, 1e308, 10.74]'
refused model "singular stiffness" "rigid-body motion" "$src/tests/data/mtx/seed_matrices.yaml" \
    --set 'structure.matrices.stiffness_n_per_m=[[1, -1, 0, 0], [-1, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]'
refused model "negative-definite damping" "damping_n_s_per_m': must be positive semi-definite" \
    "$src/tests/data/mtx/seed_matrices.yaml" \
    --set 'structure.matrices.damping_n_s_per_m=[[-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, -1, 0], [0, 0, 0, -1]]'
# a few bytes declaring 12000 x 12000: refused from the entries at once (was 80 s and 4.5 GB)
printf '%%%%MatrixMarket matrix coordinate real symmetric\n12000 12000 1\n1 1 5.37\n' >"$work/huge_mass.mtx"
refused model "declared size far beyond the entries" \
    "key 'structure.matrices.mass_kg': .*huge_mass.mtx: diagonal entry \(2,2\) is zero or missing" \
    "$src/tests/data/mtx/seed_matrices.yaml" --set structure.matrices.mass_kg="$work/huge_mass.mtx"
exit $((failures > 0))
