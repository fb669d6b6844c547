#!/usr/bin/env bash
# rths fidelity on a nonlinear example (issue 27; docs/method.md, "Integration fidelity with
# nonlinear elements"): the bilinear leg below storey 4 on the numerical side, 15.05..15.15 Hz (just past
# the fold pair near 14.96-14.99 Hz, where the response has higher harmonics). The real-time step,
# simulating the whole assembly at 10 and 20 kHz, against the harmonic-balance truth:
#  - fidelity.csv carries the three nonlinear columns after the linear ones, numbers at the
#    comparison's frequencies;
#  - the truth's own truncation (48 against 24 harmonics) is far below the step's error, so the
#    error measured is the step's;
#  - the error is below 1e-4 at the default 10 kHz (measured 2.0e-5 at 15.05 Hz, 4.2e-5 at 15.1);
#  - it falls with the sample period as the step's stated second order (docs/method.md,
#    "Nonlinear elements in the real-time step"): ratio > 2^1.5 between 10 and 20 kHz at every
#    frequency (measured about 4);
#  - a bad fidelity.nonlinear_points is refused, naming the key.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cfg="$src/examples/four_storey_bilinear_numerical.yaml"
sweep=(--set fidelity.start_hz=15.05 --set fidelity.end_hz=15.15 --set fidelity.points=3
    --set fidelity.nonlinear_points=3)

for rate in 10000 20000; do
    "$bin" fidelity "$cfg" --out "$work/r$rate" "${sweep[@]}" \
        --set controller.sample_rate_hz=$rate >"$work/stdout$rate" 2>"$work/stderr$rate"
    rc=$?
    [ "$rc" -eq 0 ] || { fail "fidelity at $rate Hz: exit $rc"; cat "$work/stderr$rate"; }
done
grep -q "Nonlinear elements: the step" "$work/stdout10000" || fail "nonlinear table not printed"
header=$(head -n 1 "$work/r10000/fidelity.csv")
expect="frequency_hz,true_amplitude_m,implicit_euler_amplitude_m,trapezoidal_amplitude_m,exact_zoh_amplitude_m,exact_foh_amplitude_m,nonlinear_true_amplitude_m,nonlinear_step_amplitude_m,nonlinear_step_error_relative"
[ "$header" = "$expect" ] || fail "fidelity.csv header: $header"

python3 - "$work/r10000/summary.json" "$work/r20000/summary.json" "$work/r10000/fidelity.csv" <<'PY' || fail "nonlinear errors"
import csv, json, math, sys
s10, s20 = (json.load(open(p))["nonlinear"] for p in sys.argv[1:3])
ok = True
def check(cond, what):
    global ok
    print(("ok   " if cond else "FAIL ") + what)
    ok &= bool(cond)
check(s10["scheme"] == "exact_foh" and s10["harmonics"] == 48, "scheme and harmonics")
check(len(s10["points"]) == 3 and len(s20["points"]) == 3, "three frequencies")
for p10, p20 in zip(s10["points"], s20["points"]):
    f = p10["frequency_hz"]
    e10, e20 = p10["error_relative"], p20["error_relative"]
    check(e10 is not None and e20 is not None, f"{f:g} Hz: a truth at both rates")
    if e10 is None or e20 is None:
        continue
    check(p10["settled"] and p20["settled"], f"{f:g} Hz: the step's response settled")
    check(p10["truth_truncation_relative"] < 0.01 * e20,
          f"{f:g} Hz: truth truncation {p10['truth_truncation_relative']:.2e} << error {e20:.2e}")
    check(e10 < 1e-4, f"{f:g} Hz: error at 10 kHz {e10:.3e} < 1e-4")
    check(e10 / e20 > 2 ** 1.5, f"{f:g} Hz: error ratio 10/20 kHz {e10 / e20:.2f} > 2^1.5")
    # the same truth at both rates (it does not depend on the step)
    check(abs(p10["true_amplitude_m"] / p20["true_amplitude_m"] - 1) < 1e-12, f"{f:g} Hz: one truth")
rows = list(csv.DictReader(open(sys.argv[3])))
filled = [r for r in rows if r["nonlinear_step_amplitude_m"] != "nan"]
check(len(filled) == 3, f"{len(filled)} rows with the step's amplitude")
for r in filled:
    e = float(r["nonlinear_step_error_relative"])
    a, t = float(r["nonlinear_step_amplitude_m"]), float(r["nonlinear_true_amplitude_m"])
    check(math.isclose(abs(a / t - 1), e, rel_tol=1e-6), f"csv error column at {r['frequency_hz']}")
sys.exit(0 if ok else 1)
PY

bad() { refused fidelity "$@"; }
bad "nonlinear_points above points" "fidelity.nonlinear_points" "$cfg" --set fidelity.points=5 \
    --set fidelity.nonlinear_points=6
bad "nonlinear_points below 2" "fidelity.nonlinear_points" "$cfg" --set fidelity.nonlinear_points=1

echo "$failures failures"
[ "$failures" -eq 0 ]
