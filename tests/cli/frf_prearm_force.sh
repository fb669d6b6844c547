#!/usr/bin/env bash
# The pre-arm prediction of the rig's forces honours rig.interface_mass (issue 23.1): on the linear
# seed (1 N at the roof) the load cell must carry F_LC = k3 (x3 - x2) + i w c3 (x3 - x2)
# - w^2 M_rig x3 at the true response, peaking at 13.47 Hz at 37.08 N with the whole 5.37 kg storey
# on the rig (full) and 30.51 N with its physical share 2.685 kg; the actuator, with its 0.1 kg
# armature's inertia, 37.32 N (numpy's complex solve of the assembly over 12..14 Hz, done
# independently when this test was written). A limit below the prediction is named before
# arming (a warning on stderr and in run.log, with the mode and the key); the run goes on (it
# trips only if its own points reach the limit: exit 0 or 1, never 2).
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cfg="$src/examples/four_storey_linear.yaml"
range=(--set continuation.start_hz=13.3 --set continuation.end_hz=13.6 --set rig.noise=false)
check() { # NAME REGEX ARGS...
    local name=$1 re=$2
    shift 2
    local o="$work/run_$RANDOM"
    "$bin" frf "$cfg" "${range[@]}" "$@" --out "$o" --quiet >/dev/null 2>"$work/err"
    local rc=$?
    [ "$rc" -le 1 ] || { fail "$name: exit $rc, expected 0 or 1"; cat "$work/err"; return; }
    grep -Eq -- "warning: $re" "$work/err" || { fail "$name: /$re/ not in: $(cat "$work/err")"; return; }
    grep -Eq -- "warning: $re" "$o/run.log" || { fail "$name: the warning is not in run.log"; return; }
    echo "ok   $name: $(grep warning "$work/err" | head -n 1)"
}
check "full: 37.08 N over a 34 N limit" \
    "the rig's interface force \(load cell\) at the true response reaches 37\.1 N at 13\.4[67] Hz in \[13\.3, 13\.6\] Hz with rig\.interface_mass: full, beyond controller\.limits\.force_n = 34 N" \
    --set controller.limits.force_n=34
check "physical_share: 30.51 N over a 30 N limit" \
    "the rig.s interface force .*reaches 30\.5 N at 13\.4[67] Hz .*rig\.interface_mass: physical_share, beyond controller\.limits\.force_n = 30 N" \
    --set controller.limits.force_n=30 --set rig.interface_mass=physical_share
check "actuator force limit" \
    "the actuator's force at the true response reaches 37\.3 N .*rig\.actuator\.limits\.force_n = 35 N" \
    --set rig.actuator.limits.force_n=35
[ "$failures" -eq 0 ] || exit 1
echo "frf_prearm_force: all passed"
