// PLY meshes: ASCII and binary of both byte orders with normals and uvs,
// polygons fan-triangulated, extra elements skipped, and malformed files as
// errors naming the file and what is wrong.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <string>

#include <fmt/core.h>

#include "cli_test_util.h"
#include "gdr/core/error.h"
#include "gdr/io/ply.h"

using namespace gdr;

namespace {

// A quad (two triangles after the fan) and a triangle over 5 vertices, with normals and uvs.
const float kPos[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5f, 0.5f, 1}};
const float kUv[5][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5f, 0.25f}};

std::string header(const std::string& format) {
    return "ply\nformat " + format +
           " 1.0\ncomment made by a test\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
           "property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n"
           "element extra 2\nproperty uchar tag\nproperty list uchar int stuff\n"
           "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
}

template <typename T>
void put(std::string& s, T v, bool big) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big) std::reverse(b, b + sizeof(T));
    s.append(b, sizeof(T));
}

std::string binary(bool big) {
    std::string s = header(big ? "binary_big_endian" : "binary_little_endian");
    for (int i = 0; i < 5; ++i) {
        for (float c : kPos[i]) put(s, c, big);
        for (float c : {0.f, 0.f, 1.f}) put(s, c, big);
        for (float c : kUv[i]) put(s, c, big);
    }
    for (int e = 0; e < 2; ++e) {
        put(s, uint8_t(7), big);
        put(s, uint8_t(2), big);
        put(s, int32_t(11), big), put(s, int32_t(12), big);
    }
    put(s, uint8_t(4), big);
    for (int i : {0, 1, 2, 3}) put(s, int32_t(i), big);
    put(s, uint8_t(3), big);
    for (int i : {0, 1, 4}) put(s, int32_t(i), big);
    return s;
}

std::string ascii() {
    std::string s = header("ascii");
    for (int i = 0; i < 5; ++i)
        s += fmt::format("{} {} {} 0 0 1 {} {}\n", kPos[i][0], kPos[i][1], kPos[i][2], kUv[i][0], kUv[i][1]);
    s += "7 2 11 12\n7 2 11 12\n4 0 1 2 3\n3 0 1 4\n";
    return s;
}

void check_mesh(const PlyMesh& m) {
    REQUIRE(m.positions.size() == 5);
    REQUIRE(m.normals.size() == 5);
    REQUIRE(m.uvs.size() == 5);
    CHECK(m.polygons == 2);
    REQUIRE(m.indices == std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 0, 1, 4});
    for (int i = 0; i < 5; ++i) {
        CHECK(m.positions[i] == Vec3(kPos[i][0], kPos[i][1], kPos[i][2]));
        CHECK(m.normals[i] == Vec3(0, 0, 1));
        CHECK(m.uvs[i] == Vec2(kUv[i][0], kUv[i][1]));
    }
}

std::string error_of_ply(const std::string& bytes) {
    try {
        parse_ply(bytes, "test.ply");
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST_CASE("ply: ASCII and binary files of both byte orders read the same mesh", "[ply]") {
    check_mesh(parse_ply(ascii(), "a.ply"));
    check_mesh(parse_ply(binary(false), "le.ply"));
    check_mesh(parse_ply(binary(true), "be.ply"));
}

TEST_CASE("ply: read_ply reads a file, CRLF headers and other type names included", "[ply]") {
    test::OutDir dir("ply");
    std::string s = "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty double x\r\nproperty double y\r\n"
                    "property double z\r\nproperty uint8 red\r\nelement face 1\r\nproperty list uint8 uint32 vertex_index\r\n"
                    "end_header\r\n0 0 0 255\r\n1 0 0 255\r\n0 1 0 255\r\n3 0 1 2\r\n";
    std::ofstream(dir("crlf.ply"), std::ios::binary) << s;
    const PlyMesh m = read_ply(dir("crlf.ply"));
    CHECK(m.positions.size() == 3);
    CHECK(m.normals.empty());
    CHECK(m.uvs.empty());
    CHECK(m.indices == std::vector<uint32_t>{0, 1, 2});
    CHECK_THROWS_WITH(read_ply(dir("missing.ply")), Catch::Contains("missing.ply") && Catch::Contains("not found"));
}

TEST_CASE("ply: malformed files are errors naming the file and the problem", "[ply][errors]") {
    CHECK_THAT(error_of_ply("solid cube\n"), Catch::Contains("test.ply") && Catch::Contains("not a PLY file"));
    CHECK_THAT(error_of_ply("ply\nformat binary_middle_endian 1.0\nend_header\n"),
               Catch::Contains("line 2") && Catch::Contains("unknown format"));
    CHECK_THAT(error_of_ply("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"),
               Catch::Contains("no end_header"));
    CHECK_THAT(error_of_ply("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"),
               Catch::Contains("line 4") && Catch::Contains("unknown property type 'quad'"));
    CHECK_THAT(error_of_ply("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n"),
               Catch::Contains("no 'z' property"));
    // Truncated binary data names the element.
    std::string b = binary(false);
    CHECK_THAT(error_of_ply(b.substr(0, b.size() - 3)), Catch::Contains("face 1") && Catch::Contains("truncated"));
    CHECK_THAT(error_of_ply(b.substr(0, header("binary_little_endian").size() + 40)),
               Catch::Contains("vertex 1") && Catch::Contains("truncated"));
    // ASCII errors name the line.
    std::string a = ascii();
    const std::string bad_number = a.substr(0, a.find("1 0 0 0 0 1")) + "1 zero 0 0 0 1 1 0\n" +
                                   a.substr(a.find("1 0 0 0 0 1") + std::string("1 0 0 0 0 1 1 0\n").size());
    CHECK_THAT(error_of_ply(bad_number), Catch::Contains("line 20") && Catch::Contains("'zero' is not a number"));
    const std::string bad_index = a.substr(0, a.rfind("3 0 1 4")) + "3 0 1 9\n";
    CHECK_THAT(error_of_ply(bad_index), Catch::Contains("face 1 references vertex 9") && Catch::Contains("5 vertices"));
    const std::string two_corners = a.substr(0, a.rfind("3 0 1 4")) + "2 0 1\n";
    CHECK_THAT(error_of_ply(two_corners), Catch::Contains("face 1 has 2 corners"));
    CHECK_THAT(error_of_ply("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                            "element face 0\nproperty list uchar int vertex_indices\nend_header\nnan 0 0\n"),
               Catch::Contains("vertex 0 is not a finite number"));
    CHECK_THAT(error_of_ply("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                            "end_header\n0 0 0\n"),
               Catch::Contains("no faces"));
    CHECK_THAT(error_of_ply("ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
                            "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n3 0 1 2\n"),
               Catch::Contains("before the vertex element"));
}

TEST_CASE("ply: element counts beyond the file are errors, elements without properties are skipped", "[ply][errors]") {
    const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                             "element face 1\nproperty list uchar int vertex_indices\n";
    const std::string body = "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    // 10^12 items of nothing: this looped for ever before such elements were skipped.
    const PlyMesh m = parse_ply(head + "element junk 1000000000000\n" + body, "empty-items.ply");
    CHECK(m.indices.size() == 3);
    // 10^12 items of one byte or more cannot fit: refused before any loop.
    CHECK_THAT(error_of_ply(head + "element junk 1000000000000\nproperty uchar j\n" + body),
               Catch::Contains("test.ply") && Catch::Contains("line 9") &&
                   Catch::Contains("declares 1000000000000 items"));
    CHECK_THAT(error_of_ply(head + "element junk 18446744073709551615\nproperty uchar j\n" + body),
               Catch::Contains("declares 18446744073709551615 items"));
}
