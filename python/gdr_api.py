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


class Transform:
    """A 4x4 affine transform built as Mitsuba 3's mi.ScalarTransform4f is: each method returns
    this transform followed by (applied after) nothing but composed on the right, so that
    gdr.Transform().translate(t).scale(s) scales a point first, then translates it. Used as a
    load_dict 'to_world'; numpy.asarray(T) (or T.matrix) is its matrix (row-major, points as
    columns). It keeps its steps, so that a dict scene places objects with the operations (and
    rounding) of the equivalent Mitsuba XML <transform>."""

    def __init__(self, matrix=None):
        import numpy as np

        self._steps = []  # (tag, attributes), in XML order: the first applies to the point first
        self.matrix = np.eye(4)
        if matrix is not None:
            m = np.asarray(matrix, dtype=float)
            if m.shape != (4, 4):
                raise ParameterError(f"gdr.Transform: a matrix must be 4x4, got shape {m.shape}")  # noqa: F821
            self._steps.append(("matrix", {"value": " ".join(repr(float(x)) for x in m.reshape(-1))}))
            self.matrix = m

    def _then(self, tag, attrs, m):
        import numpy as np

        out = Transform()
        out._steps = [(tag, attrs)] + self._steps  # composed on the right: applied first
        out.matrix = self.matrix @ np.asarray(m, dtype=float)
        return out

    def translate(self, v):
        """This transform after a translation by v (3 numbers, scene units)."""
        import numpy as np

        x, y, z = (float(c) for c in _three(v, "translate"))
        m = np.eye(4)
        m[:3, 3] = (x, y, z)
        return self._then("translate", {"x": repr(x), "y": repr(y), "z": repr(z)}, m)

    def scale(self, v):
        """This transform after a scale by v (one number, or 3 per axis)."""
        import numpy as np

        x, y, z = (float(v),) * 3 if isinstance(v, (int, float)) else (float(c) for c in _three(v, "scale"))
        return self._then("scale", {"x": repr(x), "y": repr(y), "z": repr(z)}, np.diag([x, y, z, 1.0]))

    def rotate(self, axis, angle):
        """This transform after a rotation by `angle` degrees about `axis` (3 numbers, right-handed)."""
        import math

        import numpy as np

        a = np.array([float(c) for c in _three(axis, "rotate")])
        n = np.linalg.norm(a)
        if not n > 0:
            raise ParameterError("gdr.Transform.rotate: the axis is zero")  # noqa: F821
        x, y, z = a / n
        t = math.radians(float(angle))
        c, s = math.cos(t), math.sin(t)
        r = np.eye(4)
        r[:3, :3] = [[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                     [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                     [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]]
        return self._then("rotate", {"x": repr(float(a[0])), "y": repr(float(a[1])), "z": repr(float(a[2])),
                                     "angle": repr(float(angle))}, r)

    def look_at(self, origin, target, up):
        """This transform after a camera-to-world look-at: the camera at `origin` looks at `target`
        (scene units), `up` giving the image's up direction (Mitsuba's convention: +z forward)."""
        import numpy as np

        o, t, u = (np.array([float(c) for c in _three(v, "look_at")]) for v in (origin, target, up))
        d = t - o
        if not np.linalg.norm(d) > 0:
            raise ParameterError("gdr.look_at: origin and target coincide")  # noqa: F821
        d /= np.linalg.norm(d)
        left = np.cross(u / (np.linalg.norm(u) or 1.0), d)
        if not np.linalg.norm(left) > 0:
            raise ParameterError("gdr.look_at: up is parallel to the viewing direction")  # noqa: F821
        left /= np.linalg.norm(left)
        new_up = np.cross(d, left)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, o
        f = " ".join
        return self._then("lookat", {"origin": f(repr(float(c)) for c in o), "target": f(repr(float(c)) for c in t),
                                     "up": f(repr(float(c)) for c in u)}, m)

    def __array__(self, dtype=None, copy=None):
        return self.matrix if dtype is None else self.matrix.astype(dtype)

    def __repr__(self):
        return f"gdr.Transform({self.matrix.tolist()!r})"


def _three(v, what):
    v = list(v)
    if len(v) != 3:
        raise ParameterError(f"gdr.Transform.{what}: expected 3 numbers, got {len(v)}")  # noqa: F821
    return v


def look_at(origin, target, up):
    """look_at(origin, target, up) -> gdr.Transform

    A camera-to-world transform (Mitsuba 3's ScalarTransform4f().look_at): a sensor's 'to_world'
    in a Mitsuba-style dict. numpy.asarray of it is its 4x4 matrix."""
    return Transform().look_at(origin, target, up)


# The XML element of each Mitsuba plugin type that a Mitsuba-style dict may name (gdr's Mitsuba
# importer decides which it supports, and says so naming the key).
_PLUGIN_TAGS = {}
for _tag, _names in (
        ("sensor", "perspective thinlens orthographic telecentric radiancemeter irradiancemeter batch"),
        ("film", "hdrfilm ldrfilm specfilm"),
        ("rfilter", "box tent gaussian mitchell catmullrom lanczos"),
        ("sampler", "independent stratified multijitter orthogonal ldsampler halton sobol"),
        ("integrator", "path volpath volpath_simple bdpt gpt direct aov ptracer prb prb_basic direct_projective "
                       "prb_projective moment stokes depth"),
        ("shape", "obj ply serialized rectangle cube sphere disk cylinder shapegroup instance bsplinecurve "
                  "linearcurve sdfgrid"),
        ("bsdf", "diffuse roughdiffuse conductor roughconductor dielectric thindielectric roughdielectric plastic "
                 "roughplastic phong ward twosided mask bumpmap normalmap blendbsdf coating roughcoating null "
                 "principled principledthin pplastic hair measured polarizer retarder circular"),
        ("emitter", "area point spot directional constant envmap sunsky sky sun projector directionalarea"),
        ("texture", "bitmap checkerboard scale volume mesh_attribute"),
        ("medium", "homogeneous heterogeneous"),
        ("phase", "isotropic hg rayleigh sggx"),
        ("volume", "constvolume gridvolume")):
    for _n in _names.split():
        _PLUGIN_TAGS.setdefault(_n, _tag)
del _tag, _names, _n


class _XmlWriter:
    """A Mitsuba-style dict as Mitsuba 3 XML text, one element a line, with each line's key path
    kept so that the importer's messages (which name the line) can name the key instead."""

    def __init__(self):
        self.lines = ['<?xml version="1.0"?>', '<scene version="3.0.0">']
        self.keys = {}  # line number (1-based) -> key path

    @staticmethod
    def _attrs(attrs):
        from xml.sax.saxutils import quoteattr

        return "".join(f" {k}={quoteattr(str(v))}" for k, v in attrs.items())

    def element(self, depth, tag, attrs, key, close=True):
        self.lines.append("  " * depth + f"<{tag}{self._attrs(attrs)}{'/' if close else ''}>")
        self.keys[len(self.lines)] = key

    def end(self, depth, tag):
        self.lines.append("  " * depth + f"</{tag}>")

    def plugin(self, depth, key, name, d):
        ptype = d.get("type")
        if not isinstance(ptype, str):
            raise ParameterError(f"load_dict: {key}.type: a plugin needs a 'type' (a str), got {ptype!r}")  # noqa: F821
        if ptype == "ref":
            extra = set(d) - {"type", "id"}
            if extra or not isinstance(d.get("id"), str):
                raise ParameterError(f"load_dict: {key}: a reference is {{'type': 'ref', 'id': NAME}}"  # noqa: F821
                                     + (f"; unknown key '{sorted(extra)[0]}'" if extra else ""))
            self.element(depth, "ref", {"id": d["id"], **({"name": name} if name else {})}, key)
            return
        tag = _PLUGIN_TAGS.get(ptype)
        if tag is None:
            raise ParameterError(f"load_dict: {key}.type: unknown plugin '{ptype}'")  # noqa: F821
        attrs = {"type": ptype, "id": d.get("id", key)}
        if not isinstance(attrs["id"], str):
            raise ParameterError(f"load_dict: {key}.id: must be a str, got {attrs['id']!r}")  # noqa: F821
        if name and tag in ("texture", "volume"):  # a property of its parent; other nested plugins go unnamed
            attrs["name"] = name
        self.element(depth, tag, attrs, key, close=False)
        for k, v in d.items():
            if k in ("type", "id"):
                continue
            if not isinstance(k, str):
                raise TypeError(f"load_dict: {key} has a key {k!r} of type {type(k).__name__}; keys are str")
            self.value(depth + 1, f"{key}.{k}", k, v)
        self.end(depth, tag)

    def value(self, depth, key, name, v):
        import numpy as np

        if isinstance(v, Transform):
            self.element(depth, "transform", {"name": name}, key, close=False)
            for tag, attrs in v._steps:
                self.element(depth + 1, tag, attrs, key)
            self.end(depth, "transform")
            return
        if isinstance(v, dict):
            t = v.get("type")
            if t in ("rgb", "spectrum"):
                extra = set(v) - {"type", "value"}
                if extra:
                    raise ParameterError(f"load_dict: {key}: unknown key '{sorted(extra)[0]}' of an {t} value")  # noqa: F821
                if "value" not in v:
                    raise ParameterError(f"load_dict: {key}.value: an {t} value needs 'value'")  # noqa: F821
                val = _json_ready(v["value"], f"{key}.value")
                if isinstance(val, list):
                    if t == "spectrum" and val and isinstance(val[0], list):  # [(wavelength, value), ...]
                        text = ", ".join(f"{float(a)!r}:{float(b)!r}" for a, b in val)
                    else:
                        text = " ".join(repr(float(x)) for x in val)
                elif isinstance(val, (int, float)) and not isinstance(val, bool):
                    text = repr(float(val))
                else:
                    raise ParameterError(f"load_dict: {key}.value: expected numbers, got {val!r}")  # noqa: F821
                self.element(depth, t, {"name": name, "value": text}, key)
                return
            self.plugin(depth, key, name, v)
            return
        if isinstance(v, (list, tuple, np.ndarray)):
            a = np.asarray(_json_ready(np.asarray(v) if isinstance(v, np.ndarray) else v, key), dtype=object)
            try:
                a = np.asarray(a, dtype=float)
            except (TypeError, ValueError):
                raise ParameterError(f"load_dict: {key}: expected numbers, got {v!r}") from None  # noqa: F821
            if a.shape == (4, 4):
                self.value(depth, key, name, Transform(a))
            elif a.shape == (3,):
                x, y, z = (repr(float(c)) for c in a)
                self.element(depth, "point", {"name": name, "x": x, "y": y, "z": z}, key)
            else:
                raise ParameterError(f"load_dict: {key}: a list is a point (3 numbers) or a transform "  # noqa: F821
                                     f"(4x4), got shape {a.shape}")
            return
        v = _json_ready(v, key)
        if isinstance(v, bool):
            self.element(depth, "boolean", {"name": name, "value": "true" if v else "false"}, key)
        elif isinstance(v, int):
            self.element(depth, "integer", {"name": name, "value": str(v)}, key)
        elif isinstance(v, float):
            self.element(depth, "float", {"name": name, "value": repr(v)}, key)
        elif isinstance(v, str):
            self.element(depth, "string", {"name": name, "value": v}, key)
        else:
            raise TypeError(f"load_dict: '{key}' is a {type(v).__name__}; expected a plugin dict, a number, a str, "
                            "a list or a gdr.Transform")


def _mitsuba_dict_xml(scene):
    """(XML text, {line: key path}) of a Mitsuba-style dict {'type': 'scene', ...}."""
    w = _XmlWriter()
    for k, v in scene.items():
        if k == "type":
            continue
        if not isinstance(k, str):
            raise TypeError(f"load_dict: the scene has a key {k!r} of type {type(k).__name__}; keys are str")
        if not isinstance(v, dict):
            raise ParameterError(f"load_dict: {k}: a scene holds plugins (dicts with a 'type'), got {v!r}")  # noqa: F821
        w.value(1, k, None, v)
    w.lines.append("</scene>")
    return "\n".join(w.lines) + "\n", w.keys


def _load_mitsuba_dict(scene, base_dir, lenient):
    import os
    import re

    text, keys = _mitsuba_dict_xml(scene)
    name = os.path.join(os.path.abspath(base_dir if base_dir is not None else os.getcwd()), "<dict>.xml")

    def by_key(message):
        # The importer names the generated text's lines: name the dict's keys instead.
        prefix = re.escape(name) + r":(\d+): "
        return re.sub(prefix, lambda m: f"{keys.get(int(m.group(1)), 'line ' + m.group(1))}: ", message)

    try:
        result = _load_mitsuba_text(text, name, bool(lenient))  # noqa: F821
    except Error as e:  # noqa: F821
        raise type(e)("load_dict: " + by_key(str(e))) from None
    _remember_source(result, ("mitsuba-dict", text, name, bool(lenient)))
    return result, [by_key(w) for w in result.warnings]


def load_dict(scene, base_dir=None, lenient=False):
    """load_dict(scene, base_dir=None, lenient=False) -> gdr.Scene

    A scene from a dict with the structure of gdr's JSON scene files ('camera', 'meshes',
    'materials', 'render', 'environment', 'animation'; README, "Scene files"): load_dict(d)
    renders as load_scene of a file holding json.dumps(d). Relative paths (OBJ files, camera
    files, textures) are resolved from base_dir (default: the working directory). A mesh may be
    given by numpy arrays instead of a file: {'vertices': float array (n, 3), 'triangles': int
    array (m, 3) of 0-based vertex indices, 'material': NAME, 'transform': {...}}, where the
    'materials' entry NAME defines its material ({'type': 'diffuse', 'kd': [r, g, b]}, ...);
    its faces are flat. Unknown keys raise gdr.InputError naming them, arrays of the wrong
    dtype or shape gdr.ParameterError, NaN or Inf gdr.InputError naming the key.

    A dict with 'type': 'scene' is read as Mitsuba 3's load_dict reads one: {'type': 'scene',
    'sensor': {'type': 'perspective', 'fov': 45, 'to_world': gdr.look_at(...)}, 'floor': {'type':
    'rectangle', 'bsdf': {'type': 'diffuse', 'reflectance': {'type': 'rgb', 'value': [...]}}},
    'integrator': {'type': 'path', 'max_depth': 8}, ...}. It becomes the equivalent Mitsuba XML and
    is loaded by gdr's Mitsuba importer, so it supports the plugins load_scene supports in XML;
    errors name the key path ('floor.bsdf.type: unknown plugin ...'). Transforms are gdr.Transform
    (gdr.look_at(...), gdr.Transform().translate(...).scale(...)) or 4x4 matrices (nested lists,
    numpy arrays); a 3-list is a point; base_dir resolves 'filename's. lenient (Mitsuba-style dicts
    only) is load_scene's: unsupported plugins and properties become warnings instead of errors."""
    if not isinstance(scene, dict):
        raise TypeError(f"load_dict: expected a dict, got {type(scene).__name__}")
    if "type" in scene:
        if scene["type"] != "scene":
            raise ParameterError(f"load_dict: type: a Mitsuba-style dict describes a 'scene', got {scene['type']!r}")  # noqa: F821
        result, warnings = _load_mitsuba_dict(scene, base_dir, lenient)
        for w in warnings:
            _warnings.warn(w, SceneWarning, stacklevel=2)
        return result
    if lenient:
        raise ParameterError("load_dict: lenient applies to Mitsuba-style dicts ({'type': 'scene', ...}) only")  # noqa: F821
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
    scene._edits = {}         # parameters edited in place (gdr.traverse), by key
    scene._desc_now = None    # the description with those edits (a JSON scene), once edited


def _description(scene):
    """(the scene's JSON description as a dict, its name for messages) or (None, None) for a Mitsuba scene."""
    src = getattr(scene, "_source", None)
    if src is None:
        raise TypeError("gdr: this Scene was not made by gdr.load_scene or gdr.load_dict")
    if src[0] == "mitsuba-dict":
        return None, None
    name = src[2] if src[0] == "dict" else src[1]
    if scene._desc_now is not None:
        return scene._desc_now, name
    if src[0] == "dict":
        return src[1], name
    path = src[1]
    if path.lower().endswith(".xml"):
        return None, None
    try:
        with open(path) as f:
            return _json.load(f), path
    except ValueError:  # a Mitsuba file under another name
        return None, None


def _record_edits(scene):
    """Makes the scene's content_hash and render headers say what was edited: a JSON scene hashes as
    its edited description would load (load_dict of it gives the same hash), a Mitsuba scene as its
    file's hash and the edits together; renders record the edits as metadata 'scene_edits'."""
    import os

    edits = _json.dumps(scene._edits, sort_keys=True)
    src = scene._source
    if scene._desc_now is not None:
        if src[0] == "dict":
            name, inputs = src[2], list(scene.inputs)
        else:  # the file no longer describes the scene: its edited description, beside it, does
            name, inputs = os.path.join(os.path.dirname(os.path.abspath(src[1])), "<dict>"), list(scene.inputs)[1:]
        digest = _scene_text_hash(_json.dumps(scene._desc_now), name, inputs)  # noqa: F821
    else:
        digest = _scene_text_hash(_json.dumps({"scene_hash": scene._base_hash, "edits": scene._edits}),  # noqa: F821
                                  scene.path, [])
    _set_edits(scene, edits, digest)  # noqa: F821


_CAMERA_KEYS = ("position", "target", "up", "fov", "fov_axis", "width", "height")
_MATERIAL_KEYS = ("kd", "ks", "ke", "alpha", "ns", "eta")


class SceneParameters:
    """A scene's editable parameters (gdr.traverse), by dotted key: 'camera.position', 'camera.fov',
    'camera.width', 'materials.NAME.kd', 'materials.NAME.alpha' (roughness), 'materials.NAME.ke'
    (emitted radiance), 'meshes[I].transform', 'environment.radiance', ... Assign new values, then
    call update(): each change is made in the loaded scene itself, rebuilding only what depends on
    it (docs/python.md, "Editing a scene in place"); no scene file or mesh is read again."""

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
            # The values the material has where its entry does not give them (its MTL's, or the
            # defaults); an animated scene, not edited in place, lists its entries' own.
            try:
                known = _material_values(scene, name, _json.dumps(fields))  # noqa: F821
            except Error:  # noqa: F821
                known = {}
            for k in _MATERIAL_KEYS:
                if k in fields or k in known:
                    self._values[f"materials.{name}.{k}"] = fields[k] if k in fields else known[k]
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
        if isinstance(old, list) and not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
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
        """Applies the assigned values to the scene in place; returns the keys that changed.

        A material's values rebuild its BSDF (and, for 'ke', the light distribution); a mesh's
        transform moves its triangles and rebuilds the BVH; the environment's values rebuild the
        environment and the light distribution; the camera's rebuild the camera. A refused value
        raises naming its key; the changes applied before it stay applied (and recorded)."""
        changed = {k: v for k, v in self._pending.items() if v != self._values[k]}
        self._pending = {}
        if not changed:
            return []
        scene = self._scene
        try:
            if self._desc is None:
                self._update_mitsuba_camera(changed)
            else:
                self._update_description(changed)
        finally:
            _record_edits(scene)
        return sorted(changed)

    def _applied(self, keys, changed):
        for k in keys:
            self._values[k] = changed[k]
            self._scene._edits[k] = changed[k]
        if self._desc is not None:
            self._scene._desc_now = _json.loads(_json.dumps(self._desc))

    def _update_mitsuba_camera(self, changed):
        scene = self._scene
        if any(not k.startswith("camera.") for k in changed):
            raise ParameterError("gdr.traverse: a Mitsuba scene's camera optics are its only parameters")  # noqa: F821
        cam = {k.split(".", 1)[1]: v for k, v in changed.items()}
        if "width" in cam or "height" in cam:
            scene.set_resolution(cam.get("width", scene.width), cam.get("height", scene.height))
        if "fov" in cam or "fov_axis" in cam:
            scene.set_fov(cam.get("fov", scene.fov), cam.get("fov_axis"))
        self._applied(changed, changed)

    def _update_description(self, changed):
        scene = self._scene
        materials, meshes, env, camera = {}, [], [], []
        for k in changed:
            if k.startswith("materials."):
                materials.setdefault(k[len("materials."):k.rindex(".")], []).append(k)
            elif k.startswith("meshes["):
                meshes.append(k)
            elif k.startswith("environment."):
                env.append(k)
            else:
                camera.append(k)
        for name, keys in materials.items():
            fields = dict(self._desc["materials"][name])
            for k in keys:
                fields[k.rsplit(".", 1)[1]] = changed[k]
            _edit_material(scene, name, _json.dumps(fields))  # noqa: F821
            self._desc["materials"][name] = fields
            self._applied(keys, changed)
        for k in meshes:
            i = int(k[len("meshes["):k.index("]")])
            _edit_mesh_transform(scene, i, _json.dumps(changed[k]))  # noqa: F821
            self._desc["meshes"][i]["transform"] = changed[k]
            self._applied([k], changed)
        if env:
            fields = dict(self._desc["environment"])
            for k in env:
                fields[k.split(".", 1)[1]] = changed[k]
            _edit_environment(scene, _json.dumps(fields))  # noqa: F821
            self._desc["environment"] = fields
            self._applied(env, changed)
        if camera:
            cam = {k.split(".", 1)[1]: changed[k] for k in camera}
            try:
                _set_camera(scene, cam)  # noqa: F821 (the hash is set by _record_edits)
            except Error as e:  # noqa: F821 (the camera's own message names no key)
                raise type(e)(f"gdr.traverse: {', '.join(sorted(camera))}: {e}") from None
            self._desc.setdefault("camera", {}).update(cam)
            self._applied(camera, changed)


def traverse(scene):
    """traverse(scene) -> gdr.SceneParameters

    The scene's editable parameters by dotted key (camera pose, field of view and resolution,
    materials' colours, roughness 'alpha' and emission 'ke', meshes' transforms, the environment's
    radiance), for a scene from load_dict or a JSON scene file; the camera's optics for a Mitsuba
    scene. Assign values, then call .update() (as Mitsuba 3's mi.traverse): the loaded scene is
    changed in place, rebuilding only what the change touches (a material's BSDF, the light
    distribution, one mesh's vertices and the BVH, the camera):

        params = gdr.traverse(scene)
        params['materials.floor.alpha'] = 0.05
        params.update()
        gdr.render(scene)  # the same scene object, with the new roughness

    Afterwards scene.content_hash is the edited description's (load_dict of it hashes the same)
    and renders record the edits in their metadata as 'scene_edits'."""
    return SceneParameters(scene)


def _copy_scene(scene, memo=None):
    src = getattr(scene, "_source", None)
    if src is None:
        raise TypeError("gdr: only a Scene made by gdr.load_scene or gdr.load_dict can be copied")
    if scene._desc_now is not None:  # edited in place: the edited description
        new = _load_scene_text(_json.dumps(scene._desc_now), src[2] if src[0] == "dict" else src[1])  # noqa: F821
    elif src[0] == "dict":
        new = _load_scene_text(_json.dumps(src[1]), src[2])  # noqa: F821
    elif src[0] == "mitsuba-dict":
        new = _load_mitsuba_text(src[1], src[2], src[3])  # noqa: F821
    else:
        new = _load_scene_core(src[1], src[2], src[3])
    _remember_source(new, src)
    new._base_hash = scene._base_hash
    if scene._edits:
        new._edits = _json.loads(_json.dumps(scene._edits))
        new._desc_now = _json.loads(_json.dumps(scene._desc_now)) if scene._desc_now is not None else None
    # set_resolution and set_fov called on the scene itself.
    if (new.width, new.height) != (scene.width, scene.height):
        new.set_resolution(scene.width, scene.height)
    if (new.fov, new.fov_axis) != (scene.fov, scene.fov_axis):
        new.set_fov(scene.fov, scene.fov_axis)
    if scene._edits:
        _set_edits(new, _json.dumps(new._edits, sort_keys=True), scene.content_hash)  # noqa: F821
    return new


Scene.__copy__ = _copy_scene  # noqa: F821
Scene.__deepcopy__ = _copy_scene  # noqa: F821
