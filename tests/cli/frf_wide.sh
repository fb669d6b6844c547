#!/usr/bin/env bash
# Wide sweeps (issue 18): the seed building over 3-25 Hz at 0.25 N, noise on, by natural and by
# pseudo-arclength continuation. Every point lies within the requested range, the run reaches
# its end through all three modes in the range, >= 95 % of the points lie within 3 standard
# errors of the analytic FRF at their frequency (rths's truth, the assembly solved without the
# hybrid loop), and no point with an honest standard error lies beyond 6 (3 SE "by more than a
# factor 2"). Also: rig.noise takes the laboratory preset `lab` and refuses other words.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
lin="$src/examples/four_storey_linear.yaml"
wide=(--quiet --set continuation.start_hz=3 --set continuation.end_hz=25
    --set forcing.amplitude_n=0.25)

# value of a top-level number in summary.json
json() { sed -n "s/^ *\"$2\": *\([-0-9.eE+]*\),\{0,1\}$/\1/p" "$1" | head -n 1; }

check_sweep() {
    local name=$1 dir=$2
    local s="$dir/summary.json" csv="$dir/frf.csv"
    [ -f "$s" ] || { fail "$name: no summary.json"; return; }
    grep -q '"reached_end": true' "$s" || fail "$name: did not reach 25 Hz: $(grep stop_reason "$s")"
    # within the range: the reported frequency of every point in [3, 25] Hz (to rounding)
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
             { f = $col["frequency_hz"]; if (f < 3 - 1e-9 || f > 25 + 1e-9) { print f; bad = 1 } }
             END { exit bad }' "$csv" >"$work/out_of_range" ||
        fail "$name: points outside 3-25 Hz: $(head -3 "$work/out_of_range" | tr '\n' ' ')"
    # the first mode (4.34 Hz), the second (13.47 Hz) and the third (21.82 Hz) are passed: points
    # on both sides of each
    for f in 4.3392 13.4731 21.8194; do
        awk -F, -v f=$f 'NR > 1 && $2 < f { lo = 1 } NR > 1 && $2 > f { hi = 1 } END { exit !(lo && hi) }' \
            "$csv" || fail "$name: no points on both sides of the mode at $f Hz"
    done
    local n within zmax
    n=$(json "$s" points_compared_with_truth)
    within=$(json "$s" points_within_3_standard_errors)
    zmax=$(json "$s" max_deviation_in_standard_errors)
    # 95 % is the issue's acceptance; with ~350-450 points the binomial spread of a true 99.7 %
    # coverage is 0.3 %, so falling below 95 % is not chance
    awk -v w="$within" -v n="$n" 'BEGIN { exit !(n >= 100 && w >= 0.95 * n) }' ||
        fail "$name: $within of $n points within 3 standard errors (< 95 %)"
    awk -v z="$zmax" 'BEGIN { exit !(z <= 6) }' ||
        fail "$name: a point with an honest standard error lies $z standard errors off"
    [ "$failures" -eq 0 ] && echo "ok   $name: $n points, $within within 3 SE, largest $zmax SE"
}

"$bin" frf "$lin" --out "$work/natural" "${wide[@]}" --set continuation.method=natural ||
    fail "natural sweep failed"
check_sweep "natural 3-25 Hz" "$work/natural"

# Pseudo-arclength resolves the first mode's peak (Q = 440), where the target that makes the
# interface match is 10.0 mm (the physical response is 7.4 mm; the PD loop's gain there is below
# one): past the default 10 mm displacement limit, so the sweep allows 20 mm. Steps of up to 0.1
# (relative amplitude or 2.2 Hz) keep the run short.
"$bin" frf "$lin" --out "$work/arclength" "${wide[@]}" --set continuation.method=arclength \
    --set controller.limits.displacement_m=0.02 --set continuation.max_step=0.1 \
    --set continuation.max_points=1500 || fail "arclength sweep failed"
check_sweep "arclength 3-25 Hz" "$work/arclength"

# the laboratory noise preset: accepted (and noisier than the default rig); other words refused
"$bin" frf "$lin" --out "$work/lab" --quiet --set rig.noise=lab --set continuation.start_hz=12.9 \
    --set continuation.end_hz=13.0 || fail "rig.noise=lab refused"
"$bin" frf "$lin" --out "$work/default" --quiet --set continuation.start_hz=12.9 \
    --set continuation.end_hz=13.0 || fail "default noise run failed"
se_lab=$(awk -F, 'NR == 2 { print $21 }' "$work/lab/frf.csv")
se_default=$(awk -F, 'NR == 2 { print $21 }' "$work/default/frf.csv")
# ten times the sensor noise: the first point's standard error several times larger
awk -v a="$se_lab" -v b="$se_default" 'BEGIN { exit !(a > 3 * b) }' ||
    fail "rig.noise=lab: first point's SE $se_lab m not above 3x the default's $se_default m"
refused frf "rig.noise=loud" "rig.noise" "$lin" --set rig.noise=loud
exit $((failures > 0))
