# Renders a gdr scene in Blender's Cycles, an independent production path
# tracer, and writes the block means of the image with their standard errors:
# the data tests/test_pt.cpp compares gdr's pt against.
#
#   blender -b -noaudio --factory-startup -P scripts/cycles/reference.py -- \
#       SCENE.json OUT.json [--spp N] [--runs K] [--block B] [--keep DIR]
#
# The scene is rebuilt in Cycles with settings that make both renderers
# estimate the same integral: Lambertian surfaces from the MTL's Kd, one-sided
# emission (the geometric normal's side) from Ke, a box pixel filter one pixel
# wide, a black world, no clamping, no denoising, no adaptive sampling, no
# light threshold and 1024 bounces (Cycles ends paths by roulette, without
# bias, long before that). Only what both renderers treat identically is
# accepted: a material with any other MTL term, textures, mesh transforms or
# material overrides is refused with its name.
#
# K runs with seeds 1..K of N samples each give the block means (their
# average) and standard errors (their spread over the K runs, so nothing is
# assumed about Cycles' sampling pattern).
import json
import math
import os
import sys

import bpy
from mathutils import Matrix, Vector


def fail(msg):
    print(f"reference.py: error: {msg}", file=sys.stderr)
    sys.exit(2)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) < 2:
        fail("usage: blender -b -P reference.py -- SCENE.json OUT.json [--spp N] [--runs K] [--block B] [--keep DIR]")
    opts = {"scene": argv[0], "out": argv[1], "spp": 128, "runs": 8, "block": 64, "keep": None}
    i = 2
    while i < len(argv):
        key = argv[i].lstrip("-")
        if key not in ("spp", "runs", "block", "keep") or i + 1 >= len(argv):
            fail(f"unknown option or missing value: {argv[i]}")
        opts[key] = argv[i + 1] if key == "keep" else int(argv[i + 1])
        i += 2
    if opts["runs"] < 2:
        fail("--runs must be at least 2 (the standard errors come from the spread between runs)")
    return opts


# Terms a Lambertian emitter or reflector may carry; anything else changes
# what gdr renders (a glossy lobe, a texture, transparency) and is refused.
LAMBERTIAN_KEYS = {"Kd", "Ke", "Ka", "Ns", "Ni", "illum", "Ks"}


def parse_mtl(path):
    mats, cur = {}, None
    for n, line in enumerate(open(path), 1):
        t = line.split("#")[0].split()
        if not t:
            continue
        if t[0] == "newmtl":
            cur = t[1]
            mats[cur] = {"Kd": (0.0, 0.0, 0.0), "Ke": (0.0, 0.0, 0.0)}
            continue
        if cur is None:
            continue
        if (t[0] == "d" and float(t[1]) == 1.0) or (t[0] == "Tr" and float(t[1]) == 0.0):
            continue  # opaque, spelt out
        if t[0] not in LAMBERTIAN_KEYS:
            fail(f"{path}:{n}: material '{cur}' has '{t[0]}', which this comparison does not support")
        if t[0] == "illum" and int(t[1]) not in (0, 1, 2):
            fail(f"{path}:{n}: material '{cur}' has illum {t[1]} (gdr's mirror or glass); only Lambertian materials are compared")
        if t[0] == "Ks" and any(float(x) != 0.0 for x in t[1:4]):
            fail(f"{path}:{n}: material '{cur}' has a specular Ks; only Lambertian materials are compared")
        if t[0] in ("Kd", "Ke"):
            mats[cur][t[0]] = tuple(float(x) for x in t[1:4])
    return mats


def mtl_of(obj_path):
    for line in open(obj_path):
        t = line.split()
        if t and t[0] == "mtllib":
            return os.path.join(os.path.dirname(obj_path), " ".join(t[1:]))
    fail(f"{obj_path}: no mtllib")


def lambertian_material(m, kd, ke):
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    diff = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diff.inputs["Color"].default_value = (*kd, 1.0)
    diff.inputs["Roughness"].default_value = 0.0  # 0 is Lambertian (not Oren-Nayar)
    if max(ke) <= 0.0:
        nt.links.new(diff.outputs[0], out.inputs["Surface"])
        return
    # Emission Ke on the front side only: Ke * (1 - Backfacing).
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    front = nt.nodes.new("ShaderNodeMath")
    front.operation = "SUBTRACT"
    front.inputs[0].default_value = 1.0
    nt.links.new(geo.outputs["Backfacing"], front.inputs[1])
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*ke, 1.0)
    nt.links.new(front.outputs[0], em.inputs["Strength"])
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(diff.outputs[0], add.inputs[0])
    nt.links.new(em.outputs[0], add.inputs[1])
    nt.links.new(add.outputs[0], out.inputs["Surface"])


