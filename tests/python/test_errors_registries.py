"""Bad input raises Python exceptions carrying gdr's message, the
registries list what the tool lists, and every public name is documented."""
import inspect
import os
import re
import unittest

import numpy as np

from gdr_test_util import SMALL, SOURCE_DIR, gdr, needs_cli, run_cli, scratch_dir

OUT = scratch_dir("errors")
BAD = os.path.join(SOURCE_DIR, "tests", "scenes", "bad")


class Exceptions(unittest.TestCase):
    def test_the_hierarchy(self):
        self.assertTrue(issubclass(gdr.InputError, gdr.Error) and issubclass(gdr.InputError, ValueError))
        self.assertTrue(issubclass(gdr.ParameterError, gdr.Error) and issubclass(gdr.ParameterError, ValueError))
        self.assertTrue(issubclass(gdr.RuntimeFailure, gdr.Error) and issubclass(gdr.RuntimeFailure, RuntimeError))
        self.assertTrue(issubclass(gdr.Interrupted, RuntimeError))

    def test_bad_scene_paths_and_files(self):
        with self.assertRaises(FileNotFoundError) as cm:
            gdr.load_scene(os.path.join(BAD, "nope.json"))
        self.assertIn("nope.json", str(cm.exception))
        with self.assertRaises(IsADirectoryError):
            gdr.load_scene(BAD)
        for name, named in (("malformed.json", "malformed.json"), ("missing-mtl-obj.json", "no-such-file.mtl"),
                            ("unknown-key.json", "unknown-key.json"), ("nan-vertex-obj.json", "nan-vertex.obj")):
            with self.subTest(scene=name):
                with self.assertRaises(gdr.InputError) as cm:
                    gdr.load_scene(os.path.join(BAD, name))
                self.assertIn(named, str(cm.exception))
        # A path object works as a str does.
        import pathlib
        self.assertEqual(gdr.load_scene(pathlib.Path(SMALL)).width, 24)

    def test_mitsuba_parameters_and_unsupported_elements(self):
        xml = os.path.join(OUT, "param.xml")
        with open(xml, "w") as f:
            f.write('<scene version="3.0.0"><bsdf type="diffuse" id="grey">'
                    '<rgb name="reflectance" value="$level"/></bsdf><emitter type="projector"/></scene>')
        with self.assertRaises(gdr.InputError) as cm:
            gdr.load_scene(xml)
        self.assertIn("$level", str(cm.exception))
        with self.assertRaises(gdr.InputError) as cm:
            gdr.load_scene(xml, defines={"level": 0.5})
        self.assertIn("projector", str(cm.exception))
        self.assertIn("--lenient", str(cm.exception))
        with self.assertRaises(gdr.InputError):
            gdr.load_scene(SMALL, defines={"level": 1})  # defines are for Mitsuba scenes only

    def test_unknown_integrators_and_bad_parameters(self):
        scene = gdr.load_scene(SMALL)
        with self.assertRaises(gdr.ParameterError) as cm:
            gdr.render(scene, integrator="ptt", spp=1)
        self.assertIn("'ptt'", str(cm.exception))
        self.assertIn("available", str(cm.exception))
        with self.assertRaises(ValueError) as cm:
            gdr.render(scene, integrator="pt", spp=1, params={"mx_depth": 3})
        self.assertIn("'mx_depth'", str(cm.exception))
        with self.assertRaises(ValueError) as cm:
            gdr.render(scene, integrator="pt", spp=1, params={"max_depth": "deep"})
        self.assertIn("max_depth", str(cm.exception))
        with self.assertRaises(ValueError) as cm:
            gdr.render(scene, integrator="gpt", spp=1, params={"shift": "sideways"})
        self.assertIn("sideways", str(cm.exception))
        with self.assertRaises(TypeError) as cm:
            gdr.render(scene, spp=1, params={"max_depth": [3]})
        self.assertIn("max_depth", str(cm.exception))
        with self.assertRaises(TypeError):
            gdr.render(scene, spp=1, progress=3)
        for bad in ({"spp": 0}, {"seed": -1}, {"threads": -1}, {"time": -1.0}, {"time": float("nan")},
                    {"spp": 2, "time": 1.0}, {"first_sample": -1}):
            with self.subTest(**bad):
                with self.assertRaises(ValueError):
                    gdr.render(scene, **bad)
        # numpy scalars are numbers too.
        self.assertEqual(gdr.render(scene, spp=1, params={"max_depth": np.int64(2)}).stats.spp, 1)
        # The scene file's misspelt parameter is named with the file.
        with self.assertRaises(gdr.ParameterError) as cm:
            gdr.render(gdr.load_scene(os.path.join(BAD, "misspelt-param.json")), spp=1)
        self.assertIn("misspelt-param.json", str(cm.exception))

    def test_reconstruct_and_metrics_refuse_mismatched_and_malformed_arrays(self):
        a = np.zeros((4, 5, 3), np.float32)
        with self.assertRaises(gdr.ParameterError) as cm:
            gdr.reconstruct(a, a, np.zeros((4, 6, 3)))
        self.assertIn("dy", str(cm.exception))
        with self.assertRaises(ValueError) as cm:
            gdr.reconstruct(a, a, a, direct=np.zeros((4, 5, 1)))
        self.assertIn("direct", str(cm.exception))
        with self.assertRaises(ValueError) as cm:
            gdr.reconstruct(np.zeros((4,)), a, a)
        self.assertIn("primal", str(cm.exception))
        with self.assertRaises(ValueError):
            gdr.reconstruct(a, a, a, method="poisson-l3")
        with self.assertRaises(ValueError) as cm:
            gdr.reconstruct(a, a, a, method="poisson-l2", alhpa=0.2)
        self.assertIn("alhpa", str(cm.exception))
        nan = a.copy()
        nan[1, 2, 0] = np.inf
        with self.assertRaises(gdr.InputError):
            gdr.reconstruct(a, nan, a)
        with self.assertRaises(gdr.ParameterError):
            gdr.metrics.relmse(a, np.zeros((5, 4, 3)))
        with self.assertRaises(gdr.InputError):
            gdr.metrics.mse(nan, a)
        with self.assertRaises(ValueError):
            gdr.metrics.mae(a, "not an image")

    def test_the_scene_cannot_change_while_it_renders(self):
        scene = gdr.load_scene(SMALL)
        failures = []

        def progress(p):
            try:
                scene.set_resolution(8, 8)
            except RuntimeError as e:
                failures.append(str(e))

        gdr.render(scene, spp=2, progress=progress)
        self.assertTrue(failures and "while a render" in failures[0], failures)
        scene.set_resolution(8, 8)  # afterwards it can
        self.assertEqual(gdr.render(scene, spp=1)["color"].shape, (8, 8, 3))
        with self.assertRaises(ValueError):
            scene.set_fov(200)
        with self.assertRaises(ValueError):
            scene.set_fov(30, axis="z")
        scene.set_fov(30, axis="x")
        self.assertEqual((scene.fov, scene.fov_axis), (30.0, "x"))


