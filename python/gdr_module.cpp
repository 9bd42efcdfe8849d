// The Python module `gdr`: gdr's scenes, integrators, reconstructors,
// metrics and EXR files on numpy arrays.
//
// Images cross the boundary as float32 arrays of shape (height, width,
// channels), row 0 at the top, the layout of gdr::Image, so a render's layer
// becomes an array without a copy (the array owns the Image). gdr's
// exceptions become Python exceptions carrying the same message.
//
// A render runs on a thread of its own with the GIL released. The calling
// thread waits for it, taking the GIL back every kPollSeconds only to check
// for a pending signal (Python runs its signal handlers, such as Ctrl-C's
// KeyboardInterrupt, on the main thread alone) and to call the progress
// callback. An exception from either stops the render through
// RenderSettings::abort (as the gdr tool's second Ctrl-C: the pass under way
// is abandoned where it can be undone, so it stops within about a second),
// and is raised once the render thread has ended.
#include <pybind11/eval.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "gdr/core/cancel.h"
#include "gdr/core/error.h"
#include "gdr/core/image.h"
#include "gdr/core/params.h"
#include "gdr/integrators/adaptive.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/exr.h"
#include "gdr/io/mitsuba_xml.h"
#include "gdr/io/png.h"
#include "gdr/io/render_header.h"
#include "gdr/io/scene_file.h"
#include "gdr/metrics.h"
#include "gdr/plugin.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/shift/shift.h"
#include "gdr_api_source.h"  // kApiSource: python/gdr_api.py, made by CMake

namespace py = pybind11;
namespace fs = std::filesystem;

namespace {

/// How often (s) a waiting render call checks for signals and reports progress.
constexpr double kPollSeconds = 0.05;

/// The module's exception classes, made at import (PyErr_NewException), kept for the translator.
PyObject* g_error = nullptr;
PyObject* g_input_error = nullptr;
PyObject* g_parameter_error = nullptr;
PyObject* g_runtime_failure = nullptr;
PyObject* g_interrupted = nullptr;

/// Makes the exception class gdr.<name> with the given bases and docstring.
PyObject* make_exception(py::module_& m, const char* name, py::tuple bases, const char* doc) {
    const std::string full = std::string("gdr.") + name;
    PyObject* type = PyErr_NewExceptionWithDoc(full.c_str(), doc, bases.ptr(), nullptr);
    if (!type) throw py::error_already_set();
    m.add_object(name, py::handle(type));
    return type;
}

/// Raises the OSError subclass that matches why `path` cannot be read (missing,
/// a directory, unreadable), with gdr's message; returns if none applies.
void raise_if_unreadable(const fs::path& path, const std::string& message) {
    std::error_code ec;
    PyObject* type = nullptr;
    int err = 0;
    if (!fs::exists(path, ec)) type = PyExc_FileNotFoundError, err = ENOENT;
    else if (fs::is_directory(path, ec)) type = PyExc_IsADirectoryError, err = EISDIR;
    else if (access(path.c_str(), R_OK) != 0) type = PyExc_PermissionError, err = EACCES;
    if (!type) return;
    PyErr_SetObject(type, py::make_tuple(err, message, path.string()).ptr());
    throw py::error_already_set();
}

// ------------------------------------------------------------------ images

/// A float32 array (height, width, channels) that owns `img` (no copy).
py::array_t<float> to_array(gdr::Image img) {
    auto* owned = new gdr::Image(std::move(img));
    py::capsule base(owned, [](void* p) { delete static_cast<gdr::Image*>(p); });
    const py::ssize_t h = owned->height(), w = owned->width(), c = owned->channels();
    const py::ssize_t f = sizeof(float);
    return py::array_t<float>({h, w, c}, {w * c * f, c * f, f}, owned->data(), base);
}

/// Copies a (height, width) or (height, width, channels) array of numbers into an
/// Image; ParameterError naming `what` for any other shape.
gdr::Image to_image(const py::handle& obj, const std::string& what) {
    if (obj.is_none()) throw gdr::ParameterError(what + ": expected an array, got None");
    const auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(obj);
    if (!a) throw gdr::ParameterError(what + ": expected an array of numbers, got " + std::string(py::str(py::type::of(obj).attr("__name__"))));
    std::string shape;
    for (py::ssize_t i = 0; i < a.ndim(); ++i) shape += (i ? ", " : "") + std::to_string(a.shape(i));
    if (a.ndim() != 2 && a.ndim() != 3)
        throw gdr::ParameterError(what + ": expected an array of shape (height, width) or (height, width, channels), got (" +
                                  shape + ")");
    const py::ssize_t h = a.shape(0), w = a.shape(1), c = a.ndim() == 3 ? a.shape(2) : 1;
    if (c < 1 || c > 4 || h < 1 || w < 1)
        throw gdr::ParameterError(what + ": shape (" + shape + ") is not an image of 1 to 4 channels with pixels");
    gdr::Image img{int(w), int(h), int(c)};
    std::copy(a.data(), a.data() + a.size(), img.data());
    return img;
}

/// A FrameBuffer's layers as {name: array} in the buffer's order (the arrays own copies).
py::dict layers_of(gdr::FrameBuffer& fb) {
    py::dict d;
    for (const std::string& name : fb.names()) d[py::str(name)] = to_array(std::move(fb.get(name)));
    return d;
}

// ------------------------------------------------------------------ parameters

/// Adds a Python value (bool, int, float or str) to `p` under `key`; TypeError otherwise.
void set_param(gdr::Params& p, const std::string& key, const py::handle& v) {
    if (PyBool_Check(v.ptr())) p.set(key, v.cast<bool>());
    else if (PyLong_Check(v.ptr())) p.set(key, v.cast<long long>());
    else if (PyFloat_Check(v.ptr())) p.set(key, v.cast<double>());
    else if (PyUnicode_Check(v.ptr())) p.set(key, v.cast<std::string>());
    else if (py::hasattr(v, "__index__")) p.set(key, py::reinterpret_borrow<py::object>(v).attr("__index__")().cast<long long>());  // numpy integers
    else if (py::hasattr(v, "__float__")) p.set(key, py::reinterpret_borrow<py::object>(v).attr("__float__")().cast<double>());   // numpy floats
    else
        throw py::type_error(p.context() + ": parameter '" + key + "' must be a bool, int, float or str, got " +
                             std::string(py::str(py::type::of(v).attr("__name__"))));
}

/// The name of `obj`'s type, for messages.
std::string type_name(const py::handle& obj) { return py::str(py::type::of(obj).attr("__name__")); }

/// `obj` as a dict; TypeError naming `what` for any other type (a cast would
/// raise a RuntimeError that names neither the argument nor the type).
py::dict as_dict(const py::handle& obj, const std::string& what) {
    if (!py::isinstance<py::dict>(obj)) throw py::type_error(what + " must be a dict, got " + type_name(obj));
    return py::reinterpret_borrow<py::dict>(obj);
}

/// The keys and values of a Python mapping (or None) added to `p`.
void add_params(gdr::Params& p, const py::handle& mapping) {
    if (mapping.is_none()) return;
    for (const auto& [k, v] : as_dict(mapping, p.context() + ": params")) set_param(p, py::str(k), v);
}

/// A Params' values as a Python dict.
py::dict params_dict(const gdr::Params& p) {
    py::dict d;
    for (const auto& [k, v] : p.values()) std::visit([&](const auto& x) { d[py::str(k)] = x; }, v);
    return d;
}

// ------------------------------------------------------------------ scenes

/// A loaded scene file, shared by the Python object and the renders running on it.
struct PyScene {
    gdr::SceneFile sf;            ///< The scene and what its file said.
    std::atomic<int> renders{0};  ///< Renders running on it (changing the camera is refused meanwhile).
    /// The parameters edited in place since loading (gdr.traverse), as JSON
    /// {key: value}; written to render headers as 'scene_edits'; empty if none.
    std::string edits;

