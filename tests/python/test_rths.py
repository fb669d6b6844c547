"""python/rths against the CLI and the files it writes: the package's arrays equal the CLI's CSV
columns bit for bit (both print and parse %.17g, a lossless round trip), results.mat equals the CSV
files, errors become exceptions carrying the C message. Run by tests/cli/python.sh."""
import json
import os
import re
import signal
import subprocess
import tempfile
import unittest

import h5py
import numpy as np

import rths

BIN = os.environ["RTHS_BIN"]
SRC = os.environ["RTHS_SOURCE_DIR"]
SCRATCH = os.environ.get("RTHS_SCRATCH") or tempfile.mkdtemp()
SEED_CFG = os.path.join(SRC, "examples", "four_storey.yaml")
LINEAR_CFG = os.path.join(SRC, "examples", "four_storey_linear.yaml")
# the chart on a coarse grid (as tests/cli/chart.sh): seconds instead of minutes
COARSE = {"stability.tau_points": 12, "stability.p_points": 9, "stability.mdbm_tau_points": 10,
          "stability.mdbm_p_points": 9, "stability.omega_points": 40}


def folder(name):
    return os.path.join(SCRATCH, name)


def cli(*args):
    """Runs the rths CLI; returns (status, stderr)."""
    p = subprocess.run([BIN, *args], capture_output=True, text=True)
    return p.returncode, p.stderr


def read_csv(path):
    """The CSV's columns by name, parsed by numpy (independently of librths's reader)."""
    with open(path) as f:
        names = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {n: data[:, i] if data.size else np.zeros(0) for i, n in enumerate(names)}


def mat_text(f, name):
    return "".join(map(chr, f[name][()].ravel()))


class Model(unittest.TestCase):
    def test_equals_cli_csv_bit_for_bit(self):
        out = folder("model_cli")
        rc, err = cli("model", SEED_CFG, "--out", out, "--quiet", "--set", "split.mass_ratio=0.33")
        self.assertEqual(rc, 0, err)
        m = rths.model(rths.Config.load(SEED_CFG, set={"split.mass_ratio": 0.33}))
        for table in ("modes", "true_frf"):
            want = read_csv(os.path.join(out, table + ".csv"))
            self.assertEqual(m[table].columns, list(want))
            for name, column in want.items():
                np.testing.assert_array_equal(m[table][name], column, err_msg=name)
        # the seed building's modes (README: 4.339, 13.473, 21.819, 27.367 Hz, 4 significant
        # digits printed there)
        np.testing.assert_allclose(m.modes.frequency_hz, [4.339, 13.473, 21.819, 27.367],
                                   atol=6e-4)
        self.assertEqual(m.summary["dofs"], 4)
        self.assertIsNone(m.dir)

    def test_folder_from_python(self):
        out = folder("model_py")
        m = rths.model(SEED_CFG, out=out)
        self.assertEqual(m.dir, out)
        with h5py.File(os.path.join(out, "results.mat"), "r") as f:
            np.testing.assert_array_equal(f["modes"]["frequency_hz"][()].ravel(),
                                          m.modes.frequency_hz)
        self.assertIn("structure:", m.config_yaml)
        back = rths.read_run(out)
        np.testing.assert_array_equal(back.true_frf.x3_amplitude_m, m.true_frf.x3_amplitude_m)


