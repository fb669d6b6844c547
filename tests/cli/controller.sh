#!/bin/bash
# rths controller from the command line: usage errors (exit 2, nothing started), start on an
# ephemeral port ("listening on ADDR:PORT" on stdout), a host run over TCP, a second controller on
# the same port refused, SIGTERM -> disarm, statistics, exit 0; then two interface DoFs over
# protocol version 3 (a version-1 host refused by name, rths frf against the in-process run). No timing is asserted: waits poll
# for a state with generous limits (this is not a real-time kernel).
set -u
RTHS=$1
SRC=$2
CFG="$SRC/examples/four_storey.yaml"
tmp=$(mktemp -d)
pid=
# Every controller and host started here is stopped when the script exits, whatever the outcome
# (tests/cli/lib/servers.sh: SIGTERM, SIGKILL after 10 s, waited for). Not under `timeout`: the
# exit status after SIGTERM is asserted here, and timeout forwards the signal to itself too (143).
source "$SRC/tests/cli/lib/servers.sh"
scratch_dirs+=("$tmp")
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
grep -q "CONFIG" "$tmp/x.err" || fail "missing-config message does not name the config"
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
grep -q "wrong_abi.so: ABI version 43, this controller speaks versions 1 to 2" "$tmp/x.err" ||
    fail "wrong ABI message"
[ -s "$tmp/x.out" ] && fail "a refused plug-in still printed on stdout"
expect_exit 2 "plug-in missing a symbol" "$RTHS" controller --config "$CFG" \
    --listen 127.0.0.1:0 --io "$BUILD/tests/io/missing_symbol.so"
grep -q "symbol 'rths_io_plugin_safe_state' is missing" "$tmp/x.err" || fail "missing-symbol message"
expect_exit 2 "no such plug-in" "$RTHS" controller --config "$CFG" --io "$tmp/none.so"
grep -q "none.so" "$tmp/x.err" || fail "missing plug-in message does not name the file"
# An empty --io (an unset variable in a lab's script) or a bare name (searched in the system's
# library path) is refused, naming the rule; --duration 1 ends a controller that wrongly starts.
expect_exit 2 "empty --io" "$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 --io "" \
    --duration 1 --set server.realtime=false
grep -q "plug-in path is empty" "$tmp/x.err" || fail "empty --io message"
expect_exit 2 "--io without a slash" "$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 \
    --io libc.so.6 --duration 1 --set server.realtime=false
grep -q "'libc.so.6': not a path" "$tmp/x.err" || fail "bare --io name message"
expect_exit 2 "empty io.plugin" "$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 \
    --set "io.plugin=''" --duration 1 --set server.realtime=false
grep -q "io.plugin.*is empty" "$tmp/x.err" || fail "empty io.plugin message"
expect_exit 2 "io.plugin without a slash" "$RTHS" controller --config "$CFG" \
    --listen 127.0.0.1:0 --set io.plugin=libc.so.6 --duration 1 --set server.realtime=false
grep -q "not a path" "$tmp/x.err" || fail "bare io.plugin message"

# --latency-test: the paced loop alone, no configuration needed; percentiles and the worst
# wake-up lateness on stdout (the figures themselves are the machine's, not asserted).
expect_exit 0 "--latency-test" "$RTHS" controller --latency-test 0.2 --set server.realtime=false
us='(>= )?[0-9]+ us' # a percentile beyond the histogram's 50 ms reads ">= 50000 us"
grep -Eq "^samples 2000 at 10000 Hz: wake-up lateness p50 $us, p90 $us, p99 $us, p99.9 $us, worst [0-9]+ us; [0-9]+ overruns" \
    "$tmp/x.out" || fail "--latency-test output: $(cat "$tmp/x.out")"
expect_exit 2 "--latency-test 0" "$RTHS" controller --latency-test 0
grep -q -- "--latency-test" "$tmp/x.err" || fail "--latency-test 0 message"
# server.realtime=true says plainly what was granted and what not (SCHED_FIFO, memory, CPU)
expect_exit 0 "--latency-test realtime" "$RTHS" controller --latency-test 0.05 \
    --set server.realtime=true
for what in "SCHED_FIFO priority 80" "memory" "CPU"; do
    grep -Eq "real time: .*$what.*(granted|NOT granted)|real time: memory (locked|locking)" \
        "$tmp/x.err" || fail "no real-time report of $what: $(cat "$tmp/x.err")"
