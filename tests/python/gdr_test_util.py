"""Shared set-up of the Python module's tests: where the sources, the gdr tool
and a scratch directory are (ctest sets GDR_SOURCE_DIR, GDR_CLI, GDR_TEST_OUT
and PYTHONPATH; run by hand, the paths default to this checkout and ./build)."""
import os
import subprocess
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_DIR = os.environ.get("GDR_SOURCE_DIR", os.path.normpath(os.path.join(HERE, "..", "..")))
CLI = os.environ.get("GDR_CLI", os.path.join(SOURCE_DIR, "build", "bin", "gdr"))
SMALL = os.path.join(SOURCE_DIR, "tests", "scenes", "cornell-small.json")  # the Cornell box at 24 x 24
BOX = os.path.join(SOURCE_DIR, "scenes", "cornell-box", "scene.json")       # the same box at 512 x 512

import gdr  # noqa: E402  (after the paths, so that a failed import names the PYTHONPATH in the traceback)


def scratch_dir(name):
    """A fresh directory for one test file's outputs, under GDR_TEST_OUT if set."""
    base = os.environ.get("GDR_TEST_OUT")
    if base:
        os.makedirs(base, exist_ok=True)
    return tempfile.mkdtemp(prefix=f"gdr-python-{name}-", dir=base)


def needs_cli(test):
    """Skips a test where the gdr tool is not built."""
    return unittest.skipUnless(os.access(CLI, os.X_OK), f"the gdr tool {CLI} is not built")(test)


def run_cli(*args):
    """Runs the gdr tool; returns its stdout, raising AssertionError with its stderr if it fails."""
    r = subprocess.run([CLI, *args], capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        raise AssertionError(f"gdr {' '.join(args)} failed ({r.returncode}):\n{r.stderr}")
    return r.stdout
