#!/usr/bin/env bash
# The fitted evaluation end to end (docs/method.md, "The fitted evaluation"): the two-shaker
# cantilever around its first mode, noise off, with iteration.settle.strategy wait and fit. The
# cut's tip rings in its own first mode (6.5 Hz, 0.8 % damping, 3.2 s time constant) after every
# step of the target, which waiting must let decay; the fit separates it. Asserted: every point
# converged both ways, the fit within 0.1 % of the analytic FRF on both interface DoFs (the
# acceptance of the cantilever noise off) in less than half the waiting's rig time (measured on
# the whole example: 38.8 s per point waiting, about 10 s fitted); a bad strategy is refused
# naming the key (exit 2).
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
cant="$src/examples/cantilever_two_shakers.yaml"
json() { sed -n "s/^ *\"$2\": *\"\{0,1\}\([^\",]*\)\"\{0,1\},\{0,1\}$/\1/p" "$1" | head -n 1; }

for s in wait fit; do
    "$bin" frf "$cant" --out "$work/$s" --quiet --set rig.noise=off \
        --set continuation.start_hz=2.96 --set continuation.end_hz=3.04 \
        --set iteration.settle.strategy=$s >"$work/$s.txt" 2>&1 || fail "$s run failed: $(cat "$work/$s.txt")"
    [ "$(json "$work/$s/summary.json" points)" = "$(json "$work/$s/summary.json" converged_points)" ] \
        || fail "$s: unconverged points"
done
wait_s=$(json "$work/wait/summary.json" rig_time_s)
fit_s=$(json "$work/fit/summary.json" rig_time_s)
awk -v w="$wait_s" -v f="$fit_s" 'BEGIN { exit !(f < 0.5 * w) }' \
    || fail "fit used $fit_s rig s against waiting's $wait_s (not less than half)"
# the worst relative error of every DoF (summary.json lists one per interface DoF)
errs=$(grep -o '"max_relative_error_vs_truth": [0-9.eE+-]*' "$work/fit/summary.json" | awk '{print $2}')
[ -n "$errs" ] || fail "fit: no max_relative_error_vs_truth"
for e in $errs; do
    awk -v e="$e" 'BEGIN { exit !(e < 1e-3) }' || fail "fit: a DoF $e off the analytic FRF (> 0.1 %)"
done
echo "cantilever 2.96-3.04 Hz noise off: rig s waiting $wait_s, fitted $fit_s; fitted errors $errs"

# a strategy that does not exist: refused with the key named, nothing run
"$bin" frf "$cant" --out "$work/bad" --quiet --set iteration.settle.strategy=guess >"$work/bad.txt" 2>&1
rc=$?
[ $rc -eq 2 ] || fail "bad strategy: exit $rc, not 2"
grep -q "iteration.settle.strategy" "$work/bad.txt" || fail "bad strategy: message does not name the key: $(cat "$work/bad.txt")"
echo "PASS"
