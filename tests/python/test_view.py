"""rths.view serves a run folder's web view through the C API (rths_api_view_open/serve/port/
stop): on a two-point FRF run the page answers 200 and the run's summary.json
(/run/summary.json, /api/summary) and frf.csv come back over HTTP equal to the files; a bad folder
or address raises InputError naming it, and the server is stopped whatever the test's outcome
(a with-block). Run by tests/cli/python.sh."""
import os
import subprocess
import tempfile
import unittest
import urllib.error
import urllib.request

import rths

BIN = os.environ["RTHS_BIN"]
SRC = os.environ["RTHS_SOURCE_DIR"]
SCRATCH = os.environ.get("RTHS_SCRATCH") or tempfile.mkdtemp()


class View(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.run_dir = os.path.join(tempfile.mkdtemp(prefix="view_", dir=SCRATCH), "frf")
        p = subprocess.run([BIN, "frf", os.path.join(SRC, "examples", "four_storey_linear.yaml"),
                            "--out", cls.run_dir, "--quiet", "--set",
                            "continuation.max_points=2"], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr

    def test_serves_the_folder(self):
        with rths.view(self.run_dir) as v:
            self.assertTrue(v.loopback)
            self.assertGreater(v.port, 0)
            self.assertEqual(v.url, f"http://127.0.0.1:{v.port}/")
            with urllib.request.urlopen(v.url, timeout=10) as r:
                self.assertEqual(r.status, 200)
            with open(os.path.join(self.run_dir, "summary.json"), "rb") as f:
                expected = f.read()
            for path in ("run/summary.json", "api/summary"):
                with urllib.request.urlopen(v.url + path, timeout=10) as r:
                    self.assertEqual(r.read(), expected, path)
            with open(os.path.join(self.run_dir, "frf.csv"), "rb") as f:
                with urllib.request.urlopen(v.url + "run/frf.csv", timeout=10) as r:
                    self.assertEqual(r.read(), f.read())
        v.stop()  # a second stop is harmless
        with self.assertRaises(urllib.error.URLError):
            urllib.request.urlopen(v.url, timeout=5)

    def test_refusals(self):
        with self.assertRaises(rths.InputError) as e:
            rths.view(os.path.join(SCRATCH, "no_such_run_folder"))
        self.assertIn("no_such_run_folder", str(e.exception))
        with self.assertRaises(rths.InputError) as e:
            rths.view(self.run_dir, listen="127.0.0.1:notaport")
        self.assertIn("notaport", str(e.exception))


if __name__ == "__main__":
    unittest.main()
