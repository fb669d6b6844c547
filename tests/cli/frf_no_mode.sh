#!/usr/bin/env bash
# Before arming, rths frf says when no mode of the true assembly lies in the sweep, naming the
# nearest one (the seed's modes: 4.339, 13.473, 21.819, 27.367 Hz), on stderr and in run.log; a
# sweep across mode 2, or just above it within three half-power bandwidths (13.5 Hz: 0.027 Hz
# above, bandwidth 0.095 Hz), gets no such warning, nor does the bilinear example (its
# resonance moves with the amplitude).
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
cfg="$src/examples/four_storey_linear.yaml"
short=(--set continuation.initial_step_hz=0.1 --set continuation.max_step_hz=0.1 --quiet)
"$bin" frf "$cfg" --set continuation.start_hz=7 --set continuation.end_hz=7.2 "${short[@]}" \
    --out "$work/off" 2>"$work/off_stderr" || fail "off-resonance sweep: exit $?"
re='no mode of the true assembly lies in the sweep \[7, 7.2\] Hz \(nearest: mode 1 at 4.339 Hz\)'
grep -Eq "^rths frf: warning: $re" "$work/off_stderr" || fail "stderr: $(cat "$work/off_stderr")"
grep -Eq "warning: $re" "$work/off/run.log" || fail "run.log: $(cat "$work/off/run.log")"
"$bin" frf "$cfg" --set continuation.start_hz=13.4 --set continuation.end_hz=13.5 "${short[@]}" \
    --out "$work/on" 2>"$work/on_stderr" || fail "sweep across mode 2: exit $?"
grep -q "no mode" "$work/on_stderr" "$work/on/run.log" && fail "warned on a sweep across mode 2"
"$bin" frf "$cfg" --set continuation.start_hz=13.5 --set continuation.end_hz=13.6 "${short[@]}" \
    --out "$work/near" 2>"$work/near_stderr" || fail "sweep near mode 2: exit $?"
grep -q "no mode" "$work/near_stderr" && fail "warned on a sweep 0.027 Hz above mode 2"
"$bin" frf "$src/examples/four_storey_bilinear.yaml" --set continuation.max_points=2 --quiet \
    --out "$work/bilinear" 2>"$work/bilinear_stderr"
grep -q "no mode" "$work/bilinear_stderr" && fail "warned on the bilinear example"
[ "$failures" -eq 0 ] && echo "frf_no_mode: all checks passed" || exit 1
