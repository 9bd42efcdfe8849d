// Figures the benchmarks take over their repeated runs.
#pragma once

#include <algorithm>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <sys/resource.h>

namespace gdr::bench {

/// The non-empty comma-separated items of `s` (option lists such as a,b,c).
inline std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> v;
    size_t a = 0;
    while (a <= s.size()) {
        const size_t b = std::min(s.find(',', a), s.size());
        if (b > a) v.push_back(s.substr(a, b - a));
        a = b + 1;
    }
    return v;
}

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

/// One line naming the processor and its caches, printed before any figure:
/// the ratio of shading to bare traversal differs between machines, so a
/// figure means little without it.
inline std::string machine_description() {
    // A virtual machine often reports a generic model name, so the family
    // and model numbers and the widest vector extension are given too.
    std::string model = "unknown processor", family, number, simd, line;
    std::ifstream cpuinfo("/proc/cpuinfo");
    const auto value = [&line] { return line.substr(line.find(':') + 2); };
    while (std::getline(cpuinfo, line) && line.find(':') != std::string::npos) {
        if (line.rfind("model name", 0) == 0) model = value();
        else if (line.rfind("cpu family", 0) == 0) family = value();
        else if (line.rfind("model\t", 0) == 0) number = value();
        else if (line.rfind("flags", 0) == 0) {
            const std::string flags = value() + " ";
            simd = flags.find(" avx512f ") != std::string::npos ? "AVX-512"
                   : flags.find(" avx2 ") != std::string::npos ? "AVX2"
                                                               : "no AVX2";
        }
    }
    if (!family.empty()) model += ", family " + family + " model " + number;
    if (!simd.empty()) model += ", " + simd;
    std::string caches;
    for (int i = 0; i < 8; ++i) {
        const std::string dir = "/sys/devices/system/cpu/cpu0/cache/index" + std::to_string(i) + "/";
        std::ifstream level(dir + "level"), type(dir + "type"), size(dir + "size");
        std::string l, t, z;
        if (!(level >> l) || !(type >> t) || !(size >> z)) break;
        if (t == "Instruction") continue;
        caches += (caches.empty() ? "" : ", ") + std::string("L") + l + (t == "Data" ? "d " : " ") + z;
    }
    return model + (caches.empty() ? std::string() : " (" + caches + ")");
}

}  // namespace gdr::bench
