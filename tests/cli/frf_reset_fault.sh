#!/usr/bin/env bash
# A latched controller fault and --reset-fault (issue 24.3), against a controller process on an
# ephemeral loopback port whose interface force limit (0.5 N) the seed's 1 N forcing trips:
# 1. the run that trips it exits 1 naming the force limit;
# 2. the next run without --reset-fault is refused: the fault is still latched;
# 3. with --reset-fault (and a forcing of 0.1 N, within the limit) the fault is reset, run.log
#    says which fault was cleared, the run completes, and the rig is disarmed (DISARM, excitation
#    ramped to zero) before any output is written (run.log: before "wrote summary.json");
# 4. while the fault's cause persists the reset is refused (exit 1) naming it, nothing written;
# 5. --reset-fault without --rig is bad usage (exit 2).
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
cfg="$src/examples/four_storey.yaml"
# every controller started here is stopped whatever the outcome (start_controller)
source "$src/tests/cli/lib/servers.sh"
phys=(--set "structure.storeys.damping_n_s_per_m=[60, 60, 60, 60]" --set rig.noise=false)
# the simulated plant's samples do not depend on when they run: a test machine that is not
# real-time has late samples, counted and tolerated here
host=(--set controller.max_overrun_share=1 --set continuation.method=natural --set continuation.start_hz=16
    --set continuation.end_hz=16.2 --set continuation.initial_step_hz=0.1
    --set continuation.max_step_hz=0.1 --set iteration.rel_tolerance=1e-6 --quiet)

start_controller ctl --config "$cfg" --listen 127.0.0.1:0 --set server.realtime=false "${phys[@]}" \
    --set controller.limits.force_n=0.5
[ -n "$port" ] || { fail "the controller did not start: $(cat "$work/ctl.err")"; exit 1; }
rig=(--rig "tcp://127.0.0.1:$port")

"$bin" frf "$cfg" --out "$work/trip" "${rig[@]}" "${phys[@]}" "${host[@]}" 2>"$work/trip.err"
rc=$?
[ "$rc" -eq 1 ] || fail "the tripping run: exit $rc, expected 1"
grep -q "force limit" "$work/trip.err" || fail "the trip is not named: $(cat "$work/trip.err")"

"$bin" frf "$cfg" --out "$work/latched" "${rig[@]}" "${phys[@]}" "${host[@]}" 2>"$work/latched.err"
rc=$?
[ "$rc" -eq 1 ] || fail "a run against the latched fault: exit $rc, expected 1"
grep -q "rig fault 'force limit' latched" "$work/latched.err" ||
    fail "the latched fault is not named: $(cat "$work/latched.err")"
[ "$failures" -eq 0 ] && echo "ok   a tripped controller stays latched"

"$bin" frf "$cfg" --out "$work/reset" "${rig[@]}" "${phys[@]}" "${host[@]}" --reset-fault \
    --set forcing.amplitude_n=0.1 2>"$work/reset.err" || fail "--reset-fault run: exit $? ($(cat "$work/reset.err"))"
log="$work/reset/run.log"
grep -q "RESET_FAULT sent to remote controller tcp://127.0.0.1:$port .*its 'force limit' fault cleared" "$log" ||
    fail "run.log does not record the reset: $(cat "$log")"
disarm=$(grep -n "rig disarmed (excitation ramped to zero) before the outputs" "$log" | cut -d: -f1)
written=$(grep -n "wrote summary.json" "$log" | cut -d: -f1)
[ -n "$disarm" ] && [ -n "$written" ] && [ "$disarm" -lt "$written" ] ||
    fail "the rig was not disarmed before the outputs: $(cat "$log")"
[ "$failures" -eq 0 ] && echo "ok   --reset-fault clears it (logged); disarmed before the outputs"

# 4. a cause that persists: a second controller whose displacement limit (1e-9 m) its own sensor
# noise exceeds latches the fault again right after the reset; --reset-fault is refused naming it
stop_all
start_controller ctl2 --config "$cfg" --listen 127.0.0.1:0 --set server.realtime=false \
    --set controller.limits.displacement_m=1e-9
[ -n "$port" ] || { fail "the second controller did not start: $(cat "$work/ctl2.err")"; exit 1; }
"$bin" frf "$cfg" --out "$work/persists" --rig "tcp://127.0.0.1:$port" "${host[@]}" --reset-fault \
    2>"$work/persists.err"
rc=$?
[ "$rc" -eq 1 ] || fail "--reset-fault while the cause persists: exit $rc, expected 1"
grep -q "RESET_FAULT refused: .* latched its 'displacement limit' fault again right after the reset; its cause persists" \
    "$work/persists.err" || fail "the refusal does not say the cause persists: $(cat "$work/persists.err")"
[ -e "$work/persists" ] && fail "a refused reset created the output folder"
[ "$failures" -eq 0 ] && echo "ok   --reset-fault refused while the cause persists"

refused frf "--reset-fault without --rig" "--reset-fault needs --rig" "$cfg" --reset-fault
[ "$failures" -eq 0 ] && echo ok
exit "$failures"
