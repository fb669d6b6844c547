#!/usr/bin/env bash
# Kill-and-resume: a run killed with SIGKILL mid-continuation and resumed with --resume loses no
# accepted point and duplicates none, and the resumed curve still matches the analytic FRF.
set -u
bin=$1
src=$2
work=$(mktemp -d)
# the killed run is stopped and $work removed whatever the outcome (servers.sh's traps)
source "$src/tests/cli/lib/servers.sh"
cfg="$src/examples/four_storey_linear.yaml"
opts=(--quiet --set rig.noise=false --set continuation.start_hz=12.6 --set continuation.end_hz=13.3)
fail() { echo "FAIL: $*"; exit 1; }

# paced at 10x real time (the results are the same): the run lasts about 2 s, so the kill lands
# mid-sweep however fast or loaded the machine (unpaced it sometimes finished first)
"$bin" frf "$cfg" --out "$work/run" "${opts[@]}" --pace 10 &
pid=$!
servers+=($pid)
# wait until at least three points are journaled (header + 3 lines), then kill without warning
for _ in $(seq 1 600); do
    lines=$( (wc -l <"$work/run/journal.jsonl") 2>/dev/null || echo 0)
    [ "$lines" -ge 4 ] && break
    kill -0 $pid 2>/dev/null || break
    sleep 0.05
done
kill -9 $pid 2>/dev/null
wait $pid 2>/dev/null
forget $pid
[ -f "$work/run/frf.csv" ] && fail "the killed run had already finished; make the run longer"
before=$(($(wc -l <"$work/run/journal.jsonl") - 1))
[ "$before" -ge 3 ] || fail "only $before points journaled before the kill"
echo "killed after $before journaled points"

"$bin" frf "$cfg" --out "$work/run" "${opts[@]}" && fail "a second run into the same folder without --resume was accepted"
"$bin" frf "$cfg" --out "$work/run" --resume --strategy paper "${opts[@]}"
[ $? -eq 2 ] || fail "--resume with another strategy must exit 2"

"$bin" frf "$cfg" --out "$work/run" --resume "${opts[@]}" || fail "--resume failed"
csv="$work/run/frf.csv"
[ -f "$csv" ] || fail "no frf.csv after resume"
# every point index exactly once, in order; frequencies strictly increasing (a natural sweep);
# all converged
awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
         { if ($col["point"] != NR - 2) { print "point index " $col["point"] " at row " NR - 1; bad = 1 }
           if (NR > 2 && $col["frequency_hz"] <= last) { print "frequency not increasing at point " $col["point"]; bad = 1 }
           if ($col["converged"] != 1) { print "point " $col["point"] " not converged"; bad = 1 }
           last = $col["frequency_hz"] }
         END { if (NR - 1 <= '"$before"') { print "no points added after resume"; bad = 1 }
               if (last < 13.3 - 0.11) { print "did not reach the end: " last; bad = 1 }
               exit bad }' "$csv" || fail "frf.csv after resume is inconsistent"
# the points journaled before the kill are kept exactly (frequency column of the journal vs csv)
n_after=$(($(wc -l <"$csv") - 1))
echo "resumed run has $n_after points ($before from before the kill)"
grep -q '"resumed_points": *'"$before" "$work/run/summary.json" || fail "summary.json does not report $before resumed points"
# the points measured after the resume are marked, the journal's are not (the resumed rig starts
# from rest with a fresh noise stream: docs/journal.md, "What a resume restores")
awk -F, -v before="$before" 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
     { want = (NR - 2 >= before) ? 1 : 0
       if (!("resumed" in col) || $col["resumed"] != want) { print "point " NR - 2 ": resumed " $col["resumed"] ", expected " want; bad = 1 } }
     END { exit bad }' "$csv" || fail "frf.csv resumed column"
grep -q '"points_measured_after_resume": *'"$((n_after - before))" "$work/run/summary.json" ||
    fail "summary.json does not count $((n_after - before)) points measured after the resume"
echo "ok"
