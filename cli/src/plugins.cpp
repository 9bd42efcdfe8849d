// Loading the gdr tool's plugins (gdr/cli/plugins.h).
#include "gdr/cli/plugins.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <mutex>

#include "gdr/core/error.h"
#include "gdr/integrators/gpt.h"

namespace gdr::cli {

namespace fs = std::filesystem;

namespace {

PluginLoad load_once() {
    // libtorch's OpenMP threads spin after each parallel region by
    // default, taking CPU from the tool's own threads (the EXR write after
    // the inference): gdr reconstruct --method neural of a 1280x720 render
    // took 4.5-4.9 s of user CPU (6.2-6.9 s wall) without it and 3.5-3.8 s
    // (5.2-5.8 s wall) with PASSIVE. OpenMP reads the variable when it is
    // loaded, with the neural plugin; a value the user set is kept. The tool
    // sets it, not the library: the process's environment is the program's.
    setenv("OMP_WAIT_POLICY", "PASSIVE", 0);
    return load_plugins_from(plugin_search_dirs());
}

std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
    return s;
}

// The plugin files that were not used, with why, for a name that stayed unknown.
std::string skipped_note(const PluginLoad& p) {
    std::string s;
    for (const auto& [file, why] : p.skipped) s += "; skipped plugin " + file + ": " + why;
    if (p.searched.empty()) s += "; no plugin directory was searched (GDR_PLUGIN_PATH is set but empty)";
    return s;
}

template <typename Base>
void require(const Registry<Base>& registry, const char* kind, const std::string& name, const std::string& context) {
    if (registry.has(name)) return;
    const PluginLoad& p = load_plugins();
    if (registry.has(name)) return;
    throw ParameterError(context + ": unknown " + kind + " '" + name + "' (available: " + joined(registry.names()) +
                         ")" + skipped_note(p));
}

}  // namespace

std::vector<std::string> plugin_search_dirs() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    // Without the executable's path (no /proc), only $GDR_PLUGIN_PATH's.
    if (ec) return plugin_path_dirs({});
    return plugin_path_dirs({(exe.parent_path() / GDR_PLUGIN_DIR_FROM_BIN).lexically_normal().string()});
}

const PluginLoad& load_plugins() {
    static std::once_flag once;
    static PluginLoad result;
    std::call_once(once, [] { result = load_once(); });
    return result;
}

void require_reconstructor(const std::string& method, const std::string& context) {
    if (method != "neural") return require(reconstructor_registry(), "reconstructor", method, context);
    if (reconstructor_registry().has(method)) return;
    const PluginLoad& p = load_plugins();
    if (reconstructor_registry().has(method)) return;
    // The one plugin gdr builds itself: say how to build it, or why it could not be used.
    for (const auto& [file, why] : p.skipped)
        if (fs::path(file).filename() == kNeuralPluginFile)
            throw ParameterError(context + ": the neural reconstructor's plugin " + file + " could not be loaded: " + why);
    const std::string where = p.searched.empty() ? "GDR_PLUGIN_PATH is set but empty, so no directory was searched"
                                                 : std::string("no ") + kNeuralPluginFile + " in " + joined(p.searched);
    throw ParameterError(context + ": the neural reconstructor was not built (" + where +
                         "). It needs libtorch: run scripts/install-deps.sh, which installs libtorch-dev, then configure "
                         "and build gdr again with GDR_BUILD_NEURAL=ON (the default); CMake then prints 'neural "
                         "reconstructor: built'. GDR_PLUGIN_PATH=DIR[:DIR...] sets where the plugin is looked for");
}

void require_shift(const std::string& name, const std::string& context) {
    require(shift_registry(), "shift mapping", name, context);
}

void require_integrator(const std::string& name, const std::string& context) {
    require(integrator_registry(), "integrator", name, context);
}

void require_plugins_of(const Params& integrator_params, const std::string& context) {
    const auto& values = integrator_params.values();
    if (const auto it = values.find("reconstruct"); it != values.end()) {
        const std::string choice = to_string(it->second);
        for (const std::string& m : GradientReconstructions::methods_of(choice, context))
            require_reconstructor(m, context + " (reconstruct=" + choice + ")");
    }
    if (const auto it = values.find("shift"); it != values.end()) {
        const std::string shift = to_string(it->second);
        if (shift != "combined") {
            require_shift(shift, context + " (shift=" + shift + ")");
        } else if (const auto two = values.find("shifts"); two != values.end()) {
            const std::string list = to_string(two->second);
            for (size_t pos = 0; pos < list.size();) {
                const size_t comma = std::min(list.find(',', pos), list.size());
                if (comma > pos) require_shift(list.substr(pos, comma - pos), context + " (shifts=" + list + ")");
                pos = comma + 1;
            }
        }
    }
}

}  // namespace gdr::cli