    /// Throws RuntimeFailure if a render is running (`what` names the change).
    void require_idle(const std::string& what) const {
        if (renders.load() > 0)
            throw gdr::RuntimeFailure(sf.path + ": cannot " + what + " while a render of the scene is running");
    }
};

/// Scene files and texts loaded by this module (gdr._scene_loads()): tests
/// check with it that editing a scene in place reads no scene again.
std::atomic<long long> g_scene_loads{0};

/// gdr.load_scene: the scene file at `path`, loaded without the GIL.
std::shared_ptr<PyScene> load_scene(const fs::path& path, const py::object& defines, bool lenient) {
    gdr::SceneFileOptions options;
    options.lenient = lenient;
    options.editable = true;  // gdr.traverse edits it in place
    if (!defines.is_none())
        for (const auto& [k, v] : as_dict(defines, "load_scene: defines")) {
            // As the command line's -D name=value: text, with Python's booleans spelt as XML's.
            options.defines[py::str(k)] =
                PyBool_Check(v.ptr()) ? std::string(v.cast<bool>() ? "true" : "false") : std::string(py::str(v));
        }
    auto scene = std::make_shared<PyScene>();
    try {
        py::gil_scoped_release nogil;
        ++g_scene_loads;
        scene->sf = gdr::load_scene_file(path.string(), options);
    } catch (const gdr::InputError& e) {
        raise_if_unreadable(path, e.what());
        throw;
    }
    return scene;
}

/// Throws ParameterError unless `a` and `b` have one shape, stated in numpy's order
/// (height x width x channels), which is how Python callers see their arrays.
void require_same_shape(const gdr::Image& a, const std::string& a_name, const gdr::Image& b, const std::string& b_name,
                        const std::string& fn) {
    if (a.width() == b.width() && a.height() == b.height() && a.channels() == b.channels()) return;
    const auto shape = [](const gdr::Image& i) {
        return std::to_string(i.height()) + " x " + std::to_string(i.width()) + " x " + std::to_string(i.channels());
    };
    throw gdr::ParameterError(fn + ": " + a_name + " is " + shape(a) + " but " + b_name + " is " + shape(b) +
                              " (height x width x channels)");
}

// Defined with the render files below.
void record_render(gdr::FrameBuffer& fb, const PyScene& scene, const std::string& integrator,
                   const gdr::RenderSettings& st, const gdr::RenderStats& stats);
void require_extension(const fs::path& path, const std::string& ext, const std::string& fn);

// ------------------------------------------------------------------ rendering

/// What the render thread and the waiting caller share.
struct RenderJob {
    std::mutex mutex;               ///< Guards finished, latest and reports.
    std::condition_variable finished_cv;  ///< Signalled when finished is set.
    bool finished = false;          ///< The render thread has returned.
    gdr::Progress latest;           ///< Latest progress a worker reported.
    uint64_t reports = 0;           ///< Progress reports so far.
    std::atomic<bool> abort{false}; ///< Set by the caller to stop the render (RenderSettings::abort).
    gdr::FrameBuffer fb;            ///< The render's layers.
    gdr::RenderStats stats;         ///< What the render did.
    std::exception_ptr error;       ///< What the render threw, if anything.
};

/// The class gdr.Layers, defined in Python at import.
py::object g_layers_type;

/// A gdr.Layers of the buffer's layers (moved out of it), metadata and `stats` (a RenderStats or None).
py::object make_layers(gdr::FrameBuffer& fb, py::object stats) {
    py::dict meta;
    for (const auto& [k, v] : fb.metadata()) meta[py::str(k)] = v;
    return g_layers_type(layers_of(fb), meta, stats);
}

/// gdr.render: renders on a thread of its own while this one waits without the GIL (see the file comment).
py::object render(const std::shared_ptr<PyScene>& scene, const std::optional<std::string>& integrator,
                  std::optional<long long> spp, std::optional<long long> seed, int threads, const py::object& params,
                  const py::object& progress, double time, long long first_sample, double adaptive,
                  double select_gradients) {
    // pybind11 passes None as an empty pointer.
    if (!scene) throw py::type_error("render: scene must be a gdr.Scene (from gdr.load_scene), got None");
    const gdr::SceneFile& sf = scene->sf;
    if (!(select_gradients == 0.0 || (select_gradients > 0.0 && select_gradients <= 0.5)))
        throw gdr::ParameterError("render: select_gradients is the pilots' share of the budget, above 0 and at most "
                                  "0.5 (0: gradients everywhere), got " + std::to_string(select_gradients));
    if (select_gradients > 0.0 && adaptive > 0.0)
        throw gdr::ParameterError("render: adaptive and select_gradients are two uses of a pilot; give one of them");
    const bool select = select_gradients > 0.0;
    if (select) adaptive = select_gradients;
    if (!(adaptive == 0.0 || (adaptive > 0.0 && adaptive <= 0.5)))
        throw gdr::ParameterError("render: adaptive is the pilot's share of the budget, above 0 and at most 0.5 (0: "
                                  "uniform sampling), got " + std::to_string(adaptive));
    if (adaptive > 0.0 && first_sample > 0)
        throw gdr::ParameterError("render: adaptive sampling chooses its own density, so it cannot continue a "
                                  "sequence (first_sample)");
    if (spp && *spp < 1) throw gdr::ParameterError("render: spp must be at least 1, got " + std::to_string(*spp));
    if (seed && *seed < 0) throw gdr::ParameterError("render: seed must be >= 0, got " + std::to_string(*seed));
    if (threads < 0) throw gdr::ParameterError("render: threads must be >= 0 (0: all cores), got " + std::to_string(threads));
    if (!(time >= 0.0) || !std::isfinite(time))
        throw gdr::ParameterError("render: time must be a finite number of seconds >= 0, got " + std::to_string(time));
    if (spp && time > 0.0) throw gdr::ParameterError("render: give either spp or time, not both");
    if (first_sample < 0) throw gdr::ParameterError("render: first_sample must be >= 0, got " + std::to_string(first_sample));
    if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
        throw py::type_error("render: progress must be callable (it receives a gdr.Progress), got " +
                             std::string(py::str(py::type::of(progress).attr("__name__"))));

    // As gdr render: the scene's parameters, then the caller's over them.
    const std::string name = integrator ? *integrator : sf.defaults.integrator;
    const bool given = !params.is_none() && py::len(params) > 0;
    gdr::Params p(sf.defaults.params.context() + (given ? " with render(params=...)" : ""));
    for (const auto& [k, v] : sf.defaults.params.values()) p.set(k, v);
    add_params(p, params);
    auto integ = gdr::integrator_registry().create(name, p);

    RenderJob job;
    gdr::RenderSettings st;
    st.spp = spp ? *spp : sf.defaults.spp;
    st.time_budget = time;
    st.threads = threads;
    st.seed = uint64_t(seed ? *seed : sf.defaults.seed);
    st.first_sample = first_sample;
    st.abort = &job.abort;
    gdr::ProgressFn report;
    if (!progress.is_none())
        report = [&job](const gdr::Progress& pr) {
            const std::lock_guard<std::mutex> lock(job.mutex);
            job.latest = pr;
            ++job.reports;
        };

    std::optional<py::error_already_set> raised;  // from a signal handler or the callback
    {
        scene->renders++;
        struct Running {
            PyScene& s;
            ~Running() { s.renders--; }
        } running{*scene};
        py::gil_scoped_release nogil;
        std::thread worker([&] {
            try {
                if (adaptive > 0.0) {
                    gdr::AdaptiveRender ad;
                    ad.pilot = adaptive;
                    if (select) ad.mode = gdr::AdaptiveRender::Mode::SelectGradients;
                    job.stats = gdr::render_adaptive(*integ, *sf.scene, st, job.fb, ad, report);
                } else {
                    job.stats = integ->render(*sf.scene, st, job.fb, report);
                }
            } catch (...) {
                job.error = std::current_exception();
            }
            const std::lock_guard<std::mutex> lock(job.mutex);
            job.finished = true;
            job.finished_cv.notify_all();
        });
        // Whatever leaves this block, the render is stopped and joined first.
        struct Join {
            std::thread& t;
            std::atomic<bool>& abort;
            ~Join() {
                if (t.joinable()) {
                    abort = true;
                    t.join();
                }
            }
        } join{worker, job.abort};
        uint64_t delivered = 0;
        for (bool done = false; !done;) {
            gdr::Progress latest;
            bool fresh = false;
            {
                std::unique_lock<std::mutex> lock(job.mutex);
                job.finished_cv.wait_for(lock, std::chrono::duration<double>(kPollSeconds), [&] { return job.finished; });
                done = job.finished;
                fresh = job.reports != delivered;
                delivered = job.reports;
                latest = job.latest;
            }
            if (raised) continue;
            py::gil_scoped_acquire gil;
            if (PyErr_CheckSignals() != 0) {
                raised.emplace();
                job.abort = true;
            } else if (fresh && report) {
                try {
                    progress(latest);
                } catch (py::error_already_set& e) {
                    raised.emplace(std::move(e));
                    job.abort = true;
                }
            }
        }
        worker.join();
    }
    // The caller's exception wins: a render it stopped has nothing to return.
    if (raised) throw std::move(*raised);
    if (job.error) std::rethrow_exception(job.error);
    record_render(job.fb, *scene, name, st, job.stats);
    return make_layers(job.fb, py::cast(job.stats));
}

// ------------------------------------------------------------------ reconstruction and files

/// gdr.reconstruct: the image (radiance) reconstructed by `method` from the buffers.
py::array_t<float> reconstruct(const py::object& primal, const py::object& dx, const py::object& dy,
                               const std::string& method, const py::object& direct, const py::kwargs& kwargs) {
    gdr::Params p("reconstruct(" + method + ")");
    for (const auto& [k, v] : kwargs) set_param(p, py::str(k), v);
    gdr::GradientFrame f;
    f.primal = to_image(primal, "reconstruct: primal");
    f.dx = to_image(dx, "reconstruct: dx");
    f.dy = to_image(dy, "reconstruct: dy");
    if (!direct.is_none()) f.direct = to_image(direct, "reconstruct: direct");
    require_same_shape(f.dx, "dx", f.primal, "primal", "reconstruct");
    require_same_shape(f.dy, "dy", f.primal, "primal", "reconstruct");
    if (!f.direct.empty()) require_same_shape(f.direct, "direct", f.primal, "primal", "reconstruct");
    auto r = gdr::reconstructor_registry().create(method, p);
    // As render: the solve runs on a thread of its own, and this one checks
    // for signals every kPollSeconds; Ctrl-C stops the solve between two of
    // its iterations (gdr::CancelScope) and is raised once it has stopped.
    gdr::Image out;
    std::exception_ptr error;
    std::optional<py::error_already_set> raised;
    std::atomic<bool> abort{false};
    {
        py::gil_scoped_release nogil;
        std::mutex mutex;
        std::condition_variable finished_cv;
        bool finished = false;
        std::thread worker([&] {
            try {
                const gdr::CancelScope scope(&abort);
                out = r->reconstruct(f.buffers());
            } catch (...) {
                error = std::current_exception();
            }
            const std::lock_guard<std::mutex> lock(mutex);
            finished = true;
            finished_cv.notify_all();
        });
        for (bool done = false; !done;) {
            {
                std::unique_lock<std::mutex> lock(mutex);
                finished_cv.wait_for(lock, std::chrono::duration<double>(kPollSeconds), [&] { return finished; });
                done = finished;
            }
            if (done || raised) continue;
            py::gil_scoped_acquire gil;
            if (PyErr_CheckSignals() != 0) {
                raised.emplace();
                abort = true;
            }
        }
        worker.join();
    }
    if (raised) throw std::move(*raised);
    if (error) std::rethrow_exception(error);
    return to_array(std::move(out));
}

/// gdr.read_exr: every layer of the EXR at `path`, with its header's metadata.
py::object read_exr(const fs::path& path) {
    gdr::FrameBuffer fb;
    try {
        py::gil_scoped_release nogil;
        fb = gdr::read_exr(path.string());
    } catch (const gdr::InputError& e) {
        raise_if_unreadable(path, e.what());
        throw;
    }
    return make_layers(fb, py::none());
}

/// gdr.write_exr: writes the layers and metadata as one multi-layer EXR.
void write_exr(const fs::path& path, const py::object& layers, const py::object& metadata) {
    require_extension(path, ".exr", "write_exr");
    gdr::FrameBuffer fb;
    const py::dict d = as_dict(layers, "write_exr: layers");
    if (d.size() == 0) throw gdr::ParameterError(path.string() + ": write_exr needs at least one layer");
    for (const auto& [k, v] : d) {
        const std::string name = py::str(k);
        if (name.empty()) throw gdr::ParameterError(path.string() + ": a layer has an empty name");
        gdr::Image img = to_image(v, path.string() + ": layer '" + name + "'");
        // No written image holds NaN or Inf.
        gdr::require_finite(img, path.string() + ": layer '" + name + "'");
        if (!fb.names().empty() && (img.width() != fb.width() || img.height() != fb.height()))
            throw gdr::ParameterError(path.string() + ": layer '" + name + "' is " + std::to_string(img.height()) +
                                      " x " + std::to_string(img.width()) + " but the layers before it are " +
                                      std::to_string(fb.height()) + " x " + std::to_string(fb.width()) +
                                      " (height x width)");
        fb.set(name, std::move(img));
    }
    py::object meta = metadata;
    if (meta.is_none() && py::hasattr(layers, "metadata")) meta = layers.attr("metadata");
    if (!meta.is_none())
        for (const auto& [k, v] : as_dict(meta, "write_exr: metadata")) fb.metadata()[py::str(k)] = py::str(v);
    try {
        py::gil_scoped_release nogil;
        gdr::write_exr(path.string(), fb);
    } catch (const gdr::RuntimeFailure& e) {
        PyErr_SetObject(PyExc_OSError, py::make_tuple(EIO, e.what(), path.string()).ptr());
        throw py::error_already_set();
    }
}

/// {name: description} of a registry.
template <typename R>
py::dict registry_dict(const R& r) {
    py::dict d;
    for (const std::string& n : r.names()) d[py::str(n)] = r.description(n);
    return d;
}

/// Two images for a metric, converted and named.
std::pair<gdr::Image, gdr::Image> image_pair(const py::object& img, const py::object& ref, const char* fn) {
    std::pair<gdr::Image, gdr::Image> p{to_image(img, std::string(fn) + ": image"), to_image(ref, std::string(fn) + ": reference")};
    require_same_shape(p.first, "image", p.second, "reference", fn);
    return p;
}

/// Python source of gdr.Layers: a dict subclass, so that it is Python's own mapping, with two attributes added.
const char* kLayersSource = R"PY(
class Layers(dict):
    """Image layers by name: a dict of float32 numpy arrays of shape (height, width,
    channels), row 0 at the top. ``metadata`` holds the render's settings or the file's
    header attributes (str to str); ``stats`` is a gdr.RenderStats for a render, None
    for a file."""

