#include "gdr/core/params.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <algorithm>
#include <sstream>

namespace gdr {

namespace {
// The shortest text that reads back as the same double, in fixed notation
// for decimal exponents -4 to 15 and scientific otherwise: 0.2, 0.0001,
// 1e-05, 1e+16 (the form parameter files have always been written in).
std::string shortest_text(double d) {
    if (std::isnan(d)) return std::signbit(d) ? "-nan" : "nan";
    if (std::isinf(d)) return d < 0 ? "-inf" : "inf";
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, d, std::chars_format::scientific);
    const std::string s(buf, r.ptr);
    const size_t e = s.find('e');
    const int exp = std::atoi(s.c_str() + e + 1);
    const bool neg = s[0] == '-';
    std::string digits;
    for (size_t i = neg ? 1 : 0; i < e; ++i)
        if (s[i] != '.') digits += s[i];
    std::string out;
    if (exp < -4 || exp >= 16) {
        out = digits.substr(0, 1);
        if (digits.size() > 1) out += "." + digits.substr(1);
        char eb[16];
        std::snprintf(eb, sizeof eb, "e%c%02d", exp < 0 ? '-' : '+', std::abs(exp));
        out += eb;
    } else if (exp < 0) {
        out = "0." + std::string(size_t(-exp - 1), '0') + digits;
    } else if (digits.size() <= size_t(exp) + 1) {
        out = digits + std::string(size_t(exp) + 1 - digits.size(), '0');
    } else {
        out = digits.substr(0, size_t(exp) + 1) + "." + digits.substr(size_t(exp) + 1);
    }
    return neg ? "-" + out : out;
}
}  // namespace

std::string to_string(const Params::Value& v) {
    if (auto b = std::get_if<bool>(&v)) return *b ? "true" : "false";
    if (auto i = std::get_if<long long>(&v)) return std::to_string(*i);
    // The shortest text that reads back as the same double: 0.2, not 0.20000000000000001.
    if (auto d = std::get_if<double>(&v)) return shortest_text(*d);
    return std::get<std::string>(v);
}

void Params::set_from_text(const std::string& a) {
    const auto eq = a.find('=');
    if (eq == std::string::npos || eq == 0)
        throw ParameterError(context_ + ": expected key=value, got '" + a + "'");
    const std::string key = a.substr(0, eq), text = a.substr(eq + 1);
    if (text == "true" || text == "false") return set(key, text == "true");
    char* end = nullptr;
    errno = 0;
    const long long i = std::strtoll(text.c_str(), &end, 10);
    // Out of range, strtoll saturates: the text is kept as the real it is (get_int then refuses it).
    if (!text.empty() && *end == '\0' && errno != ERANGE) return set(key, i);
    const double d = std::strtod(text.c_str(), &end);
    if (!text.empty() && *end == '\0') return set(key, d);
    set(key, text);
}

void Params::bad_type(const std::string& key, const char* expected) const {
    throw ParameterError(context_ + ": parameter '" + key_prefix_ + key + "' must be " + expected + ", got '" +
                         to_string(values_.at(key)) + "'");
}

bool Params::get_bool(const std::string& key, bool def) const {
    auto it = values_.find(key);
    if (it == values_.end()) return def;
    used_.insert(key);
    if (auto b = std::get_if<bool>(&it->second)) return *b;
    bad_type(key, "true or false");
}

long long Params::get_int(const std::string& key, long long def) const {
    auto it = values_.find(key);
    if (it == values_.end()) return def;
    used_.insert(key);
    if (auto i = std::get_if<long long>(&it->second)) return *i;
    if (auto d = std::get_if<double>(&it->second); d && std::floor(*d) == *d && std::abs(*d) < 9e15)
        return (long long)*d;
    bad_type(key, "an integer");
}

double Params::get_real(const std::string& key, double def) const {
    auto it = values_.find(key);
    if (it == values_.end()) return def;
    used_.insert(key);
    if (auto d = std::get_if<double>(&it->second)) return *d;
    if (auto i = std::get_if<long long>(&it->second)) return double(*i);
    bad_type(key, "a number");
}

std::string Params::get_string(const std::string& key, const std::string& def) const {
    auto it = values_.find(key);
    if (it == values_.end()) return def;
    used_.insert(key);
    if (auto s = std::get_if<std::string>(&it->second)) return *s;
    return to_string(it->second);
}

std::string Params::get_choice(const std::string& key, const std::string& def,
                               const std::vector<std::string>& choices) const {
    const std::string v = get_string(key, def);
    for (const auto& c : choices)
        if (c == v) return v;
    std::string list;
    for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
    throw ParameterError(context_ + ": parameter '" + key_prefix_ + key + "' is '" + v + "', expected one of: " + list);
}

void Params::check_unused(const std::string& owner) const {
    for (const auto& [k, v] : values_)
        if (!used_.count(k))
            throw ParameterError(context_ + ": unknown parameter '" + key_prefix_ + k + "' for " + owner);
}

Params Params::prefixed(const std::string& prefix) const {
    Params sub(context_);
    sub.key_prefix_ = key_prefix_ + prefix + ".";
    const std::string head = prefix + ".";
    for (const auto& [k, v] : values_)
        if (k.size() > head.size() && k.compare(0, head.size(), head) == 0) {
            sub.values_[k.substr(head.size())] = v;
            used_.insert(k);
        }
    return sub;
}

std::string Params::to_text() const {
    std::string s;
    for (const auto& [k, v] : values_) s += k + "=" + to_string(v) + "\n";
    return s;
}

std::vector<Params> Params::parts(const std::string& prefix, const std::vector<std::string>& names) const {
    const Params all = prefixed(prefix);
    std::string untargeted, targeted;
    for (const auto& [key, value] : all.values()) {
        const size_t dot = key.find('.');
        const bool to_one = dot != std::string::npos && dot + 1 < key.size() &&
                            std::find(names.begin(), names.end(), key.substr(0, dot)) != names.end();
        (to_one ? targeted : untargeted) = key;
    }
    const std::string full = key_prefix_ + prefix + ".";
    if (!untargeted.empty() && names.size() != 1) {
        std::string list;
        for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
        throw ParameterError(context_ + ": parameter '" + full + untargeted + "': " +
                             (names.empty() ? "'" + key_prefix_ + prefix + "' chooses none to take it"
                                            : "'" + key_prefix_ + prefix + "' chooses several (" + list + "); give " +
                                                  full + "<name>." + untargeted + " for one of them"));
    }
    if (!untargeted.empty() && !targeted.empty())
        throw ParameterError(context_ + ": parameters '" + full + untargeted + "' and '" + full + targeted +
                             "': give the parameters of the one '" + key_prefix_ + prefix + "' in one form, " + full +
                             "<key> or " + full + "<name>.<key>");
    std::vector<Params> out;
    // Either form keeps the key as given in messages.
    for (const std::string& name : names) out.push_back(untargeted.empty() ? all.prefixed(name) : all);
    return out;
}

}  // namespace gdr
