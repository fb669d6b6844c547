"""rths.simulate and rths.fidelity (python/rths over rths_api_simulate / rths_api_fidelity) against
the CLI and against the analytic truth:
- fidelity: the table equals fidelity.csv bit for bit (both %.17g), result.text is what
  `rths fidelity` prints, each printed peak error is summary["curves"]'s, the seed's figures are
  docs/method.md's table (implicit Euler -26.07 %, exact ZOH -8.37 %), and the true curve's peak
  equals the maximum of the model's analytic FRF (rths.model, an independent solve) on a fine grid;
- simulate: at the target the iterative FRF test converged to at 13.05 Hz (noise off), the
  physical interface amplitude equals the analytic FRF of the true assembly (rths.model) and the
  interface error is small; coefficients, trace and the printed text equal the CLI's; bad
  arguments are InputErrors naming the problem.
Run by tests/cli/python.sh."""
import json
import math
import os
import re
import subprocess
import tempfile
import unittest

import numpy as np

import rths

BIN = os.environ["RTHS_BIN"]
SRC = os.environ["RTHS_SOURCE_DIR"]
SCRATCH = os.environ.get("RTHS_SCRATCH") or tempfile.mkdtemp()
SEED_CFG = os.path.join(SRC, "examples", "four_storey.yaml")
LINEAR_CFG = os.path.join(SRC, "examples", "four_storey_linear.yaml")


def read_csv(path):
    with open(path) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {n: data[:, i] for i, n in enumerate(names)}


def cli(*args):
    p = subprocess.run([BIN, *args], capture_output=True, text=True)
    return p.returncode, p.stdout, p.stderr


class Fidelity(unittest.TestCase):
    def test_seed_equals_cli_and_docs(self):
        out = tempfile.mkdtemp(prefix="fid_", dir=SCRATCH)
        rc, stdout, stderr = cli("fidelity", SEED_CFG, "--out", out + "/cli",
                                 "--set", "fidelity.points=201")
        self.assertEqual(rc, 0, stderr)
        r = rths.fidelity(rths.Config.load(SEED_CFG, set={"fidelity.points": 201}))
        self.assertEqual(r.text, stdout)
        want = read_csv(os.path.join(out, "cli", "fidelity.csv"))
        self.assertEqual(r.fidelity.columns, list(want))
        for name, column in want.items():
            np.testing.assert_array_equal(r.fidelity[name], column, err_msg=name)
        # each printed peak error (%+.3f) is the summary's figure
        printed = {m.group(1): float(m.group(2)) for m in
                   re.finditer(r"^(\w+)\s+\S+\s+\S+\s+([+-]\d+\.\d+)$", r.text, re.M)}
        curves = r.summary["curves"]
        self.assertEqual(set(printed), set(curves))
        for name, e in printed.items():
            self.assertEqual(e, round(curves[name]["peak_error_percent"], 3), name)
        # docs/method.md, "Numerical substructure integration" (its table is printed to 2 decimals)
        self.assertAlmostEqual(curves["implicit_euler"]["peak_error_percent"], -26.07, delta=0.005)
        self.assertAlmostEqual(curves["exact_zoh"]["peak_error_percent"], -8.37, delta=0.005)
        self.assertLess(abs(curves["exact_foh"]["peak_error_percent"]), 0.002)

    def test_true_peak_is_the_model_frf_maximum(self):
        r = rths.fidelity(SEED_CFG)
        true = r.summary["curves"]["true"]
        # the model's analytic FRF on a grid of 1 mHz around the peak: its maximum is the peak to
        # within the grid's curvature error, (pi dF / half-power width)^2 / 8 ~ 1e-4 relative at
        # a 47 mHz half-power width; the frequency to half a grid step
        lo, hi = true["peak_hz"] - 0.1, true["peak_hz"] + 0.1
        m = rths.model(rths.Config.load(SEED_CFG, set={
            "model.frf.start_hz": lo, "model.frf.end_hz": hi, "model.frf.points": 201}))
        amp = m.true_frf["x3_amplitude_m"]
        k = int(np.argmax(amp))
        self.assertLess(abs(amp[k] / true["peak_amplitude_m"] - 1), 1e-4)
        self.assertLessEqual(amp[k], true["peak_amplitude_m"] * (1 + 1e-12))
        self.assertLess(abs(m.true_frf["frequency_hz"][k] - true["peak_hz"]), 0.5e-3 + 1e-9)

    def test_to_pandas(self):
        try:
            import pandas  # noqa: F401
        except ImportError:
            self.skipTest("pandas not installed (Debian: python3-pandas)")
        r = rths.fidelity(rths.Config.load(SEED_CFG, set={"fidelity.points": 21}))
        df = r.fidelity.to_pandas()
        self.assertEqual(list(df.columns), r.fidelity.columns)
        for name in r.fidelity.columns:
            np.testing.assert_array_equal(df[name].to_numpy(), r.fidelity[name], err_msg=name)
        m = rths.model(SEED_CFG).modes.to_pandas()
        self.assertEqual(str(m["mode"].dtype), "int64")
        self.assertEqual(list(m["mode"]), [1, 2, 3, 4])

    def test_bad_key_refused(self):
        with self.assertRaises(rths.InputError) as e:
            rths.fidelity(rths.Config.load(SEED_CFG, set={"fidelity.colour": 1}))
        self.assertIn("fidelity.colour", str(e.exception))


