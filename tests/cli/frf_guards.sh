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

# 2. --resume with another configuration: physics refused naming the key, nothing changed; an
# extended end frequency accepted and recorded in the journal
"$bin" frf "$lin" --out "$work/short" --quiet "${quiet[@]}" || fail "short run failed"
cp "$work/short/frf.csv" "$work/short.csv"
for change in split.mass_ratio=0.33 rig.seed=99 forcing.amplitude_n=2 continuation.start_hz=12.5; do
    "$bin" frf "$lin" --out "$work/short" --quiet --resume "${quiet[@]}" --set "$change" \
        2>"$work/short.err"
    rc=$?
    [ "$rc" -eq 2 ] || fail "resume with $change: exit $rc, expected 2"
    grep -q "key '${change%%=*}' was" "$work/short.err" || fail "resume with $change: $(cat "$work/short.err")"
done
cmp -s "$work/short/frf.csv" "$work/short.csv" || fail "a refused resume touched frf.csv"
"$bin" frf "$lin" --out "$work/short" --quiet --resume "${quiet[@]}" \
    --set continuation.end_hz=12.9 || fail "resume with a longer range refused"
[ "$(wc -l <"$work/short/frf.csv")" -gt "$(wc -l <"$work/short.csv")" ] || fail "no points added"
grep -q '"type":"resume".*continuation.end_hz: 12.8 -> 12.9' "$work/short/journal.jsonl" \
    || fail "the allowed change is not in the journal"
[ "$failures" -eq 0 ] && echo "ok   resume: physics change refused, longer range accepted"

# the noise seed given on the command line is part of the measurement too
"$bin" frf "$lin" --out "$work/seeded" --quiet --seed 7 "${quiet[@]}" || fail "seeded run failed"
for other in "--seed 8" ""; do
    # shellcheck disable=SC2086
    "$bin" frf "$lin" --out "$work/seeded" --quiet --resume $other "${quiet[@]}" 2>"$work/seed.err"
    rc=$?
    [ "$rc" -eq 2 ] || fail "resume with '${other:-no seed}': exit $rc, expected 2"
    grep -q "started with --seed 7" "$work/seed.err" || fail "seed message: $(cat "$work/seed.err")"
done
"$bin" frf "$lin" --out "$work/seeded" --quiet --resume --seed 7 "${quiet[@]}" \
    || fail "resume with the same seed refused"
[ "$failures" -eq 0 ] && echo "ok   resume: another --seed refused"

# 3. a folder in use: a long run holds DIR/run.lock; a second run into DIR is refused (exit 2,
# naming the holder's pid), and so is a --resume of it
"$bin" frf "$lin" --out "$work/busy" --quiet --set continuation.start_hz=12 \
    --set continuation.end_hz=14 --set continuation.max_step_hz=0.005 \
    --set continuation.initial_step_hz=0.005 &
holder=$!
for _ in $(seq 1 400); do
    [ -s "$work/busy/journal.jsonl" ] && break
    sleep 0.05
done
for mode in fresh resume; do
    extra=()
    [ $mode = resume ] && extra=(--resume)
    "$bin" frf "$lin" --out "$work/busy" --quiet "${extra[@]}" 2>"$work/busy.err"
    rc=$?
    [ "$rc" -eq 2 ] || fail "$mode run into a busy folder: exit $rc, expected 2"
    grep -q "in use by another rths run (pid $holder)" "$work/busy.err" \
        || fail "$mode: message does not name pid $holder: $(cat "$work/busy.err")"
done
kill "$holder" 2>/dev/null
wait "$holder" 2>/dev/null
[ "$failures" -eq 0 ] && echo "ok   busy folder -> exit 2 naming pid $holder"

[ "$failures" -eq 0 ] && echo ok
exit "$failures"