    def __init__(self, layers=(), metadata=None, stats=None):
        super().__init__(layers)
        self.metadata = dict(metadata or {})
        self.stats = stats

    def __repr__(self):
        shapes = ", ".join(f"{k!r}: {v.shape}" for k, v in self.items())
        return f"gdr.Layers({{{shapes}}}, stats={self.stats!r})"
)PY";

// ------------------------------------------------------------------ render files, previews, merges, plugins
// (what the gdr tool reads back, and reconstructors from Python and plugins)

/// Adds to a fresh render's metadata the header gdr render writes (gdr/io/render_header.h),
/// so that gdr info, --resume and gdr merge accept its EXR.
void record_render(gdr::FrameBuffer& fb, const PyScene& scene, const std::string& integrator,
                   const gdr::RenderSettings& st, const gdr::RenderStats& stats) {
    gdr::RenderRecord r;
    r.integrator = integrator;
    std::error_code ec;
    const fs::path abs = fs::absolute(scene.sf.path, ec);
    r.scene = ec ? scene.sf.path : abs.string();
    r.scene_hash = scene.sf.content_hash;
    // The scene rendered is the file's with these values changed (its hash is the edited description's).
    if (!scene.edits.empty()) fb.metadata()["scene_edits"] = scene.edits;
    r.seconds = stats.seconds;
    r.time_budget = st.time_budget;
    // As gdr render: an adaptive render's target is the passes after its pilot's share.
    const auto pilot = fb.metadata().find("adaptive_pilot_spp");
    const long long pilot_spp = pilot != fb.metadata().end() && st.time_budget <= 0.0 ? std::stoll(pilot->second) : 0;
    if (st.time_budget <= 0.0) r.target_spp = uint64_t(st.first_sample + st.spp - pilot_spp);
    r.samples = {st.seed, uint64_t(st.first_sample), uint64_t(stats.spp)};
    r.version = GDR_VERSION;
    write_render_record(fb, r);
}