class Simulate(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # the target the iterative FRF test converges to at 13.05 Hz without noise: there the
        # physical interface moves as the true assembly's DoF 3
        cls.cfg = rths.Config.load(LINEAR_CFG, set={
            "rig.noise": False, "continuation.start_hz": 13.05, "continuation.end_hz": 13.1})
        cls.work = tempfile.mkdtemp(prefix="sim_", dir=SCRATCH)
        if not rths.frf_available():
            raise unittest.SkipTest("librths built without the run module")
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rths.frf(cls.cfg, out=os.path.join(cls.work, "frf"))
        with open(os.path.join(cls.work, "frf", "journal.jsonl")) as f:
            point = next(r for r in map(json.loads, f)
                         if r.get("type") == "point" and abs(r["frequency_hz"] - 13.05) < 1e-9)
        cls.target = [point["target_a_m"][0], point["target_b_m"][0]]

    def test_matched_target_gives_the_analytic_frf(self):
        s = rths.simulate(self.cfg, 13.05, 20, target=self.target)
        c = s.coefficients
        phys = math.hypot(c["phys_a1_m"][-1], c["phys_b1_m"][-1])
        m = rths.model(self.cfg.with_set({"model.frf.start_hz": 13.05, "model.frf.end_hz": 13.1,
                                          "model.frf.points": 2}))
        self.assertEqual(m.true_frf["frequency_hz"][0], 13.05)
        truth = m.true_frf["x3_amplitude_m"][0]
        # the FRF test accepts a point at an interface mismatch of 1e-3 x the response
        # (iteration.tolerance_rel); without noise the rig repeats it: 0.2 % is the bound
        self.assertLess(abs(phys / truth - 1), 2e-3, (phys, truth))
        self.assertLess(s.summary["final_interface_error_relative"][0], 2e-3)
        self.assertEqual(c["period"].dtype, np.int64)
        self.assertEqual(list(c["period"]), list(range(1, 21)))
        self.assertEqual(s.summary["mode"], "iterative")
        self.assertIn("20 periods at 13.05 Hz", s.text)

    def test_equals_cli(self):
        out = os.path.join(self.work, "cli")
        target = "%.17g,%.17g" % tuple(self.target)
        rc, stdout, stderr = cli("simulate", LINEAR_CFG, "--frequency", "13.05", "--target",
                                 target, "--periods", "6", "--seed", "11", "--out", out,
                                 "--set", "rig.noise=false", "--set", "continuation.start_hz=13.05",
                                 "--set", "continuation.end_hz=13.1")
        self.assertEqual(rc, 0, stderr)
        s = rths.simulate(self.cfg, 13.05, 6, target=self.target, seed=11,
                          out=os.path.join(self.work, "api"))
        self.assertEqual(s.text, stdout)
        for table in ("coefficients", "trace"):
            want = read_csv(os.path.join(out, table + ".csv"))
            self.assertEqual(s[table].columns, list(want))
            for name, column in want.items():
                np.testing.assert_array_equal(s[table][name], column, err_msg=f"{table}.{name}")
        self.assertEqual(s.summary["seed"], 11)
        for f in ("coefficients.csv", "trace.csv", "summary.json", "simulate.gp", "config.yaml"):
            self.assertTrue(os.path.exists(os.path.join(self.work, "api", f)), f)
        with open(os.path.join(out, "simulate.gp")) as a, \
                open(os.path.join(self.work, "api", "simulate.gp")) as b:
            self.assertEqual(a.read(), b.read())

    def test_feedback_pure_delay(self):
        # the seed's pure-delay model at p = 0.33 diverges for any delay (tests/cli/simulate.sh)
        s = rths.simulate(rths.Config.load(SEED_CFG, set={"split.mass_ratio": 0.33}), 13, 3,
                          mode="feedback", delay=1e-3)
        self.assertTrue(s.summary["diverged"])
        self.assertEqual(s.summary["delay_s"], 1e-3)
        # periods computed from the trace carry no integrity counts (NaN), whole periods only
        c = s.coefficients
        self.assertLessEqual(c.rows, 3)
        self.assertTrue(all(math.isnan(v) for v in c["late_samples"]))
        self.assertGreater(s.trace.rows, 10)

    def test_bad_arguments(self):
        cases = [
            (dict(frequency=13, periods=3), "target: required"),
            (dict(frequency=13, periods=3, target=[1e-5]), "pairs"),
            (dict(frequency=13, periods=3, target=[1e-5, 0], mode="feedback"), "feedback"),
            (dict(frequency=13, periods=0, target=[1e-5, 0]), "periods=0"),
            (dict(frequency=-1, periods=3, target=[1e-5, 0]), "frequency_hz"),
            (dict(frequency=13, periods=3, target=[[1e-5, 0], [1e-5, 0]]),
             "2 ';'-separated lists for 1 interface DoF"),
            (dict(frequency=13, periods=3, mode="sideways"), "mode='sideways'"),
            (dict(frequency=13, periods=3, target=[1e-5, 0], delay=1e-3), "delay_s"),
        ]
        for kwargs, words in cases:
            with self.subTest(kwargs=kwargs):
                with self.assertRaises(rths.InputError) as e:
                    rths.simulate(LINEAR_CFG, **kwargs)
                self.assertIn(words, str(e.exception))


if __name__ == "__main__":
    unittest.main()