class Errors(unittest.TestCase):
    def test_config_error_carries_file_line_col(self):
        path = os.path.join(SCRATCH, "bad_ratio.yaml")
        with open(SEED_CFG) as f:
            lines = f.read().splitlines()
        row = next(i for i, line in enumerate(lines) if re.match(r"\s+mass_ratio:", line))
        col = lines[row].index(":") + 2 + len(lines[row].split(":", 1)[1]) - len(
            lines[row].split(":", 1)[1].lstrip())
        lines[row] = re.sub(r"mass_ratio:\s*[0-9.]+", "mass_ratio: 1.5", lines[row])
        with open(path, "w") as f:
            f.write("\n".join(lines) + "\n")
        with self.assertRaises(rths.InputError) as ctx:
            rths.Config.load(path)
        e = ctx.exception
        self.assertEqual(e.code, 2)
        match = re.match(re.escape(path) + r":(\d+):(\d+): key 'split.mass_ratio'", str(e))
        self.assertIsNotNone(match, str(e))
        self.assertEqual(int(match.group(1)), row + 1)
        self.assertEqual(int(match.group(2)), col)
        # the CLI says the same
        rc, err = cli("model", path, "--out", folder("never"))
        self.assertEqual(rc, 2)
        self.assertIn(str(e), err)
        self.assertFalse(os.path.exists(folder("never")))

    def test_override_and_unknown_key(self):
        with self.assertRaisesRegex(rths.InputError, r"--set split\.mass_ratio=-2"):
            rths.Config.load(SEED_CFG, set={"split.mass_ratio": -2})
        with self.assertRaisesRegex(rths.InputError, r"expected KEY=VALUE"):
            rths.Config.load(SEED_CFG, set=["split.mass_ratio"])
        # a misspelt key of a structural section: refused by the load itself
        with self.assertRaisesRegex(rths.InputError, r"model\.frf\.pointz"):
            rths.Config.load(SEED_CFG, set={"model.frf.pointz": 3})
        with self.assertRaisesRegex(rths.InputError, r"missing\.yaml: cannot read"):
            rths.Config.load(folder("missing.yaml"))
        with self.assertRaisesRegex(rths.InputError, r"does_not_exist"):
            rths.read_run(folder("does_not_exist"))


class Chart(unittest.TestCase):
    def test_equals_cli_csv(self):
        out = folder("chart_cli")
        sets = [a for k, v in COARSE.items() for a in ("--set", f"{k}={v}")]
        rc, err = cli("chart", SEED_CFG, "--out", out, "--quiet", *sets)
        self.assertEqual(rc, 0, err)
        c = rths.chart(rths.Config.load(SEED_CFG, set=COARSE))
        for table in ("chart", "boundary", "critical"):
            want = read_csv(os.path.join(out, table + ".csv"))
            self.assertEqual(c[table].columns, list(want))
            for name, column in want.items():
                # The same code on the same numbers, but OpenBLAS kernels may sum in another order
                # in another process (heap alignment, numpy's BLAS loaded first): rounding-level
                # differences, 1e-13 of the column's scale measured; 1e-9 leaves room and still
                # catches any real change (a grid point or a root moved).
                scale = np.nanmax(np.abs(column)) if column.size else 0
                np.testing.assert_allclose(c[table][name], column, rtol=0, atol=1e-9 * scale,
                                           err_msg=table + "." + name)
        # the seed's fact: p <= 1/2 is never stable (essential spectrum)
        grid = c.chart
        self.assertFalse(np.any(grid.stable[grid.p <= 0.5]))
        self.assertTrue(np.any(grid.stable[grid.p > 0.6]))


