"""gdr.render: the same arrays as the gdr tool for the same settings, its
statistics, the progress callback, the released GIL, and stopping a render
by Ctrl-C or by an exception of the callback."""
import os
import signal
import subprocess
import threading
import time
import unittest

import numpy as np

from gdr_test_util import BOX, SMALL, gdr, needs_cli, run_cli, scratch_dir

OUT = scratch_dir("render")

# A Mitsuba scene with a $parameter and an element gdr does not support (an
# environment light): a diffuse rectangle of reflectance $level lit by an
# emitter behind the camera.
MITSUBA = """<scene version="3.0.0">
  <default name="level" value="0.2"/>
  <sensor type="perspective"><float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="12"/></film></sensor>
  <shape type="rectangle"><bsdf type="diffuse"><rgb name="reflectance" value="$level"/></bsdf></shape>
  <shape type="rectangle"><boolean name="flip_normals" value="true"/>
    <transform name="to_world"><scale value="3"/><translate z="6"/></transform>
    <emitter type="area"><rgb name="radiance" value="4"/></emitter></shape>
  <emitter type="projector"/>
</scene>
"""


def assert_same_layers(test, cli_layers, py_layers):
    """Every layer of the tool's EXR equals the module's array bit for bit."""
    test.assertEqual(list(cli_layers.keys()), list(py_layers.keys()))
    for name in cli_layers:
        a, b = cli_layers[name], py_layers[name]
        test.assertEqual(a.shape, b.shape, name)
        test.assertEqual(b.dtype, np.float32, name)
        test.assertTrue(np.array_equal(a, b), f"layer {name}: largest difference {np.abs(a - b).max()}")


class RenderMatchesTheTool(unittest.TestCase):
    @needs_cli
    def test_gpt_layers_equal_the_tools_for_the_same_seed_and_spp(self):
        path = os.path.join(OUT, "gpt.exr")
        run_cli("render", SMALL, "--integrator", "gpt", "--spp", "4", "--seed", "3", "--set", "shift=reconnection",
                "--set", "max_depth=6", "-o", path)
        scene = gdr.load_scene(SMALL)
        img = gdr.render(scene, integrator="gpt", spp=4, seed=3, params={"shift": "reconnection", "max_depth": 6})
        assert_same_layers(self, gdr.read_exr(path), img)
        self.assertEqual(img.metadata["spp"], "4")
        self.assertEqual(img.metadata["seed"], "3")
        # A different seed is a different image: the comparison above can fail.
        other = gdr.render(scene, integrator="gpt", spp=4, seed=4, params={"shift": "reconnection", "max_depth": 6})
        self.assertFalse(np.array_equal(other["primal"], img["primal"]))

    @needs_cli
    def test_pt_with_a_new_resolution_and_the_scenes_defaults_equals_the_tool(self):
        path = os.path.join(OUT, "pt.exr")
        run_cli("render", BOX, "--resolution", "20x16", "--spp", "3", "--threads", "2", "-o", path)
        scene = gdr.load_scene(BOX)
        scene.set_resolution(20, 16)
        self.assertEqual((scene.width, scene.height), (20, 16))
        img = gdr.render(scene, spp=3, threads=1)  # the scene's integrator (pt) and seed; threads change nothing
        self.assertEqual(img["color"].shape, (16, 20, 3))
        assert_same_layers(self, gdr.read_exr(path), img)

    @needs_cli
    def test_a_mitsuba_scene_with_defines_and_lenient_equals_the_tool(self):
        xml = os.path.join(OUT, "rect.xml")
        with open(xml, "w") as f:
            f.write(MITSUBA)
        path = os.path.join(OUT, "rect.exr")
        run_cli("render", xml, "-D", "level=0.5", "--lenient", "--spp", "2", "-o", path)
        scene = gdr.load_scene(xml, defines={"level": 0.5}, lenient=True)
        self.assertTrue(any("projector" in w for w in scene.warnings), scene.warnings)
        img = gdr.render(scene, spp=2)
        assert_same_layers(self, gdr.read_exr(path), img)
        # The define reached the scene: the default reflectance gives a darker image.
        darker = gdr.render(gdr.load_scene(xml, lenient=True), spp=2)
        self.assertLess(darker["color"].mean(), 0.5 * img["color"].mean())

    def test_stats_count_the_samples_taken(self):
        scene = gdr.load_scene(SMALL)
        img = gdr.render(scene, integrator="pt", spp=5)
        s = img.stats
        self.assertEqual(s.spp, 5)
        self.assertEqual(s.samples, 5 * 24 * 24)
        self.assertGreater(s.rays, s.samples)  # a camera ray and at least one shadow ray on most samples
        self.assertGreater(s.seconds, 0.0)
        self.assertEqual(s.nonfinite, 0)
        self.assertTrue(np.all(img["spp"] == 5))
        self.assertEqual(set(img), {"color", "albedo", "normal", "depth", "variance", "spp"})

    @needs_cli
    def test_adaptive_sampling_equals_the_tool(self):
        path = os.path.join(OUT, "adaptive.exr")
        run_cli("render", SMALL, "--integrator", "gpt", "--spp", "8", "--seed", "2", "--adaptive", "0.25", "-o", path)
        scene = gdr.load_scene(SMALL)
        img = gdr.render(scene, integrator="gpt", spp=8, seed=2, adaptive=0.25)
        assert_same_layers(self, gdr.read_exr(path), img)
        self.assertIn("sample_density", img)
        self.assertEqual(img.metadata["adaptive_pilot_spp"], "2")
        self.assertGreater(img["spp"].max(), img["spp"].min())  # the counts differ from pixel to pixel
        with self.assertRaises(gdr.ParameterError):
            gdr.render(scene, spp=8, adaptive=0.9)

    def test_gradient_selection_records_its_mask(self):
        # The choice reads the pilots' measured seconds per pass, so only its
        # records are compared, not the image with the tool's.
        scene = gdr.load_scene(SMALL)
        img = gdr.render(scene, integrator="gpt", spp=8, seed=2, select_gradients=0.25)
        mask = img["gradient_mask"]
        self.assertEqual(mask.shape[2], 1)
        self.assertTrue(((mask == 0) | (mask == 1)).all())
        self.assertIn("gradient_share", img.metadata)
        self.assertIn("sample_density", img)
        with self.assertRaises(gdr.ParameterError):
            gdr.render(scene, spp=8, adaptive=0.2, select_gradients=0.2)
        with self.assertRaises(gdr.ParameterError):
            gdr.render(scene, integrator="pt", spp=8, select_gradients=0.2)


