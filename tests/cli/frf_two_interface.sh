#!/usr/bin/env bash
# rths frf with two interface DoFs (examples/two_interface_storeys.yaml: storeys 2 and 3 on two
# shakers). Noise off: every point converges and both interface storeys' amplitudes
# (dof1_amplitude_m, dof2_amplitude_m) are within 0.5 % of the assembly's analytic FRF, solved
# here from the storey chain's matrices (measured below 0.1 %). Default noise: at least 95 % of
# the points within 3 standard errors of it (amplitude_m, amplitude_se_m: the first DoF).
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
cfg="$src/examples/two_interface_storeys.yaml"

check() { # out_dir mode
    /usr/bin/python3 - "$1/frf.csv" "$2" <<'PY'
import csv, sys
import numpy as np
m = np.array([5.37, 5.37, 5.37, 10.74])
c = np.array([4.4062, 3.7979, 3.7421, 3.7421])
k = np.array([53048, 45724, 45052, 45052])
def chain(v):  # storey i joined to i-1 (storey 1 to the ground)
    n = len(v); a = np.zeros((n, n))
    for i in range(n):
        a[i, i] += v[i]
        if i > 0:
            a[i, i - 1] -= v[i]; a[i - 1, i] -= v[i]; a[i - 1, i - 1] += v[i]
    return a
M, C, K = np.diag(m), chain(c), chain(k)
f = np.array([0, 0, 0, 1.0])
rows = list(csv.DictReader(open(sys.argv[1])))
worst, within, n_conv = 0.0, 0, 0
for r in rows:
    w = 2 * np.pi * float(r["frequency_hz"])
    x = np.abs(np.linalg.solve(K - w * w * M + 1j * w * C, f))
    n_conv += r["converged"] == "1"
    for d, dof in ((1, 1), (2, 2)):
        worst = max(worst, abs(float(r[f"dof{d}_amplitude_m"]) / x[dof] - 1))
    se = float(r["amplitude_se_m"])
    within += abs(float(r["amplitude_m"]) - x[1]) <= 3 * se
print(f"{sys.argv[2]}: {len(rows)} points, {n_conv} converged, worst DoF error {100 * worst:.3f} %, "
      f"{within} of {len(rows)} within 3 SE")
ok = len(rows) >= 20 and n_conv == len(rows)
ok = ok and (worst < 0.005 if sys.argv[2] == "noise_off" else within >= 0.95 * len(rows))
ok = ok and (len(rows) >= 100 if sys.argv[2] == "arclength" else True)
sys.exit(0 if ok else 1)
PY
}

"$bin" frf "$cfg" --set rig.noise=false --out "$work/off" --quiet || fail "noise off: rths frf exited $?"
check "$work/off" noise_off || fail "noise off: accuracy"
"$bin" frf "$cfg" --out "$work/on" --quiet || fail "default noise: rths frf exited $?"
check "$work/on" noise_on || fail "default noise: standard errors"
# Pseudo-arclength over the 4 targets and the frequency (about 250 points through the modes, the
# steps shrinking to ~1 mHz at the peaks): every point converges and at least 95 % lie within
# 3 standard errors of the analytic FRF (measured 252 of 252; near the second mode the targets of
# neighbouring points are so nearly parallel that the n x n gains are only just determined).
"$bin" frf "$cfg" --set rig.noise=false --set continuation.method=arclength --out "$work/arc" \
    --quiet || fail "arclength: rths frf exited $?"
check "$work/arc" arclength || fail "arclength: convergence or standard errors"

# The follow-up's cantilever cut at 0.17 m (w, theta) with a coarse 7-element physical tip: the beam
# splits element by element, but the seed's grounding gains on the cut's 1.3e-7 kg m^2 rotation make
# the one-sample-late grounding loop diverge (spectral radius 1.6e4): refused by name, nothing
# written (examples/cantilever_two_shakers.yaml scales the gains to the cut's masses).
cat > "$work/beam.yaml" <<'YAML'
structure:
  beam:
    segments: {length_m: [0.17, 0.36], elements: [17, 7], EI_n_m2: [0.459317, 0.459317],
               mass_per_length_kg_per_m: [0.19939, 0.19939]}
    clamped_m: [0]
    damping: {model: rayleigh, frequencies_hz: [3.0236, 18.9485], ratios: [0.011, 0.011]}
split:
  interface: [33, 34]
  mass_ratio: 0.5
  physical: [35, 36, 37, 38, 39, 40, 41, 42, 43, 44, 45, 46, 47, 48]
forcing: {dof: 47, amplitude_n: 0.01}
continuation: {start_hz: 2.5, end_hz: 3.5, method: natural}
YAML
refused frf "beam with the seed's grounding gains" \
    "grounding control destabilises the numerical substructure" "$work/beam.yaml"

[ "$failures" -eq 0 ] && echo "frf_two_interface: all checks passed" || { echo "frf_two_interface: $failures failure(s)"; exit 1; }
