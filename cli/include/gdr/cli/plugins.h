// Plugins of the gdr tool: shared libraries, loaded on demand with dlopen(),
// that add reconstructors to the process-wide registry. The neural
// reconstructor is one: it needs libtorch, whose loading costs about 0.8 s,
// so only the runs that use it pay for it.
//
// Where plugins are looked for, in order:
//   - the directories of $GDR_PLUGIN_PATH (colon-separated), if it is set
//     (set but empty: none, so no plugin is loaded);
//   - otherwise <directory of the running executable>/GDR_PLUGIN_DIR_FROM_BIN,
//     the path from the install's bindir to <libdir>/gdr that CMake computes
//     (../lib/gdr by default): an installed bin/gdr finds lib/gdr, and the
//     build tree has the same layout (build/bin/gdr, build/lib/gdr).
//
// A plugin and the tool share C++ types (Registry, Params, Image) by layout,
// so a plugin is used only if its gdr_plugin_abi() equals the tool's (same
// gdr version, compiler and language standard). Loaded plugins are never
// unloaded: the registry holds their factories.
#pragma once

#include <string>
#include <vector>

#include "gdr/core/params.h"
#include "gdr/reconstruct/reconstructor.h"

/// The entry points a plugin exports (C linkage, so that dlsym finds them by
/// these names). The tool only looks them up; each plugin defines them.
extern "C" {
/// The build identity of the plugin; the tool refuses one that differs from its own.
const char* gdr_plugin_abi();
/// Adds the plugin's reconstructors to `registry` (the tool's process-wide one).
void gdr_plugin_register_reconstructors(gdr::Registry<gdr::Reconstructor>* registry);
}

namespace gdr::cli {

/// File name of the neural reconstructor's plugin.
inline constexpr const char* kNeuralPluginFile = "libgdr_neural_plugin.so";

/// The directories searched for plugins, in order (see the file comment).
std::vector<std::string> plugin_search_dirs();

/// What load_reconstructor_plugins() found.
struct PluginLoad {
    bool loaded = false;                ///< True if a plugin was loaded and registered.
    std::string path;                   ///< The plugin file loaded or found ("" if none was found).
    std::string error;                  ///< Why a plugin that was found could not be used ("" if none).
    std::vector<std::string> searched;  ///< The directories searched.
};

/// Loads the neural reconstructor's plugin from the first search directory
/// that holds it and registers its reconstructors into
/// reconstructor_registry(). Runs once per process (later calls return the
/// first result); never throws: a failure is reported in the result.
const PluginLoad& load_reconstructor_plugins();

/// Makes sure reconstructor `method` is registered: if it is not, loads the
/// plugins (once) and checks again. If "neural" is still missing, throws a
/// ParameterError that begins with `context` (e.g. "--method neural") and
/// says why: the plugin was not built (how to build it) or could not be
/// loaded (the file and the loader's message). Any other missing name is
/// left to the registry, whose create() names it and lists the available ones.
void require_reconstructor(const std::string& method, const std::string& context);

/// require_reconstructor() for the reconstruction an integrator's parameters
/// ask for (reconstruct=neural of gpt, gbdpt and tgpt), before the integrator
/// is created; `context` says where the parameters came from.
void require_reconstructors_of(const Params& integrator_params, const std::string& context);

}  // namespace gdr::cli
