#!/usr/bin/env bash
# tests/cli/lib/servers.sh, the way the CLI tests stop what they start (issue 28: a fresh
# `make test` left `rths view ... --listen 127.0.0.1:0` processes running): a test script that
# starts `rths view` in the background and then fails (exit 1), stops on an error (set -e) or is
# stopped by SIGTERM (as ctest stops a test at its timeout) leaves no server behind: each server
# it registered is gone when the script has ended. As a control, the same script without
# servers.sh does leave its server (so the check below can see one), which this test then stops.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
source "$src/tests/cli/lib/servers.sh"

# The inner test script: MODE is fail, error, term or none (servers.sh not sourced).
cat >"$work/inner.sh" <<'EOF'
set -u
bin=$1 src=$2 run=$3 mode=$4 pidfile=$5
source "$src/tests/cli/lib/common.sh"
[ "$mode" = none ] || source "$src/tests/cli/lib/servers.sh"
servers=()
timeout -k 5 120 "$bin" view "$run" --listen 127.0.0.1:0 >"$work/v.out" 2>&1 &
servers+=($!)
for _ in $(seq 300); do grep -q " at http://" "$work/v.out" && break; sleep 0.1; done
grep -q " at http://" "$work/v.out" || { echo "the view did not start: $(cat "$work/v.out")"; exit 3; }
pgrep -f -- "rths view $run " >"$pidfile.tmp" && mv "$pidfile.tmp" "$pidfile"
case $mode in
fail | none) exit 1 ;;
error) set -e; false; echo "not reached" ;;
term) sleep 60 & servers+=($!); wait $! ;;
esac
EOF

for mode in fail error term none; do
    run="$work/run_$mode"
    mkdir "$run" && echo '{}' >"$run/live.json" # a run folder: live.json alone
    pidfile="$work/pids_$mode"
    bash "$work/inner.sh" "$bin" "$src" "$run" "$mode" "$pidfile" &
    inner=$!
    servers+=($inner)
    for _ in $(seq 300); do [ -s "$pidfile" ] && break; kill -0 $inner 2>/dev/null || break; sleep 0.1; done
    [ -s "$pidfile" ] || { fail "$mode: the inner script started no view"; continue; }
    [ "$mode" = term ] && kill -TERM $inner
    wait $inner
    rc=$?
    forget $inner
    left=$(pgrep -af -- "rths view $run " || true)
    if [ "$mode" = none ]; then
        # the control: without servers.sh the view outlives its script
        [ -n "$left" ] && echo "ok   control: without servers.sh the view outlived its script (exit $rc)" ||
            fail "control: the view ended with its script even without servers.sh"
        kill -TERM $(cat "$pidfile") 2>/dev/null
        for _ in $(seq 100); do pgrep -f -- "rths view $run " >/dev/null || break; sleep 0.1; done
    else
        [ -z "$left" ] && echo "ok   $mode (exit $rc): the script's view ($(tr '\n' ' ' <"$pidfile")) is gone" ||
            fail "$mode (exit $rc): still running: $left"
    fi
done
exit $((failures > 0))
