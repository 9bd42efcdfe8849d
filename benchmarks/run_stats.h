// Figures the benchmarks take over their repeated runs.
#pragma once

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include <sys/resource.h>

#include "gdr/core/error.h"

namespace gdr::bench {

/// CPU seconds (user + system, all threads) this process has used so far.
inline double cpu_seconds() {
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    return double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

/// First and third quartiles of the runs (nearest rank): how far a median of
/// a few runs on a shared machine can be trusted.
inline std::pair<double, double> quartiles(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return {v[(n - 1) / 4], v[n - 1 - (n - 1) / 4]};
}

/// The integer value `v` of option `opt`, which must lie in [lo, hi]; throws a
/// ParameterError naming the option otherwise (std::stoi would name itself).
inline long long int_option(const std::string& opt, const std::string& v, long long lo, long long hi) {
    char* end = nullptr;
    errno = 0;
    const long long x = std::strtoll(v.c_str(), &end, 10);
    if (v.empty() || *end || errno == ERANGE || x < lo || x > hi)
        throw ParameterError(opt + " expects an integer from " + std::to_string(lo) + " to " + std::to_string(hi) +
                             ", got '" + v + "'");
    return x;
}

/// The real value `v` of option `opt`, which must be finite and positive; throws naming the option otherwise.
inline double positive_option(const std::string& opt, const std::string& v) {
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (v.empty() || *end || !std::isfinite(x) || !(x > 0.0))
        throw ParameterError(opt + " expects a positive number, got '" + v + "'");
    return x;
}

}  // namespace gdr::bench