done

# The seed with heavier damping (the transient dies out in seconds of wall-clock time), noise
# off, and a two-point natural continuation: shared by the controller and both host runs.
PHYS=(--set "structure.storeys.damping_n_s_per_m=[60, 60, 60, 60]" --set rig.noise=false)
# The controller process runs the simulated plant, whose samples do not depend on when they run:
# on a test machine that is not real-time the host tolerates late samples (counted, reported).
HOST=(--set controller.max_overrun_share=1 --set continuation.method=natural --set continuation.start_hz=16
    --set continuation.end_hz=16.2 --set continuation.initial_step_hz=0.1
    --set continuation.max_step_hz=0.1 --set continuation.max_points=2
    --set iteration.rel_tolerance=1e-6)

# Start on an ephemeral port, on the reference I/O plug-in loaded from its shared object. The
# host watchdog at 20 s: a host here stays armed while it writes its outputs (issue 24.3), which
# on this loaded machine can take longer than the default 2 s, and the next host would find the
# watchdog fault latched (its text says "the host was silent for 2.00 s"); the watchdog itself
# is tested in test_controller_process.
"$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 \
    --set server.realtime=false "${PHYS[@]}" --io "$BUILD/rths_io_virtual.so" --set server.watchdog_s=20 \
    >"$tmp/ctl.out" 2>"$tmp/ctl.err" &
pid=$!
servers+=($pid)
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
    servers+=($hpid)
    wait_for "armed by" "$tmp/ctl.err" "'armed' notice"
    kill -KILL "$hpid"
    wait "$hpid" 2>/dev/null
    forget "$hpid"
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
forget "$pid"
pid=
[ "$rc" -eq 0 ] || fail "controller exit $rc after SIGTERM"
grep -q "stopped after [0-9]* samples" "$tmp/ctl.err" || fail "no statistics after stop"

# ---- Two interface DoFs (examples/two_interface_storeys.yaml: storeys 2 and 3 on two shakers),
# protocol version 3 carrying every DoF's target and records. Noise off.
CFG2="$SRC/examples/two_interface_storeys.yaml"
"$RTHS" controller --config "$CFG2" --listen 127.0.0.1:0 --set server.realtime=false \
    --set rig.noise=false --io "$BUILD/rths_io_virtual.so" >"$tmp/ctl2.out" 2>"$tmp/ctl2.err" &
pid=$!
servers+=($pid)
port=
for _ in $(seq 1 400); do
    port=$(sed -n 's/^listening on 127\.0\.0\.1:\([0-9][0-9]*\)$/\1/p' "$tmp/ctl2.out")
    [ -n "$port" ] && break
    kill -0 "$pid" 2>/dev/null || fail "two-DoF controller exited before listening"
    sleep 0.05
done
[ -n "$port" ] || fail "two-DoF controller: no 'listening on' line"

# A version-1 host (its HELLO byte for byte, docs/protocol.md section 6) is told, in a frame it
# can read (version-1 framing), that the versions differ; the connection is closed.
/usr/bin/python3 - "$port" <<'PY' >"$tmp/v1.out" 2>&1 || fail "version-1 host: $(cat "$tmp/v1.out")"
import socket, struct, sys, zlib
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=20)
s.sendall(bytes.fromhex("5254010101000700010004686f7374b4542391"))
data = b""
while True:
    chunk = s.recv(4096)
    if not chunk:
        break
    data += chunk
magic, version, typ, seq, length = struct.unpack("<HBBHH", data[:8])
code, request, n = struct.unpack("<HBB", data[8:12])
text = data[12:12 + n].decode()
crc, = struct.unpack("<I", data[8 + length:12 + length])
print(f"version {version} type {typ:#x} code {code}: {text}")
ok = (version == 1 and typ == 0xFF and code == 3 and crc == zlib.crc32(data[:8 + length])
      and "peer speaks rths protocol version 1; this build speaks version 3" in text
      and len(data) == 12 + length)
sys.exit(0 if ok else 1)
PY
wait_for "peer speaks rths protocol version 1" "$tmp/ctl2.err" "version notice on the controller"

