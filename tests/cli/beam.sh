#!/usr/bin/env bash
# rths model on a structure.beam configuration (examples/cantilever_strip.yaml): the assembled
# cantilever's first two natural frequencies equal the Euler-Bernoulli closed form
# omega_i = (beta_i L)^2 sqrt(EI / (m L^4)) to 1e-5 (53 cubic elements: mesh error
# (beta h)^4 / 1440 < 1e-9 for these modes); the Rayleigh damping gives 1.1 % on both.
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"

"$bin" model "$src/examples/cantilever_strip.yaml" --out "$work/m" --quiet ||
    fail "rths model on the beam example exited $?"
awk -F, -v EI=0.459317 -v m=0.19939 -v L=0.53 '
    NR == 1 { for (c = 1; c <= NF; c++) col[$c] = c; next }
    NR == 2 || NR == 3 {
        bl = NR == 2 ? 1.875104068711961 : 4.694091132974175
        exact = bl * bl * sqrt(EI / (m * L ^ 4)) / (2 * 3.141592653589793)
        f = $col["frequency_hz"]; z = $col["damping_ratio"]
        rel = (f - exact) / exact; if (rel < 0) rel = -rel
        printf "mode %d: %.6f Hz, closed form %.6f Hz (rel %.1e), damping %.4f\n", NR - 1, f, exact, rel, z
        if (rel > 1e-5) bad = 1
        dz = z - 0.011; if (dz < 0) dz = -dz
        if (dz > 1e-4) bad = 1
    }
    END { exit bad }' "$work/m/modes.csv" || fail "beam modes differ from the closed form"

# the figure: rotations on their own right-hand radian axis, never on the metres axis; each mode
# line labelled with its frequency from modes.csv
awk '/using/ && /θ_/ && !/axes x1y2/ { print; bad = 1 } END { exit bad }' "$work/m/true_frf.gp" ||
    fail "true_frf.gp draws a rotation on the displacement axis"
grep -q "set y2label 'Rotation amplitude (rad)'" "$work/m/true_frf.gp" ||
    fail "true_frf.gp has no rotation axis"
f2=$(awk -F, 'NR == 3 { printf "%.4f", $2 }' "$work/m/modes.csv")
grep -q "set label 'mode 2: $f2 Hz'" "$work/m/true_frf.gp" ||
    fail "true_frf.gp does not label mode 2 ($f2 Hz)"

# the two-shaker example (3 + 6 elements; rig.actuators and rig.lasers are read by every command's
# setup, the rest of rig only by frf): rths model runs, and the coarse mesh's first mode is the
# closed form's to 1e-5 (measured 1.4e-6; mesh error (beta h)^4 / 1440 with h = 0.06 m)
"$bin" model "$src/examples/cantilever_two_shakers.yaml" --out "$work/two" --quiet ||
    fail "rths model on the two-shaker example exited $?"
awk -F, -v EI=0.459317 -v m=0.19939 -v L=0.53 '
    NR == 1 { for (c = 1; c <= NF; c++) col[$c] = c; next }
    NR == 2 {
        exact = 1.875104068711961 ^ 2 * sqrt(EI / (m * L ^ 4)) / (2 * 3.141592653589793)
        rel = ($col["frequency_hz"] - exact) / exact; if (rel < 0) rel = -rel
        printf "two-shaker mesh: mode 1 %.7f Hz, closed form %.7f Hz (rel %.1e)\n", $col["frequency_hz"], exact, rel
        exit rel > 1e-5
    }' "$work/two/modes.csv" || fail "two-shaker mesh: mode 1 off the closed form"

# two structure forms at once are refused at the key, nothing written
cat >"$work/two.yaml" <<'YAML'
structure:
  storeys: {mass_kg: [1], damping_n_s_per_m: [1], stiffness_n_per_m: [100]}
  beam:
    segments: {length_m: [1], elements: [2], EI_n_m2: [1], mass_per_length_kg_per_m: [1]}
    clamped_m: [0]
split: {interface: [1], mass_ratio: 0.5}
forcing: {dof: 1, amplitude_n: 1}
YAML
refused model "storeys and beam" "two.yaml:[0-9]+:[0-9]+: key 'structure.beam'.*not both" "$work/two.yaml"

[ "$failures" -eq 0 ] && echo "beam: all checks passed" || { echo "beam: $failures failure(s)"; exit 1; }
