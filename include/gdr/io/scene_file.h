// JSON scene files: camera, OBJ meshes with transforms, material overrides by
// name, and render defaults. Paths inside are relative to the scene file.
//
//   {
//     "camera": {"position": [0,1,3.5], "target": [0,1,0], "up": [0,1,0],
//                "fov": 45, "fov_axis": "y", "width": 512, "height": 512},
//        (or {"file": "camera.json", "width": 256} to read a camera.json and override keys;
//         one of width/height alone keeps the camera file's aspect ratio)
//     "meshes": [{"file": "box.obj",
//                 "transform": {"scale": 1, "rotate": [0,1,0,90], "translate": [0,0,0]}}],
//        (transform may instead be {"matrix": [16 numbers, row-major]})
//     "materials": {"sphere": {"type": "roughconductor", "ks": [0.9,0.9,0.9], "alpha": 0.1}},
//     "render": {"integrator": "pt", "spp": 64, "seed": 0, "params": {"max_depth": 16}},
//     "animation": {"first": 0, "last": 47, "fps": 24}
//   }
//
// Animation (gdr/scene/animation.h): with an "animation" block, a mesh entry
// may hold "keys": [{"frame": 0, "translate": [x,y,z], "rotate": [ax,ay,az,deg]
// or "quaternion": [w,x,y,z], "scale": s or [sx,sy,sz]}, ...], applied after
// its "transform", and the camera "keys": [{"frame": 0, "position", "target",
// "up"} or {"frame": 0, "matrix": [16 numbers, row-major camera-to-world]}].
// Frames strictly increase and may be fractional.
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "gdr/core/params.h"
#include "gdr/scene/animated_scene.h"
#include "gdr/scene/scene.h"