# The HELLO's client name reaches the operator's console only as printable text (issue 24.14):
# a newline would forge a console line, an escape sequence reach the terminal.
/usr/bin/python3 - "$port" <<'PY' >"$tmp/evil.out" 2>&1 || fail "hostile hello: $(cat "$tmp/evil.out")"
import socket, struct, sys, zlib
name = b"evil\nrths controller: t = 0 s: FORGED LINE\x1b[2J"
payload = struct.pack("<HB", 3, len(name)) + name
body = struct.pack("<BBBBHH", 0x52, 0x54, 3, 0x01, 1, len(payload)) + payload
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=20)
s.sendall(body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF))
head = s.recv(8)
print("reply type %#x" % head[3])
s.close()
sys.exit(0 if head[3] == 0x81 else 1)
PY
wait_for "says hello (evil?rths controller: t = 0 s: FORGED LINE?\[2J)" "$tmp/ctl2.err" \
    "the sanitised client name"
grep -q "^rths controller: t = 0 s: FORGED LINE" "$tmp/ctl2.err" && fail "a client name forged a line"
grep -q $'\x1b' "$tmp/ctl2.err" && fail "an escape sequence reached the console"

# rths frf of the example through the controller process against the in-process run. The link
# itself adds nothing (test_controller_process: the same per-period records to 1e-13 m), but the
# two runs are different iterations: their histories differ (the controller idles disarmed
# before ARM) and a remote rig is not assumed LTI, so the corrector takes other steps; at the
# 13.47 Hz resonance (the second mode, damping ratio 0.35 %: a 3.4 s time constant, as long as a
# point's settle wait) each keeps its own unsettled transient. So the runs agree as far as each
# is accurate: every
# point converged, each run's interface amplitudes within 0.5 % of the analytic FRF (the issue's
# acceptance) and its complex responses within 2 % (so phases within asin 0.02 = 0.02 rad: the
# phase moves ~20 rad/Hz at the 0.35 %-damped resonance, where the amplitude is flat); hence
# dof<d>_amplitude_m and dof<d>_numerical_amplitude_m differ by at most 1 % relative,
# dof<d>_phase_rad by 0.04 rad, dof<d>_interface_error_m (each below the run's tolerance) by the
# larger tolerance_m. Measured over three runs: up to 0.39 %, 0.0083 rad; errors from the
# analytic FRF up to 0.37 % (amplitude) and 0.85 % (complex) over TCP, 0.064 % and 0.074 %
# in-process.
"$RTHS" frf "$CFG2" --out "$tmp/remote2" --rig "tcp://127.0.0.1:$port" --set rig.noise=false \
    --set controller.max_overrun_share=1 \
    --quiet >"$tmp/frf2_remote.out" 2>"$tmp/frf2_remote.err" || fail "two-DoF rths frf over tcp failed"
"$RTHS" frf "$CFG2" --out "$tmp/local2" --set rig.noise=false --quiet \
    >"$tmp/frf2_local.out" 2>"$tmp/frf2_local.err" || fail "two-DoF rths frf in-process failed"
/usr/bin/python3 - "$tmp/remote2/frf.csv" "$tmp/local2/frf.csv" <<'PY' || fail "two-DoF frf over tcp differs from the in-process run"
import csv, sys
import numpy as np
remote = list(csv.DictReader(open(sys.argv[1])))
local = list(csv.DictReader(open(sys.argv[2])))
m = np.array([5.37, 5.37, 5.37, 10.74])
c = np.array([4.4062, 3.7979, 3.7421, 3.7421])
k = np.array([53048, 45724, 45052, 45052])
def chain(v):  # storey i joined to i-1 (storey 1 to the ground)
    n = len(v); a = np.zeros((n, n))
    for i in range(n):
        a[i, i] += v[i]
        if i > 0:
            a[i, i - 1] -= v[i]; a[i - 1, i] -= v[i]; a[i - 1, i - 1] += v[i]
    return a
M, C, K = np.diag(m), chain(c), chain(k)
bad = []
if len(remote) != len(local) or len(remote) < 20:
    bad.append(f"{len(remote)} points over tcp, {len(local)} in-process")
cols = [h for h in local[0] if h.startswith("dof") and "_receptance_" not in h]  # the receptance is amplitude and phase again
if sorted(set(h[:4] for h in cols)) != ["dof1", "dof2"] or len(cols) != 10:
    bad.append(f"dof columns {cols}")
