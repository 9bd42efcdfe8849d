// Vertex normals of indexed meshes as Mitsuba 0.5/0.6 computes them, and the
// triangulated cylinder.
#include "mitsuba_shapes.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

namespace gdr::detail {

std::vector<Vec3> angle_weighted_normals(const std::vector<Vec3>& pos, const std::vector<uint32_t>& idx) {
    std::vector<Vec3> acc(pos.size(), Vec3(0.f));
    for (size_t t = 0; t + 2 < idx.size(); t += 3) {
        const Vec3 c = glm::cross(pos[idx[t + 1]] - pos[idx[t]], pos[idx[t + 2]] - pos[idx[t]]);
        const float len = glm::length(c);
        if (!(len > 0.f)) continue;
        const Vec3 n = c / len;
        for (int k = 0; k < 3; ++k) {
            const Vec3 a = pos[idx[t + (k + 1) % 3]] - pos[idx[t + k]], b = pos[idx[t + (k + 2) % 3]] - pos[idx[t + k]];
            const float la = glm::length(a), lb = glm::length(b);
            if (!(la > 0.f && lb > 0.f)) continue;
            // The angle between the two edges, robust near 0 and pi.
            const float angle = std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
            acc[idx[t + k]] += n * angle;
        }
    }
    for (Vec3& n : acc) {
        const float len = glm::length(n);
        n = len > 0.f ? n / len : Vec3(1.f, 0.f, 0.f);
    }
    return acc;
}

void rebuild_with_crease_angle(IndexedMesh& m, float max_angle_deg) {
    const float threshold = std::cos(max_angle_deg * kPi / 180.f);
    const size_t nt = m.indices.size() / 3;
    std::vector<Vec3> face_n(nt);
    for (size_t t = 0; t < nt; ++t) {
        const Vec3 c = glm::cross(m.positions[m.indices[3 * t + 1]] - m.positions[m.indices[3 * t]],
                                  m.positions[m.indices[3 * t + 2]] - m.positions[m.indices[3 * t]]);
        const float len = glm::length(c);
        face_n[t] = len > 0.f ? c / len : Vec3(0.f);
    }
    // The corners at each (position, uv, colour), in file order.
    using Key = std::tuple<float, float, float, float, float, float, float, float>;
    std::map<Key, std::vector<size_t>> groups;
    for (size_t c = 0; c < m.indices.size(); ++c) {
        const uint32_t v = m.indices[c];
        const Vec3 p = m.positions[v];
        const Vec2 uv = m.uvs.empty() ? Vec2(0.f) : m.uvs[v];
        const Vec3 col = m.colors.empty() ? Vec3(0.f) : m.colors[v];
        groups[Key(p.x, p.y, p.z, uv.x, uv.y, col.x, col.y, col.z)].push_back(c);
    }
    IndexedMesh out;
    out.indices.resize(m.indices.size());
    for (const auto& [key, corners] : groups) {
        std::vector<bool> done(corners.size(), false);
        for (size_t i = 0; i < corners.size(); ++i) {
            if (done[i]) continue;
            const uint32_t v = m.indices[corners[i]];
            const uint32_t nv = uint32_t(out.positions.size());
            out.positions.push_back(m.positions[v]);
            if (!m.uvs.empty()) out.uvs.push_back(m.uvs[v]);
            if (!m.colors.empty()) out.colors.push_back(m.colors[v]);
            const Vec3 n1 = face_n[corners[i] / 3];
            for (size_t j = i; j < corners.size(); ++j) {
                if (done[j]) continue;
                const Vec3 n2 = face_n[corners[j] / 3];
                if (n1 == n2 || glm::dot(n1, n2) > threshold) {
                    out.indices[corners[j]] = nv;
                    done[j] = true;
                }
            }
        }
    }
    out.normals = angle_weighted_normals(out.positions, out.indices);
    m = std::move(out);
}

IndexedMesh cylinder_mesh(const Vec3& p0, const Vec3& p1, float r, int segments) {
    const Vec3 axis = p1 - p0;
    const Vec3 w = glm::normalize(axis);
    // Any frame around the axis: the uv's angle starts at u_dir.
    const Vec3 helper = std::abs(w.x) > 0.9f ? Vec3(0.f, 1.f, 0.f) : Vec3(1.f, 0.f, 0.f);
    const Vec3 u_dir = glm::normalize(glm::cross(helper, w)), v_dir = glm::cross(w, u_dir);
    IndexedMesh m;
    for (int i = 0; i <= segments; ++i) {
        const float phi = 2.f * kPi * float(i) / float(segments);
        const Vec3 n = std::cos(phi) * u_dir + std::sin(phi) * v_dir;
        for (int end = 0; end < 2; ++end) {
            m.positions.push_back(p0 + float(end) * axis + r * n);
            m.normals.push_back(n);
            m.uvs.emplace_back(float(i) / float(segments), float(end));
        }
    }
    for (int i = 0; i < segments; ++i) {
        const uint32_t a = uint32_t(2 * i), b = a + 1, c = a + 2, d = a + 3;  // a, c at p0; b, d at p1
        // Counter-clockwise seen from outside: the geometric normal points out.
        for (uint32_t v : {a, c, d, a, d, b}) m.indices.push_back(v);
    }
    return m;
}

}  // namespace gdr::detail
