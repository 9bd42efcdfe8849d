"""gdr.traverse: a scene updated in place renders as a freshly loaded one with
the changed value (same seed, same arrays), for materials, transforms and the
camera; bad keys and values are refused; Scene objects copy."""
import copy
import json
import unittest

import numpy as np

from gdr_test_util import SMALL, gdr
from test_load_dict import arrays_scene


def render(scene, **kw):
    return gdr.render(scene, integrator="gpt", spp=2, seed=11, **kw)


class Traverse(unittest.TestCase):
    def assert_same(self, a, b):
        ra, rb = render(a), render(b)
        self.assertEqual(sorted(ra), sorted(rb))
        for name in ra:
            np.testing.assert_array_equal(ra[name], rb[name], err_msg=name)

    def test_lists_the_editable_parameters(self):
        params = gdr.traverse(gdr.load_dict(arrays_scene()))
        for key in ("camera.position", "camera.target", "camera.fov", "camera.width", "materials.floor.kd",
                    "materials.light.ke", "meshes[1].transform"):
            self.assertIn(key, params)
        self.assertEqual(params["materials.floor.kd"], [0.6, 0.5, 0.4])
        self.assertEqual(params["camera.width"], 20)

    def test_a_material_change_equals_a_fresh_load_and_keeps_the_object(self):
        scene = gdr.load_dict(arrays_scene())
        before = render(scene)["color"]
        params = gdr.traverse(scene)
        params["materials.floor.kd"] = [0.2, 0.7, 0.3]
        params["materials.light.ke"] = np.array([4.0, 4.0, 6.0])
        self.assertEqual(params.update(), ["materials.floor.kd", "materials.light.ke"])
        d = arrays_scene()
        d["materials"]["floor"]["kd"] = [0.2, 0.7, 0.3]
        d["materials"]["light"]["ke"] = [4.0, 4.0, 6.0]
        fresh = gdr.load_dict(d)
        self.assert_same(scene, fresh)
        self.assertEqual(scene.content_hash, fresh.content_hash)
        self.assertGreater(np.abs(render(scene)["color"] - before).max(), 0.01)  # it did change

    def test_roughness_and_transforms(self):
        d = arrays_scene()
        d["materials"]["floor"] = {"type": "roughconductor", "ks": [0.9, 0.9, 0.9], "alpha": 0.3}
        scene = gdr.load_dict(d)
        params = gdr.traverse(scene)
        params["materials.floor.alpha"] = 0.05
        params["meshes[1].transform"] = {"translate": [0.2, 0.0, 0.1]}
        params.update()
        d["materials"]["floor"]["alpha"] = 0.05
        d["meshes"][1]["transform"] = {"translate": [0.2, 0.0, 0.1]}
        self.assert_same(scene, gdr.load_dict(d))

    def test_a_camera_change_is_made_in_place_and_equals_a_fresh_load(self):
        with open(SMALL) as f:
            d = json.load(f)
        scene = gdr.load_scene(SMALL)
        hash_before = scene.content_hash
        params = gdr.traverse(scene)
        params["camera.position"] = [0.3, 1.1, 3.2]
        params["camera.fov"] = 40
        params["camera.width"] = 20
        params.update()
        d["camera"].update(position=[0.3, 1.1, 3.2], fov=40, width=20)
        import os
        fresh = gdr.load_dict(d, base_dir=os.path.dirname(SMALL))
        self.assertEqual((scene.width, scene.height), (20, 24))
        self.assert_same(scene, fresh)
        # Renders of the moved camera must not merge with renders of the old one.
        self.assertNotEqual(scene.content_hash, hash_before)

    def test_bad_keys_and_values_are_refused(self):
        params = gdr.traverse(gdr.load_dict(arrays_scene()))
        with self.assertRaisesRegex(KeyError, "materials.wood.kd"):
            params["materials.wood.kd"] = [1, 1, 1]
        with self.assertRaisesRegex(gdr.ParameterError, "materials.floor.kd.*3 numbers"):
            params["materials.floor.kd"] = [1, 1]
        with self.assertRaisesRegex(gdr.InputError, "camera.fov"):
            params["camera.fov"] = float("nan")
        params["materials.floor.kd"] = [2.0, 0.0, 0.0]  # above 1: refused by the loader, naming the material
        with self.assertRaisesRegex(gdr.InputError, "floor"):
            params.update()


class Copy(unittest.TestCase):
    def test_copies_render_as_the_original_and_are_independent(self):
        scene = gdr.load_dict(arrays_scene())
        gdr.traverse(scene)  # a traverse without changes changes nothing
        params = gdr.traverse(scene)
        params["camera.fov"] = 35
        params.update()
        twin = copy.copy(scene)
        deep = copy.deepcopy(scene)
        for other in (twin, deep):
            self.assertIsNot(other, scene)
            self.assertEqual(other.content_hash, scene.content_hash)
            a, b = render(scene), render(other)
            np.testing.assert_array_equal(a["color"], b["color"])
        p = gdr.traverse(twin)
        p["materials.floor.kd"] = [0.1, 0.1, 0.1]
        p.update()
        self.assertEqual(gdr.traverse(scene)["materials.floor.kd"], [0.6, 0.5, 0.4])
        file_scene = gdr.load_scene(SMALL)
        file_scene.set_resolution(12, 12)
        c = copy.copy(file_scene)
        self.assertEqual((c.width, c.height), (12, 12))
        np.testing.assert_array_equal(render(c)["color"], render(file_scene)["color"])


if __name__ == "__main__":
    unittest.main()
