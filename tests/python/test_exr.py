"""gdr.read_exr and gdr.write_exr: round trips of every channel count with
metadata, the tool's files, and what they refuse."""
import os
import unittest

import numpy as np

from gdr_test_util import SMALL, gdr, needs_cli, run_cli, scratch_dir

OUT = scratch_dir("exr")


class RoundTrips(unittest.TestCase):
    def test_layers_of_one_to_four_channels_and_metadata_come_back_exactly(self):
        rng = np.random.default_rng(7)
        layers = {"color": rng.normal(size=(5, 7, 3)).astype(np.float32)}
        for c in (1, 2, 3, 4):
            layers[f"layer{c}"] = rng.normal(size=(5, 7, c)).astype(np.float32)
        layers["grey2d"] = rng.normal(size=(5, 7))  # float64, 2-D: stored as one float32 channel
        path = os.path.join(OUT, "round.exr")
        gdr.write_exr(path, layers, metadata={"note": "a b = c", "n": 3})
        back = gdr.read_exr(path)
        self.assertEqual(list(back.keys()), list(layers.keys()))  # the order is kept
        for name, a in layers.items():
            expected = a.astype(np.float32).reshape(5, 7, -1)
            self.assertEqual(back[name].dtype, np.float32)
            self.assertTrue(np.array_equal(back[name], expected), name)
        self.assertEqual(back.metadata["note"], "a b = c")
        self.assertEqual(back.metadata["n"], "3")
        self.assertIsNone(back.stats)
        # A gdr.Layers carries its metadata into the next file.
        again = os.path.join(OUT, "again.exr")
        gdr.write_exr(again, back)
        self.assertEqual(gdr.read_exr(again).metadata["note"], "a b = c")

    def test_write_replaces_an_existing_file_as_the_cpp_call_does(self):
        path = os.path.join(OUT, "replaced.exr")
        gdr.write_exr(path, {"color": np.zeros((2, 2, 3))})
        gdr.write_exr(path, {"color": np.ones((2, 2, 3))})
        self.assertTrue(np.all(gdr.read_exr(path)["color"] == 1.0))

    @needs_cli
    def test_a_render_of_the_tool_reads_with_its_settings(self):
        path = os.path.join(OUT, "tool.exr")
        run_cli("render", SMALL, "--spp", "2", "-o", path)
        layers = gdr.read_exr(path)
        self.assertEqual(layers["color"].shape, (24, 24, 3))
        self.assertEqual(layers["depth"].shape, (24, 24, 1))
        self.assertEqual(layers.metadata["integrator"], "pt")
        self.assertEqual(layers.metadata["spp"], "2")


class Refusals(unittest.TestCase):
    def test_nan_is_refused_naming_the_layer_and_pixel_and_nothing_is_written(self):
        a = np.zeros((3, 4, 3), np.float32)
        a[2, 1, 0] = np.nan
        path = os.path.join(OUT, "nan.exr")
        with self.assertRaises(gdr.InputError) as cm:
            gdr.write_exr(path, {"color": np.zeros((3, 4, 3)), "bad": a})
        self.assertIn("'bad'", str(cm.exception))
        self.assertIn("(1, 2)", str(cm.exception))
        self.assertFalse(os.path.exists(path))

    def test_bad_layers(self):
        path = os.path.join(OUT, "bad.exr")
        with self.assertRaises(ValueError) as cm:
            gdr.write_exr(path, {"a": np.zeros((3, 4, 3)), "b": np.zeros((4, 3, 3))})
        self.assertIn("'b'", str(cm.exception))
        with self.assertRaises(ValueError):
            gdr.write_exr(path, {"a": np.zeros((3, 4, 5))})  # five channels
        with self.assertRaises(ValueError):
            gdr.write_exr(path, {})
        self.assertFalse(os.path.exists(path))

    def test_missing_unreadable_and_malformed_files(self):
        missing = os.path.join(OUT, "no-such.exr")
        with self.assertRaises(FileNotFoundError) as cm:
            gdr.read_exr(missing)
        self.assertIn("no-such.exr", str(cm.exception))
        with self.assertRaises(IsADirectoryError):
            gdr.read_exr(OUT)
        text = os.path.join(OUT, "not.exr")
        with open(text, "w") as f:
            f.write("not an EXR\n")
        with self.assertRaises(gdr.InputError) as cm:
            gdr.read_exr(text)
        self.assertIn("not.exr", str(cm.exception))
        with self.assertRaises(OSError) as cm:
            gdr.write_exr(os.path.join(OUT, "no-dir", "x.exr"), {"color": np.zeros((2, 2, 3))})
        self.assertIn("no-dir", str(cm.exception))


if __name__ == "__main__":
    unittest.main()
