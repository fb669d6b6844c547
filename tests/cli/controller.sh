#!/bin/bash
# rths controller from the command line: usage errors (exit 2, nothing started), start on an
# ephemeral port ("listening on ADDR:PORT" on stdout), a host run over TCP, a second controller on
# the same port refused, SIGTERM -> disarm, statistics, exit 0. No timing is asserted: waits poll
# for a state with generous limits (this is not a real-time kernel).
set -u
RTHS=$1
SRC=$2
CFG="$SRC/examples/four_storey.yaml"
tmp=$(mktemp -d)
pid=
cleanup() {
    [ -n "$pid" ] && kill "$pid" 2>/dev/null
    rm -rf "$tmp"
}
trap cleanup EXIT
fail() {
    echo "FAIL: $*"
    for f in "$tmp"/*.out "$tmp"/*.err; do [ -f "$f" ] && { echo "--- $f"; cat "$f"; }; done
    exit 1
}
expect_exit() { # expected-status description command...
    local want=$1 what=$2
    shift 2
    "$@" >"$tmp/x.out" 2>"$tmp/x.err"
    local got=$?
    [ "$got" -eq "$want" ] || fail "$what: exit $got, expected $want"
}

expect_exit 0 "--help" "$RTHS" controller --help
grep -q -- "--listen ADDR:PORT" "$tmp/x.out" || fail "--help does not document --listen"
expect_exit 2 "no config" "$RTHS" controller --listen 127.0.0.1:0
grep -q "config" "$tmp/x.err" || fail "missing-config message does not name the config"
expect_exit 2 "bad --listen" "$RTHS" controller --config "$CFG" --listen localhost
expect_exit 2 "bad port" "$RTHS" controller --config "$CFG" --listen 127.0.0.1:70000
expect_exit 2 "bad watchdog" "$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 \
    --set server.watchdog_s=-1
grep -q "server.watchdog_s" "$tmp/x.err" || fail "bad watchdog message does not name the key"
expect_exit 2 "unknown server key" "$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 \
    --set server.watchdgo_s=1
expect_exit 2 "missing config file" "$RTHS" controller --config "$tmp/nope.yaml"
expect_exit 2 "unknown option" "$RTHS" controller --config "$CFG" --frobnicate
# I/O plug-ins (docs/io-plugins.md): a wrong ABI version or a missing symbol is refused before
# anything listens or runs (the deliberately broken plug-ins of tests/data/io, built beside rths)
BUILD=$(dirname "$RTHS")
"$RTHS" controller --help | grep -q -- "--io PLUGIN.so" || fail "--help does not document --io"
expect_exit 2 "wrong ABI plug-in" "$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 \
    --io "$BUILD/tests/io/wrong_abi.so"
grep -q "wrong_abi.so: ABI version 42, this controller speaks version 1" "$tmp/x.err" ||
    fail "wrong ABI message"
[ -s "$tmp/x.out" ] && fail "a refused plug-in still printed on stdout"
expect_exit 2 "plug-in missing a symbol" "$RTHS" controller --config "$CFG" \
    --listen 127.0.0.1:0 --io "$BUILD/tests/io/missing_symbol.so"
grep -q "symbol 'rths_io_plugin_safe_state' is missing" "$tmp/x.err" || fail "missing-symbol message"
expect_exit 2 "no such plug-in" "$RTHS" controller --config "$CFG" --io "$tmp/none.so"
grep -q "none.so" "$tmp/x.err" || fail "missing plug-in message does not name the file"

# The seed with heavier damping (the transient dies out in seconds of wall-clock time), noise
# off, and a two-point natural continuation: shared by the controller and both host runs.
PHYS=(--set "structure.storeys.damping_n_s_per_m=[60, 60, 60, 60]" --set rig.noise=false)
HOST=(--set continuation.method=natural --set continuation.start_hz=16
    --set continuation.end_hz=16.2 --set continuation.initial_step_hz=0.1
    --set continuation.max_step_hz=0.1 --set continuation.max_points=2
    --set iteration.rel_tolerance=1e-6)

# Start on an ephemeral port, on the reference I/O plug-in loaded from its shared object.
"$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 --set server.realtime=false "${PHYS[@]}" \
    --io "$BUILD/rths_io_virtual.so" \
    >"$tmp/ctl.out" 2>"$tmp/ctl.err" &
pid=$!
port=
for _ in $(seq 1 400); do
    port=$(sed -n 's/^listening on 127\.0\.0\.1:\([0-9][0-9]*\)$/\1/p' "$tmp/ctl.out")
    [ -n "$port" ] && break
    kill -0 "$pid" 2>/dev/null || fail "controller exited before listening"
    sleep 0.05
done
[ -n "$port" ] || fail "no 'listening on' line"
grep -q "real-time features off" "$tmp/ctl.err" || fail "no notice about real-time features"

# A second controller on the same port cannot listen: exit 1 with the reason.
expect_exit 1 "port in use" "$RTHS" controller --config "$CFG" --listen "127.0.0.1:$port" \
    --set server.realtime=false
grep -q "cannot listen" "$tmp/x.err" || fail "port-in-use message"

wait_for() { # pattern file what
    for _ in $(seq 1 400); do
        grep -q "$1" "$2" && return 0
        kill -0 "$pid" 2>/dev/null || fail "controller exited while waiting for $3"
        sleep 0.05
    done
    fail "no $3"
}

# rths frf over TCP against the same run on the in-process virtual rig: the same points, the
# same solution (both converge to 1e-6 relative; agreement asked: 1e-4 relative).
if "$RTHS" frf --help 2>/dev/null | grep -q -- "--rig"; then
    # A host killed mid-run (SIGKILL: no goodbye). The controller disarms (forcing and target
    # ramp to zero), keeps running, and serves the next host.
    "$RTHS" frf "$CFG" --out "$tmp/killed" --rig "tcp://127.0.0.1:$port" "${PHYS[@]}" \
        "${HOST[@]}" --quiet >"$tmp/killed.out" 2>"$tmp/killed.err" &
    hpid=$!
    wait_for "armed by" "$tmp/ctl.err" "'armed' notice"
    kill -KILL "$hpid"
    wait "$hpid" 2>/dev/null
    wait_for "disarmed (host connection lost)" "$tmp/ctl.err" "disarm after the host was killed"

    "$RTHS" frf "$CFG" --out "$tmp/remote" --rig "tcp://127.0.0.1:$port" "${PHYS[@]}" "${HOST[@]}" \
        --quiet >"$tmp/frf_remote.out" 2>"$tmp/frf_remote.err" || fail "rths frf over tcp failed"
    "$RTHS" frf "$CFG" --out "$tmp/local" "${PHYS[@]}" "${HOST[@]}" --quiet \
        >"$tmp/frf_local.out" 2>"$tmp/frf_local.err" || fail "rths frf in-process failed"
    [ -s "$tmp/remote/trace.csv" ] || fail "no trace recorded over tcp"
    paste -d, "$tmp/remote/frf.csv" "$tmp/local/frf.csv" | awk -F, '
        NR == 1 { n = NF / 2; for (i = 1; i <= n; i++) col[$i] = i; next }
        {
            rows++
            if ($(col["frequency_hz"]) != $(n + col["frequency_hz"])) bad = bad " frequency"
            split("amplitude_m numerical_amplitude_m target_a1_m target_b1_m", names, " ")
            for (j in names) {
                c = col[names[j]]; r = $c; l = $(n + c)
                d = r - l; if (d < 0) d = -d; s = l < 0 ? -l : l
                if (d > 1e-4 * s) bad = bad " " names[j] "(" r " vs " l ")"
            }
        }
        END { if (rows != 2 || bad != "") { print "frf remote vs local:" bad " rows " rows; exit 1 } }
    ' || fail "frf over tcp differs from the in-process run"
fi

# rths simulate over TCP: same files as in-process; the coefficients of the last period agree
# with the in-process run (same config, noise off) to 1e-4 relative.
SIM=(--frequency 16 --target 2e-5,-1e-5 --periods 40 --trace-periods 2 --quiet)
"$RTHS" simulate "$CFG" --out "$tmp/sim_remote" --rig "tcp://127.0.0.1:$port" "${PHYS[@]}" "${SIM[@]}" \
    >"$tmp/sim_remote.out" 2>"$tmp/sim_remote.err" || fail "rths simulate over tcp: $(cat "$tmp/sim_remote.err")"
"$RTHS" simulate "$CFG" --out "$tmp/sim_local" "${PHYS[@]}" "${SIM[@]}" || fail "rths simulate in-process"
for f in coefficients.csv trace.csv summary.json; do
    [ -s "$tmp/sim_remote/$f" ] || fail "simulate over tcp: no $f"
done
paste -d, <(tail -n 1 "$tmp/sim_remote/coefficients.csv") <(tail -n 1 "$tmp/sim_local/coefficients.csv") |
    awk -F, -v h="$(head -n 1 "$tmp/sim_local/coefficients.csv")" '
    BEGIN { n = split(h, names, ",") }
    { for (i = 1; i <= n; i++) if (names[i] ~ /_a1_m$|_b1_m$/) {
          r = $i; l = $(n + i); d = r - l; if (d < 0) d = -d; s = l < 0 ? -l : l
          if (d > 1e-4 * s + 1e-12) { print names[i] ": " r " over tcp vs " l; bad = 1 } }
      exit bad }' || fail "simulate over tcp differs from the in-process run"

# A connection storm (issue 18): 200 connections opened and closed at once. The controller keeps
# serving, and its connection notices are rate-limited (at most 10 a second plus one "suppressed"
# line a second: before, every connection logged a line, 200 and more). Counting lines, not time:
# the storm cannot last 15 s on loopback, so at most 15 x 11 lines.
before=$(wc -l <"$tmp/ctl.err")
for _ in $(seq 1 200); do
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null
done
"$RTHS" simulate "$CFG" --out "$tmp/sim_after" --rig "tcp://127.0.0.1:$port" "${PHYS[@]}" "${SIM[@]}" \
    >"$tmp/sim_after.out" 2>"$tmp/sim_after.err" || fail "no service after a connection storm: $(cat "$tmp/sim_after.err")"
wait_for "connection notices suppressed" "$tmp/ctl.err" "'suppressed' summary after the storm"
storm_lines=$(($(wc -l <"$tmp/ctl.err") - before))
[ "$storm_lines" -le 165 ] || fail "a storm of 200 connections logged $storm_lines lines"

# SIGTERM: disarm, ramp down, statistics on stderr, exit 0.
kill -TERM "$pid"
wait "$pid"
rc=$?
pid=
[ "$rc" -eq 0 ] || fail "controller exit $rc after SIGTERM"
grep -q "stopped after [0-9]* samples" "$tmp/ctl.err" || fail "no statistics after stop"
echo "ok"
