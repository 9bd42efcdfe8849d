// Loading plugin libraries (gdr/plugin.h).
#include "gdr/plugin.h"

#include <cstdlib>

#include <dlfcn.h>

#include <algorithm>
#include <cstring>
#include <exception>
#include <filesystem>

namespace gdr {

const char* plugin_abi() { return GDR_PLUGIN_ABI; }

std::string load_plugin(const std::string& file) {
    // RTLD_LOCAL: the plugin's own copy of libgdr must not take the place of
    // the program's symbols, nor theirs its own.
    void* handle = dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char* e = dlerror();
        return e ? e : "dlopen failed";
    }
    const auto abi = reinterpret_cast<decltype(&gdr_plugin_abi)>(dlsym(handle, "gdr_plugin_abi"));
    const auto add = reinterpret_cast<decltype(&gdr_plugin_register)>(dlsym(handle, "gdr_plugin_register"));
    if (!abi || !add) {
        dlclose(handle);
        return "it exports no gdr_plugin_abi / gdr_plugin_register: not a gdr plugin";
    }
    if (std::strcmp(abi(), plugin_abi()) != 0) {
        const std::string why = std::string("it was built for ") + abi() + ", this gdr is " + plugin_abi() +
                                " (build and install the two together)";
        dlclose(handle);
        return why;
    }
    PluginRegistries regs{&integrator_registry(), &reconstructor_registry(), &shift_registry()};
    try {
        add(&regs);
    } catch (const std::exception& e) {
        // What it registered before failing stays: the library stays loaded.
        return std::string("its registration failed: ") + e.what();
    }
    return "";
}

PluginLoad load_plugins_from(const std::vector<std::string>& dirs) {
    namespace fs = std::filesystem;
    PluginLoad r;
    r.searched = dirs;
    // A later registration of a name replaces an earlier one, so the
    // directories are loaded last to first: the earlier directory wins.
    for (auto dir = dirs.rbegin(); dir != dirs.rend(); ++dir) {
        std::error_code ec;
        std::vector<std::string> files;
        for (fs::directory_iterator it(*dir, ec), end; !ec && it != end; it.increment(ec))
            if (it->path().extension() == ".so" && fs::is_regular_file(it->path(), ec)) files.push_back(it->path().string());
        std::sort(files.begin(), files.end());
        for (const std::string& file : files) {
            const std::string why = load_plugin(file);
            if (why.empty()) r.loaded.push_back(file);
            else r.skipped.emplace_back(file, why);
        }
    }
    return r;
}

std::vector<std::string> plugin_path_dirs(std::vector<std::string> fallback) {
    const char* env = std::getenv("GDR_PLUGIN_PATH");
    if (!env) return fallback;
    std::vector<std::string> dirs;
    const std::string s = env;
    for (size_t pos = 0; pos <= s.size();) {
        const size_t colon = std::min(s.find(':', pos), s.size());
        if (colon > pos) dirs.push_back(s.substr(pos, colon - pos));
        pos = colon + 1;
    }
    return dirs;
}

}  // namespace gdr
