#!/usr/bin/env bash
# How a sweep ends, and that it says so (issue 24.15, 24.16):
# 1. a pseudo-arclength sweep that cannot pass the first mode within the stroke limit (the control
#    target would exceed controller.limits.displacement_m, 0.01 m, at 0.25 N near 4.34 Hz) stops
#    short of its end: exit 1, naming where it stopped and the cause (the displacement limit),
#    with everything accepted saved; summary.json says stopped_short.
# 2. a sweep ended by continuation.max_points (the user's limit) still exits 0.
# 3. a sweep below controller.min_frequency_hz is refused at load: exit 2, nothing written.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
lin="$src/examples/four_storey_linear.yaml"

"$bin" frf "$lin" --out "$work/short" --quiet --set forcing.amplitude_n=0.25 \
    --set continuation.start_hz=4.2 --set continuation.end_hz=5 \
    --set continuation.method=arclength --set rig.noise=false 2>"$work/short.err"
rc=$?
[ "$rc" -eq 1 ] || fail "sweep stopped by the stroke limit: exit $rc, expected 1"
grep -q "the sweep stopped at 4\.3[0-9]* Hz, short of its end 5 Hz" "$work/short.err" ||
    fail "no 'stopped short' message: $(cat "$work/short.err")"
grep -q "beyond the displacement limit 0.01 m (controller.limits.displacement_m)" "$work/short.err" ||
    fail "the cause (the displacement limit) is not named: $(cat "$work/short.err")"
grep -q '"stopped_short": true' "$work/short/summary.json" || fail "summary.json: stopped_short"
grep -q '"stop_reason": ".*displacement limit' "$work/short/summary.json" || fail "summary.json: cause"
grep -q "finished with status 1: the sweep stopped at" "$work/short/run.log" || fail "run.log: status"
rows=$(($(wc -l <"$work/short/frf.csv") - 1))
[ "$rows" -gt 10 ] || fail "the accepted points were not saved ($rows rows)"
[ -e "$work/short/run.lock" ] && fail "run.lock left in the finished folder"
[ "$failures" -eq 0 ] && echo "ok   stopped short by the stroke limit: exit 1, $rows points saved, cause named"

"$bin" frf "$lin" --out "$work/limit" --quiet --set rig.noise=false \
    --set continuation.start_hz=12.6 --set continuation.end_hz=12.9 \
    --set continuation.max_points=3 || fail "a sweep ended by max_points: exit $?"
grep -q '"stopped_short": false' "$work/limit/summary.json" || fail "max_points: stopped_short"
[ "$failures" -eq 0 ] && echo "ok   the point limit is the user's: exit 0"

refused frf "below controller.min_frequency_hz" \
    "continuation.start_hz.*0.001 Hz is below controller.min_frequency_hz \(0.1 Hz\)" "$lin" \
    --set continuation.start_hz=0.001

[ "$failures" -eq 0 ] && echo ok
exit "$failures"
