"""Renders written from Python are files the gdr tool reads (gdr info, merge,
--resume), with its PNG preview; every reconstructor from a render's layers;
reconstructions written in Python, run by render and merge; plugins; scene
warnings through the warnings module; progress=True."""
import contextlib
import io
import os
import sys
import unittest
import warnings

import numpy as np

from gdr_test_util import SMALL, gdr, needs_cli, run_cli, scratch_dir
from test_render import MITSUBA

OUT = scratch_dir("package")


def small():
    return gdr.load_scene(SMALL)


class RenderFiles(unittest.TestCase):
    @needs_cli
    def test_a_python_part_merges_with_a_cli_part_as_two_cli_parts_do(self):
        # Part A from Python, part B from the tool; the tool's merge of the two
        # must equal its merge of the same two parts both made by the tool.
        # (Without the header a Python EXR is refused: "a gdr render without its settings".)
        a_py, a_cli, b_cli = (os.path.join(OUT, f"{n}.exr") for n in ("a_py", "a_cli", "b_cli"))
        gdr.write_exr(a_py, gdr.render(small(), integrator="gpt", spp=2, seed=1))
        run_cli("render", SMALL, "--integrator", "gpt", "--spp", "2", "--seed", "1", "-o", a_cli)
        run_cli("render", SMALL, "--integrator", "gpt", "--spp", "2", "--seed", "2", "-o", b_cli)
        mixed, pure = os.path.join(OUT, "mixed.exr"), os.path.join(OUT, "pure.exr")
        run_cli("merge", a_py, b_cli, "-o", mixed)
        run_cli("merge", a_cli, b_cli, "-o", pure)
        m, p = gdr.read_exr(mixed), gdr.read_exr(pure)
        self.assertEqual(sorted(m), sorted(p))
        for name in p:
            np.testing.assert_array_equal(m[name], p[name], err_msg=name)
        self.assertEqual(m.metadata["sample_ranges"], "1:0:2,2:0:2")
        self.assertIn("scene_hash", gdr.read_exr(a_py).metadata)
        info = run_cli("info", a_py)
        self.assertIn("sample_ranges", info)
        self.assertIn("integrator", info)

    @needs_cli
    def test_resume_of_a_python_render_equals_one_render_of_all_samples(self):
        part, resumed, whole = (os.path.join(OUT, f"{n}.exr") for n in ("part", "resumed", "whole"))
        gdr.write_exr(part, gdr.render(small(), integrator="pt", spp=2, seed=3))
        run_cli("render", SMALL, "--resume", part, "--spp", "4", "-o", resumed)
        run_cli("render", SMALL, "--integrator", "pt", "--spp", "4", "--seed", "3", "-o", whole)
        r, w = gdr.read_exr(resumed), gdr.read_exr(whole)
        np.testing.assert_allclose(r["color"], w["color"], rtol=1e-5, atol=1e-6)
        self.assertEqual(r.metadata["sample_ranges"], "3:0:4")

    @needs_cli
    def test_write_png_writes_the_tools_preview_byte_for_byte(self):
        out = os.path.join(OUT, "cli.exr")
        run_cli("render", SMALL, "--integrator", "gpt", "--spp", "2", "--seed", "4", "-o", out)
        png = os.path.join(OUT, "py.png")
        gdr.write_png(png, gdr.render(small(), integrator="gpt", spp=2, seed=4))
        with open(png, "rb") as a, open(os.path.join(OUT, "cli.png"), "rb") as b:
            self.assertEqual(a.read(), b.read())

    def test_tonemap_is_srgb_of_the_scaled_image(self):
        img = np.array([[[0.0, 0.5, 1.0], [0.25, 2.0, 0.0031308]]], dtype=np.float32)
        px = gdr.tonemap(img, exposure=1.0)
        self.assertEqual(px.dtype, np.uint8)
        self.assertEqual(px.shape, (1, 2, 3))
        v = np.clip(img * 2.0, 0, 1)
        srgb = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
        np.testing.assert_allclose(px, np.round(srgb * 255), atol=1)

    def test_a_wrong_extension_is_an_error(self):
        img = np.zeros((2, 3, 3), np.float32)
        with self.assertRaisesRegex(gdr.ParameterError, r"o\.png.*must end in \.exr"):
            gdr.write_exr(os.path.join(OUT, "o.png"), {"color": img})
        with self.assertRaisesRegex(gdr.ParameterError, r"o\.exr.*must end in \.png"):
            gdr.write_png(os.path.join(OUT, "o.exr"), img)
        self.assertFalse(os.path.exists(os.path.join(OUT, "o.png")))
        with self.assertRaisesRegex(gdr.InputError, "write_png"):
            gdr.write_png(os.path.join(OUT, "nan.png"), np.full((2, 2, 3), np.nan, np.float32))