class Progress(unittest.TestCase):
    def test_the_callback_runs_on_the_calling_thread_and_ends_at_one(self):
        scene = gdr.load_scene(SMALL)
        calls = []
        caller = threading.get_ident()
        img = gdr.render(scene, integrator="pt", spp=16, threads=1,
                         progress=lambda p: calls.append((p.fraction, p.samples, p.seconds, threading.get_ident())))
        self.assertGreaterEqual(len(calls), 1)
        self.assertTrue(all(t == caller for *_, t in calls))
        fractions = [c[0] for c in calls]
        self.assertEqual(fractions, sorted(fractions))
        self.assertTrue(all(0.0 <= f <= 1.0 for f in fractions))
        self.assertEqual(fractions[-1], 1.0)
        self.assertEqual(calls[-1][1], img.stats.samples)

    def test_a_long_render_reports_while_it_runs(self):
        scene = gdr.load_scene(SMALL)
        calls = []
        gdr.render(scene, integrator="pt", time=0.6, threads=1, progress=lambda p: calls.append(p.seconds))
        # Reports about every 0.05 s: several over 0.6 s even on a busy machine.
        self.assertGreaterEqual(len(calls), 4, calls)
        self.assertEqual(calls, sorted(calls))


class TheGilIsReleased(unittest.TestCase):
    def count_ticks(self, done):
        """The main thread's clock every 1000 iterations of a Python loop, until done[0] is set."""
        ticks, n = [], 0
        while not done[0]:
            n += 1
            if n % 1000 == 0:
                ticks.append(time.perf_counter())
        return ticks

    def test_python_runs_on_another_thread_during_a_render(self):
        scene = gdr.load_scene(SMALL)
        # The loop's speed alone, as the measure of what it gets during the render:
        # a thread that only sleeps ends it.
        done = [False]
        timer = threading.Timer(0.3, lambda: done.__setitem__(0, True))
        start = time.perf_counter()
        timer.start()
        alone = len(self.count_ticks(done)) / (time.perf_counter() - start)
        done, span = [False], []

        def render():
            # No progress callback: a callback is Python code, during which the GIL
            # changes hands anyway.
            span.append(time.perf_counter())
            gdr.render(scene, integrator="pt", time=0.6, threads=1)
            span.append(time.perf_counter())
            done[0] = True

        worker = threading.Thread(target=render)
        worker.start()
        ticks = self.count_ticks(done)
        worker.join()
        t0, t1 = span[0] + 0.05, span[1] - 0.05  # the render's span, less the calls' own Python code
        during = len([t for t in ticks if t0 <= t <= t1]) / (t1 - t0)
        # Held through the render, the GIL stops this loop for all of it (0 ticks
        # when it was held on purpose); released, the loop shares the machine with
        # one render thread (half its speed alone on a busy 2-core machine). A
        # tenth leaves room for a busier one.
        self.assertGreater(during, 0.1 * alone, f"{during:.0f} ticks/s during the render, {alone:.0f} alone")


class Stopping(unittest.TestCase):
    def long_render(self, **kw):
        # About 2 * 10^9 samples: hours, unless it is stopped.
        return gdr.render(gdr.load_scene(SMALL), integrator="gpt", spp=4_000_000, threads=1, **kw)

    def test_ctrl_c_stops_the_render_and_raises_keyboard_interrupt(self):
        self.assertIs(signal.getsignal(signal.SIGINT), signal.default_int_handler)
        # SIGINT from another process, as a terminal's Ctrl-C comes: it needs no GIL.
        start = time.perf_counter()
        killer = subprocess.Popen(["sh", "-c", f"sleep 0.5 && kill -INT {os.getpid()}"])
        try:
            with self.assertRaises(KeyboardInterrupt):
                self.long_render()
        finally:
            killer.wait()
        elapsed = time.perf_counter() - start
        # The render stops at once (an abandoned pass is undone); 5 s is a busy machine's margin.
        self.assertLess(elapsed, 5.5, f"stopped {elapsed:.2f} s after the start, 0.5 s after which Ctrl-C came")
        # Nothing is left running or broken: the next render works, and Python's handler is in place.
        self.assertIs(signal.getsignal(signal.SIGINT), signal.default_int_handler)
        self.assertEqual(gdr.render(gdr.load_scene(SMALL), spp=1).stats.spp, 1)

    def test_an_exception_of_the_callback_stops_the_render_and_propagates(self):
        class Enough(Exception):
            pass

        def progress(p):
            if p.seconds > 0.3:
                raise Enough(f"stopped at {p.fraction}")

        start = time.perf_counter()
        with self.assertRaises(Enough):
            self.long_render(progress=progress)
        self.assertLess(time.perf_counter() - start, 5.3)


if __name__ == "__main__":
    unittest.main()
