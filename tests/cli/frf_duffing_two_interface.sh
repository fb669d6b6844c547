#!/usr/bin/env bash
# Issue 27: a Duffing spring on the numerical side of the two-interface building
# (examples/two_interface_duffing.yaml) in the frequency form (split.numerical_solver: frequency,
# the host's harmonic balance of the numerical side every period; the real-time form of the same
# example: frf_nonlinear_numerical.sh). Noise off, pseudo-arclength through both folds: both folds
# within 2 mHz of the truth's turning points (truth.csv, the shooting curve, which test_truth_hb
# checks against harmonic balance to 1e-5), every point within 0.5 % of the truth, the stability
# labels right at >= 95 % of the points.
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
json() { sed -n "s/^ *\"$2\": *\"\{0,1\}\([^\",]*\)\"\{0,1\},\{0,1\}$/\1/p" "$1" | head -n 1; }

"$bin" frf "$src/examples/two_interface_duffing.yaml" --out "$work/run" --quiet \
    --set rig.noise=false --set split.numerical_solver=frequency 2>/dev/null || fail "run failed"
s="$work/run/summary.json"
# the two interface storeys and storey 4 kept (the spring's DoFs), nothing condensed
grep -q "25 harmonics, 512 time samples per period (AFT), 3 DoF(s) kept" "$work/run/run.log" ||
    fail "run.log does not describe the harmonic balance"
# no modes for a nonlinear structure, and the log names its element (not "a bilinear leg")
grep -q "no modal.csv: a cubic element's response depends on its amplitude" "$work/run/run.log" ||
    fail "run.log does not say why there is no modal.csv: $(grep 'modal' "$work/run/run.log")"
# the truth curve of both interface DoFs (the figure draws each)
head -n 1 "$work/run/truth.csv" | grep -q "dof2_amplitude_m" ||
    fail "truth.csv has no dof2_amplitude_m: $(head -n 1 "$work/run/truth.csv")"
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
echo "ok"
