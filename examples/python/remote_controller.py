#!/usr/bin/env python3
"""Drive a remote controller process: start `rths controller` (the real-time side a lab runs next
to its rig; here on loopback with the virtual rig inside), run the FRF test from Python against it
over TCP, and compare with the same test on the in-process virtual rig.

    make build
    python3 examples/python/remote_controller.py [OUT_DIR]
"""
import os
import re
import subprocess
import sys
import time

import numpy as np

from _common import CLI, example, rths, run_frf

out = sys.argv[1] if len(sys.argv) > 1 else "out/python_remote"
os.makedirs(out, exist_ok=True)
config = example("four_storey.yaml")
# heavy damping and no noise: the transient dies within seconds of wall-clock time, and both
# sides see the same structure; two points of a natural sweep keep the example short
physics = {"structure.storeys.damping_n_s_per_m": [60, 60, 60, 60], "rig.noise": False}
host = {"continuation.method": "natural", "continuation.start_hz": 16,
        "continuation.end_hz": 16.2, "continuation.initial_step_hz": 0.1,
        "continuation.max_step_hz": 0.1, "continuation.max_points": 2,
        "iteration.rel_tolerance": 1e-6}

args = [CLI, "controller", "--config", config, "--listen", "127.0.0.1:0",
        "--set", "server.realtime=false"]
for key, value in physics.items():
    args += ["--set", f"{key}={rths._yaml_value(value)}"]
controller = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
try:
    line = controller.stdout.readline()  # "listening on 127.0.0.1:PORT"
    port = re.search(r":(\d+)$", line.strip()).group(1)
    print("controller", line.strip())
    cfg = rths.Config.load(config, set={**physics, **host})
    started = time.monotonic()
    remote = run_frf(cfg, os.path.join(out, "remote"), rig=f"tcp://127.0.0.1:{port}",
                     on_point=lambda row: print(f"  accepted {row['frequency_hz']:.3f} Hz, "
                                                f"{row['amplitude_m']:.4e} m"))
    print(f"remote run: {remote.frf.rows} points in {time.monotonic() - started:.1f} s")
finally:
    controller.terminate()
    controller.wait(timeout=30)
local = run_frf(cfg, os.path.join(out, "local"))
deviation = np.max(np.abs(remote.frf.amplitude_m / local.frf.amplitude_m - 1))
print(f"remote vs in-process virtual rig: amplitudes agree to {deviation:.1e} (relative)")
