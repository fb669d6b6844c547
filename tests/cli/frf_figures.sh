#!/usr/bin/env bash
# The FRF figures' convention (docs/method.md, "Figures"; report.h), read from the gnuplot scripts
# rths frf writes beside each PNG and checked against the run's own CSV files:
# 1. lissajous: units per magnitude. A bilinear sweep over the upper fold (its trace, at the
#    largest amplitude, reaches 3.6 mm in its target) labels the axes in mm and scales by 1e3;
#    a linear sweep (targets below 1 mm) in µm, by 1e6. The expected unit is computed here from
#    trace.csv (the SI unit times the power of 1000 that puts the largest |value| of the DoF's
#    physical, numerical and target traces in [1, 1000)); the labels said µm for every run.
# 2. bode with a bilinear leg: a deviation-from-truth panel with data. The shooting truth has
#    the amplitude on each branch, not the phase, so the panel shows (|H| - |H_true|) / |H_true|
#    with |H_true| = A_true / F: its data block must equal 100 (A / A_true - 1) and its bars
#    300 SE / A_true from frf.csv's amplitude_m, amplitude_se_m and true_amplitude_m at every
#    converged point (to the 8 digits written); the panel was empty ("no analytic truth"), and
#    the top panel now draws the truth's |H| (truth.csv's amplitude over F).
# 4. nyquist on a linear structure: the truth drawn smooth. truth.csv's grid drew the circle as
#    a polygon (sides a tenth of its diameter near the mode); the script's $truth block holds
#    every truth.csv frequency with its receptance (to the 8 digits written) and enough points
#    between them that no chord exceeds 1 % of the largest |H|.
# 3. iterations: the tallest bar stays below the frame (the y range clears the largest count
#    of frf.csv's iterations column by at least one and at most a fifth); it met the frame
#    when the count fell on a tick ([0:*]).
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"

bil="$src/examples/four_storey_bilinear.yaml"
lin="$src/examples/four_storey_linear.yaml"
"$bin" frf "$bil" --out "$work/bil" --quiet --set continuation.start_hz=13.8 \
    --set continuation.max_points=22 || fail "bilinear run"
"$bin" frf "$lin" --out "$work/lin" --quiet --set continuation.start_hz=13.0 \
    --set continuation.end_hz=13.6 --set rig.noise=false || fail "linear run"

/usr/bin/python3 - "$work/bil" "$work/lin" <<'PY' || fail "figure convention (above)"
import csv, math, re, sys

bad = 0


def check(ok, msg):
    global bad
    print(("ok   " if ok else "FAIL ") + msg)
    bad += not ok


def expected_unit(max_abs, si):
    """report.h's rule: the SI unit times the power of 1000 that reads max_abs in [1, 1000)."""
    prefixes = ["", "m", "µ", "n", "p"]
    k = 0
    while k < 4 and max_abs * 1000**k < 1:
        k += 1
    return prefixes[k] + si, 1000**k


def block(script, name):
    """The data block $name of a gnuplot script (its first copy: PNG), as rows of dicts."""
    text = open(script, encoding="utf-8").read()
    m = re.search(r"^\$" + re.escape(name) + r" << EOD\n(.*?)^EOD$", text, re.S | re.M)
    return list(csv.DictReader(m.group(1).splitlines())) if m else None


