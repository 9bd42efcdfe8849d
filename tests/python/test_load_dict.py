"""gdr.load_dict: a dict with the scene file's structure renders as the same
scene from a JSON file (same seed, same arrays), meshes from numpy arrays
render as the same mesh from an OBJ file, and bad dicts raise exceptions
naming the key or array."""
import copy
import json
import os
import unittest

import numpy as np

from gdr_test_util import SMALL, gdr, scratch_dir

OUT = scratch_dir("load_dict")

# A floor and an emitting quad above it, by vertex and triangle arrays.
FLOOR_V = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], dtype=np.float32)
LIGHT_V = np.array([[-0.3, 1.5, -0.3], [0.3, 1.5, -0.3], [0.3, 1.5, 0.3], [-0.3, 1.5, 0.3]], dtype=np.float64)
QUAD_T = np.array([[0, 2, 1], [0, 3, 2]], dtype=np.int32)   # floor: facing up
LIGHT_T = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)  # light: facing down
MATERIALS = {"floor": {"type": "diffuse", "kd": [0.6, 0.5, 0.4]},
             "light": {"type": "diffuse", "kd": [0, 0, 0], "ke": [8, 8, 8]}}
CAMERA = {"position": [0, 1.2, 2.5], "target": [0, 0.3, 0], "up": [0, 1, 0], "fov": 50, "width": 20, "height": 16}


def arrays_scene():
    return {"camera": dict(CAMERA),
            "meshes": [{"vertices": FLOOR_V, "triangles": QUAD_T, "material": "floor"},
                       {"vertices": LIGHT_V, "triangles": LIGHT_T, "material": "light",
                        "transform": {"translate": [0, 0.1, 0]}}],
            "materials": copy.deepcopy(MATERIALS),
            "render": {"integrator": "pt", "spp": 4, "seed": 3}}


def write_obj(path, name, v, t):
    with open(path, "w") as f:
        f.write(f"mtllib {name}.mtl\nusemtl {name}\n")
        f.writelines(f"v {x!r} {y!r} {z!r}\n" for x, y, z in v.tolist())
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in t.tolist())
    with open(os.path.join(os.path.dirname(path), f"{name}.mtl"), "w") as f:
        f.write(f"newmtl {name}\nKd 0.5 0.5 0.5\n")


class LoadDict(unittest.TestCase):
    def assert_same_render(self, a, b, **kw):
        ra, rb = gdr.render(a, **kw), gdr.render(b, **kw)
        self.assertEqual(sorted(ra), sorted(rb))
        for name in ra:
            np.testing.assert_array_equal(ra[name], rb[name], err_msg=name)

    def test_a_dict_renders_as_the_same_scene_from_its_file(self):
        with open(SMALL) as f:
            d = json.load(f)
        from_dict = gdr.load_dict(d, base_dir=os.path.dirname(SMALL))
        self.assertEqual((from_dict.width, from_dict.height, from_dict.triangles), (24, 24, 36))
        self.assert_same_render(from_dict, gdr.load_scene(SMALL), integrator="gpt", spp=2, seed=5)
        # The hash follows the content: the same dict hashes the same, another value differently.
        again = gdr.load_dict(d, base_dir=os.path.dirname(SMALL))
        self.assertEqual(from_dict.content_hash, again.content_hash)
        d["camera"]["fov"] = 46
        self.assertNotEqual(gdr.load_dict(d, base_dir=os.path.dirname(SMALL)).content_hash, from_dict.content_hash)

    def test_numpy_meshes_render_as_the_same_meshes_from_obj_files(self):
        write_obj(os.path.join(OUT, "floor.obj"), "floor", FLOOR_V, QUAD_T)
        write_obj(os.path.join(OUT, "light.obj"), "light", LIGHT_V, LIGHT_T)
        files = {"camera": dict(CAMERA),
                 "meshes": ["floor.obj", {"file": "light.obj", "transform": {"translate": [0, 0.1, 0]}}],
                 "materials": copy.deepcopy(MATERIALS), "render": {"integrator": "pt", "spp": 4, "seed": 3}}
        path = os.path.join(OUT, "quads.json")
        with open(path, "w") as f:
            json.dump(files, f)
        scene = gdr.load_dict(arrays_scene())
        self.assertEqual(scene.emitters, 2)
        self.assert_same_render(scene, gdr.load_scene(path), integrator="gpt", spp=4, seed=3)
        img = gdr.render(scene)["color"]
        self.assertGreater(img.mean(), 0.01)  # the lit floor is seen

    def test_non_contiguous_and_list_arrays_give_the_same_scene(self):
        d = arrays_scene()
        wide = np.zeros((4, 6), np.float32)
        wide[:, ::2] = FLOOR_V
        d["meshes"][0]["vertices"] = wide[:, ::2]  # a strided view
        self.assertFalse(d["meshes"][0]["vertices"].flags["C_CONTIGUOUS"])
        e = arrays_scene()
        e["meshes"][0]["vertices"] = FLOOR_V.tolist()
        e["meshes"][0]["triangles"] = [tuple(t) for t in QUAD_T.tolist()]
        self.assert_same_render(gdr.load_dict(d), gdr.load_dict(arrays_scene()), spp=2)
        self.assert_same_render(gdr.load_dict(e), gdr.load_dict(arrays_scene()), spp=2)

    def test_bad_dicts_name_the_key_or_array(self):
        def bad(change, error, pattern):
            d = arrays_scene()
            change(d)
            with self.assertRaisesRegex(error, pattern):
                gdr.load_dict(d)

        bad(lambda d: d.update(lamps=[]), gdr.InputError, "lamps")
        bad(lambda d: d["camera"].update(zoom=2), gdr.InputError, "zoom")
        bad(lambda d: d["meshes"][0].update(colour=1), gdr.InputError, "colour")
        bad(lambda d: d["meshes"][0].update(vertices=FLOOR_V.astype(np.complex64)), gdr.ParameterError,
            r"meshes\[0\]\.vertices.*complex64")
        bad(lambda d: d["meshes"][1].update(triangles=LIGHT_T.astype(np.float32)), gdr.ParameterError,
            r"meshes\[1\]\.triangles.*float32.*integer")
        bad(lambda d: d["meshes"][0].update(vertices=FLOOR_V[:, :2]), gdr.ParameterError,
            r"meshes\[0\]\.vertices.*\(4, 2\)")
        nan = FLOOR_V.copy()
        nan[2, 1] = np.nan
        bad(lambda d: d["meshes"][0].update(vertices=nan), gdr.InputError, r"meshes\.0\.vertices|meshes\[0\]\.vertices")
        bad(lambda d: d["camera"].update(fov=float("inf")), gdr.InputError, "camera.fov")
        bad(lambda d: d["meshes"][0].update(triangles=np.array([[0, 1, 9]])), gdr.InputError,
            r"meshes\[0\]\.triangles\[0\].*9.*\[0, 3\]")
        bad(lambda d: d["meshes"][0].update(material="steel"), gdr.InputError, "steel")
        bad(lambda d: d["materials"]["floor"].update(kd=[2, 0, 0]), gdr.InputError, "floor")
        bad(lambda d: d["camera"].update(width=object()), TypeError, "camera.width")
        with self.assertRaisesRegex(TypeError, "expected a dict"):
            gdr.load_dict([1, 2])


