#include "frames.h"

#include <algorithm>
#include <cctype>
#include <cstdio>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/core/error.h"

namespace gdr::cli {

std::pair<int, int> parse_frame_range(const std::string& opt, const std::string& v) {
    const size_t colon = v.find(':');
    if (colon == std::string::npos)
        throw ParameterError("option " + opt + " expects FIRST:LAST (inclusive frame numbers), got '" + v + "'");
    const int a = int(ArgReader::parse_int(opt, v.substr(0, colon), -(1LL << 30), 1LL << 30));
    const int b = int(ArgReader::parse_int(opt, v.substr(colon + 1), -(1LL << 30), 1LL << 30));
    if (b < a) throw ParameterError(fmt::format("option {}: the last frame {} comes before the first {}", opt, b, a));
    return {a, b};
}

namespace {

// The directive at pattern[i] == '%': its length and zero padding width, or length 0 if it is none.
struct Directive {
    size_t length = 0;
    int width = 0;
    bool zero = false;
};

// Widest frame number: a wider one would be a name longer than a path can hold.
constexpr int kMaxFrameWidth = 4096;

Directive directive_at(const std::string& p, size_t i) {
    Directive d;
    size_t j = i + 1;
    if (j < p.size() && p[j] == '0') d.zero = true, ++j;
    // Every digit is read (a width is never cut short), capped only so that it cannot overflow.
    while (j < p.size() && std::isdigit(static_cast<unsigned char>(p[j])))
        d.width = std::min(d.width * 10 + (p[j] - '0'), kMaxFrameWidth + 1), ++j;
    if (j < p.size() && p[j] == 'd') d.length = j + 1 - i;
    return d;
}

}  // namespace

bool has_frame_pattern(const std::string& pattern) {
    for (size_t i = pattern.find('%'); i != std::string::npos; i = pattern.find('%', i + 1))
        if (directive_at(pattern, i).length) return true;
    return false;
}

std::string frame_path(const std::string& opt, const std::string& pattern, int frame) {
    std::string out;
    bool used = false;
    for (size_t i = 0; i < pattern.size(); ++i) {
        if (pattern[i] != '%') {
            out += pattern[i];
            continue;
        }
        const Directive d = directive_at(pattern, i);
        if (!d.length)
            throw ParameterError(opt + " '" + pattern + "': a '%' must start a frame number directive (%d, %04d)");
        if (used) throw ParameterError(opt + " '" + pattern + "': holds two frame number directives; give one");
        used = true;
        if (d.width > kMaxFrameWidth)
            throw ParameterError(fmt::format("{} '{}': a frame number wider than {} characters cannot be a file name",
                                             opt, pattern, kMaxFrameWidth));
        // Padded as printf pads, to any width.
        std::string number = std::to_string(frame);
        if (int(number.size()) < d.width) {
            const size_t pad = size_t(d.width) - number.size();
            if (!d.zero) number.insert(0, pad, ' ');
            else number.insert(frame < 0 ? 1 : 0, pad, '0');
        }
        out += number;
        i += d.length - 1;
    }
    return out;
}

}  // namespace gdr::cli
