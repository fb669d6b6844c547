#!/usr/bin/env bash
# rths chart on the seed (examples/four_storey.yaml) with a coarse grid via --set: files, columns,
# the seed's facts (p <= 1/2 never stable, critical delay of order 1e-4 s at the first mode near
# 27.26 rad/s, essential-spectrum limit p = 1/2), --quiet, and bad input refused with exit 2 and
# nothing written.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cfg="$src/examples/four_storey.yaml"
coarse=(--set stability.tau_points=30 --set stability.p_points=25 --set stability.mdbm_tau_points=20
        --set stability.mdbm_p_points=20 --set stability.omega_points=56)

out="$work/chart"
"$bin" chart "$cfg" --out "$out" "${coarse[@]}" >"$work/stdout" 2>"$work/stderr"
rc=$?
[ "$rc" -eq 0 ] || { fail "chart exit status $rc"; cat "$work/stderr"; }
for f in chart.csv boundary.csv critical.csv summary.json config.yaml run.log chart.gp; do
    [ -s "$out/$f" ] || fail "missing $f"
done
if command -v gnuplot >/dev/null; then
    for f in chart.png chart.svg; do [ -s "$out/$f" ] || fail "missing $f"; done
fi
[ "$(head -n 1 "$out/chart.csv")" = "tau_s,p,max_real_part_per_s,stable" ] ||
    fail "chart.csv header: $(head -n 1 "$out/chart.csv")"
[ "$(head -n 1 "$out/boundary.csv")" = "tau_s,p,omega_rad_s" ] ||
    fail "boundary.csv header: $(head -n 1 "$out/boundary.csv")"
[ "$(head -n 1 "$out/critical.csv")" = "p,critical_delay_s,crossing_omega_rad_s" ] ||
    fail "critical.csv header: $(head -n 1 "$out/critical.csv")"
rows=$(($(wc -l <"$out/chart.csv") - 1))
[ "$rows" -eq 750 ] || fail "chart.csv has $rows rows, expected 30 x 25 = 750"
crit_rows=$(($(wc -l <"$out/critical.csv") - 1))
[ "$crit_rows" -eq 25 ] || fail "critical.csv has $crit_rows rows, expected 25"
# chart rows: 4 fields, tau inside the default range, stable is 0/1 and agrees with the sign of
# max_real_part; p <= 1/2 never stable (docs/method.md, "Delayed-feedback stability")
awk -F, 'NR > 1 { if (NF != 4) { print "fields at " NR; exit 1 }
                  if ($1 < 5e-5 * (1 - 1e-12) || $1 > 3e-4 * (1 + 1e-12)) { print "tau " $1; exit 1 }
                  if ($4 != 0 && $4 != 1) { print "stable " $4; exit 1 }
                  if ($4 == 1 && !($3 < 0)) { print "stable with max real part " $3; exit 1 }
                  if ($2 <= 0.5 && $4 == 1) { print "stable at p = " $2; exit 1 }
                  if ($4 == 1) ns++ }
         END { if (ns < 10) { print "only " ns " stable points"; exit 1 } }' "$out/chart.csv" ||
    fail "chart.csv content"
# boundary points: the first-mode crossing (about 27.26 rad/s) inside the ranges
awk -F, 'NR > 1 { if (NF != 3 || $3 < 0 || $3 > 550 || $2 < 0.01 - 1e-9 || $2 > 0.99 + 1e-9) {
                    print "bad boundary row " NR; exit 1 }
                  if ($3 > 27 && $3 < 27.5) first++ }
         END { if (NR < 20 || first < 10) { print NR " rows, " first " near 27.26 rad/s"; exit 1 } }' \
    "$out/boundary.csv" || fail "boundary.csv content"
python3 - "$out/summary.json" "$out/critical.csv" <<'PY' || fail "summary.json / critical.csv content"
import csv, json, math, sys
s = json.load(open(sys.argv[1]))
assert abs(s["essential_spectrum"]["p_limit"] - 0.5) < 1e-9, s["essential_spectrum"]
assert "left half-plane" in s["essential_spectrum"]["statement"]
x = s["labels_vs_boundaries"]
assert x["label_changes_without_boundary"] == 0 and x["boundary_points_inside_stable_region"] == 0, x
assert s["boundary_max_scaled_residual"] < 1e-9
crit = {round(c["p"], 4): c for c in s["critical_delays"]}
c = crit[0.67]
assert 5e-5 < c["critical_delay_s"] < 3e-4 and abs(c["crossing_omega_rad_s"] - 27.26) < 0.5, c
assert crit[0.5]["critical_delay_s"] == 0.0
for row in csv.DictReader(open(sys.argv[2])):
    p, t = float(row["p"]), float(row["critical_delay_s"])
    if p <= 0.5:
        assert t == 0.0, row
    else:
        assert 5e-5 < t < 3e-4, row
        assert abs(float(row["crossing_omega_rad_s"]) - 27.26) < 0.5, row
PY
grep -q "critical_delay_s" "$work/stdout" || fail "no critical-delay table printed"

# --quiet prints nothing
"$bin" chart "$cfg" --out "$work/q" --quiet "${coarse[@]}" --set stability.p_points=3 \
    >"$work/qout" 2>&1 || fail "--quiet run failed"
[ -s "$work/qout" ] && fail "--quiet printed: $(cat "$work/qout")"

# --- bad input: exit 2, a message naming the problem, nothing written ---
bad() { refused chart "$@"; } # name, regex, args...
bad unknown_key "stability\.tau_maxx" "$cfg" --set stability.tau_maxx=1e-3
bad negative_tau "stability\.tau_min_s" "$cfg" --set stability.tau_min_s=-1e-5
bad tau_order "stability\.tau_max_s" "$cfg" --set stability.tau_min_s=4e-4
bad p_range "stability\.p_max" "$cfg" --set stability.p_max=1.5
bad wrong_type "stability\.tau_points" "$cfg" --set stability.tau_points=many
bad no_out_cfg "CONFIG|config" --set stability.tau_points=3
bad missing_file "nonexistent" "$work/nonexistent.yaml"

# --help
"$bin" chart --help >"$work/help" 2>&1 || fail "--help exit status"
grep -q "stability.tau_min_s" "$work/help" || fail "--help does not list the keys"

# a configuration written for rths frf runs as it is: its continuation section (method, steps)
# is the run's; the controller's reading of the sweep (the band of a sparse model's real-time
# reduction) does not make chart the owner of it (a merge once refused continuation.method here)
"$bin" chart "$src/examples/four_storey_bilinear.yaml" --out "$work/frf_config" --quiet \
    >"$work/out" 2>&1 || fail "chart refused an rths frf configuration: $(head -c 300 "$work/out")"
"$bin" simulate "$src/examples/four_storey_bilinear.yaml" --frequency 13 --periods 2 --target 1e-4,0 \
    --out "$work/frf_config_sim" --quiet >"$work/out" 2>&1 ||
    fail "simulate refused an rths frf configuration: $(head -c 300 "$work/out")"

[ "$failures" -eq 0 ] || { echo "$failures failure(s)"; exit 1; }
echo "chart: all checks passed"
