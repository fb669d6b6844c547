#!/usr/bin/env bash
# make demo: the seed's frequency-response test on the virtual rig, figures and CSV in OUT.
#   1. the true assembly (modes, analytic FRF)                      -> OUT/model
#   2. the linear hybrid test for p = 0.33, 0.5, 0.67 (12-14 Hz)     -> OUT/linear_p*, one figure
#   3. the bilinear (nonlinear) hybrid test through both folds       -> OUT/bilinear
#   4. the two-shaker cantilever (interface displacement and rotation) -> OUT/cantilever
# Usage: tools/demo.sh RTHS_BINARY OUT_DIR
set -euo pipefail
bin=${1:?usage: tools/demo.sh RTHS_BINARY OUT_DIR}
out=${2:?usage: tools/demo.sh RTHS_BINARY OUT_DIR}
here=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"

# value of a top-level number/string in a summary.json written by rths
json() { sed -n "s/^ *\"$2\": *\"\{0,1\}\([^\",]*\)\"\{0,1\},\{0,1\}$/\1/p" "$1" | head -n 1; }

echo "== 1. the true assembly: modes and analytic FRF -> $out/model"
rm -rf "$out/model"
"$bin" model "$here/examples/four_storey.yaml" --out "$out/model"

echo
echo "== 2. linear hybrid test, three mass ratios p (numerical share of storey 3's mass)"
for p in 0.33 0.5 0.67; do
    rm -rf "$out/linear_p$p"
    "$bin" frf "$here/examples/four_storey_linear.yaml" --out "$out/linear_p$p" --quiet \
        --set split.mass_ratio=$p
    s="$out/linear_p$p/summary.json"
    printf '   p = %-5s %3s points, %3s converged, %4s evaluations (median %s per point), %6.1f s rig time\n' \
        "$p" "$(json "$s" points)" "$(json "$s" converged_points)" "$(json "$s" evaluations_total)" \
        "$(json "$s" evaluations_per_point_median)" "$(json "$s" rig_time_s)"
    printf '              max deviation from the true FRF %.3f %%; %s of %s points within 3 standard errors of it\n' \
        "$(awk -v e="$(json "$s" max_relative_error_vs_truth)" 'BEGIN { print 100 * e }')" \
        "$(json "$s" points_within_3_standard_errors)" "$(json "$s" points)"
done
cat >"$out/frf_mass_ratios.gp.tmp" <<'GP'
# The three mass ratios measure the same truth, so their points coincide: the top panel nests
# their markers (large open circle, open square, small dot), the panels below draw each p shifted
# by -0.01, 0, +0.01 Hz. Bars are +-3 standard errors (the figures' convention, docs/method.md).
set datafile separator ','
set datafile columnheaders
set grid
set xrange [11.8:14.2]
set multiplot title 'Hybrid test of the seed building around its second mode, three mass ratios p'
set lmargin at screen 0.09
set rmargin at screen 0.72
set arrow from first 13.4731, graph 0 to first 13.4731, graph 1 nohead dt 3 lw 1.2 lc rgb 'gray40' back
set tmargin at screen 0.93
set bmargin at screen 0.50
set key at screen 0.735, screen 0.93 left top Left reverse samplen 2 spacing 1.1
set label 1 'mode 2: 13.4731 Hz' at first 13.4731, graph 0.05 left offset 0.6,0 font ',10' tc rgb 'gray25' front
set label 2 "the three p coincide:\nmarkers nested, below\nshifted by -0.01, 0, +0.01 Hz" at screen 0.735, screen 0.74 left font ',10'
set format x ''
set ylabel 'Storey 3 (interface) amplitude (µm)'
set yrange [0:*]
plot 'linear_p0.5/truth.csv' using 1:(column('amplitude_m') * 1e6) with lines lw 2 lc rgb 'black' title 'true assembly (analytic)', \
     'linear_p0.33/frf.csv' using 'frequency_hz':(column('amplitude_m') * 1e6) with points pt 6 ps 2.2 lw 1.5 lc rgb '#1f77b4' title 'hybrid, p = 0.33', \
     'linear_p0.5/frf.csv' using 'frequency_hz':(column('amplitude_m') * 1e6) with points pt 4 ps 1.3 lw 1.5 lc rgb '#ff7f0e' title 'hybrid, p = 0.5', \
     'linear_p0.67/frf.csv' using 'frequency_hz':(column('amplitude_m') * 1e6) with points pt 7 ps 0.6 lc rgb '#2ca02c' title 'hybrid, p = 0.67'
unset label
set yrange [*:*]
set tmargin at screen 0.46
set bmargin at screen 0.27
set key at screen 0.735, screen 0.46
set ylabel "Deviation from\ntruth (%)"
plot 0 with lines lc rgb 'black' notitle, \
     'linear_p0.33/frf.csv' using (column('frequency_hz') - 0.01):(100 * (column('amplitude_m') / column('true_amplitude_m') - 1)):(300 * column('amplitude_se_m') / column('true_amplitude_m')) with yerrorbars pt 6 ps 0.8 lc rgb '#1f77b4' title 'p = 0.33, ±3 SE', \
     'linear_p0.5/frf.csv' using 'frequency_hz':(100 * (column('amplitude_m') / column('true_amplitude_m') - 1)):(300 * column('amplitude_se_m') / column('true_amplitude_m')) with yerrorbars pt 4 ps 0.8 lc rgb '#ff7f0e' title 'p = 0.5', \
     'linear_p0.67/frf.csv' using (column('frequency_hz') + 0.01):(100 * (column('amplitude_m') / column('true_amplitude_m') - 1)):(300 * column('amplitude_se_m') / column('true_amplitude_m')) with yerrorbars pt 7 ps 0.6 lc rgb '#2ca02c' title 'p = 0.67'
