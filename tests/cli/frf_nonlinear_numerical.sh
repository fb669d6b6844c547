#!/usr/bin/env bash
# Issue 27: the seed's bilinear leg on the numerical side (examples/four_storey_bilinear_numerical.yaml),
# integrated by the controller's step every sample. Noise off, a narrow band over both folds by
# pseudo-arclength: both folds found, each within 2 mHz of the shooting truth's turning points
# (truth.csv), every point within 0.5 % of the truth (summary.json's distance measure), the
# stability labels (fold-based) equal to the truth's Floquet stability; elements on both sides at
# once (the rig's leg and a numerical cubic spring) likewise, and a Duffing spring on the
# numerical side of the two-interface building (the frequency form of the same leg:
# frf_nonlinear_frequency.sh).
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
ex="$src/examples/four_storey_bilinear_numerical.yaml"
json() { sed -n "s/^ *\"$2\": *\"\{0,1\}\([^\",]*\)\"\{0,1\},\{0,1\}$/\1/p" "$1" | head -n 1; }

"$bin" frf "$ex" --out "$work/run" --quiet --set rig.noise=false \
    --set continuation.start_hz=14.94 --set continuation.end_hz=15.0 || fail "run failed"
s="$work/run/summary.json"
# the truth's turning points: where truth.csv's frequency changes direction
truth_folds=$(awk -F, 'NR > 1 { f = $1; if (n >= 2 && (p1 - p0) * (f - p1) < 0) printf "%s ", p1;
    p0 = p1; p1 = f; n++ }' "$work/run/truth.csv")
run_folds=$(sed -n 's/.*"frequency_hz": \([0-9.e+-]*\), "amplitude_m".*/\1/p' "$s" | tr '\n' ' ')
[ -z "$run_folds" ] && run_folds=$(tr -d '\n ' < "$s" | grep -o '"folds":\[[^]]*\]' |
    grep -o '"frequency_hz":[0-9.e+-]*' | cut -d: -f2 | tr '\n' ' ')
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
[ "$cmp" -ge 10 ] && [ $((100 * agree)) -ge $((95 * cmp)) ] ||
    fail "stability labels: $agree of $cmp agree with the truth"

# elements on both sides at once: the seed's bilinear leg on the rig (plant) and a cubic spring
# between storeys 3 and 4 on the numerical side; the truth's folds at 14.035594 and 14.003901 Hz
# (shooting); noise off over both folds
bil="$src/examples/four_storey_bilinear.yaml"
"$bin" frf "$bil" --out "$work/both" --quiet --set rig.noise=false \
    --set continuation.start_hz=13.95 --set continuation.end_hz=14.1 \
    --set 'structure.nonlinear=[{type: cubic, dofs: [4, 3], stiffness_n_per_m3: 3e8}]' ||
    fail "both sides: run failed"
s="$work/both/summary.json"
folds=$(tr -d '\n ' < "$s" | grep -o '"folds":\[[^]]*\]' | grep -o '"frequency_hz":[0-9.e+-]*' |
    cut -d: -f2 | tr '\n' ' ')
echo "both sides: hybrid folds $folds"
awk -v r="$folds" 'BEGIN { n = split(r, f, " "); t[1] = 14.035594; t[2] = 14.003901
    if (n != 2) exit 1
    for (i = 1; i <= 2; i++) { d = f[i] - t[i]; if (d < 0) d = -d; if (d > 0.002) exit 1 } }' ||
    fail "both sides: folds $folds not within 2 mHz of 14.035594 and 14.003901 Hz"
err=$(json "$s" max_relative_error_vs_truth)
awk -v e="$err" 'BEGIN { print "both sides: max error vs truth " e; exit !(e < 0.005) }' ||
    fail "both sides: a point beyond 0.5 % of the truth"
cmp=$(json "$s" stability_points_compared)
agree=$(json "$s" stability_points_agreeing)
[ "$cmp" -ge 10 ] && [ $((100 * agree)) -ge $((95 * cmp)) ] ||
    fail "both sides: stability labels: $agree of $cmp agree with the truth"

# a Duffing spring (3e9 N/m^3 between storeys 3 and 4) on the numerical side of the
# two-interface building (storeys 2 and 3 the interface; examples/two_interface_duffing.yaml),
# real-time form, harmonics 1-2 (the corrector's bound at two interface DoFs): the truth's folds
# at 13.573056 and 13.568541 Hz
two="$src/examples/two_interface_duffing.yaml"
"$bin" frf "$two" --out "$work/duffing" --quiet --set rig.noise=false || fail "Duffing: run failed"
s="$work/duffing/summary.json"
folds=$(tr -d '\n ' < "$s" | grep -o '"folds":\[[^]]*\]' | grep -o '"frequency_hz":[0-9.e+-]*' |
    cut -d: -f2 | tr '\n' ' ')
echo "Duffing: hybrid folds $folds"
awk -v r="$folds" 'BEGIN { n = split(r, f, " "); t[1] = 13.573056; t[2] = 13.568541
    if (n != 2) exit 1
    for (i = 1; i <= 2; i++) { d = f[i] - t[i]; if (d < 0) d = -d; if (d > 0.002) exit 1 } }' ||
    fail "Duffing: folds $folds not within 2 mHz of 13.573056 and 13.568541 Hz"
err=$(json "$s" max_relative_error_vs_truth)
awk -v e="$err" 'BEGIN { print "Duffing: max error vs truth " e; exit !(e < 0.005) }' ||
    fail "Duffing: a point beyond 0.5 % of the truth"
cmp=$(json "$s" stability_points_compared)
agree=$(json "$s" stability_points_agreeing)
[ "$cmp" -ge 10 ] && [ $((100 * agree)) -ge $((95 * cmp)) ] ||
    fail "Duffing: stability labels: $agree of $cmp agree with the truth"

echo "ok"
