// Plugins of the gdr tool: shared libraries, loaded on demand with dlopen(),
// that add integrators, reconstructors and shift mappings to the
// process-wide registries through gdr's entry point (gdr/plugin.h). The
// neural reconstructor is one: it needs libtorch, whose loading costs about
// 0.8 s, so plugins are loaded only when a run names something that is not
// registered, and a plain render does not pay for them.
//
// Where plugins are looked for, in order:
//   - the directories of $GDR_PLUGIN_PATH (colon-separated), if it is set
//     (set but empty: none, so no plugin is loaded);
//   - otherwise <directory of the running executable>/GDR_PLUGIN_DIR_FROM_BIN,
//     the path from the install's bindir to <libdir>/gdr that CMake computes
//     (../lib/gdr by default): an installed bin/gdr finds lib/gdr, and the
//     build tree has the same layout (build/bin/gdr, build/lib/gdr).
// Every file NAME.so in them is loaded; one that does not export
// gdr_plugin_register and gdr_plugin_abi, or whose gdr_plugin_abi() differs
// from the tool's (same gdr version, compiler and language standard), is
// skipped, and named with the reason where a name stays unknown. Where two
// plugins register one name, the one of the earlier directory wins. Loaded
// plugins are never unloaded: the registries hold their factories.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "gdr/core/params.h"
#include "gdr/plugin.h"

namespace gdr::cli {

/// File name of the neural reconstructor's plugin.
inline constexpr const char* kNeuralPluginFile = "libgdr_neural_plugin.so";

/// The directories searched for plugins, in order (see the file comment).
std::vector<std::string> plugin_search_dirs();

/// What load_plugins() found.
using PluginLoad = gdr::PluginLoad;

/// Loads every plugin of the search directories and registers what they
/// add into the process-wide registries. Runs once per process (later calls
/// return the first result); never throws: a failure is reported in the result.
const PluginLoad& load_plugins();

/// Makes sure reconstructor `method` is registered: if it is not, loads the
/// plugins (once) and checks again. If it is still missing, throws a
/// ParameterError that begins with `context` (e.g. "gdr reconstruct --method
/// neural"), lists the registered names and names each plugin file skipped
/// and why; for "neural", says how to build it (it needs libtorch) or why its
/// plugin could not be loaded.
void require_reconstructor(const std::string& method, const std::string& context);

/// The same for shift mapping `name`.
void require_shift(const std::string& name, const std::string& context);

/// The same for integrator `name`.
void require_integrator(const std::string& name, const std::string& context);

/// require_reconstructor() for every reconstructor an integrator's
/// parameters choose (reconstruct=NAME[,NAME...] of gpt, gbdpt and tgpt) and
/// require_shift() for its shift (shift=NAME, or both of shifts=A,B with
/// shift=combined), before the integrator is created; `context` says where
/// the parameters came from.
void require_plugins_of(const Params& integrator_params, const std::string& context);

}  // namespace gdr::cli
