"""examples/python/render_and_plot.py runs (at a low sample count) and writes its plot."""
import importlib.util
import os
import subprocess
import sys
import unittest

from gdr_test_util import SOURCE_DIR, scratch_dir

SCRIPT = os.path.join(SOURCE_DIR, "examples", "python", "render_and_plot.py")


@unittest.skipUnless(importlib.util.find_spec("matplotlib"), "matplotlib is not installed (Debian: python3-matplotlib)")
class Example(unittest.TestCase):
    def test_render_and_plot_writes_its_png(self):
        out = os.path.join(scratch_dir("example"), "relmse.png")
        r = subprocess.run([sys.executable, SCRIPT, "--width", "48", "--spp", "1,2,4", "--ref-spp", "64",
                            "--threads", "2", "--out", out], capture_output=True, text=True, timeout=240)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        self.assertGreater(os.path.getsize(out), 10_000)  # axes, three curves and their labels
        # One row per spp, each with three finite relMSE values, G-PT's below PT's at every spp.
        rows = [line.split() for line in r.stdout.splitlines() if line.split() and line.split()[0].isdigit()]
        self.assertEqual([row[0] for row in rows], ["1", "2", "4"])
        for spp, pt, l1, l2 in ((int(a), float(b), float(c), float(d)) for a, b, c, d in rows):
            self.assertLess(l1, pt, f"spp {spp}")
            self.assertLess(l2, pt, f"spp {spp}")

    def test_bad_options_are_refused(self):
        r = subprocess.run([sys.executable, SCRIPT, "--spp", "0", "--out", "x.png"], capture_output=True, text=True)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("--spp", r.stderr)


SWEEP = os.path.join(SOURCE_DIR, "examples", "python", "roughness_sweep.py")


@unittest.skipUnless(importlib.util.find_spec("matplotlib"), "matplotlib is not installed (Debian: python3-matplotlib)")
class RoughnessSweep(unittest.TestCase):
    def test_the_sweep_writes_its_plot_and_one_row_per_roughness_and_spp(self):
        out = os.path.join(scratch_dir("sweep"), "sweep.png")
        r = subprocess.run([sys.executable, SWEEP, "--width", "24", "--spp", "1,2", "--ref-spp", "16",
                            "--roughness", "0.05,0.4", "--threads", "2", "--out", out],
                           capture_output=True, text=True, timeout=240)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        rows = [line.split() for line in r.stdout.splitlines() if line[:1].isdigit()]
        self.assertEqual([(row[0], row[1]) for row in rows], [("0.05", "1"), ("0.05", "2"), ("0.4", "1"), ("0.4", "2")])
        for row in rows:
            self.assertTrue(all(float(x) >= 0 for x in row[2:]), row)

    def test_bad_options_are_refused(self):
        r = subprocess.run([sys.executable, SWEEP, "--roughness", "0,0.1", "--out", "x.png"], capture_output=True, text=True)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("--roughness", r.stderr)


if __name__ == "__main__":
    unittest.main()
