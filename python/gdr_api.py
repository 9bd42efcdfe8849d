# The Python half of the module gdr, run in the module's namespace when it is
# imported (CMake compiles this file into the module as a string, so the
# module stays one file). It wraps the C++ functions where Python's own
# conventions apply: warnings through the warnings module, a progress bar,
# reconstructions written in Python, merges of renders held in memory.
import json as _json
import sys as _sys
import warnings as _warnings


class SceneWarning(UserWarning):
    """An approximation made or an element skipped while loading a scene (one of Scene.warnings)."""


_load_scene_core = load_scene  # noqa: F821 (the C++ function, defined before this file runs)


def load_scene(path, defines=None, lenient=False):
    scene = _load_scene_core(path, defines, lenient)
    _remember_source(scene, ("file", str(path), dict(defines or {}), bool(lenient)))
    # stacklevel 2: the warning points at the caller's load_scene line.
    for w in scene.warnings:
        _warnings.warn(w, SceneWarning, stacklevel=2)
    return scene


load_scene.__doc__ = (_load_scene_core.__doc__ or "") + (
    "\nEach of Scene.warnings is also issued as a gdr.SceneWarning through the warnings module\n"
    "(warnings.simplefilter('error', gdr.SceneWarning) makes them errors).")


class _TextBar:
    """progress=True's display where tqdm is not installed: one line on stderr, redrawn in place."""

    width = 30

    def __init__(self, stream=None):
        self.stream = stream if stream is not None else _sys.stderr
        self.shown = -1

    def __call__(self, p):
        pct = int(p.fraction * 100)
        if pct == self.shown:
            return
        self.shown = pct
        n = pct * self.width // 100
        self.stream.write(f"\rgdr.render [{'#' * n}{'.' * (self.width - n)}] {pct:3d}% {p.seconds:6.1f} s")
        self.stream.flush()

    def close(self):
        if self.shown >= 0:
            self.stream.write("\n")
            self.stream.flush()


class _TqdmBar:
    """progress=True's display with tqdm (a widget in a notebook, a bar in a terminal)."""

    def __init__(self, tqdm):
        self.bar = tqdm(total=100, desc="gdr.render", unit="%", bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}")

    def __call__(self, p):
        self.bar.update(round(p.fraction * 100) - self.bar.n)

    def close(self):
        self.bar.close()


def _progress_display():
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return _TextBar()
    return _TqdmBar(tqdm)


# What gpt, gbdpt and tgpt take as their own reconstruct= parameter; any other
# registered reconstructor is run on the render's layers afterwards.
_INTEGRATOR_RECONSTRUCTIONS = {"all", "weighted", "l1+l2", "l1", "l2", "neural", "none"}
# Reconstructors registered from Python, by name.
_python_reconstructors = {}


def _ensure_neural():
    if "neural" not in reconstructors():  # noqa: F821
        load_plugin()


_render_core = render  # noqa: F821


def render(scene, *, progress=None, reconstruct=None, reconstruct_params=None, **kwargs):
    params = kwargs.get("params")
    extra = None
    if reconstruct is not None:
        if not isinstance(reconstruct, str):
            raise TypeError(f"render: reconstruct must be a reconstructor's name (str), got {type(reconstruct).__name__}")
        if reconstruct in _INTEGRATOR_RECONSTRUCTIONS:
            params = dict(params or {})
            params["reconstruct"] = reconstruct
            kwargs["params"] = params
        elif reconstruct not in reconstructors():  # noqa: F821
            raise ParameterError(f"render: reconstruct='{reconstruct}' is not a registered reconstructor "  # noqa: F821
                                 f"(available: {', '.join(sorted(reconstructors()))})")  # noqa: F821
        else:
            extra = reconstruct
    if params is not None and not isinstance(params, dict):
        raise TypeError(f"render: params must be a dict, got {type(params).__name__}")
    if params and params.get("reconstruct") == "neural":
        _ensure_neural()
    bar = None
    if progress is True:
        bar = progress = _progress_display()
    elif progress is False:
        progress = None
    try:
        layers = _render_core(scene, progress=progress, **kwargs)
    finally:
        if bar is not None:
            bar.close()
    if extra is not None:
        add_reconstruction(layers, extra, **(reconstruct_params or {}))
    elif reconstruct_params:
        raise ParameterError("render: reconstruct_params apply to a reconstruct= run after the render")  # noqa: F821
    return layers