# A Mitsuba 3 scene file and the Mitsuba-style dict a Mitsuba 3 user writes for it.
MITSUBA_XML = """<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="6"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin="0, 1.2, 3" target="0, 0.4, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
    <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="18"/></film>
  </sensor>
  <bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.5, 0.5, 0.5"/></bsdf>
  <shape type="rectangle" id="floor">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="2"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.6, 0.4"/></bsdf>
  </shape>
  <shape type="sphere" id="ball">
    <point name="center" x="0.4" y="0.3" z="0"/><float name="radius" value="0.3"/>
    <bsdf type="roughconductor"><float name="alpha" value="0.1"/></bsdf>
  </shape>
  <shape type="cube" id="box">
    <transform name="to_world"><scale value="0.2"/><translate x="-0.5" y="0.2"/></transform>
    <ref id="grey"/>
  </shape>
  <shape type="obj" id="tri">
    <string name="filename" value="tri.obj"/>
    <bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.1, 0.3, 0.6"/></bsdf>
  </shape>
  <shape type="rectangle" id="light">
    <transform name="to_world"><rotate x="1" angle="90"/><scale value="0.4"/><translate y="1.6"/></transform>
    <emitter type="area"><rgb name="radiance" value="9, 8, 7"/></emitter>
  </shape>
</scene>
"""


def mitsuba_dict():
    T = gdr.Transform
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 6},
        "sensor": {"type": "perspective", "fov": 45.0,
                   "to_world": gdr.look_at(origin=[0, 1.2, 3], target=[0, 0.4, 0], up=[0, 1, 0]),
                   "sampler": {"type": "independent", "sample_count": 4},
                   "film": {"type": "hdrfilm", "width": 24, "height": 18}},
        "grey": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}},
        "floor": {"type": "rectangle", "to_world": T().scale(2).rotate([1, 0, 0], -90),
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.6, 0.4]}}},
        "ball": {"type": "sphere", "center": [0.4, 0.3, 0], "radius": 0.3,
                 "bsdf": {"type": "roughconductor", "alpha": 0.1}},
        "box": {"type": "cube", "to_world": T().translate([-0.5, 0.2, 0]).scale(0.2),
                "bsdf": {"type": "ref", "id": "grey"}},
        "tri": {"type": "obj", "filename": "tri.obj",
                "bsdf": {"type": "plastic", "diffuse_reflectance": {"type": "rgb", "value": [0.1, 0.3, 0.6]}}},
        "light": {"type": "rectangle", "to_world": T().translate([0, 1.6, 0]).scale(0.4).rotate([1, 0, 0], 90),
                  "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [9, 8, 7]}}},
    }


