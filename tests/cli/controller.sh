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

# Start on an ephemeral port.
"$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 --set server.realtime=false \
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

# A host run over TCP, if the simulate command is linked and takes --rig.
if "$RTHS" simulate --help 2>/dev/null | grep -q -- "--rig"; then
    "$RTHS" simulate "$CFG" --rig "tcp://127.0.0.1:$port" --out "$tmp/sim" \
        >"$tmp/sim.out" 2>"$tmp/sim.err" || fail "rths simulate over tcp failed"
fi

# SIGTERM: disarm, ramp down, statistics on stderr, exit 0.
kill -TERM "$pid"
wait "$pid"
rc=$?
pid=
[ "$rc" -eq 0 ] || fail "controller exit $rc after SIGTERM"
grep -q "stopped after [0-9]* samples" "$tmp/ctl.err" || fail "no statistics after stop"
echo "ok"