/// Throws ParameterError unless `path` ends in `ext` (any case): a file's name says what it holds.
void require_extension(const fs::path& path, const std::string& ext, const std::string& fn) {
    std::string e = path.extension().string();
    std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (e != ext)
        throw gdr::ParameterError(fn + ": '" + path.string() + "' must end in " + ext + " (" + fn +
                                  " writes only that format)");
}

/// The image a preview shows: an array, or the preview layer of a layers dict (as the gdr tool chooses it).
gdr::Image preview_image(const py::object& image, const std::string& what) {
    if (py::isinstance<py::dict>(image)) {
        gdr::FrameBuffer fb;
        for (const auto& [k, v] : py::cast<py::dict>(image)) fb.set(py::str(k), to_image(v, what + ": layer '" + std::string(py::str(k)) + "'"));
        if (fb.names().empty()) throw gdr::ParameterError(what + ": no layers");
        return fb.get(gdr::preview_layer(fb));
    }
    return to_image(image, what);
}

/// gdr.write_png: the 8-bit sRGB preview gdr render writes beside its EXR.
void write_png(const fs::path& path, const py::object& image, float exposure) {
    require_extension(path, ".png", "write_png");
    if (!std::isfinite(exposure)) throw gdr::ParameterError("write_png: exposure must be a finite number of stops");
    const gdr::Image img = preview_image(image, "write_png");
    gdr::require_finite(img, "write_png: " + path.string());
    try {
        py::gil_scoped_release nogil;
        gdr::write_png_preview(path.string(), img, exposure);
    } catch (const gdr::RuntimeFailure& e) {
        PyErr_SetObject(PyExc_OSError, py::make_tuple(EIO, e.what(), path.string()).ptr());
        throw py::error_already_set();
    }
}

/// gdr.tonemap: the preview's 8-bit pixels (height, width, 1, 3 or 4) as a uint8 array.
py::array_t<uint8_t> tonemap(const py::object& image, float exposure) {
    if (!std::isfinite(exposure)) throw gdr::ParameterError("tonemap: exposure must be a finite number of stops");
    const gdr::Image img = preview_image(image, "tonemap");
    std::vector<uint8_t> bytes = gdr::preview_bytes(img, exposure);
    const py::ssize_t h = img.height(), w = img.width(), c = py::ssize_t(bytes.size()) / (h * w);
    py::array_t<uint8_t> out({h, w, c});
    std::copy(bytes.begin(), bytes.end(), out.mutable_data());
    return out;
}

/// A FrameBuffer of a {name: array} dict (copies) and its metadata (a gdr.Layers' .metadata, if any).
gdr::FrameBuffer frame_of(const py::handle& layers, const std::string& what) {
    if (!py::isinstance<py::dict>(layers))
        throw py::type_error(what + ": expected a dict of arrays (a gdr.Layers), got " +
                             std::string(py::str(py::type::of(layers).attr("__name__"))));
    gdr::FrameBuffer fb;
    for (const auto& [k, v] : py::cast<py::dict>(layers)) {
        const std::string name = py::str(k);
        gdr::Image img = to_image(v, what + ": layer '" + name + "'");
        if (!fb.names().empty() && (img.width() != fb.width() || img.height() != fb.height()))
            throw gdr::ParameterError(what + ": layer '" + name + "' is " + std::to_string(img.height()) + " x " +
                                      std::to_string(img.width()) + ", the others " + std::to_string(fb.height()) +
                                      " x " + std::to_string(fb.width()) + " (height x width)");
        fb.set(name, std::move(img));
    }
    if (py::hasattr(layers, "metadata"))
        for (const auto& [k, v] : py::cast<py::dict>(layers.attr("metadata"))) fb.metadata()[py::str(k)] = py::str(v);
    return fb;
}

/// gdr._reconstruct_layers: `method` on a render's layers (primal, dx, dy, and what the method needs).
py::array_t<float> reconstruct_layers(const py::object& layers, const std::string& method, const py::dict& params) {
    gdr::Params p("reconstruct(" + method + ")");
    for (const auto& [k, v] : params) set_param(p, py::str(k), v);
    const gdr::FrameBuffer fb = frame_of(layers, "reconstruct");
    gdr::GradientBuffers gb = gdr::gradient_buffers(fb);
    // As gpt does for a render without an 'spp' layer: its metadata's count in every pixel.
    gdr::Image spp;
    const auto n = fb.metadata().find("spp");
    if (!gb.spp && n != fb.metadata().end()) {
        spp = gdr::Image(fb.width(), fb.height(), 1);
        std::fill(spp.values().begin(), spp.values().end(), float(std::stod(n->second)));
        gb.spp = &spp;
    }
    auto r = gdr::reconstructor_registry().create(method, p);
    gdr::Image out;
    {
        py::gil_scoped_release nogil;
        out = r->reconstruct(gb);
    }
    return to_array(std::move(out));
}

