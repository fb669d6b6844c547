"""docs/python.md's examples run as they stand: every ```python block of the page, in order, in one
namespace, in a scratch folder holding a link to examples/; what each block prints must equal
the ```text block right under it (a block without one must only run). A block whose first line
says "# needs pandas" is skipped, with the blocks after it, when pandas is not installed.
Run by tests/cli/python.sh; `python3 tests/python/test_docs.py --print` shows each block's output
(to update the page after a deliberate change)."""
import contextlib
import io
import os
import re
import sys
import tempfile
import unittest
import warnings

SRC = os.environ["RTHS_SOURCE_DIR"]
SCRATCH = os.environ.get("RTHS_SCRATCH") or tempfile.mkdtemp()
PAGE = os.path.join(SRC, "docs", "python.md")

FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```[ \t]*\n", re.M | re.S)


def blocks(text):
    """[(code, expected output or None, line number)] of the page's python blocks."""
    found = [(m.group(1), m.group(2), m.start(), m.end()) for m in FENCE.finditer(text)]
    out = []
    for i, (lang, body, start, end) in enumerate(found):
        if lang != "python":
            continue
        expected = None
        if i + 1 < len(found) and found[i + 1][0] == "text" and found[i + 1][2] == end:
            expected = found[i + 1][1]
        out.append((body, expected, text.count("\n", 0, start) + 1))
    return out


def have_pandas():
    try:
        import pandas  # noqa: F401
        return True
    except ImportError:
        return False


class Docs(unittest.TestCase):
    def test_examples_run_and_print_what_the_page_says(self):
        with open(PAGE) as f:
            page = blocks(f.read())
        self.assertGreaterEqual(len(page), 5, "docs/python.md lost its examples")
        work = tempfile.mkdtemp(prefix="docs_", dir=SCRATCH)
        os.symlink(os.path.join(SRC, "examples"), os.path.join(work, "examples"))
        here = os.getcwd()
        os.chdir(work)
        namespace = {"__name__": "__docs__"}
        try:
            for code, expected, line in page:
                if code.startswith("# needs pandas") and not have_pandas():
                    print(f"docs/python.md:{line}: skipped (no pandas)")
                    break
                printed = io.StringIO()
                with contextlib.redirect_stdout(printed), warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    exec(compile(code, f"docs/python.md:{line}", "exec"), namespace)
                if PRINT:
                    sys.stderr.write(f"--- docs/python.md:{line}\n{printed.getvalue()}")
                elif expected is not None:
                    self.assertEqual(printed.getvalue(), expected,
                                     f"docs/python.md:{line}: printed otherwise than the page")
        finally:
            os.chdir(here)

    def test_quoted_errors_are_the_real_ones(self):
        # the page quotes a configuration error and an override's: the library must say exactly
        # that (the file's is examples/x.yaml, the seed's file with the mass ratio at 1.5)
        import rths
        with open(PAGE) as f:
            page = f.read()
        in_file = re.search(r"A configuration error reads\s+`([^`]+)`", page)
        in_override = re.search(r"\(an override:\s+`([^`]+)`", page)
        self.assertTrue(in_file and in_override, "docs/python.md no longer quotes both errors")
        work = tempfile.mkdtemp(prefix="docs_errors_", dir=SCRATCH)
        os.mkdir(os.path.join(work, "examples"))
        with open(os.path.join(SRC, "examples", "four_storey.yaml")) as f:
            seed = f.read()
        self.assertIn("\n  mass_ratio: 0.5\n", seed)
        with open(os.path.join(work, "examples", "x.yaml"), "w") as f:
            f.write(seed.replace("\n  mass_ratio: 0.5\n", "\n  mass_ratio: 1.5\n"))
        here = os.getcwd()
        os.chdir(work)
        try:
            with self.assertRaises(rths.InputError) as e:
                rths.Config.load("examples/x.yaml")
            self.assertEqual(str(e.exception), in_file.group(1))
            with self.assertRaises(rths.InputError) as e:
                rths.Config.load(os.path.join(SRC, "examples", "four_storey.yaml"),
                                 set={"split.mass_ratio": 1.5})
            self.assertEqual(str(e.exception), " ".join(in_override.group(1).split()))
        finally:
            os.chdir(here)

    def test_regression_a_wrong_output_is_caught(self):
        # the comparison itself: a block whose text block differs must fail
        page = blocks("```python\nprint(1 + 1)\n```\n```text\n3\n```\n")
        self.assertEqual(page, [("print(1 + 1)\n", "3\n", 1)])


PRINT = "--print" in sys.argv
if PRINT:
    sys.argv.remove("--print")

if __name__ == "__main__":
    unittest.main()
