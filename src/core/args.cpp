#include "gdr/core/args.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "gdr/core/error.h"

namespace gdr {

std::string ArgReader::value(const std::string& opt) {
    if (!more()) throw ParameterError("option " + opt + " needs a value");
    return next();
}

long long ArgReader::parse_int(const std::string& opt, const std::string& v, long long lo, long long hi) {
    char* end = nullptr;
    errno = 0;
    const long long x = std::strtoll(v.c_str(), &end, 10);
    if (v.empty() || *end) throw ParameterError("option " + opt + " expects an integer, got '" + v + "'");
    // strtoll saturates silently; a clamped value would be a different setting than asked for.
    if (errno == ERANGE) throw ParameterError("option " + opt + ": '" + v + "' is out of range");
    if (x < lo || x > hi)
        throw ParameterError("option " + opt + " must be " +
                             (hi == std::numeric_limits<long long>::max()
                                  ? ">= " + std::to_string(lo)
                                  : "between " + std::to_string(lo) + " and " + std::to_string(hi)) +
                             ", got '" + v + "'");
    return x;
}

double ArgReader::parse_real(const std::string& opt, const std::string& v) {
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (v.empty() || *end) throw ParameterError("option " + opt + " expects a number, got '" + v + "'");
    // strtod reads "nan" and "inf"; no option of gdr has a meaning for them.
    if (!std::isfinite(x)) throw ParameterError("option " + opt + " expects a finite number, got '" + v + "'");
    return x;
}

long long ArgReader::int_value(const std::string& opt, long long lo, long long hi) { return parse_int(opt, value(opt), lo, hi); }

double ArgReader::real_value(const std::string& opt) { return parse_real(opt, value(opt)); }

}  // namespace gdr