/// A reconstructor written in Python (gdr.register_reconstructor): solve() passes the frame's
/// layers as {name: array (height, width, channels)} and the parameters as keywords to `fn`.
class PythonReconstructor final : public gdr::Reconstructor {
public:
    /// `fn` is called as fn(layers, **params); `params` are all taken (fn refuses what it does not know).
    PythonReconstructor(std::string name, py::object fn, const gdr::Params& params)
        : name_(std::move(name)), fn_(new py::object(std::move(fn)), [](py::object* o) {
              py::gil_scoped_acquire gil;
              delete o;
          }),
          params_(params) {
        for (const auto& [k, v] : params.values()) {
            if (std::holds_alternative<bool>(v)) (void)params.get_bool(k, false);
            else if (std::holds_alternative<long long>(v)) (void)params.get_int(k, 0);
            else if (std::holds_alternative<double>(v)) (void)params.get_real(k, 0.0);
            else (void)params.get_string(k, "");
        }
    }
    std::string describe() const override {
        std::string s;
        for (const auto& [k, v] : params_.values())
            std::visit([&](const auto& x) {
                if constexpr (std::is_same_v<std::decay_t<decltype(x)>, std::string>) s += k + "=" + x + "\n";
                else s += k + "=" + std::to_string(x) + "\n";
            }, v);
        return s;
    }

protected:
    gdr::Image solve(const gdr::GradientBuffers& in) const override {
        py::gil_scoped_acquire gil;
        py::dict layers;
        const auto add = [&](const char* name, const gdr::Image* img) {
            if (img && !img->empty()) layers[name] = to_array(gdr::Image(*img));
        };
        if (in.layers)
            for (const std::string& n : in.layers->names()) layers[py::str(n)] = to_array(gdr::Image(in.layers->get(n)));
        add("primal", in.primal), add("dx", in.dx), add("dy", in.dy), add("direct", in.direct);
        add("primal_variance", in.primal_variance), add("dx_variance", in.dx_variance);
        add("dy_variance", in.dy_variance), add("spp", in.spp);
        py::object result = (*fn_)(layers, **params_dict(params_));
        gdr::Image out = to_image(result, "reconstructor '" + name_ + "': its result");
        if (out.width() != in.primal->width() || out.height() != in.primal->height() ||
            out.channels() != in.primal->channels())
            throw gdr::ParameterError("reconstructor '" + name_ + "' returned an image of " +
                                      std::to_string(out.height()) + " x " + std::to_string(out.width()) + " x " +
                                      std::to_string(out.channels()) + ", not the primal's " +
                                      std::to_string(in.primal->height()) + " x " + std::to_string(in.primal->width()) +
                                      " x " + std::to_string(in.primal->channels()) + " (height x width x channels)");
        return out;
    }

private:
    std::string name_;
    std::shared_ptr<py::object> fn_;  // released with the GIL held, whichever thread drops the last reference
    gdr::Params params_;
};

/// gdr._register_python_reconstructor: adds `fn` to the reconstructor registry under `name`.
void register_python_reconstructor(const std::string& name, const py::object& fn, const std::string& description) {
    if (name.empty()) throw gdr::ParameterError("register_reconstructor: the name is empty");
    if (!PyCallable_Check(fn.ptr()))
        throw py::type_error("register_reconstructor: fn must be callable as fn(layers, **params), got " +
                             std::string(py::str(py::type::of(fn).attr("__name__"))));
    auto shared = std::shared_ptr<py::object>(new py::object(fn), [](py::object* o) {
        // The registry outlives the interpreter's last reference: drop ours only while Python runs.
        if (Py_IsInitialized()) {
            py::gil_scoped_acquire gil;
            delete o;
        }
    });
    gdr::reconstructor_registry().add(name, description, [name, shared](const gdr::Params& p) {
        py::gil_scoped_acquire gil;
        return std::unique_ptr<gdr::Reconstructor>(new PythonReconstructor(name, *shared, p));
    });
}

/// gdr._merge_layers: two renders of one scene and integrator pooled (gdr/integrators/integrator.h's
/// merge_renders), with the layers that are not sample means recomputed by the integrator.
py::object merge_layers(const py::object& a, const py::object& b) {
    gdr::FrameBuffer into = frame_of(a, "merge: the first render");
    const gdr::FrameBuffer other = frame_of(b, "merge: the second render");
    const auto& m = into.metadata();
    for (const char* k : {"integrator", "integrator_params"})
        if (!m.count(k)) throw gdr::InputError(std::string("merge: the first render has no '") + k + "' metadata (not a gdr render)");
    gdr::Params p("merge: " + m.at("integrator") + " (integrator_params)");
    const std::string& lines = m.at("integrator_params");
    for (size_t at = 0; at < lines.size();) {
        const size_t end = std::min(lines.find('\n', at), lines.size());
        if (end > at) p.set_from_text(lines.substr(at, end - at));
        at = end + 1;
    }
    auto integ = gdr::integrator_registry().create(m.at("integrator"), p);
    {
        py::gil_scoped_release nogil;
        gdr::merge_renders(into, other);
        integ->update_merged(into);
    }
    return make_layers(into, py::none());
}

/// The plugins loaded so far (file -> registered), so that loading one twice does nothing.
std::map<std::string, bool> g_plugins;

/// gdr.load_plugin: loads a reconstructor plugin (the neural reconstructor's libgdr_neural_plugin.so)
/// and registers its reconstructors; returns the file loaded.
std::string load_plugin_file(const fs::path& file) {
    std::error_code ec;
    const std::string path = fs::weakly_canonical(file, ec).string();
    if (g_plugins.count(path)) return path;
    if (!fs::is_regular_file(path, ec)) {
        PyErr_SetObject(PyExc_FileNotFoundError, py::make_tuple(ENOENT, "load_plugin: no plugin file", file.string()).ptr());
        throw py::error_already_set();
    }
    // As the gdr tool: libtorch's OpenMP threads must not spin between parallel regions.
    setenv("OMP_WAIT_POLICY", "PASSIVE", 0);
    const std::string why = gdr::load_plugin(path);  // never unloaded: the registries hold its factories
    if (!why.empty()) throw gdr::InputError("load_plugin: " + path + ": " + why);
    g_plugins[path] = true;
    return path;
}

/// The directories gdr.load_plugin() searches without a path: $GDR_PLUGIN_PATH (colon-separated)
/// if set, else beside the module: gdr-data/LIBDIR/gdr (a pip install), ../LIBDIR/gdr (the build
/// tree) and ../../gdr (a cmake --install prefix's lib/pythonX.Y/dist-packages).
std::vector<std::string> plugin_dirs(const std::string& module_file) {
    std::vector<std::string> beside;
    const fs::path here = fs::path(module_file).parent_path();
    for (const fs::path& d : {here / "gdr-data" / GDR_LIBDIR / "gdr", here / ".." / GDR_LIBDIR / "gdr", here / ".." / ".." / "gdr"})
        beside.push_back(d.lexically_normal().string());
    return gdr::plugin_path_dirs(std::move(beside));
}

/// gdr.load_plugin(path=None): a given file, or the neural plugin from plugin_dirs().
std::string load_plugin(const std::optional<fs::path>& file, const std::string& module_file) {
    if (file) return load_plugin_file(*file);
    std::string searched;
    for (const std::string& d : plugin_dirs(module_file)) {
        const fs::path f = fs::path(d) / "libgdr_neural_plugin.so";
        std::error_code ec;
        if (fs::is_regular_file(f, ec)) return load_plugin_file(f);
        searched += (searched.empty() ? "" : ", ") + d;
    }
    throw gdr::ParameterError("load_plugin: no libgdr_neural_plugin.so in " + (searched.empty() ? "(no directory)" : searched) +
                              " (the neural reconstructor is built where CMake finds libtorch, Debian: libtorch-dev; "
                              "GDR_PLUGIN_PATH names other directories)");
}

