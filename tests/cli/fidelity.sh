#!/usr/bin/env bash
# rths fidelity on the seed: files and columns, the printed peak errors against docs/method.md,
# "Numerical substructure integration" (implicit Euler about a quarter low at p = 0.5, exact FOH within 0.5 %, exact ZOH several percent low),
# --set reaching the sweep and the sample rate, and bad input refused with exit 2 and nothing written.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cfg="$src/examples/four_storey.yaml"

# --- a short sweep (the peaks are refined beyond the grid, so 101 points suffice) ---
out="$work/fid"
"$bin" fidelity "$cfg" --out "$out" --set fidelity.points=101 >"$work/stdout" 2>"$work/stderr"
rc=$?
[ "$rc" -eq 0 ] || { fail "fidelity exit status $rc"; cat "$work/stderr"; }
for f in fidelity.csv summary.json config.yaml run.log fidelity.gp; do
    [ -s "$out/$f" ] || fail "missing $f"
done
if command -v gnuplot >/dev/null; then
    for f in fidelity.png fidelity.svg; do [ -s "$out/$f" ] || fail "missing $f"; done
fi
header=$(head -n 1 "$out/fidelity.csv")
expect="frequency_hz,true_amplitude_m,implicit_euler_amplitude_m,trapezoidal_amplitude_m,exact_zoh_amplitude_m,exact_foh_amplitude_m"
[ "$header" = "$expect" ] || fail "fidelity.csv header: $header"
rows=$(($(wc -l <"$out/fidelity.csv") - 1))
# 101 grid points plus up to 5 refined peak frequencies
[ "$rows" -ge 101 ] && [ "$rows" -le 106 ] || fail "fidelity.csv has $rows rows, expected 101..106"
# every row has 6 finite positive numbers; frequencies ascending; default range is +-10 % around
# the second natural frequency 13.473 Hz (docs/method.md, "The seed structure")
awk -F, 'NR > 1 { if (NF != 6) { print "bad field count at line " NR; exit 1 }
                  for (i = 1; i <= 6; i++) if (!($i + 0 > 0)) { print "non-positive at line " NR; exit 1 }
                  if (NR > 2 && $1 <= prev) { print "not ascending at line " NR; exit 1 }
                  prev = $1 }' "$out/fidelity.csv" || fail "fidelity.csv content"
awk -F, 'NR == 2 { if ($1 < 12.1 || $1 > 12.2) { print "start " $1; exit 1 } }
         END { if ($1 < 14.8 || $1 > 14.9) { print "end " $1; exit 1 } }' "$out/fidelity.csv" ||
    fail "default sweep range is not 0.9..1.1 x 13.473 Hz"

# printed peak errors (docs/method.md, "Numerical substructure integration"): implicit_euler 2.53e-4 vs 3.42e-4 m -> about -26 %; FOH within
# 0.5 %; ZOH several percent low (-3 % .. -15 %)
err_of() { awk -v s="$1" '$1 == s { print $4 }' "$work/stdout"; }
ie=$(err_of implicit_euler)
foh=$(err_of exact_foh)
zoh=$(err_of exact_zoh)
trap_e=$(err_of trapezoidal)
awk -v e="$ie" 'BEGIN { exit !(e < -24 && e > -28) }' || fail "implicit Euler peak error '$ie' %, expected about -26 %"
awk -v e="$foh" 'BEGIN { exit !(e > -0.5 && e < 0.5) }' || fail "exact FOH peak error '$foh' %, expected within 0.5 %"
awk -v e="$trap_e" 'BEGIN { exit !(e > -0.5 && e < 0.5) }' || fail "trapezoidal peak error '$trap_e' %"
awk -v e="$zoh" 'BEGIN { exit !(e < -3 && e > -15) }' || fail "exact ZOH peak error '$zoh' %, expected -3..-15 %"
# the true peak printed and in summary.json: 3.42e-4 m at 13.47 Hz (docs/method.md, "The seed structure")
python3 - "$out/summary.json" <<'PY' || fail "summary.json content"
import json, sys
s = json.load(open(sys.argv[1]))
t = s["curves"]["true"]
assert abs(t["peak_amplitude_m"] - 3.42e-4) < 0.005e-4, t
assert abs(t["peak_hz"] - 13.47) < 0.005, t
ie = s["curves"]["implicit_euler"]
assert abs(ie["peak_amplitude_m"] - 2.53e-4) < 0.005e-4, ie
assert s["sample_rate_hz"] == 10000 and s["interface_dof"] == 3, s
assert s["mass_ratio"] == 0.5
PY

# --- --set reaches the controller rate: at 20 kHz implicit Euler's error roughly halves (first
# order), so it must lie between -10 % and -17 % ---
out2="$work/fid20k"
"$bin" fidelity "$cfg" --out "$out2" --quiet --set fidelity.points=51 \
    --set controller.sample_rate_hz=20000 >"$work/stdout2" 2>&1 || fail "20 kHz run failed"
[ -s "$work/stdout2" ] && fail "--quiet printed: $(cat "$work/stdout2")"
python3 - "$out2/summary.json" <<'PY' || fail "20 kHz implicit Euler error"
import json, sys
s = json.load(open(sys.argv[1]))
e = s["curves"]["implicit_euler"]["peak_error_percent"]
assert -17 < e < -10, e
assert abs(s["time_step_s"] - 5e-05) < 1e-18
PY

# --- bad input: exit 2, a message naming the problem, nothing written ---
bad() { refused fidelity "$@"; } # name, regex, args...
bad "end below start" "fidelity.end_hz" "$cfg" --set fidelity.start_hz=20 --set fidelity.end_hz=10
bad "too few points" "fidelity.points" "$cfg" --set fidelity.points=2
bad "zero sample rate" "controller.sample_rate_hz" "$cfg" --set controller.sample_rate_hz=0
bad "unknown fidelity key" "fidelity.colour" "$cfg" --set fidelity.colour=1
bad "unknown option" "--frobnicate" "$cfg" --frobnicate
bad "missing config" "missing CONFIG"
bad "two configs" "unexpected argument" "$cfg" "$cfg"
# missing --out: nothing may be created anywhere (checked by status and message)
"$bin" fidelity "$cfg" >/dev/null 2>"$work/bstderr"
[ $? -eq 2 ] && grep -q -- "--out" "$work/bstderr" || fail "missing --out not refused"
"$bin" fidelity --help | grep -q "Usage: rths fidelity" || fail "--help"

echo "$failures failures"
[ "$failures" -eq 0 ]
