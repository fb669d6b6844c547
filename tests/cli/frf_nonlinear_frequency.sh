#!/usr/bin/env bash
# Issue 27: the seed's bilinear leg on the numerical side (examples/four_storey_bilinear_numerical.yaml)
# with split.numerical_solver: frequency: the host solves the numerical substructure by harmonic
# balance every period (docs/method.md, "Nonlinear elements in the frequency form"). Noise off, a
# narrow band over both folds by pseudo-arclength: both folds found, each within 2 mHz of the
# shooting truth's turning points (truth.csv), every point within 0.5 % of the truth, the stability
# labels equal to the truth's Floquet stability at >= 95 % of the points; the harmonic balance's
# harmonics and time samples in run.log. Then elements on both sides at once in the frequency
# form: the seed's bilinear leg on the rig (the plant) and a cubic spring between storeys 3 and 4
# on the host's numerical side, likewise against the shooting truth.
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
ex="$src/examples/four_storey_bilinear_numerical.yaml"
json() { sed -n "s/^ *\"$2\": *\"\{0,1\}\([^\",]*\)\"\{0,1\},\{0,1\}$/\1/p" "$1" | head -n 1; }

"$bin" frf "$ex" --out "$work/run" --quiet --set rig.noise=false --set split.numerical_solver=frequency \
    --set continuation.start_hz=14.94 --set continuation.end_hz=15.0 || fail "run failed"
s="$work/run/summary.json"
grep -q "harmonic balance of the numerical substructure: 25 harmonics, 512 time samples per period" \
    "$work/run/run.log" || fail "run.log does not name the harmonic balance's harmonics and samples"
grep -q "periods converted" "$work/run/run.log" || fail "run.log does not count the conversions"
truth_folds=$(awk -F, 'NR > 1 { f = $1; if (n >= 2 && (p1 - p0) * (f - p1) < 0) printf "%s ", p1;
    p0 = p1; p1 = f; n++ }' "$work/run/truth.csv")
run_folds=$(tr -d '\n ' < "$s" | grep -o '"folds":\[[^]]*\]' | grep -o '"frequency_hz":[0-9.e+-]*' |
    cut -d: -f2 | tr '\n' ' ')
echo "truth folds: $truth_folds; hybrid folds: $run_folds"
awk -v t="$truth_folds" -v r="$run_folds" 'BEGIN {
    nt = split(t, tf, " "); nr = split(r, rf, " ");
    if (nt != 2 || nr != 2) { print "fold counts: truth " nt ", hybrid " nr; exit 1 }
    for (i = 1; i <= 2; i++) { best = 1e9
        for (j = 1; j <= 2; j++) { d = rf[i] - tf[j]; if (d < 0) d = -d; if (d < best) best = d }
        printf "fold %s Hz: %.2f mHz from the truth\n", rf[i], 1000 * best
        if (best > 0.002) exit 1 }
}' || fail "folds not within 2 mHz of the truth"
err=$(json "$s" max_relative_error_vs_truth)
awk -v e="$err" 'BEGIN { print "max error vs truth " e; exit !(e < 0.005) }' \
    || fail "a point beyond 0.5 % of the truth"
cmp=$(json "$s" stability_points_compared)
agree=$(json "$s" stability_points_agreeing)
echo "stability labels: $agree of $cmp agree with the truth"
[ "$cmp" -ge 10 ] && [ $((100 * agree)) -ge $((95 * cmp)) ] ||
    fail "stability labels: $agree of $cmp agree with the truth"

# both sides at once: the truth's folds at 14.035594 and 14.003901 Hz (shooting)
"$bin" frf "$src/examples/four_storey_bilinear.yaml" --out "$work/both" --quiet \
    --set rig.noise=false --set split.numerical_solver=frequency \
    --set continuation.start_hz=13.95 --set continuation.end_hz=14.1 \
    --set 'structure.nonlinear=[{type: cubic, dofs: [4, 3], stiffness_n_per_m3: 3e8}]' \
    2>/dev/null || fail "both sides: run failed"
s="$work/both/summary.json"
truth_folds=$(awk -F, 'NR > 1 { f = $1; if (n >= 2 && (p1 - p0) * (f - p1) < 0) printf "%s ", p1;
    p0 = p1; p1 = f; n++ }' "$work/both/truth.csv")
run_folds=$(tr -d '\n ' < "$s" | grep -o '"folds":\[[^]]*\]' | grep -o '"frequency_hz":[0-9.e+-]*' |
    cut -d: -f2 | tr '\n' ' ')
echo "both sides: truth folds $truth_folds; hybrid folds $run_folds"
awk -v t="$truth_folds" -v r="$run_folds" 'BEGIN {
    nt = split(t, tf, " "); nr = split(r, rf, " ");
    if (nt != 2 || nr != 2) { print "fold counts: truth " nt ", hybrid " nr; exit 1 }
    for (i = 1; i <= 2; i++) { best = 1e9
        for (j = 1; j <= 2; j++) { d = rf[i] - tf[j]; if (d < 0) d = -d; if (d < best) best = d }
        printf "fold %s Hz: %.2f mHz from the truth\n", rf[i], 1000 * best
        if (best > 0.002) exit 1 }
}' || fail "both sides: folds not within 2 mHz of the truth"
err=$(json "$s" max_relative_error_vs_truth)
awk -v e="$err" 'BEGIN { print "both sides: max error vs truth " e; exit !(e < 0.005) }' \
    || fail "both sides: a point beyond 0.5 % of the truth"
cmp=$(json "$s" stability_points_compared)
agree=$(json "$s" stability_points_agreeing)
echo "both sides: stability labels: $agree of $cmp agree with the truth"
[ "$cmp" -ge 10 ] && [ $((100 * agree)) -ge $((95 * cmp)) ] ||
    fail "both sides: stability labels: $agree of $cmp agree with the truth"
echo "ok"
