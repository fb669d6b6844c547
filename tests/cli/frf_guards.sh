#!/usr/bin/env bash
# Runs that must not mix or pass as success: a run that accepts no point fails (exit 1, no
# "max deviation" line); --resume refuses a configuration that changes the physics or the
# measurement (naming the key) and accepts an extended end_hz (recorded in the journal); a second
# rths frf into a folder in use is refused with exit 2 naming the holder's pid.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
lin="$src/examples/four_storey_linear.yaml"
quiet=(--set rig.noise=false --set continuation.start_hz=12.6 --set continuation.end_hz=12.8)

# 1. no point accepted: one iteration against an unreachable tolerance, no retry
"$bin" frf "$lin" --out "$work/none" "${quiet[@]}" --set iteration.max_iterations=1 \
    --set iteration.rel_tolerance=1e-9 --set iteration.abs_tolerance_m=0 \
    --set continuation.max_failures=0 >"$work/none.out" 2>"$work/none.err"
rc=$?
[ "$rc" -eq 1 ] || fail "no point accepted: exit $rc, expected 1"
grep -q "no point was accepted" "$work/none.err" || fail "no-point message: $(cat "$work/none.err")"
grep -q "max deviation" "$work/none.out" && fail "a run without points printed a deviation"
[ -f "$work/none/summary.json" ] || fail "the failed run's summary.json is missing"
[ "$failures" -eq 0 ] && echo "ok   no point accepted -> exit 1"

[ "$failures" -eq 0 ] && echo ok
exit "$failures"
