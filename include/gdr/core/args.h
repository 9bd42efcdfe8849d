// Command-line scanning for gdr's programs (the gdr tool, the benchmarks,
// examples): an option's value, checked as an integer in a range or a finite
// real number, with errors that name the option.
#pragma once

#include <string>
#include <vector>

namespace gdr {

/// Scans a program's command-line arguments: options with values, integers
/// in a range and finite reals, each refused with a ParameterError naming
/// the option and the text given.
struct ArgReader {
    const std::vector<std::string>& args;  ///< All arguments of the subcommand.
    size_t i = 0;                          ///< Current position.
    /// True while arguments remain.
    bool more() const { return i < args.size(); }
    /// The next argument.
    const std::string& next() { return args[i++]; }
    /// The value following option `opt`; throws naming the option if absent.
    std::string value(const std::string& opt);
    /// The value of `opt` as an integer in [lo, hi] (throws naming the option if malformed or out of range).
    long long int_value(const std::string& opt, long long lo, long long hi);
    /// The value of `opt` as a finite real number (throws naming the option if malformed, NaN or infinite).
    double real_value(const std::string& opt);
    /// `v`, the text given for option `opt`, as an integer in [lo, hi] (throws naming the option otherwise).
    static long long parse_int(const std::string& opt, const std::string& v, long long lo, long long hi);
    /// `v`, the text given for option `opt`, as a finite real number (throws naming the option otherwise).
    static double parse_real(const std::string& opt, const std::string& v);
};

}  // namespace gdr
