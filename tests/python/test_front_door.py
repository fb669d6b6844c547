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


if __name__ == "__main__":
    unittest.main()
