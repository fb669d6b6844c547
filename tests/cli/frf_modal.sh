#!/usr/bin/env bash
# The modal-testing outputs of `rths frf` (issue 28): on the linear example (the run `make demo`
# makes for p = 0.5, noise on, 41 points over 12-14 Hz)
#  - frf.csv's receptance columns are the reported amplitude and phase over the 1 N force, and
#    truth.csv's equal numpy's complex solve of the seed chain (independent of rths) to 1e-9;
#  - modal.csv identifies mode 2 within 0.1 % in frequency and 10 % in damping of the truth's
#    13.4731 Hz / 0.3516 % (measured: -0.0001 % and -0.3 %), its truth columns equal numpy's modes;
#  - frf.uff, read back by a small universal-file-format-58 reader written here (fixed-width
#    records as the dataset defines them; pyuff is not packaged in Debian), holds every converged
#    point's receptance as frf.csv does (abscissa to its 6 significant digits, values to 1e-11).
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
"$bin" frf "$src/examples/four_storey_linear.yaml" --out "$work/lin" --quiet 2>"$work/err" ||
    fail "rths frf: $(cat "$work/err")"
/usr/bin/python3 - "$work/lin" <<'PY' || fail "receptance, modal.csv or frf.uff"
import csv, sys
import numpy as np
d = sys.argv[1]
bad = []
m = np.diag([5.37, 5.37, 5.37, 10.74])
def chain(v):
    a = np.zeros((4, 4))
    for i in range(4):
        a[i, i] += v[i]
        if i > 0:
            a[i - 1, i - 1] += v[i]; a[i - 1, i] -= v[i]; a[i, i - 1] -= v[i]
    return a
c, k = chain([4.4062, 3.7979, 3.7421, 3.7421]), chain([53048, 45724, 45052, 45052])
force = np.array([0, 0, 0, 1.0])
def truth(hz):  # storey 3 per newton on storey 4
    w = 2 * np.pi * hz
    return np.linalg.solve(k - w * w * m + 1j * w * c, force)[2]

rows = list(csv.DictReader(open(d + "/frf.csv")))
names = list(rows[0].keys())
if names[:29] != ["point", "frequency_hz", "amplitude_m", "numerical_amplitude_m", "phase_rad",
                  "interface_error_m", "interface_error_h2_m", "interface_error_h3_m",
                  "amplitude_h2_m", "amplitude_h3_m", "target_a1_m", "target_b1_m",
                  "residual_norm_m", "tolerance_m", "evaluations", "iterations", "rig_time_s",
                  "converged", "fold", "segment", "amplitude_se_m", "measured_amplitude_m",
                  "se_honest", "stable", "late_samples", "clipped_demand_samples",
                  "saturated_sensor_samples", "resumed", "below_noise_floor"] \
        or names[29:] != ["receptance_real_m_per_n", "receptance_imag_m_per_n", "true_amplitude_m"]:
    bad.append("frf.csv header %s" % names)
h = np.array([complex(float(r["receptance_real_m_per_n"]), float(r["receptance_imag_m_per_n"]))
              for r in rows])
amp = np.array([float(r["amplitude_m"]) for r in rows])
phase = np.array([float(r["phase_rad"]) for r in rows])
f = np.array([float(r["frequency_hz"]) for r in rows])
# |H| is the reported (matched) amplitude; its phase the matched estimate's, within the small
# extrapolation of the measured phase_rad (measured: 2.5e-3 rad at most)
amp_err = np.max(np.abs(np.abs(h) / amp - 1))
phase_err = np.max(np.abs(np.angle(h * np.exp(-1j * phase))))
if amp_err > 1e-12 or phase_err > 0.01:
    bad.append("receptance vs amplitude/phase: %.1e, %.1e rad" % (amp_err, phase_err))
hyb_err = np.max(np.abs(h - np.array([truth(x) for x in f])) / np.abs(h))
if hyb_err > 0.01:
    bad.append("hybrid receptance vs numpy: %.2e" % hyb_err)
true_amp = np.array([float(r["true_amplitude_m"]) for r in rows])
ta_err = np.max(np.abs(true_amp / np.abs([truth(x) for x in f]) - 1))
if ta_err > 1e-9:
    bad.append("true_amplitude_m vs numpy: %.1e" % ta_err)
t = list(csv.DictReader(open(d + "/truth.csv")))
t_err = max(abs(complex(float(r["receptance_real_m_per_n"]), float(r["receptance_imag_m_per_n"]))
                / truth(float(r["frequency_hz"])) - 1) for r in t)
if t_err > 1e-9:
    bad.append("truth.csv receptance vs numpy: %.1e" % t_err)

# modal.csv: mode 2 and its truth (numpy's undamped modes, mass-normalised; proportional damping)
modal = list(csv.DictReader(open(d + "/modal.csv")))
if len(modal) != 1 or modal[0]["mode"] != "2":
    bad.append("modal.csv rows: %s" % [r["mode"] for r in modal])