class MitsubaDicts(unittest.TestCase):
    """load_dict of a Mitsuba-style dict ({'type': 'scene', ...}) as Mitsuba 3's load_dict reads it."""

    @classmethod
    def setUpClass(cls):
        cls.dir = scratch_dir("mitsuba_dict")
        with open(os.path.join(cls.dir, "tri.obj"), "w") as f:
            f.write("v -0.3 0 -0.6\nv 0.3 0 -0.6\nv 0 0.7 -0.6\nf 1 2 3\n")
        cls.xml = os.path.join(cls.dir, "scene.xml")
        with open(cls.xml, "w") as f:
            f.write(MITSUBA_XML)

    def test_a_mitsuba_dict_renders_as_the_same_scene_from_its_xml_file(self):
        from_dict = gdr.load_dict(mitsuba_dict(), base_dir=self.dir)
        from_xml = gdr.load_scene(self.xml)
        self.assertEqual((from_dict.width, from_dict.height), (24, 18))
        self.assertEqual(from_dict.defaults, from_xml.defaults)
        self.assertEqual(from_dict.defaults["spp"], 4)
        self.assertEqual(from_dict.defaults["params"]["max_depth"], 6)
        self.assertEqual((from_dict.triangles, from_dict.emitters), (from_xml.triangles, from_xml.emitters))
        self.assertGreater(from_dict.emitters, 0)
        for integrator in ("pt", "gpt"):
            a = gdr.render(from_dict, integrator=integrator, spp=2, seed=9)
            b = gdr.render(from_xml, integrator=integrator, spp=2, seed=9)
            self.assertEqual(sorted(a), sorted(b))
            for name in a:
                np.testing.assert_array_equal(a[name], b[name], err_msg=f"{integrator} {name}")
        self.assertGreater(a["color"].mean(), 0.01)

    def test_copies_and_camera_edits(self):
        scene = gdr.load_dict(mitsuba_dict(), base_dir=self.dir)
        twin = copy.copy(scene)
        np.testing.assert_array_equal(gdr.render(twin, spp=1, seed=2)["color"], gdr.render(scene, spp=1, seed=2)["color"])
        params = gdr.traverse(scene)
        self.assertEqual(sorted(params), ["camera.fov", "camera.fov_axis", "camera.height", "camera.width"])
        params["camera.fov"] = 30
        params.update()
        self.assertNotEqual(scene.content_hash, twin.content_hash)
        self.assertEqual(copy.copy(scene).fov, 30)

    def test_matrices_and_numpy_arrays_as_transforms(self):
        # A 4x4 matrix (nested lists or numpy) gives the same placement as its steps would, up to
        # the rounding of a matrix product done in float64 instead of float32 step by step.
        d = mitsuba_dict()
        d["light"]["to_world"] = np.asarray(d["light"]["to_world"])
        d["box"]["to_world"] = np.asarray(d["box"]["to_world"]).tolist()
        a = gdr.render(gdr.load_dict(d, base_dir=self.dir), integrator="pt", spp=4, seed=9)["color"]
        b = gdr.render(gdr.load_scene(self.xml), integrator="pt", spp=4, seed=9)["color"]
        self.assertLess(np.abs(a - b).mean(), 1e-3 * max(b.mean(), 1e-6) + 1e-4)
        m = np.asarray(gdr.look_at([0, 0, 0], [0, 0, -1], [0, 1, 0]))
        np.testing.assert_allclose(m[:3, 2], [0, 0, -1])  # +z looks at the target, as Mitsuba's
        np.testing.assert_allclose(m[:3, 0], [-1, 0, 0])

    def test_unknown_plugins_and_keys_name_the_key_path(self):
        def bad(change, error, pattern):
            d = mitsuba_dict()
            change(d)
            with self.assertRaisesRegex(error, pattern):
                gdr.load_dict(d, base_dir=self.dir)

        bad(lambda d: d["floor"]["bsdf"].update(type="foo"), gdr.ParameterError,
            r"floor\.bsdf\.type: unknown plugin 'foo'")
        bad(lambda d: d["ball"].update(radiuz=2.0), gdr.InputError, r"ball\.radiuz")
        bad(lambda d: d["light"]["emitter"]["radiance"].update(value=[1, float("nan"), 1]), gdr.InputError,
            r"light\.emitter\.radiance\.value")
        bad(lambda d: d["sensor"].update(fov="wide"), gdr.InputError, r"sensor\.fov")
        bad(lambda d: d["ball"].update(center=[1, 2]), gdr.ParameterError, r"ball\.center")
        bad(lambda d: d.update(type="shape"), gdr.ParameterError, "type")
        bad(lambda d: d["tri"].update(filename="missing.obj"), gdr.InputError, r"tri.*missing\.obj")
        # lenient, as load_scene's: the property skipped with a warning naming it.
        d = mitsuba_dict()
        d["ball"]["radiuz"] = 2.0
        with self.assertWarnsRegex(gdr.SceneWarning, r"^ball\.radiuz: "):
            scene = gdr.load_dict(d, base_dir=self.dir, lenient=True)
        self.assertTrue(any("radiuz" in w for w in scene.warnings))


if __name__ == "__main__":
    unittest.main()