render.__doc__ = (_render_core.__doc__ or "").replace(
    "render(scene, *, integrator=None,", "render(scene, *, reconstruct=None, reconstruct_params=None, integrator=None,", 1) + (
    "\nprogress=True shows a bar (tqdm's where it is installed, else a line on stderr).\n"
    "reconstruct: 'weighted', 'l1', 'l2', 'l1+l2', 'all', 'neural' or 'none' set gpt's (gbdpt's,\n"
    "tgpt's) reconstruct parameter; any other registered reconstructor (gdr.reconstructors(), one\n"
    "registered with gdr.register_reconstructor) is run on the render's layers with\n"
    "reconstruct_params and stored as layer 'reconstruction_<name>' (gdr.merge recomputes it).")


def add_reconstruction(layers, method, **params):
    """add_reconstruction(layers, method, **params) -> array

    Runs reconstructor `method` on a render's layers (a gdr.Layers) and stores the result as
    layer 'reconstruction_<method>', recorded in the metadata so that gdr.merge recomputes it."""
    if method == "neural":
        _ensure_neural()
    image = _reconstruct_layers(layers, method, params)  # noqa: F821
    layers[f"reconstruction_{method}"] = image
    meta = getattr(layers, "metadata", None)
    if meta is not None:
        done = [m for m in meta.get("added_reconstructions", "").split(",") if m and m != method]
        meta["added_reconstructions"] = ",".join(done + [method])
        meta[f"reconstruction_params_{method}"] = _json.dumps(params, sort_keys=True)
    return image


_reconstruct_arrays = reconstruct  # noqa: F821


def reconstruct(primal, dx=None, dy=None, method="poisson-l1", direct=None, **params):
    if isinstance(primal, dict):
        if dx is not None or dy is not None or direct is not None:
            raise TypeError("reconstruct: give a render's layers alone (a dict), or the arrays primal, dx and dy")
        if method == "neural":
            _ensure_neural()
        return _reconstruct_layers(primal, method, params)  # noqa: F821
    if dx is None or dy is None:
        raise TypeError("reconstruct: dx and dy are needed with a primal array (or pass a render's layers, a dict)")
    if method == "neural":
        _ensure_neural()
    return _reconstruct_arrays(primal, dx, dy, method, direct, **params)


reconstruct.__doc__ = (
    "reconstruct(layers, method='poisson-l1', **params) -> array\n"
    "reconstruct(primal, dx, dy, method='poisson-l1', direct=None, **params) -> array\n\n"
    "The first form takes a render's result (gdr.Layers) or any dict of named layers ('primal',\n"
    "'dx', 'dy', optionally 'direct', and what the method needs: 'primal_variance', 'dx_variance',\n"
    "'dy_variance' and 'spp' for poisson-weighted; its metadata 'spp' stands for a missing 'spp'\n"
    "layer), so every registered reconstructor works, 'neural' included (its plugin is loaded on\n"
    "first use). The second is the arrays form:\n\n" + (_reconstruct_arrays.__doc__ or "").split("\n\n", 1)[-1])


def register_reconstructor(name, fn, description=None):
    """register_reconstructor(name, fn, description=None)

    Adds a reconstruction written in Python to the reconstructor registry (gdr.reconstructors()),
    replacing any of that name. fn(layers, **params) receives the frame's layers as a dict of
    float32 arrays (height, width, channels) -- 'primal', 'dx', 'dy', the variances and 'spp'
    where the render has them, and every other layer of the render -- and the parameters given
    to reconstruct(); it returns the image (height, width, channels) of the primal's shape, in
    radiance, without 'direct': gdr adds the directly visible emitters to it. The result is
    checked for NaN and Inf. gdr.reconstruct(layers, method=name), gdr.render(...,
    reconstruct=name) and gdr.merge use it."""
    if not isinstance(name, str):
        raise TypeError(f"register_reconstructor: name must be a str, got {type(name).__name__}")
    if description is None:
        doc = (getattr(fn, "__doc__", None) or "").strip()
        description = doc.splitlines()[0] if doc else f"written in Python ({getattr(fn, '__qualname__', fn)!s})"
    _register_python_reconstructor(name, fn, str(description))  # noqa: F821
    _python_reconstructors[name] = fn


