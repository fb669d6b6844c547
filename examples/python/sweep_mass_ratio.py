#!/usr/bin/env python3
"""Sweep the mass ratio p (numerical share of the interface storey's mass): the iterative hybrid
test of the seed building across its second mode for several p, against the true assembly's
analytic FRF, in one figure.

    make build
    sudo apt install python3-matplotlib      # or pip in a virtual environment (docs/python.md)
    python3 examples/python/sweep_mass_ratio.py [OUT_DIR]      -> OUT_DIR/mass_ratios.png
"""
import os
import sys

from _common import example, pyplot, rths, run_frf

out = sys.argv[1] if len(sys.argv) > 1 else "out/python_sweep"
os.makedirs(out, exist_ok=True)
base = rths.Config.load(example("four_storey_linear.yaml"))
truth = rths.model(base).true_frf  # p does not change the true assembly
band = (truth.frequency_hz >= 11.5) & (truth.frequency_hz <= 14.5)

plt = pyplot()
fig, ax = plt.subplots(figsize=(9, 6))
ax.plot(truth.frequency_hz[band], truth.x3_amplitude_m[band], "k-", lw=2,
        label="true assembly (analytic)")
for p, marker in ((0.33, "o"), (0.5, "s"), (0.67, "^")):
    folder = os.path.join(out, f"p{p}")
    run = run_frf(base.with_set({"split.mass_ratio": p}), folder, seed=1)
    frf = run.frf
    ax.plot(frf.frequency_hz, frf.amplitude_m, marker, ms=5, mfc="none",
            label=f"hybrid test, p = {p} ({frf.rows} points, "
                  f"{int(frf.evaluations.sum())} evaluations)")
    print(f"p = {p}: {frf.rows} points, max interface error {frf.interface_error_m.max():.2e} m,"
          f" {run.summary.get('points_within_3_standard_errors')} within 3 standard errors")
ax.set_xlabel("Forcing frequency (Hz)")
ax.set_ylabel("Interface (storey 3) displacement amplitude (m)")
ax.set_title("Iterative hybrid test of the seed building for three mass ratios")
ax.grid(True)
ax.legend()
fig.tight_layout()
fig.savefig(os.path.join(out, "mass_ratios.png"), dpi=120)
print("figure:", os.path.join(out, "mass_ratios.png"))
