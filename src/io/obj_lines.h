// Checks of OBJ and MTL text before tinyobjloader reads it. The reader
// silently turns what it cannot parse into zeros (a NaN vertex, "Kd x") and
// drops faces it cannot index, so the lines are checked first and every such
// line is an error naming the file and line. Private to the scene loader.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace gdr::detail {

/// Why `file` cannot be read as a file (": file not found", ": not a file
/// (it is a directory)"), or "" if it can.
std::string not_a_file(const std::string& file);

/// The whole of a file, or an InputError naming it.
std::string read_file_text(const std::string& file);

/// Throws an InputError naming the file and line of a numeric MTL line that
/// tinyobjloader would read as 0; nothing for a missing library (the reader reports it).
void check_material_lines(const std::string& lib);

/// What the pre-pass of an OBJ found besides errors.
struct ObjLines {
    std::vector<std::string> libraries;  ///< mtllib names, relative to the OBJ's directory.
    size_t triangles = 0;                ///< What the faces triangulate to: corners - 2 each.
};

/// Throws an InputError naming the file, line and value of a vertex, normal,
/// texture-coordinate or face line that tinyobjloader would misread or drop;
/// returns the material libraries and the expected triangle count (nothing
/// for an unreadable file: the reader reports it).
ObjLines check_obj_lines(const std::string& path);

}  // namespace gdr::detail