class MatFile(unittest.TestCase):
    """results.mat holds every column of every CSV of the folder, equal to the CSV values."""

    def check_folder(self, out):
        with h5py.File(os.path.join(out, "results.mat"), "r") as f:
            csvs = sorted(n for n in os.listdir(out) if n.endswith(".csv"))
            self.assertTrue(csvs)
            for name in csvs:
                want = read_csv(os.path.join(out, name))
                stem = name[:-4]
                self.assertEqual(f[stem].attrs["MATLAB_class"], b"struct")
                for column, values in want.items():
                    got = f[stem][column][()].ravel()
                    np.testing.assert_array_equal(got, values, err_msg=f"{name}:{column}")
            with open(os.path.join(out, "config.yaml")) as y:
                self.assertEqual(mat_text(f, "config_yaml"), y.read())
            with open(os.path.join(out, "summary.json")) as s:
                summary = json.load(s)
            self.assertEqual(json.loads(mat_text(f, "summary_json")), summary)
            for key, value in summary.items():
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    self.assertEqual(f["summary"][key][()].ravel()[0], value, key)
                elif isinstance(value, str):
                    self.assertEqual(mat_text(f["summary"], key), value, key)
            return list(f.keys())

    def test_every_command_folder(self):
        out = folder("mat_model")
        self.assertEqual(cli("model", SEED_CFG, "--out", out, "--quiet")[0], 0)
        self.check_folder(out)
        out = folder("mat_chart")
        sets = [a for k, v in COARSE.items() for a in ("--set", f"{k}={v}")]
        self.assertEqual(cli("chart", SEED_CFG, "--out", out, "--quiet", *sets)[0], 0)
        self.check_folder(out)
        out = folder("mat_simulate")
        rc, err = cli("simulate", SEED_CFG, "--frequency", "13", "--target", "1e-5,0", "--periods",
                      "20", "--out", out, "--quiet")
        self.assertEqual(rc, 0, err)
        self.assertIn("coefficients", self.check_folder(out))
        out = folder("mat_fidelity")
        self.assertEqual(cli("fidelity", SEED_CFG, "--out", out, "--quiet")[0], 0)
        self.check_folder(out)
        out = folder("mat_frf")
        rc, err = cli("frf", LINEAR_CFG, "--out", out, "--quiet", "--seed", "7")
        self.assertEqual(rc, 0, err)
        keys = self.check_folder(out)
        self.assertIn("harmonics", keys)
        frf = read_csv(os.path.join(out, "frf.csv"))
        with h5py.File(os.path.join(out, "results.mat"), "r") as f:
            h = {k: f["harmonics"][k][()].ravel() for k in f["harmonics"].keys()}
        # the measured fundamental of the physical side is frf.csv's measured_amplitude_m, and
        # the interface error its distance to the numerical side's (frf.csv computes both with
        # hypot from the same doubles: equal bit for bit)
        np.testing.assert_array_equal(h["point"], frf["point"])
        np.testing.assert_array_equal(np.hypot(h["phys_a1_m"], h["phys_b1_m"]),
                                      frf["measured_amplitude_m"])
        np.testing.assert_array_equal(
            np.hypot(h["phys_a1_m"] - h["num_a1_m"], h["phys_b1_m"] - h["num_b1_m"]),
            frf["interface_error_m"])
        np.testing.assert_array_equal(h["target_a1_m"], frf["target_a1_m"])
        run = rths.read_run(out)
        for name, column in frf.items():
            np.testing.assert_array_equal(run.frf[name], column, err_msg=name)
        with open(os.path.join(out, "summary.json")) as s:
            self.assertEqual(run.summary, json.load(s))


class Folders(unittest.TestCase):
    """A run folder belongs to one command (report.h, rths_report_open)."""

    def test_other_command_refused_same_command_replaced(self):
        out = folder("owned")
        sets = [a for k, v in COARSE.items() for a in ("--set", f"{k}={v}")]
        self.assertEqual(cli("chart", SEED_CFG, "--out", out, "--quiet", *sets)[0], 0)
        before = sorted(os.listdir(out))
        rc, err = cli("model", SEED_CFG, "--out", out, "--quiet")
        self.assertEqual(rc, 2)
        self.assertIn("earlier 'rths chart' run", err)
        self.assertEqual(sorted(os.listdir(out)), before)
        with self.assertRaisesRegex(rths.InputError, "earlier 'rths chart' run"):
            rths.model(SEED_CFG, out=out)
        # an earlier model run: its files go (here a stale table it listed), a user's stay
        out = folder("owned_model")
        self.assertEqual(cli("model", SEED_CFG, "--out", out, "--quiet")[0], 0)
        with open(os.path.join(out, "old_table.csv"), "w") as f:
            f.write("x_m\n1\n")
        with open(os.path.join(out, ".rths-files"), "a") as f:
            f.write("old_table.csv\n")
        with open(os.path.join(out, "notes.txt"), "w") as f:
            f.write("mine\n")
        self.assertEqual(cli("model", SEED_CFG, "--out", out, "--quiet")[0], 0)
        names = os.listdir(out)
        self.assertNotIn("old_table.csv", names)
        self.assertIn("notes.txt", names)
        with h5py.File(os.path.join(out, "results.mat"), "r") as f:
            self.assertNotIn("old_table", f)
        with open(os.path.join(out, "run.log")) as f:
            self.assertEqual(sum(" model: " in line for line in f), 2)  # history kept