namespace gdr {

/// Render defaults stored in a scene file (the CLI may override each).
struct RenderDefaults {
    std::string integrator = "pt";  ///< Integrator name.
    long long spp = 16;             ///< Samples per pixel.
    long long seed = 0;             ///< Sampler seed.
    Params params{"scene file"};    ///< Integrator parameters.
};

/// What one entry of a scene file's `meshes` contributed, so that a truncated or
/// partly unreadable mesh shows in the load report instead of passing unnoticed.
struct MeshStats {
    std::string file;               ///< The OBJ as opened: the scene file's directory joined with its name.
    size_t triangles = 0;           ///< Triangles read from it (polygons triangulated), zero-area ones included.
    size_t degenerate_skipped = 0;  ///< Of those, zero-area triangles the Scene dropped.
};

struct SceneEditState;

/// A loaded scene file.
struct SceneFile {
    std::unique_ptr<Scene> scene;  ///< The scene, ready to render.
    RenderDefaults defaults;       ///< Render settings from the file.
    std::string path;              ///< The file it came from.
    std::vector<MeshStats> meshes; ///< One per `meshes` entry, in the file's order.
    /// Every file the scene read (scene file first, then camera file, OBJs, MTL
    /// libraries, textures), each once, in the order first read; paths as opened.
    std::vector<std::string> inputs;
    /// scene_content_hash(path, inputs): 16 hex digits that change with any byte
    /// or name of any input (and with a Mitsuba scene's -D values), e.g. to
    /// refuse resuming a render of an edited scene.
    std::string content_hash;
    /// Approximations made and elements skipped while loading (Mitsuba XML),
    /// one line each, naming the file and line; empty for JSON scene files.
    std::vector<std::string> warnings;
    /// The scene at every frame, for a file with an `animation` block; null
    /// for a still scene. `scene` is then its frame `frame`.
    std::shared_ptr<AnimatedScene> animation;
    /// The frame `scene` shows (animation->range().first after loading); 0 for a still scene.
    int frame = 0;
    /// What edit_material, edit_mesh_transform and edit_environment need (the
    /// meshes' untransformed vertices, the materials' descriptions before the
    /// scene file's overrides): kept for a still JSON scene loaded with
    /// `editable`, else null.
    std::shared_ptr<SceneEditState> edit;
};

/// Options of load_scene_file that only Mitsuba XML scenes take.
struct SceneFileOptions {
    /// Values of the scene's $parameters, as Mitsuba's `-D name=value`; they
    /// override the scene's <default> elements.
    std::map<std::string, std::string> defines;
    /// Unsupported elements become one warning each and are skipped (or
    /// replaced, as the warning says) instead of an error.
    bool lenient = false;
    /// Keep what editing the loaded scene in place needs (SceneFile::edit):
    /// a copy of the meshes' untransformed vertices, normals and uvs.
    bool editable = false;
    /// A Mitsuba XML scene's text, read in place of the file `path` names (which
    /// then need not exist; relative paths are still resolved from its
    /// directory, and content_hash covers the text): a scene made in memory.
    std::string text;
};

/// Loads a scene file: Mitsuba XML (a name ending in .xml, or text starting
/// with '<'; see gdr/io/mitsuba_xml.h) or gdr's JSON. Throws InputError as the
/// format's loader does, and for `defines` given to a JSON scene.
SceneFile load_scene_file(const std::string& path, const SceneFileOptions& options);

/// Loads a JSON scene file (or a Mitsuba XML one, as load_scene_file(path, {})); throws InputError naming the file (and key, line)
/// when it is missing, a directory, malformed, gives a key twice, names unknown
/// keys or references missing or malformed meshes.
SceneFile load_scene_file(const std::string& path);

/// Loads a scene from JSON text in the scene file format (a Python dict's
/// json.dumps, say), as load_scene_file() loads a file: `name` stands for the
/// file in messages and SceneFile::path, and relative paths inside are
/// resolved from its directory. A mesh may also be given by its arrays:
/// {"vertices": [[x, y, z], ...], "triangles": [[i, j, k], ...] (0-based),
/// "material": NAME, "transform": {...}}, where the `materials` entry NAME
/// defines the material ("type" and its values over MTL defaults); its faces
/// are flat. content_hash covers the text and every file it names.
SceneFile load_scene_text(const std::string& text, const std::string& name, bool editable = false);

/// The content_hash load_scene_text(text, name) gives a scene that read the
/// files `inputs` (as the loaded SceneFile::inputs), without loading it: the
/// hash of a scene edited in place is that of the edited description.
std::string scene_text_hash(const std::string& text, const std::string& name, const std::vector<std::string>& inputs);

/// Replaces the scene-file values of material `name` (the scene file's
/// materials.NAME, a JSON object given as text, e.g. {"type": "plastic",
/// "kd": [0.5, 0.5, 0.5], "alpha": 0.1}) and rebuilds, in place, the BSDF and
/// emitted radiance of every material of that name as loading would have
/// (see Scene::set_material: light distribution refreshed where the emission
/// changes; a map_kd image is read again). Needs an editable still scene (ParameterError otherwise);
/// InputError naming materials.NAME.KEY for a bad value.
void edit_material(SceneFile& sf, const std::string& name, const std::string& fields_json);

/// The description material `name` would be built from with the scene-file
/// values `fields_json` (as edit_material takes them): its MTL values with
/// those over them (colours unitless or W/(m^2 sr), pr the GGX alpha or
/// negative, ns the Phong exponent, ni the index of refraction); e.g. to list
/// the values a material has without the scene file giving them. Errors as edit_material's.
MaterialDesc material_description(SceneFile& sf, const std::string& name, const std::string& fields_json);

/// Sets mesh entry `index`'s transform (the scene file's meshes[i].transform,
/// JSON text; "null" for none) and moves its triangles in place from their
/// untransformed vertices, as loading would place them (Scene::set_object_geometry
/// rebuilds the BVH and the light distribution). ParameterError for a scene
/// that is not editable, an index out of range, or a transform that makes a
/// different set of its triangles zero-area than the current one (loading
/// drops those); InputError naming meshes[i].transform for a malformed one.
void edit_mesh_transform(SceneFile& sf, size_t index, const std::string& transform_json);

/// Replaces the environment (the scene file's environment, JSON text; "null"
/// removes it) and with it the light-selection distribution. An envmap's
/// image is read again.
void edit_environment(SceneFile& sf, const std::string& environment_json);
/// The folder of the larger public scenes (the bathroom, the Mitsuba test
/// scenes), which a JSON scene file names as "$GDR_SCENES/...": the environment
/// variable GDR_SCENES where it is set and not empty, else the build's CMake
/// setting GDR_SCENES (by default ../shared/scenes beside the source tree).
std::string scenes_dir();

/// FNV-1a 64 hash, as 16 lowercase hex digits, of the files `inputs` in the given
/// order: each one's path relative to the directory of `scene_path`, its size
/// and its bytes. A copy of the whole scene elsewhere hashes the same. Throws
/// InputError naming a file that cannot be read.
std::string scene_content_hash(const std::string& scene_path, const std::vector<std::string>& inputs);

/// Rebuilds the scene's camera at `width` x `height` pixels, keeping its position,
/// orientation and field of view along its fov_axis. 0 for one side keeps the
/// camera's aspect ratio (that side rounded to the nearest pixel, at least 1).
/// Throws ParameterError for a negative side, both sides 0, or a resolution the
/// camera rejects. An animation's later frames (set_frame, scene_at) get it too.
void set_resolution(SceneFile& sf, int width, int height);

/// Replaces sf.scene by the animation's frame `frame` (time t = frame, an
/// instant: no motion blur), keeping the camera's resolution and field of
/// view. Throws InputError for a still scene, ParameterError for a frame
/// outside the animation's range.
void set_frame(SceneFile& sf, int frame);

/// Rebuilds the scene's camera with a full field of view of `fov_deg` degrees,
/// in (0, 180), along `axis`: 'x' horizontal, 'y' vertical, 0 the camera's own
/// fov_axis. The resolution is kept. Throws ParameterError for an angle or axis
/// out of range. An animation's later frames get it too.
void set_fov(SceneFile& sf, float fov_deg, char axis = 0);

/// Loads one OBJ (+ MTL) into `mesh` and `materials`, applying a 4x4 transform;
/// material overrides replace MTL materials by name. Throws InputError naming the file.
void load_obj(const std::string& path, const Mat4& transform, TriangleMesh& mesh, std::vector<Material>& materials);

}  // namespace gdr
