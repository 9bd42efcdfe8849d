// JSON scene files: camera, OBJ meshes with transforms, material overrides by
// name, and render defaults. Paths inside are relative to the scene file.
//
//   {
//     "camera": {"position": [0,1,3.5], "target": [0,1,0], "up": [0,1,0],
//                "fov": 45, "fov_axis": "y", "width": 512, "height": 512},
//        (or {"file": "camera.json", "width": 256} to read a camera.json and override keys)
//     "meshes": [{"file": "box.obj",
//                 "transform": {"scale": 1, "rotate": [0,1,0,90], "translate": [0,0,0]}}],
//        (transform may instead be {"matrix": [16 numbers, row-major]})
//     "materials": {"sphere": {"type": "roughconductor", "ks": [0.9,0.9,0.9], "alpha": 0.1}},
//     "render": {"integrator": "pt", "spp": 64, "seed": 0, "params": {"max_depth": 16}}
//   }
#pragma once

#include <memory>
#include <string>

#include "gdr/core/params.h"
#include "gdr/scene/scene.h"

namespace gdr {

/// Render defaults stored in a scene file (the CLI may override each).
struct RenderDefaults {
    std::string integrator = "pt";  ///< Integrator name.
    long long spp = 16;             ///< Samples per pixel.
    long long seed = 0;             ///< Sampler seed.
    Params params{"scene file"};    ///< Integrator parameters.
};

/// A loaded scene file.
struct SceneFile {
    std::unique_ptr<Scene> scene;  ///< The scene, ready to render.
    RenderDefaults defaults;       ///< Render settings from the file.
    std::string path;              ///< The file it came from.
};

/// Loads a JSON scene file; throws InputError naming the file (and key) when it
/// is missing, malformed, names unknown keys or references missing meshes.
SceneFile load_scene_file(const std::string& path);

/// Loads one OBJ (+ MTL) into `mesh` and `materials`, applying a 4x4 transform;
/// material overrides replace MTL materials by name. Throws InputError naming the file.
void load_obj(const std::string& path, const Mat4& transform, TriangleMesh& mesh, std::vector<Material>& materials);

}  // namespace gdr
