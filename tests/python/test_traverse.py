"""gdr.traverse: a scene updated in place renders as a freshly loaded one with
the changed value (same seed, same arrays, bit for bit), for material colours,
roughness, emitted radiance, transforms, the environment and the camera,
without loading the scene again; render headers record the edits; bad keys and
values are refused naming the key; Scene objects copy."""
import copy
import json
import os
import unittest

import numpy as np

from gdr_test_util import BOX, SMALL, gdr
from test_load_dict import arrays_scene

# The Cornell box with two spheres: an OBJ with vertex normals (smooth spheres)
# and an MTL, overridden by the scene's materials.
SPHERES = os.path.join(os.path.dirname(BOX), "CornellBox-Sphere.obj")


def spheres_scene():
    return {"camera": {"position": [0, 1, 3.5], "target": [0, 1, 0], "up": [0, 1, 0], "fov": 45,
                       "width": 20, "height": 20},
            "meshes": [{"file": SPHERES, "transform": {"rotate": [0, 1, 0, 4]}}],
            "materials": {"leftSphere": {"type": "roughconductor", "ks": [0.9, 0.8, 0.6], "alpha": 0.2},
                          "light": {"ke": [17, 12, 4]}}}


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


class InPlace(unittest.TestCase):
    """Each kind of edit, made in place, against a fresh load of the edited description."""

    def assert_same(self, a, b):
        Traverse.assert_same(self, a, b)

    def edit(self, make, changes, check_changed=True):
        """Loads make(), applies `changes` ({key: value}) through traverse without any scene being
        loaded again, and returns (the edited scene, a fresh load of the edited description)."""
        scene = make_scene = gdr.load_dict(make())
        before = render(scene)["color"]
        loads = gdr._scene_loads()
        params = gdr.traverse(scene)
        for k, v in changes.items():
            params[k] = v
        self.assertEqual(params.update(), sorted(changes))
        self.assertEqual(gdr._scene_loads(), loads, "update() loaded a scene: it must edit in place")
        self.assertIs(scene, make_scene)
        if check_changed:
            self.assertGreater(np.abs(render(scene)["color"] - before).max(), 1e-3)  # the edit shows
        d = make()
        for k, v in changes.items():
            d = _set_key(d, k, v)
        fresh = gdr.load_dict(d)
        self.assertEqual(scene.content_hash, fresh.content_hash)
        return scene, fresh

    def test_material_colour(self):
        self.assert_same(*self.edit(arrays_scene, {"materials.floor.kd": [0.2, 0.7, 0.3]}))

    def test_roughness(self):
        self.assert_same(*self.edit(spheres_scene, {"materials.leftSphere.alpha": 0.02}))
        # Glossy to smooth: the material's cached classification (a delta BSDF now) follows.
        self.assert_same(*self.edit(spheres_scene, {"materials.leftSphere.alpha": 0.0}))

    def test_emitter_radiance(self):
        self.assert_same(*self.edit(spheres_scene, {"materials.light.ke": [5, 9, 20]}))
        # A second emitter appears: the light distribution is rebuilt over both.
        scene, fresh = self.edit(arrays_scene, {"materials.floor.ke": [0.5, 0.2, 0.1]})
        self.assertEqual(scene.emitters, 4)
        self.assert_same(scene, fresh)

    def test_values_the_scene_file_does_not_give(self):
        # Listed with the values the material has (its MTL's, or the defaults), and editable.
        params = gdr.traverse(gdr.load_dict(spheres_scene()))
        np.testing.assert_allclose(params["materials.light.kd"], [0.78, 0.78, 0.78], rtol=1e-6)
        self.assertEqual(params["materials.leftSphere.alpha"], 0.2)
        self.assertEqual(gdr.traverse(gdr.load_dict(arrays_scene()))["materials.floor.ke"], [0.0, 0.0, 0.0])
        self.assert_same(*self.edit(spheres_scene, {"materials.light.kd": [0.1, 0.5, 0.2]}))

    def test_transforms(self):
        # Smooth normals of an OBJ turned with it.
        self.assert_same(*self.edit(spheres_scene, {"meshes[0].transform": {"rotate": [0, 1, 0, -7],
                                                                            "scale": [1.0, 1.1, 0.9]}}))
        # The emitting quad moved and scaled: its area, and so its share of the light, changes.
        self.assert_same(*self.edit(arrays_scene, {"meshes[1].transform": {"translate": [0.2, 0.05, 0.1],
                                                                           "scale": 1.5}}))

    def test_environment(self):
        def lit():
            d = arrays_scene()
            d["environment"] = {"type": "constant", "radiance": [0.2, 0.3, 0.5]}
            return d
        self.assert_same(*self.edit(lit, {"environment.radiance": [0.9, 0.4, 0.1]}))

    def test_camera(self):
        self.assert_same(*self.edit(spheres_scene, {"camera.position": [0.2, 1.1, 3.3], "camera.fov": 40}))

    def test_several_edits_at_once_and_in_turn(self):
        changes = {"materials.light.ke": [9, 9, 9], "materials.leftSphere.ks": [0.5, 0.9, 0.5],
                   "meshes[0].transform": {"translate": [0.05, 0, 0]}, "camera.fov": 50}
        scene, fresh = self.edit(spheres_scene, changes)
        params = gdr.traverse(scene)  # a second traverse sees the edited values and edits on
        self.assertEqual(params["materials.light.ke"], [9, 9, 9])
        params["materials.leftSphere.alpha"] = 0.4
        params.update()
        d = _set_key(json.loads(json.dumps(spheres_scene())), "materials.leftSphere.alpha", 0.4)
        for k, v in changes.items():
            d = _set_key(d, k, v)
        self.assert_same(scene, gdr.load_dict(d))

    def test_an_edit_of_a_scene_file(self):
        scene = gdr.load_scene(SMALL)
        loads = gdr._scene_loads()
        params = gdr.traverse(scene)
        self.assertNotIn("materials.light.ke", params)  # the file overrides no material
        params["camera.target"] = [0.1, 0.9, 0]
        params.update()
        self.assertEqual(gdr._scene_loads(), loads)
        with open(SMALL) as f:
            d = json.load(f)
        d["camera"]["target"] = [0.1, 0.9, 0]
        fresh = gdr.load_dict(d, base_dir=os.path.dirname(SMALL))
        self.assert_same(scene, fresh)
        self.assertEqual(scene.content_hash, fresh.content_hash)

    def test_the_load_counter_counts(self):
        # The no-reload checks above rely on it: a load must show.
        loads = gdr._scene_loads()
        gdr.load_dict(arrays_scene())
        gdr.load_scene(SMALL)
        self.assertEqual(gdr._scene_loads(), loads + 2)

    def test_render_headers_record_the_edits(self):
        scene = gdr.load_dict(arrays_scene())
        original = render(scene).metadata
        self.assertNotIn("scene_edits", original)
        params = gdr.traverse(scene)
        params["materials.light.ke"] = [3, 3, 3]
        params["meshes[1].transform"] = {"translate": [0, 0.2, 0]}
        params.update()
        meta = render(scene).metadata
        self.assertNotEqual(meta["scene_hash"], original["scene_hash"])
        self.assertEqual(json.loads(meta["scene_edits"]), {"materials.light.ke": [3, 3, 3],
                                                           "meshes[1].transform": {"translate": [0, 0.2, 0]}})
        # Renders of the edited scene and of the original do not merge.
        with self.assertRaisesRegex(gdr.InputError, "scene_hash"):
            gdr.merge(render(scene), gdr.render(gdr.load_dict(arrays_scene()), integrator="gpt", spp=2, seed=12))

    def test_refused_values_name_the_key_and_leave_the_scene_as_it_was(self):
        scene = gdr.load_dict(spheres_scene())
        before = render(scene)
        params = gdr.traverse(scene)
        with self.assertRaisesRegex(gdr.ParameterError, r"materials\.light\.ke.*3 numbers"):
            params["materials.light.ke"] = [1, 2]
        with self.assertRaisesRegex(gdr.InputError, r"materials\.leftSphere\.alpha"):
            params["materials.leftSphere.alpha"] = float("nan")
        with self.assertRaisesRegex(KeyError, r"materials\.leftSphere\.roughness"):
            params["materials.leftSphere.roughness"] = 0.1
        for key, value, error in (
                ("materials.leftSphere.alpha", -0.1, gdr.InputError),
                ("materials.light.ke", [1, -1, 1], gdr.InputError),
                ("meshes[0].transform", {"rotat": [0, 1, 0, 3]}, gdr.InputError),
                ("meshes[0].transform", {"scale": 0}, gdr.ParameterError),
                ("camera.fov", 200, gdr.ParameterError)):
            params[key] = value
            with self.assertRaisesRegex(error, key.replace(".", r"\.").replace("[", r"\[")):
                params.update()
            self.assertEqual(gdr.traverse(scene)[key], spheres_scene_value(key))
        after = render(scene)
        for name in before:
            np.testing.assert_array_equal(before[name], after[name], err_msg=name)


def spheres_scene_value(key):
    node = spheres_scene()
    for part in _split_key(key):
        node = node[part]
    return node


def _split_key(key):
    if key.startswith("meshes["):
        i = int(key[len("meshes["):key.index("]")])
        return ["meshes", i] + key[key.index("]") + 2:].split(".")
    if key.startswith("materials."):
        name, field = key[len("materials."):].rsplit(".", 1)
        return ["materials", name, field]
    return key.split(".")


def _set_key(d, key, value):
    node = d
    parts = _split_key(key)
    for p in parts[:-1]:
        node = node[p]
    node[parts[-1]] = value
    return d


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