class Registries(unittest.TestCase):
    def test_built_ins_with_descriptions(self):
        self.assertTrue({"pt", "gpt", "bdpt"} <= set(gdr.integrators()))
        self.assertTrue({"half-vector", "reconnection", "replay", "replay-reconnect"} <= set(gdr.shifts()))
        self.assertTrue({"poisson-l1", "poisson-l2"} <= set(gdr.reconstructors()))
        for registry in (gdr.integrators(), gdr.shifts(), gdr.reconstructors()):
            self.assertTrue(all(isinstance(d, str) and d for d in registry.values()), registry)
        d = gdr.integrator_defaults("gpt")
        self.assertEqual(d["shift"], "half-vector")
        self.assertEqual(d["alpha"], 0.2)
        self.assertEqual(d["max_depth"], -1)
        with self.assertRaises(ValueError):
            gdr.integrator_defaults("nope")

    @needs_cli
    def test_the_same_names_and_descriptions_as_gdr_list(self):
        text = run_cli("list")
        for registry in (gdr.integrators(), gdr.shifts(), gdr.reconstructors()):
            for name, description in registry.items():
                self.assertRegex(text, rf"(?m)^  {re.escape(name)}\s+{re.escape(description)}$")


class Documentation(unittest.TestCase):
    def test_every_public_function_and_class_has_a_docstring(self):
        missing = []
        for module in (gdr, gdr.metrics):
            for name, obj in vars(module).items():
                if name.startswith("_") or inspect.ismodule(obj):
                    continue
                if not (obj.__doc__ or "").strip():
                    missing.append(f"{module.__name__}.{name}")
                if inspect.isclass(obj) and not issubclass(obj, BaseException):
                    for attr, member in vars(obj).items():
                        if not attr.startswith("_") and not (getattr(member, "__doc__", "") or "").strip():
                            missing.append(f"{module.__name__}.{name}.{attr}")
        self.assertEqual(missing, [])
        self.assertTrue(gdr.__doc__.strip())
        self.assertRegex(gdr.__version__, r"^\d+\.\d+\.\d+$")


if __name__ == "__main__":
    unittest.main()
