// The entry point of a plugin library: a shared library that adds
// integrators, reconstructors or shift mappings to the gdr tool's registries.
// The tool looks for plugins in its plugin directories (see the tool's
// documentation: <libdir>/gdr beside its executable, or $GDR_PLUGIN_PATH) and
// loads them when a run names something that is not registered.
//
// A plugin is one source file that defines its registration and exports it:
//
//     #include "gdr/plugin.h"
//     void add_mine(gdr::PluginRegistries& r) {
//         gdr::register_shift<MyShift>(*r.shifts, "what it does");
//         r.reconstructors->add("mine", "what it does", [](const gdr::Params& p) { ... });
//     }
//     GDR_EXPORT_PLUGIN(add_mine)
//
// built as a MODULE library with GDR_PLUGIN_ABI defined to gdr's own build
// identity (CMake's variable of that name where gdr is built). A plugin and
// the tool share C++ types (Registry, Params, Image) by layout, so the tool
// uses a plugin only if its identity equals the tool's.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "gdr/integrators/integrator.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/registry.h"
#include "gdr/shift/shift.h"

namespace gdr {

/// The registries a plugin adds to: the tool's process-wide ones.
struct PluginRegistries {
    Registry<Integrator>* integrators = nullptr;        ///< integrator_registry()
    Registry<Reconstructor>* reconstructors = nullptr;  ///< reconstructor_registry()
    Registry<Shift>* shifts = nullptr;                  ///< shift_registry()
};

/// This build's identity (gdr version, compiler and its version, C++
/// standard): a plugin is used only if its gdr_plugin_abi() returns the same.
const char* plugin_abi();

/// Loads plugin library `file` with dlopen and registers what it adds into
/// the process-wide registries. Returns "" if it registered, else why it was
/// not used (dlopen's error, not a gdr plugin, built for another identity,
/// its registration threw: what it registered before stays). Never throws.
/// A loaded plugin is never unloaded (the registries hold its factories);
/// loading a file twice registers it twice, so callers keep track.
std::string load_plugin(const std::string& file);

/// What load_plugins_from() found.
struct PluginLoad {
    std::vector<std::string> loaded;                            ///< Plugin files loaded and registered.
    std::vector<std::pair<std::string, std::string>> skipped;  ///< Files not used, each with why.
    std::vector<std::string> searched;                          ///< The directories searched.
};

/// Loads every NAME.so in `dirs` (in file-name order within a directory)
/// with load_plugin(); where two plugins register one name, the one of the
/// earlier directory wins. A missing directory is skipped. Never throws.
PluginLoad load_plugins_from(const std::vector<std::string>& dirs);

/// The plugin directories a program searches: those of $GDR_PLUGIN_PATH
/// (colon-separated; set but empty: none), or `fallback` where the variable
/// is unset (the gdr tool's is beside its executable, the benchmarks' the
/// build tree's, the Python module's beside the module).
std::vector<std::string> plugin_path_dirs(std::vector<std::string> fallback);

}  // namespace gdr

/// The entry points a plugin exports (C linkage, so that dlsym finds them by
/// these names); GDR_EXPORT_PLUGIN defines both.
extern "C" {
/// The build identity of the plugin; the tool refuses one that differs from its own.
const char* gdr_plugin_abi();
/// Adds the plugin's integrators, reconstructors and shifts to the registries given.
void gdr_plugin_register(gdr::PluginRegistries* registries);
}

/// Defines the two entry points of a plugin whose registration is
/// `void fn(gdr::PluginRegistries&)`; needs GDR_PLUGIN_ABI (a string) defined.
#define GDR_EXPORT_PLUGIN(fn)                                                                          \
    extern "C" __attribute__((visibility("default"))) const char* gdr_plugin_abi() { return GDR_PLUGIN_ABI; } \
    extern "C" __attribute__((visibility("default"))) void gdr_plugin_register(gdr::PluginRegistries* r) { fn(*r); }
