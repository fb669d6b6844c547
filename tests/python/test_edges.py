"""The package's edges found by a hostile probe (issue 24, item 11): read_run on a killed run, on a
folder with a user's CSV, on a damaged summary.json and on a folder that is no run; frf's out,
seed and harmonics checked before ctypes narrows them; threads writing run folders at once. Run by
tests/cli/python.sh."""
import os
import signal
import subprocess
import tempfile
import threading
import time
import unittest

import h5py
import numpy as np

import rths

BIN = os.environ["RTHS_BIN"]
SRC = os.environ["RTHS_SOURCE_DIR"]
SCRATCH = os.environ.get("RTHS_SCRATCH") or tempfile.mkdtemp()
SEED_CFG = os.path.join(SRC, "examples", "four_storey.yaml")
LINEAR_CFG = os.path.join(SRC, "examples", "four_storey_linear.yaml")


def fresh(name):
    """A new, empty scratch folder (unique: tests may run at once)."""
    return tempfile.mkdtemp(prefix=name + "_", dir=SCRATCH)


def model_folder(name):
    out = os.path.join(fresh(name), "run")
    p = subprocess.run([BIN, "model", SEED_CFG, "--out", out, "--quiet",
                        "--set", "model.frf.points=30"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return out


class ReadRun(unittest.TestCase):
    def test_killed_run_is_flagged_incomplete(self):
        # a real `rths frf` killed (SIGKILL) after its second accepted point: no summary.json
        out = os.path.join(fresh("killed"), "run")
        p = subprocess.Popen([BIN, "frf", LINEAR_CFG, "--out", out, "--quiet", "--seed", "5"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        journal = os.path.join(out, "journal.jsonl")
        deadline = time.monotonic() + 120
        try:
            while time.monotonic() < deadline and p.poll() is None:
                if os.path.exists(journal):
                    with open(journal) as f:
                        if len(f.readlines()) >= 3:  # header + 2 points
                            break
                time.sleep(0.02)
        finally:
            p.send_signal(signal.SIGKILL)
            p.wait()
        self.assertEqual(p.returncode, -signal.SIGKILL, "the run ended before it was killed")
        self.assertFalse(os.path.exists(os.path.join(out, "summary.json")))
        with self.assertWarns(rths.IncompleteRunWarning) as w:
            run = rths.read_run(out)
        self.assertFalse(run.complete)
        self.assertEqual(run.summary, {})
        self.assertIn("did not finish", str(w.warning))
        self.assertIn("resume=True", str(w.warning))
        self.assertNotIn("frf", run.tables)  # frf.csv is written when the run ends
        # the same folder with a user's CSV: still read, without it
        with open(os.path.join(out, "notes.csv"), "w") as f:
            f.write("my notes, not numbers\n")
        with self.assertWarns(rths.IncompleteRunWarning):
            again = rths.read_run(out)
        self.assertEqual(list(again.tables), list(run.tables))

    def test_finished_run_is_complete(self):
        out = model_folder("finished")
        with warnings_as_errors():
            run = rths.read_run(out)
        self.assertTrue(run.complete)
        self.assertEqual(sorted(run.tables), ["modes", "true_frf"])

    def test_users_csv_not_read(self):
        out = model_folder("notes")
        with open(os.path.join(out, "notes.csv"), "w") as f:
            f.write("date,remark\n2026-12-01,shaker warm\n")
        with open(os.path.join(out, "numbers.csv"), "w") as f:
            f.write("a_m\n1\n")  # even one that parses: not rths's
        run = rths.read_run(out)
        self.assertEqual(sorted(run.tables), ["modes", "true_frf"])
        self.assertEqual(run.true_frf.rows, 30)

    def test_damaged_summary_names_the_file(self):
        out = model_folder("damaged")
        path = os.path.join(out, "summary.json")
        with open(path) as f:
            text = f.read()
        with open(path, "w") as f:
            f.write(text[: len(text) // 2])  # cut in the middle
        with self.assertRaises(rths.InputError) as ctx:
            rths.read_run(out)
        self.assertIn(path + ": not a JSON object", str(ctx.exception))
        self.assertEqual(ctx.exception.code, 2)
        with open(path, "w") as f:
            f.write("[1, 2]\n")
        with self.assertRaisesRegex(rths.InputError, "summary.json: not a JSON object"):
            rths.read_run(out)

    def test_not_a_run_folder(self):
        with self.assertRaisesRegex(rths.InputError, r"^/ is not a run folder: no run\.log"):
            rths.read_run("/")
        empty = fresh("empty")
        with self.assertRaisesRegex(rths.InputError, "is not a run folder"):
            rths.read_run(empty)
        with self.assertRaisesRegex(rths.InputError, "not a directory"):
            rths.read_run(SEED_CFG)
        with self.assertRaisesRegex(rths.InputError, "a folder is required"):
            rths.read_run(None)


class warnings_as_errors:
    """A block in which any warning fails the test."""

    def __enter__(self):
        import warnings
        self.catch = warnings.catch_warnings()
        self.catch.__enter__()
        warnings.simplefilter("error")

    def __exit__(self, *exc):
        return self.catch.__exit__(*exc)


class FrfArguments(unittest.TestCase):
    """Refused before anything runs: no folder, no ./None."""

    def refused(self, regex, **kwargs):
        here = fresh("args")
        cwd = os.getcwd()
        os.chdir(here)
        try:
            with self.assertRaisesRegex(rths.InputError, regex):
                rths.frf(LINEAR_CFG, **kwargs)
        finally:
            os.chdir(cwd)
        self.assertEqual(os.listdir(here), [])

    def test_out_none(self):
        self.refused(r"^out: a folder is required, got None$", out=None)
        self.refused(r"^out: expected a path", out=3)

    def test_seed_range(self):
        self.refused(r"^seed=18446744073709551616: must be in \[0, 18446744073709551615\]$",
                     out="run", seed=2**64)
        self.refused(r"^seed=-1: must be in", out="run", seed=-1)
        self.refused(r"^seed=1\.5: expected an integer$", out="run", seed=1.5)

    def test_harmonics_range(self):
        self.refused(r"^harmonics=1099511627776: must be in \[1, ", out="run", harmonics=2**40)
        self.refused(r"^harmonics=0: must be in \[1, ", out="run", harmonics=0)
        # the library's own limit, above the package's check
        out = os.path.join(fresh("harmonics"), "run")
        with self.assertRaisesRegex(rths.InputError, r"harmonics 99 is not in 1\.\.\d"):
            rths.frf(LINEAR_CFG, out=out, harmonics=99)

    def test_model_out_none_is_no_folder(self):
        self.assertIsNone(rths.model(SEED_CFG, out=None).dir)


@unittest.skipUnless(rths.frf_available(), "librths built without the run module")
class Overwrite(unittest.TestCase):
    def test_rerun_needs_overwrite(self):
        # re-running a script into its folder: refused naming resume; overwrite=True starts a new
        # run there, the same as a run into a fresh folder; a user's file stays
        out = os.path.join(fresh("overwrite"), "run")
        rths.frf(LINEAR_CFG, out=out, seed=3)
        with open(os.path.join(out, "notes.txt"), "w") as f:
            f.write("mine\n")
        with self.assertRaises(rths.InputError) as e:
            rths.frf(LINEAR_CFG, out=out, seed=4)
        # named as frf's arguments, not the command's --resume and --out
        self.assertEqual(str(e.exception),
                         f"{out} already holds a run (journal.jsonl): continue it with "
                         "resume=True, start a new run there with overwrite=True, or choose "
                         "another out")
        with self.assertRaisesRegex(rths.InputError, "^resume=True: "):
            rths.frf(LINEAR_CFG, out=os.path.join(fresh("overwrite_none"), "run"), resume=True)
        with self.assertRaisesRegex(rths.InputError, "choose one"):
            rths.frf(LINEAR_CFG, out=out, seed=4, overwrite=True, resume=True)
        again = rths.frf(LINEAR_CFG, out=out, seed=4, overwrite=True)
        fresh_run = rths.frf(LINEAR_CFG, out=os.path.join(fresh("overwrite_ref"), "run"), seed=4)
        self.assertEqual(again.frf.columns, fresh_run.frf.columns)
        for name in fresh_run.frf.columns:
            np.testing.assert_array_equal(again.frf[name], fresh_run.frf[name], err_msg=name)
        self.assertEqual(again.summary["seed"], 4)
        with open(os.path.join(out, "journal.jsonl")) as f:
            self.assertEqual(len(f.readlines()), 1 + fresh_run.frf.rows)
        self.assertTrue(os.path.exists(os.path.join(out, "notes.txt")))


class ConfigValues(unittest.TestCase):
    """Config.load checks the keys it can at once, and values read back (issue 28)."""

    def test_typos_refused_at_load(self):
        with self.assertRaisesRegex(rths.InputError,
                                    r"unknown key 'structure\.storeys\.mass_kgg'.*mass_kg"):
            rths.Config.load(SEED_CFG, set={"structure.storeys.mass_kgg": [1, 2, 3, 4]})
        with self.assertRaisesRegex(rths.InputError, r"unknown key 'rigg'"):
            rths.Config.load(SEED_CFG, set={"rigg.noise": False})

    def test_rig_and_controller_checked_at_load(self):
        # the keys and values the virtual rig reads: refused by the load, not by the first
        # operation that runs the hybrid loop (a model-only script never saw them)
        cases = {
            "rig.noize": (False, "--set rig.noize=false: unknown key 'rig.noize' (did you mean "
                                 "'rig.noise'?)"),
            "controller.kp_v_per_mm": (1, "--set controller.kp_v_per_mm=1: unknown key "
                                          "'controller.kp_v_per_mm' (did you mean "
                                          "'controller.kp_v_per_m'?)"),
            "controller.sample_rate_hz": (-5, "--set controller.sample_rate_hz=-5: key "
                                              "'controller.sample_rate_hz': must be in [100, "
                                              "1e+06] (got -5)"),
        }
        for key, (value, message) in cases.items():
            with self.assertRaises(rths.InputError, msg=key) as e:
                rths.Config.load(SEED_CFG, set={key: value})
            self.assertEqual(str(e.exception), message)
        # what a run reads besides (its pace, a multi-site test's sites) is no typo
        rths.Config.load(SEED_CFG, set={"rig.pace": 2, "rig.noise": False})

    def test_run_sections_checked_at_load(self):
        # iteration, continuation, stability and server, read over their defaults as rths frf
        # and rths controller read them: a typo or a value out of range fails at the load
        cases = {
            "continuation.strat_hz": (13, "unknown key 'continuation.strat_hz' (did you mean "
                                          "'continuation.start_hz'?)"),
            "iteration.harmonics": (99, "key 'iteration.harmonics': must be in [1, 3] (got 99)"),
            "stability.experimental_floquett": (True, "unknown key "
                                                      "'stability.experimental_floquett'"),
            "server.watchdog": (1, "unknown key 'server.watchdog'"),
        }
        for key, (value, message) in cases.items():
            with self.assertRaises(rths.InputError, msg=key) as e:
                rths.Config.load(SEED_CFG, set={key: value})
            self.assertIn(message, str(e.exception))
        # keys their commands read with the structure they need are left to those commands
        rths.Config.load(SEED_CFG, set={"output.trace_frequency_hz": 13.5, "fidelity.points": 5,
                                        "continuation.start_hz": 12.5, "server.realtime": False})

    def test_read_back(self):
        cfg = rths.Config.load(SEED_CFG, set={"split.mass_ratio": 0.33, "rig.noise": False})
        self.assertEqual(cfg["split.mass_ratio"], 0.33)
        self.assertIs(cfg["rig.noise"], False)
        self.assertEqual(cfg["structure.storeys.mass_kg"], [5.37, 5.37, 5.37, 10.74])
        five = cfg.with_set({"split.mass_ratio": 0.5})
        self.assertEqual(five["split.mass_ratio"], 0.5)
        self.assertEqual(cfg["split.mass_ratio"], 0.33)  # the original is unchanged
        two = ["structure.matrices.mass_kg=[[2, 0], [0, 1]]",
               "structure.matrices.damping_n_s_per_m=[[1, 0], [0, 1]]",
               "structure.matrices.stiffness_n_per_m=[[2000, -1000], [-1000, 1000.5]]",
               "split.interface=[2]", "split.physical=[1]", "split.mass_ratio=0.5",
               "forcing.dof=2"]
        m = rths.Config.load(None, set=two)
        stiffness = m["structure.matrices.stiffness_n_per_m"]
        self.assertEqual(stiffness, [[2000.0, -1000.0], [-1000.0, 1000.5]])  # rows as written
        self.assertIs(type(stiffness[0][0]), float)
        self.assertEqual(m["split.interface"], [2.0])
        self.assertEqual(m.dofs, 2)
        with self.assertRaisesRegex(KeyError, "is not set in the configuration"):
            cfg["continuation.start_hz"]
        self.assertEqual(cfg.get("continuation.start_hz", 3.5), 3.5)
        with self.assertRaisesRegex(KeyError, "holds a mapping"):
            cfg["structure"]


class IntegerColumns(unittest.TestCase):
    """Counts and labels come back as integers (issue 28: row["point"] was a float)."""

    def test_model_and_frf(self):
        m = rths.model(SEED_CFG)
        self.assertEqual(m.modes.mode.dtype, np.int64)
        self.assertEqual(list(m.modes.mode), [1, 2, 3, 4])
        self.assertEqual(m.modes.frequency_hz.dtype, np.float64)
        out = os.path.join(fresh("ints"), "run")
        rows = []
        # two points are enough: the callback stops the run cleanly after the second
        def take(row):
            rows.append(row)
            if len(rows) == 2:
                raise StopIteration

        with self.assertRaises(StopIteration):
            rths.frf(LINEAR_CFG, out=out, seed=3, on_point=take)
        self.assertIs(type(rows[0]["point"]), int)
        self.assertIs(type(rows[1]["evaluations"]), int)
        self.assertIs(type(rows[0]["frequency_hz"]), float)
        run = rths.read_run(out)
        for name in ("point", "evaluations", "iterations", "converged", "segment"):
            self.assertEqual(run.frf[name].dtype, np.int64, name)
        self.assertEqual(list(run.frf.point), [0, 1])
        self.assertEqual(run.frf.amplitude_m.dtype, np.float64)


class Threads(unittest.TestCase):
    def test_threads_write_folders_at_once(self):
        # results.mat from 4 threads at once (each rths_api_model with a folder): HDF5 lock errors
        # came intermittently before the MAT writer was serialised
        base = fresh("threads")
        cfg = rths.Config.load(SEED_CFG, set={"model.frf.points": 200})
        errors = []

        def work(k):
            try:
                for i in range(3):
                    rths.model(cfg, out=os.path.join(base, f"t{k}_{i}"))
            except Exception as e:  # noqa: BLE001 - reported below
                errors.append(e)

        threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        self.assertEqual(errors, [])
        want = rths.model(cfg).true_frf.x3_amplitude_m
        for name in sorted(os.listdir(base)):
            with h5py.File(os.path.join(base, name, "results.mat"), "r") as f:
                np.testing.assert_array_equal(f["true_frf"]["x3_amplitude_m"][()].ravel(), want)
            self.assertFalse([n for n in os.listdir(os.path.join(base, name)) if ".tmp" in n])


if __name__ == "__main__":
    unittest.main()