/// Binds the functions of this section into the module.
void bind_package(py::module_& m) {
    m.def("write_png", &write_png, py::arg("path"), py::arg("image"), py::arg("exposure") = 0.0f,
          "write_png(path, image, exposure=0.0)\n\n"
          "Writes the 8-bit sRGB preview gdr render writes beside its EXR: the image (an array, or\n"
          "the layer a render's preview shows of a gdr.Layers: its reconstruction, else 'color')\n"
          "scaled by 2**exposure, clamped to [0, 1]. path must end in .png (gdr.ParameterError).");
    m.def("tonemap", &tonemap, py::arg("image"), py::arg("exposure") = 0.0f,
          "tonemap(image, exposure=0.0) -> uint8 array (height, width, channels)\n\n"
          "The pixels write_png stores: sRGB of the linear image scaled by 2**exposure, clamped.");
    m.def("_reconstruct_layers", &reconstruct_layers, py::arg("layers"), py::arg("method"), py::arg("params"));
    m.def("_register_python_reconstructor", &register_python_reconstructor, py::arg("name"), py::arg("fn"),
          py::arg("description"));
    m.def("_merge_layers", &merge_layers, py::arg("a"), py::arg("b"));
    m.def(
        "_load_scene_text",
        [](const std::string& text, const std::string& name) {
            auto scene = std::make_shared<PyScene>();
            py::gil_scoped_release nogil;
            ++g_scene_loads;
            scene->sf = gdr::load_scene_text(text, name, true);
            return scene;
        },
        py::arg("text"), py::arg("name"));
    m.def("_scene_loads", [] { return g_scene_loads.load(); });
    m.def(
        "_load_mitsuba_text",
        [](const std::string& text, const std::string& name, bool lenient) {
            auto scene = std::make_shared<PyScene>();
            gdr::SceneFileOptions options;
            options.text = text;
            options.lenient = lenient;
            py::gil_scoped_release nogil;
            ++g_scene_loads;
            scene->sf = gdr::load_mitsuba_scene(name, options);
            return scene;
        },
        py::arg("text"), py::arg("name"), py::arg("lenient") = false);
    m.def(
        "_edit_material",
        [](PyScene& s, const std::string& name, const std::string& fields) {
            s.require_idle("change a material");
            gdr::edit_material(s.sf, name, fields);
        },
        py::arg("scene"), py::arg("name"), py::arg("fields"));
    m.def(
        "_material_values",
        [](PyScene& s, const std::string& name, const std::string& fields) {
            const gdr::MaterialDesc d = gdr::material_description(s.sf, name, fields);
            const auto rgb = [](const gdr::Color& c) { return std::vector<double>{c.r, c.g, c.b}; };
            py::dict v;
            v["kd"] = rgb(d.kd), v["ks"] = rgb(d.ks), v["ke"] = rgb(d.ke);
            v["ns"] = double(d.ns), v["eta"] = double(d.ni);
            if (d.pr >= 0.f) v["alpha"] = double(d.pr);
            return v;
        },
        py::arg("scene"), py::arg("name"), py::arg("fields"));
    m.def(
        "_edit_mesh_transform",
        [](PyScene& s, size_t index, const std::string& transform) {
            s.require_idle("move a mesh");
            gdr::edit_mesh_transform(s.sf, index, transform);
        },
        py::arg("scene"), py::arg("index"), py::arg("transform"));
    m.def(
        "_edit_environment",
        [](PyScene& s, const std::string& environment) {
            s.require_idle("change the environment");
            gdr::edit_environment(s.sf, environment);
        },
        py::arg("scene"), py::arg("environment"));
    m.def(
        "_set_edits",
        [](PyScene& s, const std::string& edits, const std::string& content_hash) {
            s.require_idle("record edits");
            s.edits = edits;
            s.sf.content_hash = content_hash;
        },
        py::arg("scene"), py::arg("edits"), py::arg("content_hash"));
    m.def("_scene_text_hash", &gdr::scene_text_hash, py::arg("text"), py::arg("name"), py::arg("inputs"));
    m.def(
        "_set_camera",
        [](PyScene& s, const py::dict& changes) {
            s.require_idle("change the camera");
            if (s.sf.animation) throw gdr::ParameterError(s.sf.path + ": an animated scene's camera follows its keys");
            gdr::CameraDesc d = s.sf.scene->camera().desc();
            const auto vec = [&](const char* k, gdr::Vec3& v) {
                if (!changes.contains(k)) return;
                const auto a = changes[k].cast<std::vector<float>>();
                if (a.size() != 3 || !std::isfinite(a[0]) || !std::isfinite(a[1]) || !std::isfinite(a[2]))
                    throw gdr::ParameterError(std::string("camera.") + k + " must be 3 finite numbers");
                v = gdr::Vec3(a[0], a[1], a[2]);
            };
            vec("position", d.position), vec("target", d.target), vec("up", d.up);
            if (changes.contains("fov")) d.fov_deg = changes["fov"].cast<float>();
            if (changes.contains("fov_axis")) {
                const auto axis = changes["fov_axis"].cast<std::string>();
                if (axis != "x" && axis != "y") throw gdr::ParameterError("camera.fov_axis must be 'x' or 'y', got '" + axis + "'");
                d.fov_axis = axis[0];
            }
            if (changes.contains("width")) d.width = changes["width"].cast<int>();
            if (changes.contains("height")) d.height = changes["height"].cast<int>();
            s.sf.scene->set_camera(gdr::Camera(d));  // rejects a degenerate camera
            // The content hash and the render headers record the change through _set_edits.
        },
        py::arg("scene"), py::arg("changes"));
    m.def(
        "_load_plugin",
        [](const std::optional<fs::path>& file) {
            return load_plugin(file, py::module_::import("gdr").attr("__file__").cast<std::string>());
        },
        py::arg("path") = py::none());
}

}  // namespace

