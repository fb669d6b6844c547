#!/usr/bin/env bash
# rths campaign (docs/campaign.md) on examples/campaign/four_storey_grid.yaml: 12 runs (3 mass
# ratios x 2 PD gains x 2 noise seeds) of a 0.2 Hz sweep, each a few points.
#  - serially: one row per run, in plan order, every run exit 0, its values those of the grid,
#    and each run against the analytic FRF (the runs' own summary.json, computed without the
#    hybrid loop): worst error <= 0.5 % (measured <= 0.09 %), share within 3 SE = 1;
#  - --jobs 2 gives the same campaign.csv byte for byte (no timing column: rig time is simulated);
#  - a campaign killed (SIGKILL) mid-way resumes: the runs finished before the kill keep their
#    folders untouched (inode and mtime of the folder and its summary.json), the rest run, and
#    campaign.csv equals the serial one;
#  - with MPI built in and mpirun installed: mpirun -n 3 equals the serial campaign.csv, and a
#    worker rank killed mid-campaign (mpirun then ends the job) loses no finished run: the same
#    command again resumes and completes, equal to the serial one (skipped, said why, otherwise);
#  - bad plans exit 2 naming FILE:LINE:COL and key, and write nothing: among them a grid or set:
#    key no reader asks for (a typo, with "did you mean") and a value a run's reader refuses,
#    both found before any run starts.
set -u
bin=$1
src=$(cd "$2" && pwd)
source "$src/tests/cli/lib/common.sh"
# the campaigns started in the background are stopped when the script exits, whatever the outcome
source "$src/tests/cli/lib/servers.sh"
plan="$src/examples/campaign/four_storey_grid.yaml"
export OPENBLAS_NUM_THREADS=1

serial="$work/serial"
"$bin" campaign "$plan" --out "$serial" --quiet 2>"$work/serial.err" ||
    fail "serial campaign exit $?: $(tail -n 3 "$work/serial.err")"
csv="$serial/campaign.csv"
[ "$(wc -l <"$csv")" -eq 13 ] || fail "serial: $(wc -l <"$csv") lines in campaign.csv, expected 13"
head -n 1 "$csv" | grep -qx 'run,split.mass_ratio,controller.kp_v_per_m,seed,exit_status,points,converged_points,evaluations,rig_time_s,max_relative_error_vs_truth,share_within_3_standard_errors' ||
    fail "serial: header $(head -n 1 "$csv")"
# rows in plan order: the last grid key varies fastest after the seed
awk -F, 'NR > 1 {
        k = NR - 2
        ratio = (k < 4) ? "0.4" : (k < 8) ? "0.5" : "0.6"
        kp = (int(k / 2) % 2) ? "150" : "100"
        seed = (k % 2) ? "2" : "1"
        if ($1 != sprintf("run_%04d", k) || $2 != ratio || $3 != kp || $4 != seed) {
            print "row " k ": " $0; bad = 1 }
        if ($5 != 0 || $6 < 3 || $7 != $6 || $8 < $6 || $9 <= 0 || $10 > 0.005 || $11 != 1) {
            print "row " k " results: " $0; bad = 1 }
    } END { exit bad }' "$csv" || fail "serial: rows wrong (above)"
# the rows carry what each run's summary.json says (run_0005 checked field by field)
s5="$serial/run_0005/summary.json"
json() { sed -n "s/^ *\"$2\": *\([-0-9.eE+]*\),\{0,1\}$/\1/p" "$1" | head -n 1; }
row5=$(sed -n 7p "$csv")
[ "$(echo "$row5" | cut -d, -f6)" = "$(json "$s5" points)" ] &&
    [ "$(echo "$row5" | cut -d, -f8)" = "$(json "$s5" evaluations_total)" ] &&
    grep -q '"seed": 2' "$s5" && grep -q '"split.mass_ratio=0.5"' "$s5" &&
    grep -q '"controller.kp_v_per_m=100"' "$s5" ||
    fail "run_0005: row $row5 does not match its summary.json"
[ "$failures" -eq 0 ] && echo "ok   serial campaign: 12 runs, each within 0.5 % of the analytic FRF"

"$bin" campaign "$plan" --out "$work/jobs" --jobs 2 --quiet 2>"$work/jobs.err" ||
    fail "--jobs 2: exit $?: $(tail -n 3 "$work/jobs.err")"
cmp -s "$csv" "$work/jobs/campaign.csv" && echo "ok   --jobs 2: campaign.csv identical to the serial one" ||
    fail "--jobs 2: campaign.csv differs: $(diff "$csv" "$work/jobs/campaign.csv" | head -n 4)"

# finished_stats DIR: "run inode mtime inode mtime" of every run with a recorded exit status
finished_stats() {
    for st in "$1"/logs/run_*.status; do
        [ -e "$st" ] || continue
        local r
        r=$(basename "$st" .status)
        [ -f "$1/$r/summary.json" ] || continue
        echo "$r $(stat -c '%i %Y.%y' "$1/$r") $(stat -c '%i %y' "$1/$r/summary.json")"
    done
}
# wait_runs DIR N PID: until N runs have a recorded status (or PID ended, or 5 minutes on a
# loaded machine); 0 if N reached
wait_runs() {
    for _ in $(seq 1 3000); do
        [ "$(ls "$1"/logs/*.status 2>/dev/null | wc -l)" -ge "$2" ] && return 0
        kill -0 "$3" 2>/dev/null || return 1
        sleep 0.1
    done
    return 1
}