class Reconstructions(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.r = gdr.render(small(), integrator="gpt", spp=4, seed=5)

    def test_every_builtin_reconstructor_runs_on_a_renders_layers(self):
        r = self.r
        np.testing.assert_array_equal(gdr.reconstruct(r, method="poisson-weighted"), r["reconstruction_weighted"])
        np.testing.assert_array_equal(gdr.reconstruct(r, method="poisson-l1", alpha=0.2), r["reconstruction_l1"])
        np.testing.assert_array_equal(gdr.reconstruct(r, method="poisson-l2", alpha=0.2), r["reconstruction_l2"])
        # Named layers without the render's metadata: the 'spp' layer gives the counts.
        named = {k: r[k] for k in ("primal", "dx", "dy", "direct", "primal_variance", "dx_variance", "dy_variance", "spp")}
        np.testing.assert_array_equal(gdr.reconstruct(named, method="poisson-weighted"), r["reconstruction_weighted"])

    def test_missing_layers_are_named(self):
        named = {k: self.r[k] for k in ("primal", "dx", "dy")}
        with self.assertRaisesRegex(gdr.Error, "variance"):
            gdr.reconstruct(named, method="poisson-weighted")
        with self.assertRaisesRegex(TypeError, "dx and dy"):
            gdr.reconstruct(self.r["primal"], method="poisson-l2")

    def test_bad_layer_arrays_raise_exceptions_naming_the_layer(self):
        def with_primal(a):
            d = dict(self.r)
            d["primal"] = a
            return d

        p = self.r["primal"]
        with self.assertRaisesRegex(gdr.ParameterError, "layer 'primal': expected an array of numbers"):
            gdr.reconstruct(with_primal(np.full(p.shape[:2], "a")), method="poisson-l2")
        with self.assertRaisesRegex(gdr.ParameterError, r"layer 'primal'.*\(1, 24, 24, 3\)"):
            gdr.reconstruct(with_primal(p[None]), method="poisson-l2")
        nan = p.copy()
        nan[0, 1, 2] = np.nan
        with self.assertRaisesRegex(gdr.InputError, r"primal.*nan.*pixel \(1, 0\)"):
            gdr.reconstruct(with_primal(nan), method="poisson-l2")
        # Any memory layout and float dtype is read as the same image.
        for other in (np.asfortranarray(p), p.astype(np.float64), np.ascontiguousarray(p[:, ::-1])[:, ::-1]):
            np.testing.assert_array_equal(gdr.reconstruct(with_primal(other), method="poisson-l2"),
                                          gdr.reconstruct(self.r, method="poisson-l2"))

    def test_a_python_reconstructor_is_run_by_render_and_merge(self):
        calls = []

        def halve(layers, scale=0.5):
            """the primal scaled (a test reconstruction)"""
            calls.append(sorted(layers))
            return layers["primal"] * scale

        gdr.register_reconstructor("test-halve", halve)
        self.assertEqual(gdr.reconstructors()["test-halve"], "the primal scaled (a test reconstruction)")
        a = gdr.render(small(), integrator="gpt", spp=2, seed=6, reconstruct="test-halve", reconstruct_params={"scale": 0.25})
        self.assertEqual(len(calls), 1)
        self.assertIn("primal_variance", calls[0])
        # gdr adds the directly visible emitters to the result.
        np.testing.assert_allclose(a["reconstruction_test-halve"], 0.25 * a["primal"] + a["direct"], rtol=1e-6)
        b = gdr.render(small(), integrator="gpt", spp=2, seed=7, reconstruct="test-halve", reconstruct_params={"scale": 0.25})
        m = gdr.merge(a, b)
        self.assertEqual(len(calls), 3)
        # Recomputed on the merged layers, not averaged (averaging gives the same here only if
        # the reconstruction is linear; this one is, so compare against the merged primal).
        np.testing.assert_allclose(m["reconstruction_test-halve"], 0.25 * m["primal"] + m["direct"], rtol=1e-6)
        np.testing.assert_allclose(m["primal"], 0.5 * (a["primal"] + b["primal"]), rtol=1e-6)
        self.assertEqual(m.metadata["sample_ranges"], "6:0:2,7:0:2")
        np.testing.assert_array_equal(m["reconstruction_weighted"], gdr.reconstruct(m, method="poisson-weighted"))
        with self.assertRaisesRegex(gdr.InputError, "same samples"):
            gdr.merge(a, a)

    def test_a_nonlinear_python_reconstruction_is_recomputed_after_a_merge(self):
        # The mean of two medians is not the median of the mean: a merge that
        # averaged the layer instead of rerunning fn would fail this.
        gdr.register_reconstructor("test-square", lambda layers: layers["primal"] ** 2)
        a = gdr.render(small(), integrator="gpt", spp=2, seed=8, reconstruct="test-square")
        b = gdr.render(small(), integrator="gpt", spp=2, seed=9, reconstruct="test-square")
        m = gdr.merge(a, b)
        np.testing.assert_allclose(m["reconstruction_test-square"], m["primal"] ** 2 + m["direct"], rtol=1e-5)
        averaged = 0.5 * (a["reconstruction_test-square"] + b["reconstruction_test-square"])
        self.assertGreater(np.abs(averaged - m["reconstruction_test-square"]).max(), 1e-4)

    def test_a_bad_python_reconstructor_raises_a_python_exception(self):
        gdr.register_reconstructor("test-wrong-shape", lambda layers: layers["primal"][:, :-1])
        with self.assertRaisesRegex(gdr.ParameterError, r"returned an image of 24 x 23 x 3, not the primal's 24 x 24 x 3"):
            gdr.reconstruct(self.r, method="test-wrong-shape")

        def fails(layers):
            raise ZeroDivisionError("inside the reconstruction")

        gdr.register_reconstructor("test-raises", fails)
        with self.assertRaisesRegex(ZeroDivisionError, "inside the reconstruction"):
            gdr.reconstruct(self.r, method="test-raises")
        gdr.register_reconstructor("test-nan", lambda layers: layers["primal"] * np.nan)
        with self.assertRaisesRegex(gdr.RuntimeFailure, "not finite"):
            gdr.reconstruct(self.r, method="test-nan")
        with self.assertRaises(TypeError):
            gdr.register_reconstructor("test-not-callable", 3)
        with self.assertRaisesRegex(gdr.ParameterError, "not a registered reconstructor"):
            gdr.render(small(), integrator="gpt", spp=1, reconstruct="no-such-method")


class Plugins(unittest.TestCase):
    def test_bad_plugin_files_are_refused(self):
        with self.assertRaises(FileNotFoundError):
            gdr.load_plugin(os.path.join(OUT, "missing.so"))
        # The module itself is a shared library, but no plugin of gdr's.
        with self.assertRaisesRegex(gdr.InputError, "not a gdr plugin"):
            gdr.load_plugin(gdr.__file__)

    def test_the_neural_plugin_loads_where_it_is_built(self):
        try:
            path = gdr.load_plugin()
        except gdr.ParameterError as e:
            self.skipTest(f"the neural plugin is not built: {e}")
        self.assertTrue(os.path.isfile(path))
        self.assertIn("neural", gdr.reconstructors())
        r = gdr.render(small(), integrator="gpt", spp=2, seed=10)
        out = gdr.reconstruct(r, method="neural")
        self.assertEqual(out.shape, r["primal"].shape)
        self.assertTrue(np.isfinite(out).all())
        n = gdr.render(small(), integrator="gpt", spp=2, seed=10, reconstruct="neural")
        np.testing.assert_allclose(n["reconstruction_neural"], out, rtol=1e-4, atol=1e-5)


class Manners(unittest.TestCase):
    def test_scene_warnings_go_through_the_warnings_module(self):
        xml = os.path.join(OUT, "warned.xml")
        with open(xml, "w") as f:
            f.write(MITSUBA)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            scene = gdr.load_scene(xml, lenient=True)
        mine = [w for w in caught if issubclass(w.category, gdr.SceneWarning)]
        self.assertTrue(scene.warnings)
        self.assertEqual([str(w.message) for w in mine], scene.warnings)
        self.assertEqual(mine[0].filename, __file__)  # points at the caller's line
        with warnings.catch_warnings():
            warnings.simplefilter("error", gdr.SceneWarning)
            with self.assertRaises(gdr.SceneWarning):
                gdr.load_scene(xml, lenient=True)

    def test_sizes_in_messages_are_in_numpy_order(self):
        a, b = np.zeros((4, 5, 3), np.float32), np.zeros((4, 6, 3), np.float32)
        with self.assertRaisesRegex(gdr.ParameterError, r"dy is 4 x 6 x 3 but primal is 4 x 5 x 3 \(height x width x channels\)"):
            gdr.reconstruct(a, a, b)
        with self.assertRaisesRegex(gdr.ParameterError, r"image is 4 x 5 x 3 but reference is 4 x 6 x 3"):
            gdr.metrics.mse(a, b)
        with self.assertRaisesRegex(gdr.ParameterError, r"layer 'b' is 4 x 6 but the layers before it are 4 x 5"):
            gdr.write_exr(os.path.join(OUT, "sizes.exr"), {"a": a, "b": b})
        with self.assertRaisesRegex(gdr.ParameterError, r"layer 'b' is 4 x 6, the others 4 x 5 \(height x width\)"):
            gdr.reconstruct({"primal": a, "dx": a, "b": b})

    def test_progress_true_uses_tqdm_where_it_is_installed(self):
        try:
            import tqdm  # noqa: F401
        except ImportError:
            self.skipTest("tqdm is not installed (Debian: python3-tqdm)")
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            gdr.render(small(), integrator="pt", spp=4, seed=0, progress=True)
        text = err.getvalue()
        self.assertIn("gdr.render: 100%|", text)  # tqdm's bar_format, at its end
        self.assertNotIn("gdr.render [", text)    # not the fallback line

    def test_progress_true_draws_a_bar_without_tqdm(self):
        saved = {k: sys.modules.get(k) for k in ("tqdm", "tqdm.auto")}
        sys.modules["tqdm"] = sys.modules["tqdm.auto"] = None  # import tqdm now raises ImportError
        try:
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                r = gdr.render(small(), integrator="pt", spp=4, seed=0, progress=True)
        finally:
            for k, v in saved.items():
                if v is None:
                    sys.modules.pop(k, None)
                else:
                    sys.modules[k] = v
        text = err.getvalue()
        self.assertIn("gdr.render [", text)
        self.assertIn("100%", text)
        self.assertTrue(text.endswith("\n"))
        np.testing.assert_array_equal(r["color"], gdr.render(small(), integrator="pt", spp=4, seed=0)["color"])


if __name__ == "__main__":
    unittest.main()