def build_scene(scene_path):
    desc = json.load(open(scene_path))
    base = os.path.dirname(os.path.abspath(scene_path))
    if "materials" in desc:
        fail(f"{scene_path}: material overrides are not supported by this comparison")
    cam = dict(desc.get("camera", {}))
    if "file" in cam:
        # As gdr reads it: the file's keys, overridden by the scene's own.
        with open(os.path.join(base, cam.pop("file"))) as f:
            cam = {**json.load(f), **cam}
        if "fov_deg" in cam:
            cam["fov"] = cam.pop("fov_deg")

    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    for mesh in desc["meshes"]:
        if set(mesh) - {"file"}:
            fail(f"{scene_path}: mesh keys {sorted(set(mesh) - {'file'})} are not supported by this comparison")
        obj_path = os.path.join(base, mesh["file"])
        mtl = parse_mtl(mtl_of(obj_path))
        before = set(bpy.context.scene.objects)
        bpy.ops.import_scene.obj(filepath=obj_path, split_mode="OFF")
        for ob in set(bpy.context.scene.objects) - before:
            # The importer turns the file's Y-up into Blender's Z-up through
            # the object's transform; undo it: coordinates stay the file's.
            ob.matrix_world = Matrix.Identity(4)
            for slot in ob.material_slots:
                name = slot.material.name
                key = name if name in mtl else name.rsplit(".", 1)[0]
                if key not in mtl:
                    fail(f"{obj_path}: material '{name}' is not in its MTL")
                lambertian_material(slot.material, mtl[key]["Kd"], mtl[key]["Ke"])

    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    sc.world = world

    pos = Vector(cam.get("position", [0, 0, 0]))
    target = Vector(cam.get("target", [0, 0, -1]))
    up = Vector(cam.get("up", [0, 1, 0]))
    fwd = (target - pos).normalized()
    right = fwd.cross(up).normalized()
    cam_up = right.cross(fwd)
    # A Blender camera looks down its -Z axis with +Y up.
    rot = Matrix((right, cam_up, -fwd)).transposed()
    data = bpy.data.cameras.new("camera")
    data.sensor_fit = "HORIZONTAL" if cam.get("fov_axis", "y") == "x" else "VERTICAL"
    data.angle = math.radians(float(cam.get("fov", 45.0)))
    data.clip_start = 1e-4
    ob = bpy.data.objects.new("camera", data)
    ob.matrix_world = Matrix.Translation(pos) @ rot.to_4x4()
    sc.collection.objects.link(ob)
    sc.camera = ob

    sc.render.engine = "CYCLES"
    cy = sc.cycles
    cy.device = "CPU"
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.pixel_filter_type = "BOX"
    cy.filter_width = 1.0
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces"):
        setattr(cy, attr, 1024)
    cy.volume_bounces = 0
    cy.transparent_max_bounces = 0
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.light_sampling_threshold = 0.0
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    cy.blur_glossy = 0.0
    sc.render.resolution_x = int(cam.get("width", 512))
    sc.render.resolution_y = int(cam.get("height", 512))
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = False
    sc.view_settings.view_transform = "Standard"
    sc.view_settings.look = "None"
    sc.view_settings.exposure = 0.0
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_depth = "32"
    sc.render.image_settings.color_mode = "RGB"
    return sc


def block_means(path, w, h, b):
    """Per-block RGB means, blocks in rows from the image's top-left."""
    img = bpy.data.images.load(path)
    px = img.pixels[:]  # RGBA floats, rows from the bottom
    bpy.data.images.remove(img)
    nx, ny = w // b, h // b
    sums = [[0.0, 0.0, 0.0] for _ in range(nx * ny)]
    for y in range(ny * b):
        row = (h - 1 - y) * w * 4
        by = (y // b) * nx
        for x in range(nx * b):
            i = row + 4 * x
            s = sums[by + x // b]
            s[0] += px[i]
            s[1] += px[i + 1]
            s[2] += px[i + 2]
    return [[v / (b * b) for v in s] for s in sums]


def main():
    o = parse_args()
    sc = build_scene(o["scene"])
    w, h, b = sc.render.resolution_x, sc.render.resolution_y, o["block"]
    if w % b or h % b:
        fail(f"--block {b} must divide the resolution {w}x{h}")
    keep = o["keep"] or bpy.app.tempdir
    os.makedirs(keep, exist_ok=True)
    runs = []
    for seed in range(1, o["runs"] + 1):
        sc.cycles.samples = o["spp"]
        sc.cycles.seed = seed
        sc.render.filepath = os.path.join(keep, f"cycles-{seed}.exr")
        bpy.ops.render.render(write_still=True)
        runs.append(block_means(sc.render.filepath, w, h, b))
        if not o["keep"]:
            os.remove(sc.render.filepath)
    k = len(runs)
    nb = len(runs[0])
    mean = [[sum(r[i][c] for r in runs) / k for c in range(3)] for i in range(nb)]
    stderr = [[math.sqrt(sum((r[i][c] - mean[i][c]) ** 2 for r in runs) / (k - 1) / k) for c in range(3)]
              for i in range(nb)]
    whole = [[sum(blk[c] for blk in r) / nb for c in range(3)] for r in runs]
    image_mean = [sum(v[c] for v in whole) / k for c in range(3)]
    image_stderr = [math.sqrt(sum((v[c] - image_mean[c]) ** 2 for v in whole) / (k - 1) / k) for c in range(3)]
    out = {
        "renderer": f"Blender {bpy.app.version_string} Cycles (CPU)",
        "scene": o["scene"],
        "width": w, "height": h, "block": b, "blocks_x": w // b, "blocks_y": h // b,
        "runs": k, "spp_per_run": o["spp"],
        "note": "block means (RGB, rows of blocks from the top-left) over runs with seeds 1..runs; "
                "stderr = standard error of each mean from the spread between runs",
        "image_mean": image_mean, "image_stderr": image_stderr,
        "mean": mean, "stderr": stderr,
    }
    with open(o["out"], "w") as f:
        json.dump(out, f, indent=1)
    print(f"reference.py: wrote {o['out']} ({k} runs of {o['spp']} spp, {nb} blocks of {b}x{b})")


main()
