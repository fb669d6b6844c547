#!/usr/bin/env bash
# rths frf end to end on the virtual rig: columns and summary, paper vs default strategies,
# harmonics 1-3 cut the higher-harmonic interface error, a rig fault and a bad configuration end
# the run cleanly (exit 1 with everything accepted saved; exit 2 with nothing written).
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
lin="$src/examples/four_storey_linear.yaml"
bil="$src/examples/four_storey_bilinear.yaml"
json() { sed -n "s/^ *\"$2\": *\"\{0,1\}\([^\",]*\)\"\{0,1\},\{0,1\}$/\1/p" "$1" | head -n 1; }

# 1. default and paper strategies on a short linear range, noise off
for s in default paper; do
    "$bin" frf "$lin" --out "$work/$s" --quiet --strategy $s --set rig.noise=false \
        --set continuation.start_hz=12.9 --set continuation.end_hz=13.2 || fail "$s run failed"
    head -n 1 "$work/$s/frf.csv" | grep -q '^point,frequency_hz,amplitude_m,numerical_amplitude_m,phase_rad,interface_error_m' \
        || fail "$s: frf.csv header"
    for k in points converged_points evaluations_total rig_time_s wall_time_s strategy; do
        [ -n "$(json "$work/$s/summary.json" $k)" ] || fail "$s: summary.json lacks $k"
    done
    grep -q '"folds"' "$work/$s/summary.json" || fail "$s: no folds list"
    [ "$(json "$work/$s/summary.json" points)" = "$(json "$work/$s/summary.json" converged_points)" ] \
        || fail "$s: unconverged points"
    for f in frf.png iterations.png lissajous.png truth.csv trace.csv journal.jsonl config.yaml run.log; do
        [ -s "$work/$s/$f" ] || fail "$s: $f missing"
    done
done
# the default strategy is at least as accurate as the paper's implicit-Euler substructure
awk -v d="$(json "$work/default/summary.json" max_relative_error_vs_truth)" \
    -v p="$(json "$work/paper/summary.json" max_relative_error_vs_truth)" \
    'BEGIN { print "max error vs truth: default " d ", paper " p; exit !(d < 0.01 && d <= p) }' \
    || fail "default strategy not within 1 % / not better than paper"

# 1b. the acceptance run: the linear example, 12-14 Hz, default sensor noise (seed 1), three p.
# Every point converges and lies within 1 % of the analytic FRF; the reported standard errors are
# honest: at least 97 % of the points lie within 3 of them (a Gaussian would put 99.7 % there; the
# standard errors come from a few periods each, so their own scatter widens the tails).
total=0; inside=0
for p in 0.33 0.5 0.67; do
    "$bin" frf "$lin" --out "$work/noisy_p$p" --quiet --set split.mass_ratio=$p || fail "p = $p run failed"
    sj="$work/noisy_p$p/summary.json"
    n=$(json "$sj" points); c=$(json "$sj" converged_points); w=$(json "$sj" points_within_3_standard_errors)
    [ "$n" -ge 40 ] && [ "$n" = "$c" ] || fail "p = $p: $c of $n points converged"
    awk -v e="$(json "$sj" max_relative_error_vs_truth)" -v p=$p -v w="$w" -v n="$n" \
        'BEGIN { printf "p = %s: max error vs analytic FRF %.3f %%, %d of %d within 3 SE\n", p, 100 * e, w, n; exit !(e < 0.01) }' \
        || fail "p = $p: not within 1 % of the analytic FRF"
    total=$((total + n)); inside=$((inside + w))
done
[ $((100 * inside)) -ge $((97 * total)) ] || fail "only $inside of $total points within 3 standard errors"

# 2. harmonics: on the large-amplitude branch of the bilinear test (right of the folds, single
#    valued) the 2nd/3rd harmonic mismatch left by matching the fundamental alone is cut at
#    least tenfold by matching harmonics 1-3
for n in 1 3; do
    "$bin" frf "$bil" --out "$work/h$n" --quiet --harmonics $n --set rig.noise=false \
        --set continuation.method=natural --set continuation.start_hz=14.4 \
        --set continuation.end_hz=14.1 --set continuation.initial_step_hz=0.05 || fail "harmonics $n"
done
awk -v a="$(json "$work/h1/summary.json" max_interface_error_h2_m)" \
    -v b="$(json "$work/h3/summary.json" max_interface_error_h2_m)" \
    -v c="$(json "$work/h1/summary.json" max_interface_error_h3_m)" \
    -v d="$(json "$work/h3/summary.json" max_interface_error_h3_m)" \
    'BEGIN { print "2nd harmonic error " a " -> " b " m, 3rd " c " -> " d " m"; exit !(b * 10 <= a && d * 10 <= c) }' \
    || fail "matching 3 harmonics did not cut the 2nd/3rd harmonic error tenfold"

# 3. a rig fault (a force limit far too low) ends the run with exit 1, points kept
"$bin" frf "$lin" --out "$work/fault" --quiet --set rig.noise=false --set controller.limits.force_n=0.5 \
    --set continuation.start_hz=13.2 --set continuation.end_hz=13.5 2>"$work/fault.err"
rc=$?
[ $rc -eq 1 ] || fail "rig fault: exit $rc, expected 1"
grep -q "force limit" "$work/fault.err" || fail "rig fault message: $(cat "$work/fault.err")"
[ -f "$work/fault/frf.csv" ] && [ -f "$work/fault/summary.json" ] || fail "rig fault: results not saved"
grep -q '"stop_reason": "virtual rig fault' "$work/fault/summary.json" || fail "rig fault: stop_reason"

# 4. bad input: exit 2 and nothing written
"$bin" frf "$lin" --out "$work/bad1" --set continuation.method=spline 2>"$work/bad.err"
[ $? -eq 2 ] && [ ! -e "$work/bad1" ] || fail "bad continuation.method accepted"
grep -q "continuation.method" "$work/bad.err" || fail "message does not name the key"
"$bin" frf "$lin" --out "$work/bad2" --harmonics 7 2>/dev/null
[ $? -eq 2 ] && [ ! -e "$work/bad2" ] || fail "--harmonics 7 accepted"
"$bin" frf "$lin" --out "$work/bad3" --strategy fastest 2>/dev/null
[ $? -eq 2 ] && [ ! -e "$work/bad3" ] || fail "--strategy fastest accepted"
"$bin" frf "$lin" --out "$work/bad4" --set rig.shaker.delay_s=-1 2>/dev/null
[ $? -eq 2 ] && [ ! -e "$work/bad4" ] || fail "negative shaker delay accepted"
"$bin" frf --help | grep -q -- "--strategy" || fail "--help"
echo ok