def load_plugin(path=None):
    """load_plugin(path=None) -> str

    Loads a reconstructor plugin of the gdr tool (a shared library exporting gdr_plugin_abi and
    gdr_plugin_register) and registers its reconstructors; returns the file. Without
    a path, the neural reconstructor's plugin is looked for in $GDR_PLUGIN_PATH's directories if
    set, else where pip or CMake put it beside the module. Loading a file twice does nothing.
    Raises gdr.ParameterError when none is found, gdr.InputError for a file that is not a plugin
    of this gdr (another version or compiler)."""
    return _load_plugin(path)  # noqa: F821


def _sample_ranges(layers, which):
    meta = getattr(layers, "metadata", {}) or {}
    text = meta.get("sample_ranges")
    if text is None and "seed" in meta and "spp" in meta:
        text = f"{meta['seed']}:{meta.get('first_sample', 0)}:{meta['spp']}"
    if not text:
        raise InputError(f"merge: the {which} render has no 'sample_ranges' or 'seed' metadata (not a gdr render)")  # noqa: F821
    out = []
    for item in text.split(","):
        try:
            seed, first, count = (int(x) for x in item.split(":"))
        except ValueError:
            raise InputError(f"merge: the {which} render's 'sample_ranges' has a malformed range '{item}'") from None  # noqa: F821
        out.append((seed, first, count))
    return out


def _normalized(ranges):
    out = []
    for seed, first, count in sorted(ranges):
        if out and out[-1][0] == seed and out[-1][1] + out[-1][2] == first:
            out[-1] = (seed, out[-1][1], out[-1][2] + count)
        else:
            out.append((seed, first, count))
    return out


def merge(a, b):
    """merge(a, b) -> gdr.Layers

    Pools two renders of one scene and integrator made with different samples (other seeds, or a
    continuation's first_sample), as gdr merge does: means weighted by sample counts, variances
    pooled, the integrator's reconstructions recomputed, and each reconstruction added with
    add_reconstruction or render(reconstruct=...) recomputed by its reconstructor (a Python one
    too). The metadata says which samples the result holds (sample_ranges), so gdr merge and
    gdr render --resume accept its EXR. Raises gdr.InputError for renders of different scenes,
    integrators, parameters or sizes, or holding the same samples."""
    ra, rb = _sample_ranges(a, "first"), _sample_ranges(b, "second")
    ma, mb = a.metadata, b.metadata
    for key in ("integrator", "integrator_params", "scene_hash"):
        if ma.get(key) != mb.get(key):
            raise InputError(f"merge: the renders differ in '{key}': {ma.get(key)!r} against {mb.get(key)!r}")  # noqa: F821
    for s, f, n in ra:
        for t, g, m in rb:
            if s == t and f < g + m and g < f + n:
                raise InputError(f"merge: the renders hold the same samples (seed {s}, samples {f}-{f + n - 1} and "  # noqa: F821
                                 f"{g}-{g + m - 1}): merge renders with different seeds or continuations")
    out = _merge_layers(a, b)  # noqa: F821
    ranges = _normalized(ra + rb)
    meta = out.metadata
    one = len(ranges) == 1
    meta["seed"] = str(ranges[0][0]) if one else "mixed"
    meta["first_sample"] = str(ranges[0][1]) if one else "mixed"
    meta["sample_ranges"] = ",".join(f"{s}:{f}:{n}" for s, f, n in ranges)
    held = sum(n for _, _, n in ranges)
    meta["target_spp"] = str((ranges[0][1] if one else 0) + held)
    meta["time_budget"] = "0"
    meta["render_seconds"] = f"{float(ma.get('render_seconds', 0)) + float(mb.get('render_seconds', 0)):.3f}"
    meta["interrupted"] = "true" if "true" in (ma.get("interrupted"), mb.get("interrupted")) else "false"
    meta["gdr_version"] = __version__  # noqa: F821
    for key in ("added_reconstructions",):
        names = [m for m in (ma.get(key, "") + "," + mb.get(key, "")).split(",") if m]
        for name in dict.fromkeys(names):
            params = _json.loads(ma.get(f"reconstruction_params_{name}") or mb.get(f"reconstruction_params_{name}") or "{}")
            add_reconstruction(out, name, **params)
    return out


