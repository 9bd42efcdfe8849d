// Create-by-name registries for plugins (integrators, reconstructors, shift
// mappings). Built-ins are added by explicit register_builtins() calls rather
// than static initialisers, which a static library's linker would drop.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "gdr/core/error.h"
#include "gdr/core/params.h"

namespace gdr {

/// A name -> factory table for one plugin base type.
template <typename Base, typename... Args>
class Registry {
public:
    using Factory = std::function<std::unique_ptr<Base>(const Params&, Args...)>;

    /// `kind` is the plugin family's name used in messages ("integrator").
    explicit Registry(std::string kind) : kind_(std::move(kind)) {}

    /// Adds a plugin; re-adding a name replaces it (lets users override built-ins).
    void add(const std::string& name, const std::string& description, Factory f) {
        entries_[name] = Entry{description, std::move(f)};
    }
    /// True if a plugin of that name exists.
    bool has(const std::string& name) const { return entries_.count(name) != 0; }
    /// Registered names, sorted.
    std::vector<std::string> names() const {
        std::vector<std::string> n;
        for (const auto& [k, e] : entries_) n.push_back(k);
        return n;
    }
    /// One-line description of a plugin.
    const std::string& description(const std::string& name) const { return find(name).description; }

    /// Creates a plugin; throws ParameterError for an unknown name (listing the
    /// available ones) or for any parameter the plugin did not read.
    std::unique_ptr<Base> create(const std::string& name, const Params& params, Args... args) const {
        auto obj = find(name).factory(params, args...);
        params.check_unused(kind_ + " '" + name + "'");
        return obj;
    }

private:
    struct Entry {
        std::string description;
        Factory factory;
    };
    const Entry& find(const std::string& name) const {
        auto it = entries_.find(name);
        if (it == entries_.end()) {
            std::string list;
            for (const auto& [k, e] : entries_) list += (list.empty() ? "" : ", ") + k;
            throw ParameterError("unknown " + kind_ + " '" + name + "' (available: " + list + ")");
        }
        return it->second;
    }
    std::string kind_;
    std::map<std::string, Entry> entries_;
};

/// The process-wide registry of one plugin family: made on first use (thread-safe
/// static initialisation) and filled by `register_builtins`. Each family's accessor
/// (integrator_registry(), shift_registry(), ...) is a one-line call to this.
template <typename Base>
Registry<Base>& process_registry(const char* kind, void (*register_builtins)(Registry<Base>&)) {
    static Registry<Base> r = [&] {
        Registry<Base> reg(kind);
        register_builtins(reg);
        return reg;
    }();
    return r;
}

}  // namespace gdr
