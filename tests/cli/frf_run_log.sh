#!/usr/bin/env bash
# run.log shows a run's progress (issue 28): one line per accepted point (frequency, amplitude,
# its standard error, evaluations, rig time), written as the point is accepted, so `tail -f
# run.log` under nohup follows the run.
# 1. A paced run (5 x real time) interrupted by Ctrl-C once two points are journaled: while the
#    run is still going, run.log already holds a line for every journaled point; after SIGINT the
#    run exits 130 and run.log ends with "stopped by the user (exit 130)".
# 2. Each line's numbers are those of frf.csv's row (frequency to 1e-6 Hz, amplitude and SE to
#    the 6 and 2 digits printed, evaluations and rig time to the 0.01 s printed).
# 3. Each failed correction has a line (below).
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
# the paced run is stopped whatever the outcome (servers.sh's traps)
. "$src/tests/cli/lib/servers.sh"
cfg="$src/examples/four_storey_linear.yaml"
run=(--set rig.noise=false --set continuation.start_hz=12.6 --set continuation.end_hz=13.2)

"$bin" frf "$cfg" --out "$work/r" --quiet "${run[@]}" --pace 5 2>"$work/r.err" &
pid=$!
servers+=($pid)
for _ in $(seq 1 600); do
    [ "$(wc -l <"$work/r/journal.jsonl" 2>/dev/null || echo 0)" -ge 3 ] && break
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.05
done
journaled=$(($(wc -l <"$work/r/journal.jsonl") - 1))
logged=$(grep -c " accepted: " "$work/r/run.log")
kill -0 "$pid" 2>/dev/null || fail "the run ended before it could be watched"
# the journal is fsynced before the log line is written: allow the point in between
[ "$logged" -ge 2 ] && [ "$logged" -ge $((journaled - 1)) ] ||
    fail "while running: $journaled points journaled, $logged logged in run.log"
kill -INT "$pid"
wait "$pid"
rc=$?
forget "$pid"
[ "$rc" -eq 130 ] || fail "interrupted run: exit $rc, expected 130 ($(cat "$work/r.err"))"
tail -n 1 "$work/r/run.log" | grep -q "finished: stopped by the user (exit 130)" ||
    fail "run.log does not end with the user's stop: $(tail -n 1 "$work/r/run.log")"
/usr/bin/python3 - "$work/r" <<'PY' || fail "run.log's point lines differ from frf.csv"
import csv, re, sys
d = sys.argv[1]
rows = list(csv.DictReader(open(f"{d}/frf.csv")))
pat = re.compile(r"point (\d+) accepted: ([0-9.]+) Hz, amplitude ([0-9.e+-]+) m \+- ([0-9.e+-]+) "
                 r"\(SE\), (\d+) evaluations?, ([0-9.]+) s rig")
lines = [pat.search(l) for l in open(f"{d}/run.log") if " accepted: " in l]
ok = len(lines) == len(rows) >= 2 and all(lines)
for m, r in zip(lines, rows) if ok else []:
    ok = ok and int(m.group(1)) == int(r["point"])
    ok = ok and abs(float(m.group(2)) - float(r["frequency_hz"])) < 1e-6
    ok = ok and abs(float(m.group(3)) / float(r["amplitude_m"]) - 1) < 1e-5
    ok = ok and abs(float(m.group(4)) - float(r["amplitude_se_m"])) <= 0.06 * float(r["amplitude_se_m"]) + 1e-300
    ok = ok and int(m.group(5)) == int(r["evaluations"])
    ok = ok and abs(float(m.group(6)) - float(r["rig_time_s"])) <= 0.006
print(f"{len(lines)} point lines for {len(rows)} rows")
sys.exit(0 if ok else 1)
PY
# 3. A failed correction says where, why and what follows: with one iteration allowed
#    (noise off, natural sweep) the first point fails once (retried from the corrector's last
#    iterate) and the second once (retried with a shorter step), as many lines as summary.json's
#    failed_corrections.
"$bin" frf "$cfg" --out "$work/f" --quiet "${run[@]}" --set iteration.max_iterations=1 \
    --set continuation.method=natural 2>"$work/f.err" || fail "one iteration: $(cat "$work/f.err")"
grep -q "correction failed near 12.6 Hz (1 in a row): corrector did not converge at 12.6 Hz: .*; the first point is tried again" "$work/f/run.log" ||
    fail "run.log lacks the first point's failed correction: $(grep -i fail "$work/f/run.log")"
grep -q "correction failed near 12.65 Hz (1 in a row): .*; retried with a shorter step" "$work/f/run.log" ||
    fail "run.log lacks the second point's failed correction: $(grep -i fail "$work/f/run.log")"
failed=$(sed -n 's/^ *"failed_corrections": *\([0-9]*\),*$/\1/p' "$work/f/summary.json")
[ "$(grep -c "correction failed near" "$work/f/run.log")" = "$failed" ] ||
    fail "$(grep -c "correction failed near" "$work/f/run.log") lines for $failed failed corrections"
[ "$failures" -eq 0 ] && echo "ok   run.log: a line per accepted point as it is accepted; Ctrl-C says exit 130; a line per failed correction"
exit $((failures > 0))