# killed and resumed
res="$work/resumed"
"$bin" campaign "$plan" --out "$res" --jobs 2 --quiet 2>"$work/res1.err" &
pid=$!
servers+=($pid)
if wait_runs "$res" 3 $pid; then
    kill -KILL $pid
    wait $pid 2>/dev/null
    forget $pid
    before=$(finished_stats "$res")
    n_before=$(echo "$before" | grep -c run_)
    if [ "$n_before" -ge 3 ] && [ "$n_before" -lt 12 ]; then
        sleep 1.1 # a rewritten file would show a later mtime
        "$bin" campaign "$plan" --out "$res" --jobs 2 --quiet 2>"$work/res2.err" ||
            fail "resume: exit $?: $(tail -n 3 "$work/res2.err")"
        grep -q "resuming the campaign in .*: $n_before finished run(s) kept, $((12 - n_before)) to run" \
            "$work/res2.err" || fail "resume: no message saying so: $(cat "$work/res2.err")"
        after=$(finished_stats "$res")
        while read -r line; do
            echo "$after" | grep -qxF "$line" || fail "resume: a finished run was touched: $line"
        done <<<"$before"
        cmp -s "$csv" "$res/campaign.csv" || fail "resume: campaign.csv differs from the serial one"
        [ "$failures" -eq 0 ] &&
            echo "ok   killed after $n_before runs, resumed: those untouched, campaign.csv as serial"
    else
        fail "resume: $n_before runs finished at the kill, expected 3..11"
    fi
else
    fail "resume: the campaign ended before 3 runs were recorded: $(cat "$work/res1.err")"
fi

# MPI
if ! command -v mpirun >/dev/null; then
    echo "skip MPI: mpirun is not installed (Debian openmpi-bin)"
elif ! "$bin" --version | grep -q 'MPI: built in'; then
    echo "skip MPI: rths is built without MPI (Debian libopenmpi-dev; see rths --version)"
else
    # In the sanitizer build, OpenMPI's components (dlopen'ed and unloaded by MPI_Finalize) leave
    # allocations LeakSanitizer reports at exit in every rank, none of them rths's: leak
    # detection is off for the ranks (AddressSanitizer's other checks stay on).
    mpi=(env "ASAN_OPTIONS=detect_leaks=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
        mpirun --allow-run-as-root --oversubscribe -n 3)
    "${mpi[@]}" "$bin" campaign "$plan" --out "$work/mpi" --quiet >"$work/mpi.out" 2>&1 ||
        fail "mpirun -n 3: exit $?: $(tail -n 5 "$work/mpi.out")"
    cmp -s "$csv" "$work/mpi/campaign.csv" &&
        echo "ok   mpirun -n 3: campaign.csv identical to the serial one" ||
        fail "mpirun -n 3: campaign.csv differs: $(diff "$csv" "$work/mpi/campaign.csv" | head -n 4)"

    # a worker rank killed mid-campaign: find rank 1 among mpirun's children by its environment
    kr="$work/mpi_killed"
    "${mpi[@]}" "$bin" campaign "$plan" --out "$kr" --quiet >"$work/mk1.out" 2>&1 &
    mpid=$!
    servers+=($mpid)
    if wait_runs "$kr" 3 $mpid; then
        rank1=""
        for child in $(pgrep -P $mpid); do
            tr '\0' '\n' <"/proc/$child/environ" 2>/dev/null | grep -qx 'OMPI_COMM_WORLD_RANK=1' &&
                rank1=$child
        done
        if [ -n "$rank1" ]; then
            kill -KILL "$rank1"
            wait $mpid 2>/dev/null
            forget $mpid
            before=$(finished_stats "$kr")
            n_before=$(echo "$before" | grep -c run_)
            sleep 1.1
            "${mpi[@]}" "$bin" campaign "$plan" --out "$kr" --quiet >"$work/mk2.out" 2>&1 ||
                fail "MPI resume: exit $?: $(tail -n 5 "$work/mk2.out")"
            after=$(finished_stats "$kr")
            while read -r line; do
                [ -z "$line" ] || echo "$after" | grep -qxF "$line" ||
                    fail "MPI resume: a finished run was touched: $line"
            done <<<"$before"
            cmp -s "$csv" "$kr/campaign.csv" ||
                fail "MPI resume: campaign.csv differs from the serial one"
            [ "$n_before" -ge 3 ] || fail "MPI: only $n_before finished runs recorded after the kill"
            [ "$failures" -eq 0 ] &&
                echo "ok   MPI rank 1 killed after $n_before runs: all kept, resumed to the serial campaign.csv"
        else
            kill -TERM $mpid
            wait $mpid 2>/dev/null
            fail "MPI: rank 1 not found among mpirun's children"
        fi
    else
        fail "MPI kill: the campaign ended before 3 runs were recorded: $(tail -n 5 "$work/mk1.out")"
    fi
