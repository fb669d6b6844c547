#!/usr/bin/env bash
# Runs that must not mix or pass as success: a run that accepts no point fails (exit 1, no
# "max deviation" line); --resume refuses a configuration that changes the physics or the
# measurement (naming the key) and accepts an extended end_hz (recorded in the journal); a second
# rths frf into a folder in use is refused with exit 2 naming the holder's pid.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
# the background runs below are stopped whatever the outcome (servers.sh's traps)
source "$src/tests/cli/lib/servers.sh"
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
servers+=($holder)
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
forget "$holder"
[ "$failures" -eq 0 ] && echo "ok   busy folder -> exit 2 naming pid $holder"

# 4. a journal without its header (killed between creating the file and writing the header):
# --resume refuses it by name, exit 2 (it crashed on a NULL strategy)
mkdir -p "$work/empty"
cp "$work/short/config.yaml" "$work/empty/config.yaml"
: >"$work/empty/journal.jsonl"
"$bin" frf "$lin" --out "$work/empty" --quiet --resume "${quiet[@]}" 2>"$work/empty.err"
rc=$?
[ "$rc" -eq 2 ] && grep -q "no header record" "$work/empty.err" ||
    fail "header-less journal: exit $rc, $(cat "$work/empty.err")"
[ "$failures" -eq 0 ] && echo "ok   header-less journal -> exit 2"

# 5. the journal records the rig the run measured on
grep -q '"rig":"virtual"' "$work/short/journal.jsonl" || fail "the journal's header names no rig"

# 6. a resume continues as the uninterrupted run would: a natural sweep keeps its grown step
# (12 points at once == 6 points + --resume to 12, frequencies to 1e-12), and replaying a
# journal finds the same folds (a finished bilinear run resumed: folds unchanged)
nat=(--set rig.noise=false --set continuation.method=natural --set continuation.start_hz=12.5
    --set continuation.initial_step_hz=0.02 --set continuation.max_step_hz=0.1)
"$bin" frf "$lin" --out "$work/nat12" --quiet "${nat[@]}" --set continuation.max_points=12 ||
    fail "natural 12-point run"
"$bin" frf "$lin" --out "$work/nat6" --quiet "${nat[@]}" --set continuation.max_points=6 ||
    fail "natural 6-point run"
"$bin" frf "$lin" --out "$work/nat6" --quiet --resume "${nat[@]}" \
    --set continuation.max_points=12 || fail "natural resume to 12"
/usr/bin/python3 - "$work/nat12/frf.csv" "$work/nat6/frf.csv" <<'PY' || fail "resumed grid differs"
import csv, sys
a, b = ([float(r["frequency_hz"]) for r in csv.DictReader(open(p))] for p in sys.argv[1:])
worst = max(abs(x - y) / x for x, y in zip(a, b)) if len(a) == len(b) else float("inf")
print(f"natural sweep, resumed vs uninterrupted: {len(b)} vs {len(a)} points, worst {worst:.1e}")
sys.exit(0 if len(a) == len(b) == 12 and worst < 1e-12 else 1)
PY
bil="$src/examples/four_storey_bilinear.yaml"
"$bin" frf "$bil" --out "$work/bil" --quiet --set rig.noise=false || fail "bilinear run"
mkdir -p "$work/bil2"
cp "$work/bil/config.yaml" "$work/bil/journal.jsonl" "$work/bil2/"
"$bin" frf "$bil" --out "$work/bil2" --quiet --resume --set rig.noise=false || fail "bilinear resume"
/usr/bin/python3 - "$work/bil/summary.json" "$work/bil2/summary.json" <<'PY' || fail "replayed folds differ"
import json, sys
a, b = (json.load(open(p))["folds"] for p in sys.argv[1:])
print(f"folds: run {[(f['frequency_hz']) for f in a]}, replayed {[(f['frequency_hz']) for f in b]}")
sys.exit(0 if a == b and len(a) == 2 else 1)
PY
[ "$failures" -eq 0 ] && echo "ok   resume continues as the uninterrupted run"

# 7. Ctrl-C (SIGINT) ends a run cleanly after the point in progress: exit 130, frf.csv and
# summary.json written with every journaled point, live.json "ended"; --resume finishes it.
# (A paced run, so the signal lands mid-sweep; the wait is for the journal, not a timing.)
# (12.6 -> 13.2 Hz at 5 x real time: about a second of wall time per point, so the signal sent once
# 3 points are journaled lands mid-sweep even on a loaded machine)
interrupt=(--set rig.noise=false --set continuation.start_hz=12.6 --set continuation.end_hz=13.2)
"$bin" frf "$lin" --out "$work/int" --quiet "${interrupt[@]}" --pace 5 2>"$work/int.err" &
pid=$!
servers+=($pid)
for _ in $(seq 1 300); do
    [ "$(wc -l <"$work/int/journal.jsonl" 2>/dev/null || echo 0)" -ge 4 ] && break
    sleep 0.1
done
kill -INT "$pid"
wait "$pid"
rc=$?
forget "$pid"
[ "$rc" -eq 130 ] || fail "interrupted run: exit $rc, expected 130 ($(cat "$work/int.err"))"
/usr/bin/python3 - "$work/int" <<'PY' || fail "interrupted run: outputs incomplete"
import csv, json, sys
d = sys.argv[1]
journal = [json.loads(l) for l in open(d + "/journal.jsonl")]
points = {r["index"] for r in journal if r.get("type") == "point"}
rows = list(csv.DictReader(open(d + "/frf.csv")))
s = json.load(open(d + "/summary.json"))
live = json.load(open(d + "/live.json"))
print(f"interrupted: {len(rows)} rows, {len(points)} journaled, stop: {s['stop_reason']}, live {live['state']}")
sys.exit(0 if len(rows) == len(points) == s["points"] > 0 and live["state"] == "ended" else 1)
PY
# the log says who stopped it and the status the command exits with (not "status 0")
grep -q "finished: stopped by the user (exit 130)" "$work/int/run.log" ||
    fail "interrupted run: run.log does not say the user stopped it: $(tail -n 2 "$work/int/run.log")"
grep -q '"stop_reason": "stopped by the user after' "$work/int/summary.json" ||
    fail "interrupted run: summary.json stop_reason"
[ -e "$work/int/run.lock" ] && fail "interrupted run: run.lock left behind"
"$bin" frf "$lin" --out "$work/int" --quiet --resume "${interrupt[@]}" || fail "resume after Ctrl-C"
[ "$failures" -eq 0 ] && echo "ok   Ctrl-C saves everything accepted, exit 130, resumable"

# 8. a test the model knows will exceed the rig's displacement limit (the seed's first mode at 1 N:
# 29.5 mm against 10 mm) is refused before anything is written; --force runs it, with a warning
refused frf "beyond the displacement limit" \
    "reaches 0.0295 m at 4.339 Hz.*controller.limits.displacement_m = 0.01 m.*--force" "$lin" \
    --set continuation.start_hz=3 --set continuation.end_hz=6
"$bin" frf "$lin" --out "$work/forced" --quiet --force --set continuation.start_hz=3 \
    --set continuation.end_hz=6 --set continuation.max_points=2 --set rig.noise=false \
    2>"$work/forced.err" || fail "--force: exit $?"
grep -q "warning: the true assembly's interface response reaches" "$work/forced/run.log" ||
    fail "--force: no warning in run.log"

[ "$failures" -eq 0 ] && echo ok
exit "$failures"
