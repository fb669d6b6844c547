#!/usr/bin/env bash
# Folds under noise (issue 27): the Duffing spring on the numerical side of the two-interface
# building (examples/two_interface_duffing.yaml) with the rig's default noise, in both numerical
# forms. Near each fold the branch stands vertical, the corrector's noisy mismatch moves the
# points' frequencies, and the continuation reverses by a few tenths of a mHz: the fold tracker
# (src/continuation/fold.c) reports a fold only when the frequency comes back from its extreme
# beyond the points' local frequency scatter, on two consecutive points. Exactly the truth's two
# folds, each within 2 mHz of the truth's turning points (before: 7 folds in real time, 6 in the
# frequency form). Noise off the fold results are unchanged (frf_duffing_two_interface.sh,
# frf_nonlinear_numerical.sh).
# The frequency form's standard errors there: at least the points' scatter about the branch near
# each (src/run/frf.c, frf_branch_scatter_floor), so >= 95 % of the points away from folds lie
# within 3 standard errors of the truth (before: 45 of 52, the misses 0.15-0.4 % off with
# standard errors of 0.03-0.1 %).
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

check_folds() { # run folder, label
    local s="$1/summary.json" truth_folds run_folds
    truth_folds=$(awk -F, 'NR > 1 { f = $1; if (n >= 2 && (p1 - p0) * (f - p1) < 0) printf "%s ", p1;
        p0 = p1; p1 = f; n++ }' "$1/truth.csv")
    run_folds=$(tr -d '\n ' < "$s" | grep -o '"folds":\[[^]]*\]' |
        grep -o '"frequency_hz":[0-9.e+-]*' | cut -d: -f2 | tr '\n' ' ')
    echo "$2: truth folds: $truth_folds; hybrid folds: $run_folds"
    awk -v t="$truth_folds" -v r="$run_folds" 'BEGIN {
        nt = split(t, tf, " "); nr = split(r, rf, " ");
        if (nt != 2 || nr != 2) { print "fold counts: truth " nt ", hybrid " nr; exit 1 }
        for (i = 1; i <= 2; i++) { d = rf[i] - tf[i]; if (d < 0) d = -d
            printf "fold %s Hz: %.2f mHz from the truth\n", rf[i], 1000 * d
            if (d > 0.002) exit 1 }
    }' || fail "$2: not exactly the truth's two folds within 2 mHz"
}

"$bin" frf "$src/examples/two_interface_duffing.yaml" --out "$work/realtime" --quiet \
    2>/dev/null || fail "real-time run failed"
check_folds "$work/realtime" "real-time form"
"$bin" frf "$src/examples/two_interface_duffing.yaml" --out "$work/frequency" --quiet \
    --set split.numerical_solver=frequency 2>/dev/null || fail "frequency-form run failed"
check_folds "$work/frequency" "frequency form"
json() { sed -n "s/^ *\"$2\": *\"\{0,1\}\([^\",]*\)\"\{0,1\},\{0,1\}$/\1/p" "$1" | head -n 1; }
far=$(json "$work/frequency/summary.json" points_far_from_folds)
within=$(json "$work/frequency/summary.json" points_far_from_folds_within_3_standard_errors)
echo "frequency form: $within of $far points away from folds within 3 standard errors"
[ "$far" -ge 40 ] && [ $((100 * within)) -ge $((95 * far)) ] ||
    fail "frequency form: $within of $far points away from folds within 3 standard errors"
echo "ok"