worst = {h: 0.0 for h in cols}
truth_err = {"tcp": [0.0, 0.0], "in-process": [0.0, 0.0]}  # amplitude, complex
for r, l in zip(remote, local):
    if r["frequency_hz"] != l["frequency_hz"] or r["converged"] != "1" or l["converged"] != "1":
        bad.append(f"point {r['point']}: {r['frequency_hz']} Hz converged {r['converged']}")
    w = 2 * np.pi * float(r["frequency_hz"])
    x = np.linalg.solve(K - w * w * M + 1j * w * C, np.array([0, 0, 0, 1.0]))
    for run, row in (("tcp", r), ("in-process", l)):
        for dof in (1, 2):
            amp, phase = float(row[f"dof{dof}_amplitude_m"]), float(row[f"dof{dof}_phase_rad"])
            e_amp = abs(amp / abs(x[dof]) - 1)
            e_cx = abs(amp * np.exp(1j * phase) - x[dof]) / abs(x[dof])
            truth_err[run] = [max(truth_err[run][0], e_amp), max(truth_err[run][1], e_cx)]
            if e_amp > 0.005 or e_cx > 0.02:
                bad.append(f"{run} dof{dof} at {row['frequency_hz']} Hz: {100 * e_amp:.3f} % "
                           f"(amplitude), {100 * e_cx:.3f} % (complex) from the analytic FRF")
    tol = max(float(r["tolerance_m"]), float(l["tolerance_m"]))
    for h in cols:
        a, b = float(r[h]), float(l[h])
        if h.endswith("_phase_rad"):
            d, limit = abs(a - b), 0.04
        elif h.endswith("_interface_error_m"):
            d, limit = abs(a - b), tol
        elif h.endswith("_amplitude_se_m"):
            # the two runs' standard errors are estimates from different evaluations (the
            # iterations differ, see above; measured up to a factor 2.4 apart): not compared,
            # but each must be a finite positive number (their coverage: test_multi_interface)
            d, limit = (0.0 if np.isfinite(a) and np.isfinite(b) and a > 0 and b > 0 else 1.0), 0.5
        else:
            d, limit = abs(a - b) / abs(b), 0.01
        worst[h] = max(worst[h], d)
        if d > limit:
            bad.append(f"{h} at {r['frequency_hz']} Hz: {a} over tcp vs {b} ({d:.3g} > {limit:.3g})")
print("two interface DoFs, tcp vs in-process, largest difference per column:",
      ", ".join(f"{h} {v:.3g}" for h, v in worst.items()))
print("largest error from the analytic FRF (amplitude, complex):",
      ", ".join(f"{run} {v[0]:.3g}, {v[1]:.3g}" for run, v in truth_err.items()))
print("\n".join(bad))
sys.exit(1 if bad else 0)
PY
kill -TERM "$pid"
wait "$pid"
rc=$?
forget "$pid"
pid=
[ "$rc" -eq 0 ] || fail "two-DoF controller exit $rc after SIGTERM"

# ---- A misbehaving I/O plug-in (tests/data/io/misbehaving.c, built here against librths) ----
cc -shared -fPIC -std=c11 -D_GNU_SOURCE -I"$SRC/include" "$SRC/tests/data/io/misbehaving.c" \
    -o "$tmp/misbehaving.so" -L"$BUILD" -lrths -Wl,-rpath,"$BUILD" 2>"$tmp/cc.err" ||
    fail "cannot build the misbehaving plug-in: $(cat "$tmp/cc.err")"
start_controller() { # out-prefix, then extra arguments
    local out=$1
    shift
    "$RTHS" controller --config "$CFG" --listen 127.0.0.1:0 \
        --set server.realtime=false "${PHYS[@]}" --io "$tmp/misbehaving.so" "$@" \
        >"$tmp/$out.out" 2>"$tmp/$out.err" &
    pid=$!
    servers+=($pid)
    port=
    for _ in $(seq 1 400); do
        port=$(sed -n 's/^listening on 127\.0\.0\.1:\([0-9][0-9]*\)$/\1/p' "$tmp/$out.out")
        [ -n "$port" ] && return 0
        kill -0 "$pid" 2>/dev/null || fail "$out: controller exited before listening"
        sleep 0.05
    done
    fail "$out: no 'listening on' line"
}