def _json_ready(value, where):
    """`value` with numpy arrays and scalars made JSON's lists and numbers, checked on the way:
    TypeError or gdr.ParameterError naming the key of a value JSON cannot hold, gdr.InputError
    naming the key of a NaN or Inf."""
    import numpy as np

    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise TypeError(f"load_dict: {where} has a key {k!r} of type {type(k).__name__}; keys are str")
            out[k] = _json_ready(v, f"{where}.{k}" if where else k)
        return out
    if isinstance(value, (list, tuple)):
        return [_json_ready(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            raise ParameterError(f"load_dict: '{where}' is an array of {value.dtype}; expected numbers "  # noqa: F821
                                 "(float or int)")
        if value.dtype.kind == "f" and not np.isfinite(value).all():
            bad = tuple(int(i) for i in np.argwhere(~np.isfinite(value))[0])
            raise InputError(f"load_dict: '{where}' holds {value[bad]} at index {bad}; values must be finite")  # noqa: F821
        return value.tolist()
    if isinstance(value, np.generic):
        return _json_ready(value.item(), where)
    if isinstance(value, float):
        if value != value or value in (float("inf"), float("-inf")):
            raise InputError(f"load_dict: '{where}' is {value}; values must be finite")  # noqa: F821
        return value
    if value is None or isinstance(value, (bool, int, str)):
        return value
    raise TypeError(f"load_dict: '{where}' is a {type(value).__name__}; a scene holds dicts, lists, numbers, "
                    "strings and numpy arrays")


def _check_mesh_arrays(scene):
    import numpy as np

    meshes = scene.get("meshes")
    if not isinstance(meshes, (list, tuple)):
        return
    for i, m in enumerate(meshes):
        if not isinstance(m, dict):
            continue
        for key, kind, what in (("vertices", "fiu", "float"), ("triangles", "iu", "integer")):
            a = m.get(key)
            if isinstance(a, np.ndarray):
                name = f"meshes[{i}].{key}"
                if a.dtype.kind not in kind:
                    raise ParameterError(f"load_dict: '{name}' is an array of {a.dtype}; expected {what}")  # noqa: F821
                if a.ndim != 2 or a.shape[1] != 3:
                    raise ParameterError(f"load_dict: '{name}' has shape {a.shape}; expected (n, 3)")  # noqa: F821


def load_dict(scene, base_dir=None):
    """load_dict(scene, base_dir=None) -> gdr.Scene

    A scene from a dict with the structure of gdr's JSON scene files ('camera', 'meshes',
    'materials', 'render', 'environment', 'animation'; README, "Scene files"): load_dict(d)
    renders as load_scene of a file holding json.dumps(d). Relative paths (OBJ files, camera
    files, textures) are resolved from base_dir (default: the working directory). A mesh may be
    given by numpy arrays instead of a file: {'vertices': float array (n, 3), 'triangles': int
    array (m, 3) of 0-based vertex indices, 'material': NAME, 'transform': {...}}, where the
    'materials' entry NAME defines its material ({'type': 'diffuse', 'kd': [r, g, b]}, ...);
    its faces are flat. Unknown keys raise gdr.InputError naming them, arrays of the wrong
    dtype or shape gdr.ParameterError, NaN or Inf gdr.InputError naming the key."""
    if not isinstance(scene, dict):
        raise TypeError(f"load_dict: expected a dict, got {type(scene).__name__}")
    _check_mesh_arrays(scene)
    text = _json.dumps(_json_ready(scene, ""))
    import os

    name = os.path.join(os.path.abspath(base_dir if base_dir is not None else os.getcwd()), "<dict>")
    result = _load_scene_text(text, name)  # noqa: F821
    _remember_source(result, ("dict", _json.loads(text), name))
    for w in result.warnings:
        _warnings.warn(w, SceneWarning, stacklevel=2)
    return result


def _remember_source(scene, source):
    """Keeps what a scene was loaded from, for gdr.traverse and copy.copy."""
    scene._source = source
    scene._base_hash = scene.content_hash
    scene._camera_changes = {}


def _description(scene):
    """(the scene's JSON description as a dict, its name for messages) or (None, None) for a Mitsuba scene."""
    src = getattr(scene, "_source", None)
    if src is None:
        raise TypeError("gdr: this Scene was not made by gdr.load_scene or gdr.load_dict")
    if src[0] == "dict":
        return src[1], src[2]
    path = src[1]
    if path.lower().endswith(".xml"):
        return None, None
    try:
        with open(path) as f:
            return _json.load(f), path
    except ValueError:  # a Mitsuba file under another name
        return None, None


_CAMERA_KEYS = ("position", "target", "up", "fov", "fov_axis", "width", "height")
_MATERIAL_KEYS = ("kd", "ks", "ke", "alpha", "ns", "eta")


class SceneParameters:
    """A scene's editable parameters (gdr.traverse), by dotted key: 'camera.position', 'camera.fov',
    'camera.width', 'materials.NAME.kd', 'materials.NAME.alpha' (roughness), 'materials.NAME.ke'
    (emitted radiance), 'meshes[I].transform', 'environment.radiance', ... Assign new values, then
    call update(): a change of the camera alone rebuilds the camera in place; any other rebuilds the
    scene from its changed description (its meshes are read again). The Scene object stays the
    same, so renders of it see the new values."""

    def __init__(self, scene):
        self._scene = scene
        desc, self._name = _description(scene)
        self._desc = _json.loads(_json.dumps(desc)) if desc is not None else None
        self._values = {}
        self._pending = {}
        if self._desc is None:  # Mitsuba XML: the camera's optics only
            self._values = {"camera.fov": scene.fov, "camera.fov_axis": scene.fov_axis,
                            "camera.width": scene.width, "camera.height": scene.height}
            return
        cam = self._desc.get("camera", {})
        for k in _CAMERA_KEYS:
            if k in cam:
                self._values[f"camera.{k}"] = cam[k]
        self._values.update({"camera.fov": scene.fov, "camera.fov_axis": scene.fov_axis,
                             "camera.width": scene.width, "camera.height": scene.height})
        for name, fields in (self._desc.get("materials") or {}).items():
            for k in _MATERIAL_KEYS:
                if k in fields:
                    self._values[f"materials.{name}.{k}"] = fields[k]
        for i, m in enumerate(self._desc.get("meshes") or []):
            if isinstance(m, dict) and "transform" in m:
                self._values[f"meshes[{i}].transform"] = m["transform"]
        env = self._desc.get("environment")
        if isinstance(env, dict):
            for k in ("radiance", "scale"):
                if k in env:
                    self._values[f"environment.{k}"] = env[k]

    def keys(self):
        """The parameters' dotted keys."""
        return self._values.keys()

    def items(self):
        """(key, value) of every parameter; a value assigned but not yet applied by update() included."""
        return [(k, self[k]) for k in self._values]

    def __iter__(self):
        return iter(self._values)

    def __len__(self):
        return len(self._values)

    def __contains__(self, key):
        return key in self._values

    def __getitem__(self, key):
        if key not in self._values:
            raise KeyError(f"gdr.traverse: no parameter '{key}' (parameters: {', '.join(self._values)})")
        return self._pending.get(key, self._values[key])

    def __setitem__(self, key, value):
        if key not in self._values:
            raise KeyError(f"gdr.traverse: no parameter '{key}' (parameters: {', '.join(self._values)})")
        old = self._values[key]
        value = _json_ready(value, key)
        if isinstance(old, list) and not (isinstance(value, list) and len(value) == len(old)):
            raise ParameterError(f"gdr.traverse: '{key}' takes a list of {len(old)} numbers, got {value!r}")  # noqa: F821
        if isinstance(old, (int, float)) and not isinstance(old, bool) and (
                isinstance(value, bool) or not isinstance(value, (int, float))):
            raise ParameterError(f"gdr.traverse: '{key}' takes a number, got {value!r}")  # noqa: F821
        if isinstance(old, dict) and not isinstance(value, dict):
            raise ParameterError(f"gdr.traverse: '{key}' takes a dict, got {value!r}")  # noqa: F821
        self._pending[key] = value

    def __repr__(self):
        return "gdr.SceneParameters({" + ", ".join(f"{k!r}: {self[k]!r}" for k in self._values) + "})"

    def update(self):
        """Applies the assigned values to the scene; returns the keys that changed."""
        changed = {k: v for k, v in self._pending.items() if v != self._values[k]}
        self._pending = {}
        if not changed:
            return []
        scene = self._scene
        if all(k.startswith("camera.") for k in changed):
            cam = {k.split(".", 1)[1]: v for k, v in changed.items()}
            if self._desc is None:
                if "width" in cam or "height" in cam:
                    scene.set_resolution(cam.get("width", scene.width), cam.get("height", scene.height))
                if "fov" in cam or "fov_axis" in cam:
                    scene.set_fov(cam.get("fov", scene.fov), cam.get("fov_axis"))
            else:
                scene._camera_changes.update(cam)
                salt = scene._base_hash + _json.dumps(scene._camera_changes, sort_keys=True)
                _set_camera(scene, cam, salt)  # noqa: F821
                self._desc.setdefault("camera", {}).update(cam)
        else:
            if self._desc is None:
                raise ParameterError("gdr.traverse: a Mitsuba scene's camera optics are its only parameters")  # noqa: F821
            for k, v in changed.items():
                self._set_in_desc(k, v)
            optics = (scene.width, scene.height, scene.fov, scene.fov_axis)
            fresh = _load_scene_text(_json.dumps(self._desc), self._name)  # noqa: F821
            # set_resolution and set_fov called on the scene itself hold for the rebuilt one.
            if (fresh.width, fresh.height) != optics[:2]:
                fresh.set_resolution(*optics[:2])
            if (fresh.fov, fresh.fov_axis) != optics[2:]:
                fresh.set_fov(*optics[2:])
            _replace_scene(scene, fresh)  # noqa: F821
            _remember_source(scene, ("dict", _json.loads(_json.dumps(self._desc)), self._name))
        self._values.update(changed)
        return sorted(changed)

    def _set_in_desc(self, key, value):
        if key.startswith("meshes["):
            i = int(key[len("meshes["):key.index("]")])
            self._desc["meshes"][i]["transform"] = value
            return
        parts = key.split(".")
        node = self._desc
        if parts[0] == "materials":
            node = node["materials"][".".join(parts[1:-1])]
        else:
            for p in parts[:-1]:
                node = node.setdefault(p, {})
        node[parts[-1]] = value


def traverse(scene):
    """traverse(scene) -> gdr.SceneParameters

    The scene's editable parameters by dotted key (camera pose, field of view and resolution,
    materials' colours, roughness 'alpha' and emission 'ke', meshes' transforms, the environment's
    radiance), for a scene from load_dict or a JSON scene file; the camera's optics for a Mitsuba
    scene. Assign values, then call .update() (as Mitsuba 3's mi.traverse):

        params = gdr.traverse(scene)
        params['materials.floor.alpha'] = 0.05
        params.update()
        gdr.render(scene)  # the same scene object, with the new roughness"""
    return SceneParameters(scene)


def _copy_scene(scene, memo=None):
    src = getattr(scene, "_source", None)
    if src is None:
        raise TypeError("gdr: only a Scene made by gdr.load_scene or gdr.load_dict can be copied")
    if src[0] == "dict":
        new = _load_scene_text(_json.dumps(src[1]), src[2])  # noqa: F821
    else:
        new = _load_scene_core(src[1], src[2], src[3])
    _remember_source(new, src)
    if scene._camera_changes:
        new._camera_changes = dict(scene._camera_changes)
        new._base_hash = scene._base_hash
        _set_camera(new, new._camera_changes, scene._base_hash + _json.dumps(new._camera_changes, sort_keys=True))  # noqa: F821
    # set_resolution and set_fov called on the scene itself.
    if (new.width, new.height) != (scene.width, scene.height):
        new.set_resolution(scene.width, scene.height)
    if (new.fov, new.fov_axis) != (scene.fov, scene.fov_axis):
        new.set_fov(scene.fov, scene.fov_axis)
    return new


Scene.__copy__ = _copy_scene  # noqa: F821
Scene.__deepcopy__ = _copy_scene  # noqa: F821
