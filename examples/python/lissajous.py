#!/usr/bin/env python3
"""Load a finished FRF run and plot its Lissajous figures: for every accepted point the physical
against the numerical interface displacement over one period, rebuilt from the harmonic
coefficients in the run's results.mat (a perfect test draws a line of slope 1), and the recorded
time trace (trace.csv) of the traced point.

    make build && make demo        # or any `rths frf ... --out DIR`
    sudo apt install python3-matplotlib python3-h5py
    python3 examples/python/lissajous.py out/demo/linear_p0.33     -> DIR/lissajous_python.png
"""
import os
import sys

import h5py
import numpy as np

from _common import pyplot, rths

folder = sys.argv[1] if len(sys.argv) > 1 else "out/demo/linear_p0.33"
run = rths.read_run(folder)
with h5py.File(os.path.join(folder, "results.mat"), "r") as mat:
    h = {name: mat["harmonics"][name][()].ravel() for name in mat["harmonics"].keys()}

phase = np.linspace(0, 2 * np.pi, 200)


def signal(side, i):
    """x(t) = a0 + sum_k a_k cos(k w t) + b_k sin(k w t) over one period, point i."""
    x = np.full_like(phase, h[f"{side}_a0_m"][i])
    k = 1
    while f"{side}_a{k}_m" in h:
        x += h[f"{side}_a{k}_m"][i] * np.cos(k * phase) + h[f"{side}_b{k}_m"][i] * np.sin(k * phase)
        k += 1
    return x


plt = pyplot()
fig, (left, middle, right) = plt.subplots(1, 3, figsize=(19, 6))
norm = plt.Normalize(h["frequency_hz"].min(), h["frequency_hz"].max())
for i, f_hz in enumerate(h["frequency_hz"]):
    colour = plt.cm.viridis(norm(f_hz))
    left.plot(1e6 * signal("phys", i), 1e6 * signal("num", i), color=colour, lw=1)
    # what is left of the mismatch at an accepted point: small loops, nanometres
    middle.plot(1e6 * signal("phys", i), 1e9 * (signal("num", i) - signal("phys", i)),
                color=colour, lw=1)
sm = plt.cm.ScalarMappable(cmap="viridis", norm=norm)
fig.colorbar(sm, ax=middle, label="Forcing frequency (Hz)")
middle.set_xlabel("Physical interface displacement x_3 (µm)")
middle.set_ylabel("Interface mismatch ξ_3 − x_3 (nm)")
middle.set_title("The mismatch left at each accepted point")
middle.grid(True)
left.set_xlabel("Physical interface displacement x_3 (µm)")
left.set_ylabel("Numerical interface displacement ξ_3 (µm)")
left.set_title(f"Every accepted point ({len(h['point'])}), from results.mat")
left.set_aspect("equal", adjustable="datalim")
left.grid(True)
if "trace" in run.tables:
    t = run.trace
    right.plot(1e6 * t.x_phys_m, 1e6 * t.x_num_m, lw=1.5, label="measured, 3 periods")
    right.set_title("Traced point (trace.csv)")
    right.set_xlabel("Physical interface displacement x_3 (µm)")
    right.set_ylabel("Numerical interface displacement ξ_3 (µm)")
    right.set_aspect("equal", adjustable="datalim")
    right.grid(True)
    right.legend()
fig.tight_layout()
path = os.path.join(folder, "lissajous_python.png")
fig.savefig(path, dpi=110)
print("figure:", path)
