// The neural reconstructor as a plugin of the gdr tool (gdr/plugin.h).
// The tool loads this library, and libtorch with it, only when a run asks for
// the method, so its other runs start without libtorch's load time.
//
// weights defaults to the shipped model, looked for at
// <this library's directory>/GDR_DATA_DIR_FROM_PLUGIN/neural/GDR_SHIPPED_MODEL:
// installed, <libdir>/gdr/libgdr_neural_plugin.so finds
// <datadir>/gdr/neural/unet-v2.pt; the build copies the model to the same
// relative place in the build tree (build/share/gdr/neural).
#include <dlfcn.h>

#include <filesystem>
#include <string>

#include "gdr/plugin.h"
#include "gdr/neural/neural_reconstructor.h"

namespace {

namespace fs = std::filesystem;

// The expected path of the shipped model, from where this library was loaded ("" if unknown).
std::string shipped_model_path() {
    Dl_info info{};
    if (dladdr(reinterpret_cast<void*>(&shipped_model_path), &info) == 0 || !info.dli_fname) return "";
    const fs::path lib = fs::absolute(info.dli_fname);
    return (lib.parent_path() / GDR_DATA_DIR_FROM_PLUGIN / "neural" / GDR_SHIPPED_MODEL).lexically_normal().string();
}

void add_neural(gdr::PluginRegistries& registries) {
    const std::string model = shipped_model_path();
    std::error_code ec;
    const bool found = !model.empty() && fs::is_regular_file(model, ec);
    gdr::neural::register_neural_reconstructor(
        *registries.reconstructors, found ? model : "",
        found ? "" : "the shipped model " + std::string(GDR_SHIPPED_MODEL) + " is not at " + (model.empty() ? "(the plugin's directory is unknown)" : model));
}

}  // namespace

GDR_EXPORT_PLUGIN(add_neural)