else:
    r = {key: float(v) for key, v in modal[0].items()}
    w2, phi = np.linalg.eig(np.linalg.solve(m, k))
    order = np.argsort(w2)
    w2, phi = w2[order], phi[:, order]
    phi = phi / np.sqrt(np.diag(phi.T @ m @ phi))
    zeta = np.diag(phi.T @ c @ phi) / (2 * np.sqrt(w2))
    true_a = phi[2, 1] * phi[3, 1]
    if abs(r["true_frequency_hz"] / (np.sqrt(w2[1]) / 2 / np.pi) - 1) > 1e-9 \
            or abs(r["true_damping_ratio"] / zeta[1] - 1) > 1e-6 \
            or abs(r["true_modal_constant_per_kg"] / true_a - 1) > 1e-6:
        bad.append("modal.csv truth %s" % r)
    df = r["frequency_hz"] / 13.4731 - 1
    dz = r["damping_ratio"] / 0.003516 - 1
    da = r["modal_constant_real_per_kg"] / true_a - 1
    print("mode 2: %.5f +- %.5f Hz (%+.4f %%), damping %.4f +- %.4f %% (%+.2f %%), modal constant "
          "%.5g +- %.2g 1/kg (%+.2f %%), %d bootstrap replicates"
          % (r["frequency_hz"], r["frequency_se_hz"], 100 * df, 100 * r["damping_ratio"],
             100 * r["damping_ratio_se"], 100 * dz, r["modal_constant_real_per_kg"],
             r["modal_constant_real_se_per_kg"], 100 * da, r["bootstrap_replicates"]))
    if abs(df) > 1e-3 or abs(dz) > 0.1 or abs(da) > 0.1:
        bad.append("mode 2 not within 0.1 %% / 10 %%: %+.4f %%, %+.2f %%" % (100 * df, 100 * dz))
    if not (r["frequency_se_hz"] > 0 and r["damping_ratio_se"] > 0 and r["bootstrap_replicates"] == 200):
        bad.append("modal.csv standard errors %s" % r)

# frf.uff: an independent reader of dataset 58 (uneven abscissa, complex double ordinates)
def read_uff58(path):
    lines = open(path).read().split("\n")
    sets, i = [], 0
    while i < len(lines):
        if lines[i].strip() == "-1" and i + 1 < len(lines) and lines[i + 1].strip() == "58":
            ids = lines[i + 2:i + 7]
            r6 = lines[i + 7]
            func_type, func_id = int(r6[0:5]), int(r6[5:15])
            resp_node, resp_dir = int(r6[41:51]), int(r6[51:55])
            ref_node, ref_dir = int(r6[66:76]), int(r6[76:80])
            r7 = lines[i + 8]
            ord_type, npts, spacing = int(r7[0:10]), int(r7[10:20]), int(r7[20:30])
            axes = [(int(l[0:10]), l[26:46].strip(), l[47:67].strip()) for l in lines[i + 9:i + 13]]
            data = []
            for l in lines[i + 13:i + 13 + npts]:
                data.append((float(l[0:13]), complex(float(l[13:33]), float(l[33:53]))))
            if lines[i + 13 + npts].strip() != "-1":
                raise ValueError("dataset not closed")
            sets.append(dict(ids=ids, func_type=func_type, func_id=func_id, resp=(resp_node, resp_dir),
                             ref=(ref_node, ref_dir), ord_type=ord_type, spacing=spacing,
                             axes=axes, data=data))
            i += 14 + npts
        else:
            i += 1
    return sets
sets = read_uff58(d + "/frf.uff")
if len(sets) != 1:
    bad.append("frf.uff: %d datasets" % len(sets))
else:
    s = sets[0]
    if (s["func_type"], s["ord_type"], s["spacing"], s["resp"], s["ref"]) != (4, 6, 0, (3, 1), (4, 1)):
        bad.append("frf.uff record 6/7: %s" % s)
    if [a[0] for a in s["axes"]] != [18, 8, 13, 0] or s["axes"][1][2] != "m" or s["axes"][2][2] != "N":
        bad.append("frf.uff axes %s" % s["axes"])
    fu = np.array([x[0] for x in s["data"]])
    hu = np.array([x[1] for x in s["data"]])
    if len(fu) != len(f) or np.max(np.abs(fu / f - 1)) > 5e-6 or np.max(np.abs(hu - h)) > 1e-11 * np.max(np.abs(h)):
        bad.append("frf.uff values differ from frf.csv")
print("receptance vs amplitude/phase %.1e / %.1e rad, vs numpy %.2e; truth.csv %.1e; frf.uff %d points"
      % (amp_err, phase_err, hyb_err, t_err, len(sets[0]["data"]) if sets else 0))
for b in bad:
    print("FAIL", b)
sys.exit(1 if bad else 0)
PY
[ "$failures" -eq 0 ] || exit 1
echo "frf_modal: ok"