# A read that takes 200 us at 10 kHz (a whole sample period and more): the loop overruns, and
# every period record carries its late samples (issue 24.1: before, overruns were counted only in
# the process's histogram and every period looked good). A version-3 host, raw: HELLO, SUBSCRIBE
# to periods, SET_FORCING (periods close disarmed too), then three PERIOD frames.
start_controller slow --set io.sleep_us=200
/usr/bin/python3 - "$port" <<'PY' >"$tmp/late.out" 2>&1 || fail "late samples: $(cat "$tmp/late.out")"
import socket, struct, sys, zlib
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=30)
def send(typ, seq, payload):
    body = struct.pack("<BBBBHH", 0x52, 0x54, 3, typ, seq, len(payload)) + payload
    s.sendall(body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF))
buf = b""
def frame():
    global buf
    while True:
        if len(buf) >= 8:
            length = struct.unpack("<H", buf[6:8])[0]
            if len(buf) >= 12 + length:
                f, buf = buf[:12 + length], buf[12 + length:]
                return f[3], f[8:8 + length]
        chunk = s.recv(65536)
        if not chunk:
            sys.exit("connection closed")
        buf += chunk
send(0x01, 1, struct.pack("<HB", 3, 4) + b"test")
send(0x08, 2, struct.pack("<BI", 1, 1))
send(0x04, 3, struct.pack("<dd", 10.0, 0.0))
periods = []
while len(periods) < 4:
    typ, p = frame()
    if typ == 0x84:
        index, f, t0, t1, samples, late, clipped, saturated = struct.unpack("<IdddIIII", p[:44])
        periods.append((samples, late, clipped, saturated))
periods = periods[1:]  # the first may have opened before SET_FORCING took effect
for samples, late, clipped, saturated in periods:
    print(f"period of {samples} samples: {late} late, {clipped} clipped, {saturated} saturated")
ok = all(0 < late <= samples and clipped == 0 and saturated == 0 for samples, late, clipped, saturated in periods)
sys.exit(0 if ok else 1)
PY
cat "$tmp/late.out"
# ...and a hybrid test on that loop is refused: rths frf exits 1 naming the late samples
# (issue 24, acceptance; controller.max_overrun_share at its default 0)
"$RTHS" frf "$CFG" --out "$tmp/slow_frf" --rig "tcp://127.0.0.1:$port" "${PHYS[@]}" \
    --set continuation.method=natural --set continuation.start_hz=16 \
    --set continuation.end_hz=16.2 --set continuation.initial_step_hz=0.1 \
    --set continuation.max_step_hz=0.1 --quiet >"$tmp/slow_frf.out" 2>"$tmp/slow_frf.err"
rc=$?
[ "$rc" -eq 1 ] || fail "rths frf on an overrunning loop: exit $rc, expected 1"
grep -Eq "rths frf: .*[0-9]+ were late \(share [0-9.]+, controller.max_overrun_share 0\)" \
    "$tmp/slow_frf.err" || fail "the refusal does not name the late samples: $(cat "$tmp/slow_frf.err")"
grep -q "late_samples" "$tmp/slow_frf/summary.json" 2>/dev/null ||
    fail "summary.json does not report the late samples"
kill -TERM "$pid"
wait "$pid"
rc=$?
forget "$pid"
pid=
[ "$rc" -eq 0 ] || fail "slow plug-in controller exit $rc after SIGTERM"

# A read that never returns (issue 24.2): the supervisor drives the plug-in's safe state (the
# plug-in reports how long after the missed deadline), latches a fault naming the stall, and the
# process still exits on SIGTERM, with status 1 naming the stall. (How soon is printed, not
# asserted: this machine is no real-time kernel.)
start_controller stall --set io.block_after_samples=5000 --set server.stall_margin_s=0.05
wait_for "misbehaving plug-in: safe state" "$tmp/stall.err" "the safe state of a stalled loop"
wait_for "fault latched: watchdog: the loop stalled" "$tmp/stall.err" "the stall's fault notice"
grep "misbehaving plug-in: safe state" "$tmp/stall.err"
kill -TERM "$pid"
for _ in $(seq 1 200); do
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.05
done
kill -0 "$pid" 2>/dev/null && fail "a stalled controller did not exit on SIGTERM"
wait "$pid"
rc=$?
forget "$pid"
pid=
[ "$rc" -eq 1 ] || fail "stalled controller exit $rc after SIGTERM, expected 1"
grep -q "the loop stalled in the I/O device" "$tmp/stall.err" || fail "no stall message at exit"
echo "ok"
