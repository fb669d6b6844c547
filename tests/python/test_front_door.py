"""`rths model` and rths.model are one implementation (issue 28, "one front door", first step):
the command computes through the library's rths_api_model_compute and writes through its writer,
so the package's tables and summary equal the command's files, also where they once differed (a
model above 64 DoFs, whose modes.csv holds only the output DoFs' shapes; the summary naming the
configuration file and the overrides). Run by tests/cli/python.sh."""
import json
import os
import subprocess
import tempfile
import unittest

import numpy as np

import rths

BIN = os.environ["RTHS_BIN"]
SRC = os.environ["RTHS_SOURCE_DIR"]
SCRATCH = os.environ.get("RTHS_SCRATCH") or tempfile.mkdtemp()
ROD = os.path.join(SRC, "examples", "rod_chain_1000", "rod_chain_1000.yaml")
SEED_CFG = os.path.join(SRC, "examples", "four_storey.yaml")


def read_csv(path):
    with open(path) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {n: data[:, i] for i, n in enumerate(names)}


def without_time(summary):
    return {k: v for k, v in summary.items() if k != "created_utc"}


class Model(unittest.TestCase):
    def check(self, cfg_path, sets):
        out = os.path.join(tempfile.mkdtemp(prefix="front_", dir=SCRATCH), "cli")
        args = [a for k, v in sets.items() for a in ("--set", f"{k}={v}")]
        p = subprocess.run([BIN, "model", cfg_path, "--out", out, "--quiet", *args],
                           capture_output=True, text=True)
        self.assertEqual(p.returncode, 0, p.stderr)
        overrides = [f"{k}={v}" for k, v in sets.items()]
        m = rths.model(rths.Config.load(cfg_path, set=overrides))
        for table in ("modes", "true_frf"):
            want = read_csv(os.path.join(out, table + ".csv"))
            self.assertEqual(m[table].columns, list(want), table)
            for name, column in want.items():
                np.testing.assert_array_equal(m[table][name], column, err_msg=name)
        with open(os.path.join(out, "summary.json")) as f:
            cli_summary = json.load(f)
        self.assertEqual(without_time(m.summary), without_time(cli_summary))
        self.assertEqual(m.summary["config_file"], cfg_path)
        self.assertEqual(m.summary["overrides"], overrides)
        return m

    def test_above_64_dofs(self):
        # 1000 DoFs: modes.csv has the output DoFs' shapes only (the API had all 1000)
        m = self.check(ROD, {"model.frf.points": 40})
        self.assertLess(len(m.modes.columns), 4 + 64)
        self.assertEqual(m.modes.rows, 1000)

    def test_seed_with_overrides(self):
        self.check(SEED_CFG, {"split.mass_ratio": 0.4, "model.frf.points": 50})


COARSE = {"stability.tau_points": 12, "stability.p_points": 9, "stability.mdbm_tau_points": 10,
          "stability.mdbm_p_points": 9, "stability.omega_points": 40}


def same_shape(test, a, b, where="summary"):
    """a and b have the same keys, list lengths and types everywhere; numbers agree to 1e-9 of
    their size (the chart's LAPACK sums may differ in the last bits between processes, see
    test_rths.py's Chart test), everything else exactly."""
    if isinstance(a, dict):
        test.assertEqual(list(a), list(b), where)
        for k in a:
            same_shape(test, a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        test.assertEqual(len(a), len(b), where)
        for i, (x, y) in enumerate(zip(a, b)):
            same_shape(test, x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        test.assertLessEqual(abs(a - b), 1e-9 * max(abs(a), abs(b), 1e-300), where)
    else:
        test.assertEqual(a, b, where)


class Chart(unittest.TestCase):
    def test_summary_is_the_commands(self):
        # rths_api_chart's summary was a different, thinner one (tau_points, p_points,
        # essential_spectrum_p_limit); it is now the command's, from the same code
        out = os.path.join(tempfile.mkdtemp(prefix="front_chart_", dir=SCRATCH), "cli")
        args = [a for k, v in COARSE.items() for a in ("--set", f"{k}={v}")]
        p = subprocess.run([BIN, "chart", SEED_CFG, "--out", out, "--quiet", *args],
                           capture_output=True, text=True)
        self.assertEqual(p.returncode, 0, p.stderr)
        c = rths.chart(rths.Config.load(SEED_CFG, set=COARSE))
        with open(os.path.join(out, "summary.json")) as f:
            cli_summary = json.load(f)
        skip = ("created_utc", "compute_seconds")
        same_shape(self, {k: v for k, v in c.summary.items() if k not in skip},
                   {k: v for k, v in cli_summary.items() if k not in skip})
        self.assertIn("statement", c.summary["essential_spectrum"])
        for table in ("chart", "boundary", "critical"):
            self.assertEqual(c[table].columns, list(read_csv(os.path.join(out, table + ".csv"))))


if __name__ == "__main__":
    unittest.main()
