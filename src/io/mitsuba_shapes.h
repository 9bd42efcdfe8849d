// Geometry of Mitsuba 0.5/0.6 shapes that the XML importer builds: the vertex
// normals Mitsuba computes for an indexed mesh (angle-weighted, and with a
// crease angle), and the triangulations of its analytic shapes. Private to
// the Mitsuba importer.
#pragma once

#include <cstdint>
#include <vector>

#include "gdr/core/math.h"

namespace gdr::detail {

/// An indexed triangle mesh: per-vertex arrays (normals, uvs may be empty)
/// and three indices per triangle.
struct IndexedMesh {
    std::vector<Vec3> positions, normals;
    std::vector<Vec2> uvs;
    std::vector<Vec3> colors;
    std::vector<uint32_t> indices;
};

/// Unit vertex normals as Mitsuba computes them where a mesh has none: the
/// sum of the adjacent faces' unit normals, each weighted by the face's angle
/// at the vertex (Thuermer and Wuethrich, "Computing Vertex Normals from
/// Polygonal Facets", JGT 1998); a vertex of degenerate faces only gets (1, 0, 0).
std::vector<Vec3> angle_weighted_normals(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices);

/// Mitsuba's `maxSmoothAngle`: the mesh's normals are dropped, and each group
/// of corners at one (position, uv, colour) is split greedily into vertices
/// whose faces' normals lie within `max_angle_deg` of the first face of the
/// group (in file order); the new vertices get angle-weighted normals. Edges
/// sharper than the angle become creases.
void rebuild_with_crease_angle(IndexedMesh& m, float max_angle_deg);

/// A cylinder of Mitsuba's `cylinder` shape without caps: radius `r` around
/// the segment p0 -> p1, triangulated with `segments` quads around, its
/// corners on the exact surface and its vertex normals the exact radial
/// normals; uv = (angle / 2 pi, height fraction), Mitsuba's. Outward facing.
IndexedMesh cylinder_mesh(const Vec3& p0, const Vec3& p1, float r, int segments);

}  // namespace gdr::detail
