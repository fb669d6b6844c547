"""rths.tune (python/rths over rths_api_tune) against the CLI: the "loop" table equals loop.csv bit
for bit (both print and parse %.17g), summary["tuned_yaml"] is what `rths tune` prints, the
seed's tuned pair is docs/method.md's; on the two-interface building the keys to paste are a list
per interface DoF with every loop and the coupled loop meeting the rule; a delay out of range is
an InputError naming the range. Run by tests/cli/python.sh."""
import os
import subprocess
import tempfile
import unittest

import numpy as np
import yaml

import rths

BIN = os.environ["RTHS_BIN"]
SRC = os.environ["RTHS_SOURCE_DIR"]
SCRATCH = os.environ.get("RTHS_SCRATCH") or tempfile.mkdtemp()
SEED_CFG = os.path.join(SRC, "examples", "four_storey.yaml")
TWO_CFG = os.path.join(SRC, "examples", "two_interface_storeys.yaml")


def read_csv(path):
    with open(path) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {n: data[:, i] for i, n in enumerate(names)}


class Tune(unittest.TestCase):
    def test_seed_equals_cli(self):
        out = tempfile.mkdtemp(prefix="tune_cli_", dir=SCRATCH) + "/cli"
        p = subprocess.run([BIN, "tune", SEED_CFG, "--out", out], capture_output=True, text=True)
        self.assertEqual(p.returncode, 0, p.stderr)
        t = rths.tune(SEED_CFG)
        want = read_csv(os.path.join(out, "loop.csv"))
        self.assertEqual(t["loop"].columns, list(want))
        for name, column in want.items():
            np.testing.assert_array_equal(t["loop"][name], column, err_msg=name)
        self.assertEqual(t.summary["tuned_yaml"], p.stdout)
        keys = yaml.safe_load(t.summary["tuned_yaml"])["controller"]
        # docs/method.md, "On the seed": 891.251 V/m, 100 V s/m
        self.assertEqual(keys["kp_v_per_m"], 891.251)
        self.assertEqual(keys["kd_v_s_per_m"], 100)
        self.assertTrue(t.summary["tuned"]["stable"])
        self.assertEqual(t.summary["delay_samples"], 3)

    def test_delay_and_folder(self):
        out = tempfile.mkdtemp(prefix="tune_api_", dir=SCRATCH) + "/api"
        t = rths.tune(rths.Config.load(SEED_CFG), delay=2.5e-4, out=out)
        self.assertAlmostEqual(t.summary["delay_samples"], 2.5, places=9)
        with open(os.path.join(out, "tuned.yaml")) as f:
            self.assertEqual(f.read(), t.summary["tuned_yaml"])
        self.assertTrue(os.path.exists(os.path.join(out, "loop.csv")))
        with self.assertRaises(rths.InputError) as e:
            rths.tune(SEED_CFG, delay=2)
        self.assertIn("[0, 0.1]", str(e.exception))

    def test_two_interface_dofs(self):
        t = rths.tune(TWO_CFG)
        keys = yaml.safe_load(t.summary["tuned_yaml"])["controller"]
        self.assertEqual(sorted(keys), ["grounding_kd_per_dof", "grounding_kp_per_dof",
                                        "kd_per_dof", "kp_per_dof"])
        self.assertTrue(all(len(v) == 2 for v in keys.values()))
        tuned = t.summary["tuned"]
        self.assertGreaterEqual(tuned["coupled_gain_margin_db"], 6)
        for loop in tuned["loops"]:
            self.assertTrue(loop["stable"])
            self.assertGreaterEqual(loop["gain_margin_db"], 6)
            self.assertGreaterEqual(loop["phase_margin_deg"], 45)
        self.assertEqual(t.summary["interface_dofs"], [2, 3])
        self.assertEqual(len(t["loop"].columns), 13)


if __name__ == "__main__":
    unittest.main()
