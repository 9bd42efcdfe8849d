// Mitsuba 0.5/0.6's `.serialized` meshes: one or more zlib-compressed indexed
// triangle meshes in one file, format versions 3 and 4, single or double
// precision, with optional per-vertex normals, texture coordinates and
// colours, and (from version 3 on) an end-of-file dictionary of the meshes'
// byte offsets.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "gdr/core/math.h"

namespace gdr {

/// One mesh of a `.serialized` file, in the file's own coordinates and units;
/// double-precision values are rounded to float.
struct SerializedMesh {
    std::string name;               ///< The mesh's name (version 4 only; empty in version 3).
    std::vector<Vec3> positions;    ///< One per vertex.
    std::vector<Vec3> normals;      ///< One per vertex, as stored (not normalised), or empty.
    std::vector<Vec2> uvs;          ///< One per vertex, as stored (Mitsuba's uv: v = 0 at an image's top), or empty.
    std::vector<Vec3> colors;       ///< One per vertex (linear RGB), or empty.
    std::vector<uint32_t> indices;  ///< Three vertex indices per triangle.
    bool face_normals = false;      ///< The file asks for face normals (flag 0x0010).
    bool double_precision = false;  ///< The file stores doubles (flag 0x2000), else floats.
    int version = 4;                ///< The format version of the mesh's header: 3 or 4.
};

/// A `.serialized` file held in memory, from which meshes are decoded on
/// demand (a scene often takes many meshes of one file).
class SerializedFile {
public:
    /// Reads `path`. Throws InputError naming the file when it is missing, is
    /// not a serialized mesh file (header 0x041C), has a version other than 3
    /// or 4, or its offset dictionary is corrupt.
    explicit SerializedFile(const std::string& path);
    /// The same of bytes already in memory; `name` names them in messages.
    SerializedFile(std::string bytes, std::string name);

    /// The number of meshes (1 when the file has no valid dictionary).
    size_t size() const { return offsets_.size(); }
    /// Decodes mesh `index`. Throws InputError naming the file and the index
    /// when the index is out of range, or the mesh's data is truncated or
    /// corrupt (bad zlib data, counts larger than the file can hold, an index
    /// out of range, a non-finite position, both precisions flagged).
    SerializedMesh mesh(size_t index) const;

private:
    void index();
    std::string bytes_, name_;
    std::vector<uint64_t> offsets_;  // byte offset of each mesh's header
    size_t data_end_ = 0;            // where the last mesh's data ends: the dictionary, or the file's end
    int version_ = 4;
};

}  // namespace gdr