set tmargin at screen 0.23
set bmargin at screen 0.07
set key at screen 0.735, screen 0.23
set format x '%g'
set xlabel 'Forcing frequency (Hz)'
set logscale y
set format y '10^{%T}'
set ylabel "Interface error,\nfundamental (nm)"
plot 'linear_p0.33/frf.csv' using (column('frequency_hz') - 0.01):(column('interface_error_m') > 0 ? column('interface_error_m') * 1e9 : 1/0) with points pt 6 ps 0.8 lc rgb '#1f77b4' title 'p = 0.33', \
     'linear_p0.5/frf.csv' using 'frequency_hz':(column('interface_error_m') > 0 ? column('interface_error_m') * 1e9 : 1/0) with points pt 4 ps 0.8 lc rgb '#ff7f0e' title 'p = 0.5', \
     'linear_p0.67/frf.csv' using (column('frequency_hz') + 0.01):(column('interface_error_m') > 0 ? column('interface_error_m') * 1e9 : 1/0) with points pt 7 ps 0.6 lc rgb '#2ca02c' title 'p = 0.67'
unset multiplot
GP
{
    echo "set terminal pngcairo size 1300,1100 font 'DejaVu Sans,12' enhanced"
    echo "set output 'frf_mass_ratios.png'"
    cat "$out/frf_mass_ratios.gp.tmp"
    echo "set terminal svg size 1300,1100 font 'DejaVu Sans,12' enhanced background rgb 'white'"
    echo "set output 'frf_mass_ratios.svg'"
    cat "$out/frf_mass_ratios.gp.tmp"
    echo "unset output"
} >"$out/frf_mass_ratios.gp"
rm -f "$out/frf_mass_ratios.gp.tmp"
if command -v gnuplot >/dev/null; then
    (cd "$out" && gnuplot frf_mass_ratios.gp) || echo "warning: gnuplot failed on $out/frf_mass_ratios.gp" >&2
else
    echo "warning: gnuplot not installed; $out/frf_mass_ratios.gp kept" >&2
fi

echo
echo "== 3. nonlinear hybrid test: bilinear leg with preload, 3 N, pseudo-arclength through the folds"
rm -rf "$out/bilinear"
"$bin" frf "$here/examples/four_storey_bilinear.yaml" --out "$out/bilinear" --quiet
s="$out/bilinear/summary.json"
printf '   %s points, %s converged, %s evaluations; max deviation from the shooting solution %.3f %%\n' \
    "$(json "$s" points)" "$(json "$s" converged_points)" "$(json "$s" evaluations_total)" \
    "$(awk -v e="$(json "$s" max_relative_error_vs_truth)" 'BEGIN { print 100 * e }')"
printf '   %s of %s points farther than 5 mHz from a fold within 3 standard errors of the truth on their branch;\n' \
    "$(json "$s" points_far_from_folds_within_3_standard_errors)" "$(json "$s" points_far_from_folds)"
printf '   stable label (fold-based) agrees with the shooting solution'"'"'s Floquet stability for %s of %s points\n' \
    "$(json "$s" stability_points_agreeing)" "$(json "$s" stability_points_compared)"
# the hybrid test's located folds, and the shooting solution's (where its stability flips)
printf '   folds (Hz): hybrid %s; shooting %s\n' \
    "$(sed -n 's/.*"frequency_hz": *\([0-9.]*\).*/\1/p' "$s" | awk '{ printf "%s%.4f", (NR > 1 ? ", " : ""), $1 }')" \
    "$(awk -F, 'NR > 2 && $5 != prev { printf "%s%.4f", n++ ? ", " : "", $1 } NR > 1 { prev = $5 }' "$out/bilinear/truth.csv")"

echo
echo "== 4. two interface DoFs: the follow-up's steel cantilever, numerical clamped root, physical tip,"
echo "      two shakers and two lasers through transforms (examples/cantilever_two_shakers.yaml)"
rm -rf "$out/cantilever"
"$bin" frf "$here/examples/cantilever_two_shakers.yaml" --out "$out/cantilever" --quiet
python3 - "$out/cantilever/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
print("   %d points, %d converged, %d evaluations (median %.1f per point), %.0f s rig time"
      % (s["points"], s["converged_points"], s["evaluations_total"],
         s["evaluations_per_point_median"], s["rig_time_s"]))
for d in s["interface_dofs"]:
    print("   interface DoF %d (%s): max deviation from the true FRF %.3f %%; %d of %d points within "
          "3 standard errors" % (d["interface_dof"], "rotation, rad" if d["unit"] == "rad" else
          "displacement, m", 100 * d["max_relative_error_vs_truth"],
          d["points_within_3_standard_errors"], d["points_compared_with_truth"]))
PY

echo
echo "Figures: $out/model/true_frf.png, $out/frf_mass_ratios.png, $out/bilinear/frf.png,"
echo "         $out/bilinear/iterations.png, $out/linear_p0.5/lissajous.png,"
echo "         $out/linear_p0.5/bode.png, $out/linear_p0.5/nyquist.png,"
echo "         $out/cantilever/frf.png (CSV and .gp beside each)"
echo "Modes identified from the hybrid FRF: $out/linear_p0.5/modal.csv (UFF58: frf.uff)"
