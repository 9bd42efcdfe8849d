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
