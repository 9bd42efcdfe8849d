// Figures the benchmarks take over their repeated runs.
#pragma once

#include <algorithm>
#include <utility>
#include <vector>

#include <sys/resource.h>

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

}  // namespace gdr::bench
