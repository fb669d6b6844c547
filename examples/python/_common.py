"""Shared by the examples: find the checkout, run an FRF test through the package (or, with a
librths built before the FRF run was part of the C API, through the rths CLI), import matplotlib."""
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "python"))  # not needed once installed (docs/python.md)

import rths  # noqa: E402

CLI = os.environ.get("RTHS_BIN", os.path.join(ROOT, "build", "rths"))


def example(name):
    return os.path.join(ROOT, "examples", name)


def run_frf(cfg, out, seed=None, rig=None, on_point=None):
    """rths.frf when this librths can run it, else `rths frf` then rths.read_run."""
    if rths.frf_available():
        return rths.frf(cfg, out=out, seed=seed, rig=rig, on_point=on_point)
    args = [CLI, "frf", cfg.path, "--out", out, "--quiet"]
    for s in cfg.overrides:
        args += ["--set", s]
    if seed is not None:
        args += ["--seed", str(seed)]
    if rig is not None:
        args += ["--rig", rig]
    subprocess.run(args, check=True)
    return rths.read_run(out)


def pyplot():
    """matplotlib.pyplot without a display, or exit with how to install it."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        return plt
    except ImportError:
        sys.exit("this example plots with matplotlib: sudo apt install python3-matplotlib "
                 "(or pip install matplotlib in a virtual environment, docs/python.md)")
