// Loading the gdr tool's plugins (gdr/cli/plugins.h).
#include "gdr/cli/plugins.h"

#include <dlfcn.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>

#include "gdr/core/error.h"

namespace gdr::cli {

namespace fs = std::filesystem;

namespace {

PluginLoad load_once() {
    PluginLoad r;
    r.searched = plugin_search_dirs();
    for (const std::string& dir : r.searched) {
        const fs::path file = fs::path(dir) / kNeuralPluginFile;
        std::error_code ec;
        if (!fs::is_regular_file(file, ec)) continue;
        r.path = file.string();
        // libtorch's OpenMP threads spin after each parallel region by
        // default, taking CPU from the tool's own threads (the EXR write after
        // the inference): gdr reconstruct --method neural of a 1280x720 render
        // took 4.5-4.9 s of user CPU (6.2-6.9 s wall) without it and 3.5-3.8 s
        // (5.2-5.8 s wall) with PASSIVE. OpenMP reads the variable when it is
        // loaded, with the plugin; a value the user set is kept.
        setenv("OMP_WAIT_POLICY", "PASSIVE", 0);
        // RTLD_LOCAL: the plugin's own copy of libgdr must not take the place
        // of the tool's symbols, nor theirs its own.
        void* handle = dlopen(r.path.c_str(), RTLD_NOW | RTLD_LOCAL);
        if (!handle) {
            const char* e = dlerror();
            r.error = e ? e : "dlopen failed";
            return r;
        }
        const auto abi = reinterpret_cast<decltype(&gdr_plugin_abi)>(dlsym(handle, "gdr_plugin_abi"));
        const auto add =
            reinterpret_cast<decltype(&gdr_plugin_register_reconstructors)>(dlsym(handle, "gdr_plugin_register_reconstructors"));
        if (!abi || !add) {
            r.error = "it exports no gdr_plugin_abi / gdr_plugin_register_reconstructors: not a gdr plugin";
            dlclose(handle);
            return r;
        }
        if (std::strcmp(abi(), GDR_PLUGIN_ABI) != 0) {
            r.error = std::string("it was built for ") + abi() + ", this gdr is " + GDR_PLUGIN_ABI +
                      " (build and install the two together)";
            dlclose(handle);
            return r;
        }
        add(&reconstructor_registry());
        r.loaded = true;
        return r;
    }
    return r;
}

std::string joined(const std::vector<std::string>& v) {
    std::string s;
    for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
    return s;
}

}  // namespace

std::vector<std::string> plugin_search_dirs() {
    std::vector<std::string> dirs;
    if (const char* env = std::getenv("GDR_PLUGIN_PATH")) {
        const std::string s = env;
        for (size_t pos = 0; pos <= s.size();) {
            const size_t colon = std::min(s.find(':', pos), s.size());
            if (colon > pos) dirs.push_back(s.substr(pos, colon - pos));
            pos = colon + 1;
        }
        return dirs;
    }
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) dirs.push_back((exe.parent_path() / GDR_PLUGIN_DIR_FROM_BIN).lexically_normal().string());
    return dirs;
}

const PluginLoad& load_reconstructor_plugins() {
    static std::once_flag once;
    static PluginLoad result;
    std::call_once(once, [] { result = load_once(); });
    return result;
}

void require_reconstructor(const std::string& method, const std::string& context) {
    if (reconstructor_registry().has(method)) return;
    const PluginLoad& p = load_reconstructor_plugins();
    if (reconstructor_registry().has(method) || method != "neural") return;
    if (!p.path.empty())
        throw ParameterError(context + ": the neural reconstructor's plugin " + p.path + " could not be loaded: " +
                             (p.error.empty() ? "it registers no 'neural'" : p.error));
    const std::string where = p.searched.empty() ? "GDR_PLUGIN_PATH is set but empty, so no directory was searched"
                                                 : std::string("no ") + kNeuralPluginFile + " in " + joined(p.searched);
    throw ParameterError(context + ": the neural reconstructor was not built (" + where +
                         "). It needs libtorch: run scripts/install-deps.sh, which installs libtorch-dev, then configure "
                         "and build gdr again with GDR_BUILD_NEURAL=ON (the default); CMake then prints 'neural "
                         "reconstructor: built'. GDR_PLUGIN_PATH=DIR[:DIR...] sets where the plugin is looked for");
}

void require_reconstructors_of(const Params& integrator_params, const std::string& context) {
    const auto it = integrator_params.values().find("reconstruct");
    if (it == integrator_params.values().end()) return;
    const std::string choice = to_string(it->second);
    if (choice == "neural") require_reconstructor("neural", context + " (reconstruct=neural)");
}

}  // namespace gdr::cli
