"""gdr.reconstruct and gdr.metrics: the same numbers as the gdr tool's
reconstruct and compare commands, and the metrics' formulas."""
import os
import re
import unittest

import numpy as np

from gdr_test_util import SMALL, gdr, needs_cli, run_cli, scratch_dir

OUT = scratch_dir("reconstruct")


def gpt_render(seed=3):
    return gdr.render(gdr.load_scene(SMALL), integrator="gpt", spp=4, seed=seed)


class Reconstruct(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.img = gpt_render()

    def buffers(self):
        return self.img["primal"], self.img["dx"], self.img["dy"]

    @needs_cli
    def test_both_solvers_equal_the_tools_reconstruct_command(self):
        render = os.path.join(OUT, "gpt.exr")
        run_cli("render", SMALL, "--integrator", "gpt", "--spp", "4", "--seed", "5", "-o", render)
        layers = gdr.read_exr(render)
        for method, cli_params, params in (("poisson-l2", ["--alpha", "0.3"], {"alpha": 0.3}),
                                           ("poisson-l1", ["--set", "iterations=7"], {"iterations": 7})):
            with self.subTest(method=method):
                out = os.path.join(OUT, f"{method}.exr")
                run_cli("reconstruct", render, "--method", method, *cli_params, "-o", out)
                expected = gdr.read_exr(out)["color"]
                got = gdr.reconstruct(layers["primal"], layers["dx"], layers["dy"], method=method,
                                      direct=layers["direct"], **params)
                self.assertEqual(got.dtype, np.float32)
                self.assertEqual(got.shape, expected.shape)
                self.assertTrue(np.array_equal(got, expected), f"largest difference {np.abs(got - expected).max()}")
                # ... and a parameter that matters changes it: the comparison can fail.
                other = gdr.reconstruct(layers["primal"], layers["dx"], layers["dy"], method=method,
                                        direct=layers["direct"], alpha=0.05)
                self.assertFalse(np.array_equal(other, expected))

    def test_the_renders_own_reconstructions_are_reconstruct_of_its_buffers(self):
        for layer, method in (("reconstruction_l1", "poisson-l1"), ("reconstruction_l2", "poisson-l2")):
            got = gdr.reconstruct(*self.buffers(), method=method, direct=self.img["direct"])
            self.assertTrue(np.array_equal(got, self.img[layer]), layer)

    def test_exact_gradients_give_back_the_image(self):
        # An image and its exact forward differences: L2 must return the image itself.
        rng = np.random.default_rng(1)
        image = rng.uniform(0.1, 2.0, size=(12, 17, 3)).astype(np.float32)
        dx = np.zeros_like(image)
        dy = np.zeros_like(image)
        dx[:, :-1] = image[:, 1:] - image[:, :-1]
        dy[:-1, :] = image[1:, :] - image[:-1, :]
        got = gdr.reconstruct(image, dx, dy, "poisson-l2")  # the method may also come fourth
        np.testing.assert_allclose(got, image, rtol=0, atol=1e-4)
        # 2-D grey arrays (height, width) come back as (height, width, 1), and float64 is accepted.
        grey = gdr.reconstruct(image[..., 0].astype(np.float64), dx[..., 0], dy[..., 0], method="poisson-l2")
        self.assertEqual(grey.shape, (12, 17, 1))
        np.testing.assert_allclose(grey[..., 0], image[..., 0], rtol=0, atol=1e-4)


class Metrics(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.a = gpt_render(3)["reconstruction_l1"]
        cls.b = gdr.render(gdr.load_scene(SMALL), integrator="pt", spp=8)["color"]

    def test_formulas(self):
        x, r = self.a.astype(np.float64), self.b.astype(np.float64)
        m = gdr.metrics
        self.assertAlmostEqual(m.mse(self.a, self.b), np.mean((x - r) ** 2), delta=1e-6 * np.mean((x - r) ** 2))
        self.assertAlmostEqual(m.mae(self.a, self.b), np.mean(np.abs(x - r)), delta=1e-6 * np.mean(np.abs(x - r)))
        thesis = np.mean((x - r) ** 2 / (r ** 2 + 0.01))
        self.assertAlmostEqual(m.relmse(self.a, self.b), thesis, delta=1e-6 * thesis)
        grey = np.mean((x - r) ** 2 / (r.mean(axis=2, keepdims=True) ** 2 + 0.001))
        got = m.relmse(self.a, self.b, eps=0.001, grey_denominator=True)
        self.assertAlmostEqual(got, grey, delta=1e-6 * grey)
        self.assertEqual(m.ssim(self.b, self.b), 1.0)
        self.assertLess(m.ssim(self.a, self.b), 1.0)
        self.assertEqual(m.relmse(self.b, self.b), 0.0)

    @needs_cli
    def test_the_tools_compare_prints_the_same_numbers(self):
        pa, pb = os.path.join(OUT, "a.exr"), os.path.join(OUT, "b.exr")
        gdr.write_exr(pa, {"color": self.a})
        gdr.write_exr(pb, {"color": self.b})
        text = run_cli("compare", pa, pb)

        def printed(label):
            match = re.search(rf"^{re.escape(label)}:\s+(\S+)", text, re.M)
            self.assertIsNotNone(match, f"no '{label}:' line in\n{text}")
            return float(match.group(1))

        m = gdr.metrics
        for label, value in (("MSE", m.mse(self.a, self.b)), ("relMSE", m.relmse(self.a, self.b)),
                             ("relMSE grey", m.relmse(self.a, self.b, eps=0.001, grey_denominator=True)),
                             ("MAE", m.mae(self.a, self.b)), ("SSIM", m.ssim(self.a, self.b)),
                             ("SSIM sRGB", m.ssim(self.a, self.b, srgb=True))):
            with self.subTest(metric=label):
                # The tool prints six significant digits.
                self.assertAlmostEqual(printed(label), value, delta=1e-5 * abs(value))
        self.assertIn("relMSE", m.compare_report(self.a, self.b))

    def test_box_downsample_keeps_the_mean(self):
        small = gdr.metrics.box_downsample(self.b, 4)
        self.assertEqual(small.shape, (6, 6, 3))
        np.testing.assert_allclose(small[0, 0], self.b[:4, :4].mean(axis=(0, 1)), rtol=1e-6)
        with self.assertRaises(ValueError):
            gdr.metrics.box_downsample(self.b, 5)


if __name__ == "__main__":
    unittest.main()
