// PLY meshes (Stanford polygon files): ASCII and binary little/big endian,
// vertex positions with optional normals and texture coordinates, polygon
// faces fan-triangulated. Elements other than vertex and face are skipped.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gdr/core/math.h"

namespace gdr {

/// A triangle mesh as a PLY file stores it, in the file's own coordinates and units.
struct PlyMesh {
    std::vector<Vec3> positions;    ///< One per vertex (x, y, z).
    std::vector<Vec3> normals;      ///< One per vertex (nx, ny, nz), or empty when the file has none.
    std::vector<Vec2> uvs;          ///< One per vertex (u, v; also named s, t or texture_u, texture_v), or empty; as stored.
    std::vector<uint32_t> indices;  ///< Three vertex indices per triangle; polygons are fan-triangulated.
    size_t polygons = 0;            ///< Faces read, before triangulation.
};

/// Reads a PLY file. Throws InputError naming the file (and the header line,
/// or the element and its index, or the ASCII line) when it is missing, is not
/// a PLY file, has an unknown format or property type, lacks x/y/z or a face
/// index list, is truncated, has a non-finite vertex, a face of fewer than
/// three corners or an index out of range.
PlyMesh read_ply(const std::string& path);

/// read_ply() of PLY text or bytes already in memory; `name` names it in messages.
PlyMesh parse_ply(const std::string& bytes, const std::string& name);

}  // namespace gdr
