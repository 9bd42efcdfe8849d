// Typed parameters for plugins. Every read marks a key as used; after
// construction the registry rejects keys nobody read, so a typo never
// silently becomes a default.
#pragma once

#include <map>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include "gdr/core/error.h"

namespace gdr {

/// A bag of named, typed values (bool, integer, real, string) with usage tracking.
class Params {
public:
    using Value = std::variant<bool, long long, double, std::string>;

    Params() = default;
    /// `context` names where the values came from (a file, "--set"), for error messages.
    explicit Params(std::string context) : context_(std::move(context)) {}

    /// Sets a value (replacing any previous one).
    void set(const std::string& key, Value v) { values_[key] = std::move(v); }
    /// Parses "key=value" text: true/false, integers, reals, else string.
    void set_from_text(const std::string& assignment);
    /// True if the key is present.
    bool has(const std::string& key) const { return values_.count(key) != 0; }

    /// Reads a boolean (default if absent); ill-typed values throw naming the key.
    bool get_bool(const std::string& key, bool def) const;
    /// Reads an integer (default if absent); reals with a fraction throw.
    long long get_int(const std::string& key, long long def) const;
    /// Reads a real number (default if absent); integers are accepted.
    double get_real(const std::string& key, double def) const;
    /// Reads a string (default if absent).
    std::string get_string(const std::string& key, const std::string& def) const;
    /// Reads a string that must be one of `choices`.
    std::string get_choice(const std::string& key, const std::string& def, const std::vector<std::string>& choices) const;

    /// Throws ParameterError naming the first key that no getter read.
    void check_unused(const std::string& owner) const;
    /// Where these values came from.
    const std::string& context() const { return context_; }
    /// All keys and values as "key=value" lines, sorted by key (for file headers).
    std::string to_text() const;
    /// Raw access for merging.
    const std::map<std::string, Value>& values() const { return values_; }

    /// The parameters of a part chosen by name (a reconstructor, a shift): the
    /// keys "<prefix>.<key>" of these, as "<key>", in Params whose messages
    /// name the full key ("unknown parameter 'reconstruct.radius'"). Marks
    /// the prefixed keys read here: the part's own registry checks them.
    Params prefixed(const std::string& prefix) const;
    /// The parameters of the parts that parameter `prefix` chooses by name
    /// (`names`, in order; one Params each): "<prefix>.<name>.<key>" goes to
    /// part `name`, "<prefix>.<key>" to the only part chosen. Throws
    /// ParameterError naming the key for "<prefix>.<key>" when none or several
    /// are chosen, or when both forms are mixed. Marks every prefixed key read here.
    std::vector<Params> parts(const std::string& prefix, const std::vector<std::string>& names) const;
    /// What prefixed() removed from each key ("reconstruct."), "" otherwise.
    const std::string& key_prefix() const { return key_prefix_; }

private:
    [[noreturn]] void bad_type(const std::string& key, const char* expected) const;
    std::string context_ = "parameters";
    std::string key_prefix_;
    std::map<std::string, Value> values_;
    mutable std::set<std::string> used_;
};

/// The text form of one value ("true", "12", "0.5", "abc").
std::string to_string(const Params::Value& v);

}  // namespace gdr