@unittest.skipUnless(rths.frf_available(), "librths built without the run module (run.h)")
class Frf(unittest.TestCase):
    def test_equals_cli_same_seed(self):
        out_cli, out_py = folder("frf_cli"), folder("frf_py")
        rc, err = cli("frf", LINEAR_CFG, "--out", out_cli, "--quiet", "--seed", "11")
        self.assertEqual(rc, 0, err)
        rows = []
        run = rths.frf(rths.Config.load(LINEAR_CFG), out=out_py, seed=11, on_point=rows.append)
        want = read_csv(os.path.join(out_cli, "frf.csv"))
        self.assertEqual(run.frf.columns, list(want))
        for name, column in want.items():
            np.testing.assert_allclose(run.frf[name], column, rtol=1e-12, atol=0, err_msg=name)
        # one callback per accepted point, with the row frf.csv got
        self.assertEqual(len(rows), len(want["point"]))
        np.testing.assert_allclose([r["amplitude_m"] for r in rows], want["amplitude_m"],
                                   rtol=1e-12)
        # evaluations.csv: a row per evaluation, equal to the command's, its role flags integers
        ev, want_ev = run.evaluations, read_csv(os.path.join(out_cli, "evaluations.csv"))
        self.assertEqual(ev.columns, list(want_ev))
        for name, column in want_ev.items():
            np.testing.assert_allclose(ev[name], column, rtol=1e-12, atol=0, err_msg=name)
        self.assertEqual(ev.rows, run.summary["evaluations_total"])
        self.assertEqual(ev["prediction"].dtype, np.int64)
        self.assertEqual(int(ev["prediction"].sum() + ev["jacobian"].sum() + ev["step"].sum()
                             + ev["damped_step"].sum() + ev["gain_probe"].sum()
                             + ev["accuracy_step"].sum()), ev.rows)

    def test_two_interface_dofs_rows(self):
        # two interface storeys: the callback's rows carry frf.csv's dof<d>_* columns, and the
        # first DoF's equal amplitude_m
        out = folder("frf_two_interface")
        cfg = os.path.join(SRC, "examples", "two_interface_storeys.yaml")
        rows = []
        run = rths.frf(rths.Config.load(cfg, set={"rig.noise": "false"}), out=out,
                       on_point=rows.append)
        self.assertEqual(len(rows), len(run.frf.point))
        for name in ("dof1_amplitude_m", "dof2_amplitude_m", "dof2_interface_error_m"):
            self.assertIn(name, rows[0])
            np.testing.assert_allclose([r[name] for r in rows], run.frf[name], rtol=1e-12)
        np.testing.assert_allclose([r["dof1_amplitude_m"] for r in rows],
                                   [r["amplitude_m"] for r in rows], rtol=1e-12)

    def test_typo_in_a_read_section_refused(self):
        # the virtual rig reads rig.*: a misspelt rig key would run with noise on, silently; the
        # load refuses it (as it refuses the rig's other keys), before any run
        out = folder("frf_typo")
        with self.assertRaisesRegex(rths.InputError, r"rig\.nosie.*did you mean 'rig\.noise'"):
            cfg = rths.Config.load(LINEAR_CFG, set={"rig.nosie": "false"})
            rths.frf(cfg, out=out)
        self.assertFalse(os.path.exists(out))

    def test_raising_callback_stops_cleanly(self):
        out = folder("frf_raise")

        def stop_after_three(row):
            if row["point"] >= 2:
                raise ValueError("enough")

        with self.assertRaisesRegex(ValueError, "enough"):
            rths.frf(LINEAR_CFG, out=out, seed=3, on_point=stop_after_three)
        saved = rths.read_run(out)
        self.assertEqual(list(saved.frf.point), [0, 1, 2])
        with open(os.path.join(out, "journal.jsonl")) as f:
            self.assertEqual(len(f.readlines()), 1 + 3)  # header + the accepted points

    def test_ctrl_c_cancels_and_saves(self):
        out = folder("frf_sigint")

        def interrupt(row):
            if row["point"] == 1:
                os.kill(os.getpid(), signal.SIGINT)

        with self.assertRaises(rths.Cancelled) as ctx:
            rths.frf(LINEAR_CFG, out=out, seed=3, on_point=interrupt)
        self.assertGreaterEqual(ctx.exception.result.frf.rows, 2)
        resumed = rths.frf(LINEAR_CFG, out=out, seed=3, resume=True)
        self.assertGreater(resumed.frf.rows, ctx.exception.result.frf.rows)


if __name__ == "__main__":
    unittest.main()