fi

# bad input: exit 2, FILE:LINE:COL and key named, nothing written
cfg="$src/examples/four_storey_linear.yaml"
bad="$work/bad.yaml"
printf 'config: %s\ngrid:\n  split.mass_ratio: [0.5, 2]\n' "$cfg" >"$bad"
refused campaign "grid value out of range" "bad.yaml:3:27: key 'grid.split.mass_ratio': value '2': .*must be in \(0, 1\)" "$bad"
# (the plan check's scratch folder goes to TMPDIR: one of this test's own, checked empty after)
mkdir "$work/tmp" && export TMPDIR="$work/tmp"
# keys no reader of the run asks for (typos) and values a run's reader refuses, found before
# anything runs (every grid value through the run's own readers), named at their place
# in the plan with the configuration reader's "did you mean"
printf 'config: %s\ngrid:\n  split.mas_ratio: [0.4, 0.5]\n' "$cfg" >"$bad"
refused campaign "grid key typo (structure)" "bad.yaml:3:3: key 'grid.split.mas_ratio': .*unknown key 'split.mas_ratio' \(did you mean 'split.mass_ratio'\?\)" "$bad"
printf 'config: %s\ngrid:\n  split.mass_ratio: [0.5]\n  controller.kp_v_per_mm: [100, 150]\n' "$cfg" >"$bad"
refused campaign "grid key typo (a run section)" "bad.yaml:4:3: key 'grid.controller.kp_v_per_mm': .*unknown key 'controller.kp_v_per_mm' \(did you mean 'controller.kp_v_per_m'\?\)" "$bad"
printf 'config: %s\nset:\n  continuation.ned_hz: 12\ngrid:\n  split.mass_ratio: [0.5]\n' "$cfg" >"$bad"
refused campaign "set: key typo" "bad.yaml:3:3: key 'set.continuation.ned_hz': .*unknown key 'continuation.ned_hz' \(did you mean 'continuation.end_hz'\?\)" "$bad"
# (in run_0003, not the first run: every value of every grid key is checked)
printf 'config: %s\ngrid:\n  split.mass_ratio: [0.4, 0.5]\n  controller.kp_v_per_m: [100, -5]\nseeds: [3, 4]\n' "$cfg" >"$bad"
refused campaign "grid value a run refuses" "bad.yaml:4:32: key 'grid.controller.kp_v_per_m': value '-5': .*must be in \[0, 1e\+09\] \(got -5\)" "$bad"
[ -z "$(ls -A "$TMPDIR")" ] || fail "the plan check left its scratch folder: $(ls -A "$TMPDIR")"
printf 'config: %s\nseeds: [1, x]\n' "$cfg" >"$bad"
refused campaign "bad seed" "bad.yaml:2:12: key 'seeds': 'x' is not an unsigned 64-bit integer" "$bad"
printf 'config: %s\ngrids: {split.mass_ratio: [0.5]}\n' "$cfg" >"$bad"
refused campaign "unknown plan key" "bad.yaml:2:1: key 'grids': unknown key" "$bad"
printf 'config: %s\ngrid: {split.mass_ratio: 0.5}\n' "$cfg" >"$bad"
refused campaign "grid not a list" "bad.yaml:2:8: key 'grid.split.mass_ratio': must be a non-empty list" "$bad"
printf 'config: missing.yaml\n' >"$bad"
refused campaign "missing configuration" "missing.yaml: cannot read" "$bad"
refused campaign "--jobs 0" "option --jobs: must be in \[1, 1024\]" "$plan" --jobs 0
# a folder holding something else, or a campaign of another plan
mkdir -p "$work/other" && touch "$work/other/x"
"$bin" campaign "$plan" --out "$work/other" --quiet 2>"$work/o.err"
rc=$?
[ $rc -eq 2 ] && grep -q "holds no campaign" "$work/o.err" && [ "$(ls "$work/other")" = x ] &&
    echo "ok   a folder holding something else is refused" ||
    fail "other folder: exit $rc: $(cat "$work/o.err")"
printf 'config: %s\nseeds: [1]\n' "$cfg" >"$bad"
"$bin" campaign "$bad" --out "$serial" --quiet 2>"$work/o.err"
rc=$?
[ $rc -eq 2 ] && grep -q "holds a campaign of another plan" "$work/o.err" &&
    cmp -s "$csv" "$work/jobs/campaign.csv" && echo "ok   a campaign of another plan is refused" ||
    fail "another plan: exit $rc: $(cat "$work/o.err")"

# the same grid with another override is another plan: the finished runs are not taken for it
"$bin" campaign "$plan" --out "$serial" --set forcing.amplitude_n=2 --quiet 2>"$work/o.err"
rc=$?
[ $rc -eq 2 ] && grep -q "holds a campaign of another plan" "$work/o.err" &&
    cmp -s "$csv" "$work/jobs/campaign.csv" &&
    echo "ok   the same grid with another --set is refused as another plan" ||
    fail "another --set: exit $rc: $(cat "$work/o.err")"

exit $((failures > 0))
