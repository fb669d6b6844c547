"""The structs python/rths/_lib.py declares through ctypes have the C layout: sizes and field
offsets equal to what the compiler makes of include/rths/rths.h (a tiny C program compiled here,
the independent truth) and to what the loaded library reports (rths_api_sizeof/_offsetof), and an
error message longer than the 1024 bytes the package once assumed comes back whole, without
corrupting the interpreter's heap (issue 24, item 5). Run by tests/cli/python.sh."""
import ctypes
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import unittest

import rths
from rths import _lib

SRC = os.environ["RTHS_SOURCE_DIR"]
SCRATCH = os.environ.get("RTHS_SCRATCH") or tempfile.mkdtemp()
LINEAR_CFG = os.path.join(SRC, "examples", "four_storey_linear.yaml")

# every field of every struct the package mirrors
FIELDS = {
    "rths_error": ["code", "msg"],
    "rths_api_frf_options": [f for f, _ in _lib.FrfOptions._fields_],
    "rths_api_simulate_options": [f for f, _ in _lib.SimulateOptions._fields_],
}

PROBE = r"""
#include "rths/rths.h"
#include <stddef.h>
#include <stdio.h>
#define SIZE(t) printf("%s %zu\n", #t, sizeof(t))
#define FIELD(t, f) printf("%s.%s %zu\n", #t, #f, offsetof(t, f))
int main(void) {
BODY
    return 0;
}
"""


def compiled_layout():
    """{"rths_error": size, "rths_error.msg": offset, ...} from the C compiler and rths.h."""
    lines = []
    for t, fields in FIELDS.items():
        lines.append(f"    SIZE({t});")
        lines += [f"    FIELD({t}, {f});" for f in fields]
    work = tempfile.mkdtemp(dir=SCRATCH)
    c = os.path.join(work, "probe.c")
    with open(c, "w") as f:
        f.write(PROBE.replace("BODY", "\n".join(lines)))
    exe = os.path.join(work, "probe")
    cc = shutil.which("cc") or shutil.which("gcc")
    subprocess.run([cc, "-std=c11", "-I", os.path.join(SRC, "include"), c, "-o", exe],
                   check=True, capture_output=True)
    out = subprocess.run([exe], check=True, capture_output=True, text=True).stdout
    return {k: int(v) for k, v in (line.split() for line in out.splitlines())}


def python_subprocess(code):
    """Runs code in a fresh interpreter with the package (a corrupted heap there cannot take this
    test process down); returns (status, stdout, stderr)."""
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env=dict(os.environ))
    return p.returncode, p.stdout, p.stderr


class Layout(unittest.TestCase):
    def test_ctypes_equals_compiled_header_and_library(self):
        truth = compiled_layout()
        lib = rths._c()
        types = {"rths_error": lib.Error, "rths_api_frf_options": _lib.FrfOptions,
                 "rths_api_simulate_options": _lib.SimulateOptions}
        for t, ctype in types.items():
            self.assertEqual(ctypes.sizeof(ctype), truth[t], t)
            self.assertEqual(lib.rths_api_sizeof(t.encode()), truth[t], t)
            for f in FIELDS[t]:
                self.assertEqual(getattr(ctype, f).offset, truth[f"{t}.{f}"], f"{t}.{f}")
                self.assertEqual(lib.rths_api_offsetof(t.encode(), f.encode()),
                                 truth[f"{t}.{f}"], f"{t}.{f}")
        self.assertEqual(lib.rths_api_sizeof(b"no_such_type"), 0)
        self.assertEqual(lib.rths_api_offsetof(b"rths_error", b"no_such_field"), -1)

    def test_mismatch_refused_at_load(self):
        # a package whose FrfOptions lacks its last field (as a package older than the library
        # would be) refuses the library with a message naming the struct
        code = ("import ctypes, rths._lib as L\n"
                "L.FrfOptions = type('FrfOptions', (ctypes.Structure,), "
                "{'_fields_': L.FrfOptions._fields_[:-1]})\n"
                "try:\n    L.load()\nexcept L.LayoutError as e:\n    print('refused:', e)\n")
        rc, out, err = python_subprocess(code)
        self.assertEqual(rc, 0, err)
        self.assertIn("refused:", out)
        self.assertIn("rths_api_frf_options has", out)
        self.assertIn("refusing to use it", out)


class LongMessages(unittest.TestCase):
    def test_long_path_error_whole(self):
        # a configuration path of 3000 bytes: the message (path and reason) is longer than 1024
        # bytes and must arrive whole, the reason at its end
        deep = os.path.join(SCRATCH, "d" * 200)
        path = os.path.join(*([deep] + ["e" * 200] * 14 + ["missing.yaml"]))
        self.assertGreater(len(path), 3000)
        code = ("import rths\n"
                f"try:\n    rths.Config.load({path!r})\n"
                "except rths.InputError as e:\n    print(len(str(e)), str(e)[-80:])\n")
        rc, out, err = python_subprocess(code)
        self.assertEqual(rc, 0, err)
        length, tail = out.split(" ", 1)
        self.assertGreater(int(length), 1024)
        self.assertIn("missing.yaml: cannot read the configuration: No such file or directory", tail)

    @unittest.skipUnless(rths.frf_available(), "librths built without the run module")
    def test_rig_failure_over_tcp_raises(self):
        # a controller that is not there: the run fails (status 1) and the library copies its
        # whole rths_error into the caller's (src/run/frf.c), which a 1028-byte ctypes struct
        # did not hold ("double free or corruption" at exit)
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]  # closed again before the run: nothing listens there
        out = os.path.join(tempfile.mkdtemp(dir=SCRATCH), "run")
        code = ("import rths\n"
                f"try:\n    rths.frf({LINEAR_CFG!r}, out={out!r}, rig='tcp://127.0.0.1:{port}')\n"
                "except rths.RunError as e:\n    print('RunError', e.code, e)\n")
        rc, stdout, err = python_subprocess(code)
        self.assertEqual(rc, 0, err)
        self.assertEqual(err, "")
        self.assertTrue(stdout.startswith("RunError 1 "), stdout)
        self.assertIn(str(port), stdout)


if __name__ == "__main__":
    unittest.main()
