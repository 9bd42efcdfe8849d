#include "gdr/path/connection.h"

#include <charconv>

namespace gdr {

std::optional<Connection> parse_connection(std::string_view text, int min_vertices) {
    const auto number = [](std::string_view v, int& out) {
        const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
        return ec == std::errc() && end == v.data() + v.size();
    };
    const size_t comma = text.find(',');
    Connection c;
    if (comma == std::string_view::npos || !number(text.substr(0, comma), c.s) || !number(text.substr(comma + 1), c.t))
        return std::nullopt;
    if (c.s < 0 || c.t < 1 || (c.s == 1 && c.t == 1) || c.s + c.t < min_vertices) return std::nullopt;
    return c;
}

template void connection_densities(const Scene&, const Subpath&, const Subpath&, Connection, const Vertex*,
                                   PathDensities&);
template ConnectionResult connect(const Scene&, const Subpath&, const Subpath&, Connection, const Sampler&,
                                  const StrategySet&, bool, uint64_t&);

}  // namespace gdr