for run in sys.argv[1:]:
    name = run.rsplit("/", 1)[1]
    # 1. lissajous units from trace.csv (one interface DoF here: columns 2-4)
    trace = list(csv.DictReader(open(run + "/trace.csv")))
    peak = max(abs(float(r[k])) for r in trace for k in ("x_phys_m", "x_num_m", "target_m"))
    unit, scale = expected_unit(peak, "m")
    gp = open(run + "/lissajous.gp", encoding="utf-8").read()
    labels = set(re.findall(r"^set ylabel 'Displacement \((.*?)\)'$", gp, re.M))
    factors = set(re.findall(r"using 1:\(\$2 \* ([0-9.e+]+)\)", gp))
    check(labels == {unit} and {float(f) for f in factors} == {scale},
          f"{name} lissajous: peak {peak * 1e3:.3f} mm -> '{unit}' x {scale:g}; "
          f"script: {sorted(labels)} x {sorted(factors)}")

    # 3. iterations: the range clears the tallest bar
    rows = list(csv.DictReader(open(run + "/frf.csv")))
    counts = {}
    for r in rows:
        counts[int(float(r["iterations"]))] = counts.get(int(float(r["iterations"])), 0) + 1
    tallest = max(counts.values())
    top = re.search(r"^set yrange \[0:(\d+)\]$", open(run + "/iterations.gp").read(), re.M)
    check(top is not None and tallest < int(top.group(1)) <= tallest + max(1, tallest // 5),
          f"{name} iterations: tallest bar {tallest}, y range to "
          f"{top.group(1) if top else 'autoscale (meets the frame on a tick)'}")

# 2. the bilinear bode's deviation panel against frf.csv
run = sys.argv[1]
rows = [r for r in csv.DictReader(open(run + "/frf.csv")) if r["converged"] == "1"]
rec = block(run + "/bode.gp", "rec1")
check(rec is not None and len(rec) == len(rows),
      f"bilinear bode: {len(rec) if rec else 0} deviation rows for {len(rows)} converged points")
worst_dev = worst_bar = 0.0  # percentage points; relative
for r, d in zip(rows, rec or []):
    a, se, truth = float(r["amplitude_m"]), float(r["amplitude_se_m"]), float(r["true_amplitude_m"])
    want_dev, want_bar = 100 * (a / truth - 1), 300 * se / truth
    dev, bar = float(d["deviation_percent"]), float(d["bar_percent"])
    worst_dev = max(worst_dev, abs(dev - want_dev) if math.isfinite(dev) else math.inf)
    worst_bar = max(worst_bar, abs(bar / want_bar - 1) if math.isfinite(bar) else math.inf)
# 8 significant digits written: 1e-6 of a deviation of at most a few %, 1e-6 relative for bars
check(rec is not None and worst_dev < 1e-6 and worst_bar < 1e-6,
      f"bilinear bode: deviation and bars equal frf.csv's (largest differences {worst_dev:.2g} "
      f"percentage points, {worst_bar:.2g} relative)")
gp = open(run + "/bode.gp", encoding="utf-8").read()
check("column('amplitude_m') / 3 *" in gp and "true assembly, unstable" in gp,
      "bilinear bode: the shooting truth's |H| (truth.csv amplitude over F = 3 N) drawn, "
      "stable and unstable")

# 4. the linear run's Nyquist truth against truth.csv
run = sys.argv[2]
truth = list(csv.DictReader(open(run + "/truth.csv")))
ref = block(run + "/nyquist.gp", "truth")
gp = open(run + "/nyquist.gp", encoding="utf-8").read()
scale = 1e6  # µm/N: the receptance peaks at 341 µm/N on this range
check(ref is not None and "Re H (µm/N)" in gp, "linear nyquist: a $truth block, in µm/N")
if ref:
    freqs = sorted(float(r["frequency_hz"]) for r in ref)
    at = {float(r["frequency_hz"]): r for r in ref}
    worst = 0.0
    for r in truth:
        f = float(r["frequency_hz"])
        h = complex(float(r["receptance_real_m_per_n"]), float(r["receptance_imag_m_per_n"]))
        near = min(freqs, key=lambda x: abs(x - f))  # written to 10 digits
        got = at[near] if abs(near - f) <= 1e-9 * f else None
        if got is None:
            worst = math.inf
            break
        worst = max(worst, abs(complex(float(got["real_1"]), float(got["imag_1"])) / scale - h)
                    / abs(h))
    pts = [complex(float(r["real_1"]), float(r["imag_1"])) for r in ref]
    top = max(abs(p) for p in pts)
    chord = max(abs(pts[j + 1] - pts[j]) for j in range(len(pts) - 1)) / top
    check(worst < 1e-6 and chord <= 0.01,
          f"linear nyquist: {len(ref)} truth points for truth.csv's {len(truth)} (each of its "
          f"rows to {worst:.2g}), largest chord {100 * chord:.2f} % of max |H|")
sys.exit(1 if bad else 0)
PY
exit $((failures > 0))