PYBIND11_MODULE(gdr, m) {
    m.doc() =
        "gdr: gradient-domain Monte Carlo rendering.\n\n"
        "Load a scene (gdr's JSON or Mitsuba XML), render it with any registered\n"
        "integrator, reconstruct gradient-domain renders and compare images. Images are\n"
        "float32 numpy arrays of shape (height, width, channels) in radiance, row 0 at\n"
        "the top. Errors are gdr.Error subclasses (also ValueError or RuntimeError)\n"
        "carrying gdr's message, and OSError subclasses for unreadable files.";
    m.attr("__version__") = GDR_VERSION;
    // Each docstring starts with its own signature line, in Python's terms.
    py::options options;
    options.disable_function_signatures();

    g_error = make_exception(m, "Error", py::make_tuple(py::handle(PyExc_Exception)),
                             "Base of gdr's errors; the message names the file, key or pixel.");
    g_input_error = make_exception(m, "InputError", py::make_tuple(py::handle(g_error), py::handle(PyExc_ValueError)),
                                   "Bad input data: a malformed file, a NaN in an image, a degenerate mesh.");
    g_parameter_error =
        make_exception(m, "ParameterError", py::make_tuple(py::handle(g_error), py::handle(PyExc_ValueError)),
                       "A bad parameter: unknown or ill-typed key, out-of-range value, unknown plugin name, "
                       "images of different shapes.");
    g_runtime_failure =
        make_exception(m, "RuntimeFailure", py::make_tuple(py::handle(g_error), py::handle(PyExc_RuntimeError)),
                       "A failure reported by a dependency at run time (Embree, OpenEXR, FFTW).");
    g_interrupted =
        make_exception(m, "Interrupted", py::make_tuple(py::handle(g_error), py::handle(PyExc_RuntimeError)),
                       "A render stopped before it had an image.");
    py::register_exception_translator([](std::exception_ptr e) {
        try {
            if (e) std::rethrow_exception(e);
        } catch (const gdr::InputError& x) {
            PyErr_SetString(g_input_error, x.what());
        } catch (const gdr::ParameterError& x) {
            PyErr_SetString(g_parameter_error, x.what());
        } catch (const gdr::RuntimeFailure& x) {
            PyErr_SetString(g_runtime_failure, x.what());
        } catch (const gdr::Interrupted& x) {
            PyErr_SetString(g_interrupted, x.what());
        } catch (const gdr::Error& x) {
            PyErr_SetString(g_error, x.what());
        }
    });

    py::dict scope;
    scope["__name__"] = "gdr";
    py::exec(kLayersSource, scope);
    g_layers_type = scope["Layers"];
    m.attr("Layers") = g_layers_type;
    // The module may be unloaded after the interpreter's last reference; drop ours at exit.
    py::module_::import("atexit").attr("register")(py::cpp_function([] { g_layers_type = py::object(); }));

    py::class_<gdr::Progress>(m, "Progress", "Progress of a running render, as passed to render()'s callback.")
        .def_readonly("fraction", &gdr::Progress::fraction, "Done fraction in [0, 1] (of spp, or of the time budget).")
        .def_readonly("samples", &gdr::Progress::samples, "Pixel samples finished so far (all pixels).")
        .def_readonly("seconds", &gdr::Progress::seconds, "Wall time (s) since the render started.")
        .def("__repr__", [](const gdr::Progress& p) {
            return "gdr.Progress(fraction=" + std::to_string(p.fraction) + ", samples=" + std::to_string(p.samples) +
                   ", seconds=" + std::to_string(p.seconds) + ")";
        });

    py::class_<gdr::RenderStats>(m, "RenderStats", "What a render did.")
        .def_readonly("seconds", &gdr::RenderStats::seconds, "Wall time (s) of the render.")
        .def_readonly("samples", &gdr::RenderStats::samples, "Pixel samples taken (all pixels).")
        .def_readonly("rays", &gdr::RenderStats::rays, "Rays cast (intersection and shadow rays).")
        .def_readonly("spp", &gdr::RenderStats::spp, "Samples per pixel taken.")
        .def_readonly("nonfinite", &gdr::RenderStats::nonfinite, "NaN or Inf samples, dropped as zero.")
        .def_readonly("nonfinite_pixels", &gdr::RenderStats::nonfinite_pixels,
                      "The first few pixels (x, y) where a NaN or Inf sample was dropped.")
        .def("__repr__", [](const gdr::RenderStats& s) {
            return "gdr.RenderStats(spp=" + std::to_string(s.spp) + ", samples=" + std::to_string(s.samples) +
                   ", rays=" + std::to_string(s.rays) + ", seconds=" + std::to_string(s.seconds) +
                   ", nonfinite=" + std::to_string(s.nonfinite) + ")";
        });

    py::class_<PyScene, std::shared_ptr<PyScene>>(m, "Scene", "A loaded scene file, ready to render (see load_scene).",
                                                  py::dynamic_attr())
        .def_property_readonly("path", [](const PyScene& s) { return s.sf.path; }, "The file it was loaded from.")
        .def_property_readonly("width", [](const PyScene& s) { return s.sf.scene->camera().width(); },
                               "Image width (pixels).")
        .def_property_readonly("height", [](const PyScene& s) { return s.sf.scene->camera().height(); },
                               "Image height (pixels).")
        .def_property_readonly("fov", [](const PyScene& s) { return s.sf.scene->camera().desc().fov_deg; },
                               "The camera's full field of view (degrees) along fov_axis.")
        .def_property_readonly("fov_axis", [](const PyScene& s) { return std::string(1, s.sf.scene->camera().desc().fov_axis); },
                               "'x' (horizontal) or 'y' (vertical): the axis fov is measured along.")
        .def_property_readonly(
            "defaults",
            [](const PyScene& s) {
                py::dict d;
                d["integrator"] = s.sf.defaults.integrator;
                d["spp"] = s.sf.defaults.spp;
                d["seed"] = s.sf.defaults.seed;
                d["params"] = params_dict(s.sf.defaults.params);
                return d;
            },
            "The scene file's render defaults: {'integrator', 'spp', 'seed', 'params'}; render() uses them "
            "for what it is not given.")
        .def_property_readonly("warnings", [](const PyScene& s) { return s.sf.warnings; },
                               "Approximations made and elements skipped while loading (Mitsuba XML), one line each.")
        .def_property_readonly("inputs", [](const PyScene& s) { return s.sf.inputs; },
                               "Every file the scene read, scene file first.")
        .def_property_readonly("content_hash", [](const PyScene& s) { return s.sf.content_hash; },
                               "16 hex digits that change with any byte of any input (and any define).")
        .def_property_readonly("triangles", [](const PyScene& s) { return s.sf.scene->stats().triangles; },
                               "Triangles in the scene.")
        .def_property_readonly("emitters", [](const PyScene& s) { return s.sf.scene->stats().emitters; },
                               "Emitting triangles in the scene.")
        .def(
            "set_resolution",
            [](PyScene& s, int width, int height) {
                s.require_idle("change the resolution");
                gdr::set_resolution(s.sf, width, height);
            },
            py::arg("width") = 0, py::arg("height") = 0,
            "set_resolution(width=0, height=0)\n\nSets the image size (pixels), keeping the camera's position, orientation and field of view; 0 "
            "for one side keeps the aspect ratio (as gdr render --width/--height).")
        .def(
            "set_fov",
            [](PyScene& s, float degrees, const std::optional<std::string>& axis) {
                s.require_idle("change the field of view");
                if (axis && *axis != "x" && *axis != "y")
                    throw gdr::ParameterError("set_fov: axis must be 'x' or 'y', got '" + *axis + "'");
                gdr::set_fov(s.sf, degrees, axis ? (*axis)[0] : 0);
            },
            py::arg("degrees"), py::arg("axis") = py::none(),
            "set_fov(degrees, axis=None)\n\nSets the full field of view (degrees, in (0, 180)) along axis 'x' or 'y' (default: the camera's "
            "fov_axis), keeping the resolution (as gdr render --set fov=DEG).")
        .def("__repr__", [](const PyScene& s) {
            return "<gdr.Scene '" + s.sf.path + "' " + std::to_string(s.sf.scene->camera().width()) + "x" +
                   std::to_string(s.sf.scene->camera().height()) + ", " + std::to_string(s.sf.scene->stats().triangles) +
                   " triangles>";
        });

    m.def("load_scene", &load_scene, py::arg("path"), py::arg("defines") = py::none(), py::arg("lenient") = false,
          "load_scene(path, defines=None, lenient=False) -> gdr.Scene\n\n"
          "Loads a scene file: gdr's JSON, or Mitsuba 0.6/3.x XML (a name ending in .xml).\n"
          "defines: {name: value} for a Mitsuba scene's $name parameters (gdr render's -D).\n"
          "lenient: a Mitsuba scene's unsupported elements become warnings (Scene.warnings)\n"
          "instead of errors (gdr render's --lenient).\n"
          "Raises FileNotFoundError (or IsADirectoryError, PermissionError) when path cannot be\n"
          "read, gdr.InputError (a ValueError) naming the file, line or key for a malformed\n"
          "scene or a file it names.");

    m.def("render", &render, py::arg("scene"), py::kw_only(), py::arg("integrator") = py::none(),
          py::arg("spp") = py::none(), py::arg("seed") = py::none(), py::arg("threads") = 0,
          py::arg("params") = py::none(), py::arg("progress") = py::none(), py::arg("time") = 0.0,
          py::arg("first_sample") = 0, py::arg("adaptive") = 0.0, py::arg("select_gradients") = 0.0,
          "render(scene, *, integrator=None, spp=None, seed=None, threads=0, params=None, progress=None,\n"
          "       time=0.0, first_sample=0, adaptive=0.0, select_gradients=0.0) -> gdr.Layers\n\n"
          "Renders the scene and returns its layers ('color', and for gpt 'primal', 'dx', 'dy',\n"
          "'direct', 'reconstruction_l1', ...) as float32 arrays (height, width, channels) with\n"
          "the statistics in .stats (gdr.RenderStats: spp, samples, rays, seconds) and the\n"
          "settings in .metadata. The same seed and spp give the same arrays as gdr render.\n"
          "integrator, spp, seed: default to the scene file's (Scene.defaults).\n"
          "threads: worker threads, 0 for all cores.\n"
          "params: integrator parameters {key: bool|int|float|str} over the scene's (gdr render's\n"
          "--set; gdr.integrators() lists the integrators). Unknown keys raise gdr.ParameterError.\n"
          "progress: called as progress(gdr.Progress) on this thread about every 0.05 s while\n"
          "the render advances, and once at its end.\n"
          "time: > 0 renders whole passes until that many seconds have passed, instead of spp.\n"
          "first_sample: the index of the first sample per pixel (continuing a sequence).\n"
          "adaptive: > 0 samples adaptively (gdr render --adaptive): a pilot of that share of the\n"
          "budget sets each pixel's density; 'spp' and 'sample_density' record counts and density.\n"
          "select_gradients: > 0, gpt only (gdr render --select-gradients): pilots of that share\n"
          "choose per tile whether gradients pay; the others take primal-only samples\n"
          "('gradient_mask', 'sample_density').\n"
          "The GIL is released while rendering. Ctrl-C (KeyboardInterrupt), or any exception\n"
          "raised by the progress callback, stops the render within about a second; the\n"
          "exception is raised when the render has stopped, and the partial image is discarded.");

    m.def("reconstruct", &reconstruct, py::arg("primal"), py::arg("dx"), py::arg("dy"),
          py::arg("method") = "poisson-l1", py::arg("direct") = py::none(),
          "reconstruct(primal, dx, dy, method='poisson-l1', direct=None, **params) -> array\n\n"
          "The image reconstructed from a gradient-domain render's buffers (arrays of shape\n"
          "(height, width[, channels]), all of one shape): dx(x, y) = I(x+1, y) - I(x, y) at the\n"
          "left pixel, dy(x, y) = I(x, y+1) - I(x, y) at the top pixel (rows downwards).\n"
          "direct, if given, is added after solving (directly visible emitters).\n"
          "method: any registered reconstructor (gdr.reconstructors()); params are its parameters,\n"
          "e.g. alpha=0.2, iterations=20 for poisson-l1. Mismatched shapes, unknown methods or\n"
          "parameters raise gdr.ParameterError; NaN or Inf in an input gdr.InputError.");

    m.def("read_exr", &read_exr, py::arg("path"),
          "read_exr(path) -> gdr.Layers\n\n"
          "Reads every layer of an EXR ('L.R/G/B[/A]' -> layer L of 3 or 4 channels, 'L.Y' -> 1\n"
          "channel, bare R, G, B -> 'color') as float32 arrays; .metadata holds the header's\n"
          "string attributes (a gdr render's settings). Raises FileNotFoundError for a missing\n"
          "file, gdr.InputError for a malformed one.");

    m.def("write_exr", &write_exr, py::arg("path"), py::arg("layers"), py::arg("metadata") = py::none(),
          "write_exr(path, layers, metadata=None)\n\n"
          "Writes {name: array (height, width[, channels]), 1 to 4 channels} as one multi-layer\n"
          "32-bit float EXR, as gdr render writes its layers, with metadata {str: str} (default:\n"
          "layers.metadata of a gdr.Layers) as header attributes. Like gdr's C++ write_exr, it\n"
          "replaces an existing file at path (only the gdr tool refuses to overwrite its inputs).\n"
          "Layers of different sizes raise gdr.ParameterError, NaN or Inf gdr.InputError naming\n"
          "the layer and pixel, and a failed write OSError.");

    m.def("integrators", [] { return registry_dict(gdr::integrator_registry()); },
          "integrators() -> {name: description} of the registered integrators (render's integrator=).");
    m.def("shifts", [] { return registry_dict(gdr::shift_registry()); },
          "shifts() -> {name: description} of the registered shift mappings (gpt's params={'shift': name}).");
    m.def("reconstructors", [] { return registry_dict(gdr::reconstructor_registry()); },
          "reconstructors() -> {name: description} of the registered reconstructors (reconstruct's method=).");
    m.def(
        "integrator_defaults",
        [](const std::string& name) {
            // describe() states every parameter with its value, one "key=value" line each.
            gdr::Params parsed("integrator_defaults");
            const std::string text = gdr::integrator_registry().create(name, gdr::Params("defaults"))->describe();
            for (size_t at = 0; at < text.size();) {
                const size_t end = std::min(text.find('\n', at), text.size());
                if (end > at) parsed.set_from_text(text.substr(at, end - at));
                at = end + 1;
            }
            return params_dict(parsed);
        },
        py::arg("name"),
        "integrator_defaults(name) -> {key: value}: the integrator's parameters and their defaults.");

    py::module_ metrics = m.def_submodule(
        "metrics",
        "Image error metrics of an image against a reference (arrays of one shape, (height, width[, channels])),\n"
        "averaged over pixels and channels; shapes that differ raise gdr.ParameterError, NaN or Inf gdr.InputError.");
    metrics.def(
        "mse",
        [](const py::object& a, const py::object& b) {
            auto [x, r] = image_pair(a, b, "mse");
            return gdr::mse(x, r);
        },
        py::arg("image"), py::arg("reference"), "mse(image, reference) -> mean of (x - r)^2 (radiance^2).");
    metrics.def(
        "mae",
        [](const py::object& a, const py::object& b) {
            auto [x, r] = image_pair(a, b, "mae");
            return gdr::mae(x, r);
        },
        py::arg("image"), py::arg("reference"), "mae(image, reference) -> mean of |x - r| (radiance).");
    metrics.def(
        "relmse",
        [](const py::object& a, const py::object& b, float eps, bool grey) {
            auto [x, r] = image_pair(a, b, "relmse");
            return gdr::relmse(x, r, gdr::RelMseOptions{eps, grey});
        },
        py::arg("image"), py::arg("reference"), py::kw_only(), py::arg("eps") = 0.01f, py::arg("grey_denominator") = false,
        "relmse(image, reference, *, eps=0.01, grey_denominator=False) -> relative MSE (unitless):\n"
        "mean of (x - r)^2 / (d + eps), d = r_c^2 (the thesis convention, the default) or, with\n"
        "grey_denominator, (mean_c r_c)^2 (the later neural convention uses eps=0.001 with it).");
    metrics.def(
        "ssim",
        [](const py::object& a, const py::object& b, bool srgb) {
            auto [x, r] = image_pair(a, b, "ssim");
            return gdr::ssim(x, r, gdr::SsimOptions{srgb});
        },
        py::arg("image"), py::arg("reference"), py::kw_only(), py::arg("srgb") = false,
        "ssim(image, reference, *, srgb=False) -> structural similarity (1 = identical; Wang et al. 2004)\n"
        "with an 11x11 Gaussian window on values clamped to [0, 1], sRGB-encoded first with srgb.");
    metrics.def(
        "compare_report",
        [](const py::object& a, const py::object& b) {
            auto [x, r] = image_pair(a, b, "compare_report");
            return gdr::compare_report(x, r);
        },
        py::arg("image"), py::arg("reference"),
        "compare_report(image, reference) -> str: every metric with its convention and the channel means, "
        "as gdr compare prints them.");
    metrics.def(
        "box_downsample",
        [](const py::object& a, int factor) { return to_array(gdr::box_downsample(to_image(a, "box_downsample"), factor)); },
        py::arg("image"), py::arg("factor"),
        "box_downsample(image, factor) -> array: each output pixel the mean of a factor x factor block "
        "(factor must divide both sides).");

    bind_package(m);
    // The Python half of the module (python/gdr_api.py): wrappers that add Python's own manners.
    py::exec(kApiSource, m.attr("__dict__"));
}
