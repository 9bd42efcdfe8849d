// The larger public scenes (the bathroom, the Mitsuba test scenes), which are
// not part of the repository: found in scenes_dir() (GDR_SCENES), and a test
// that needs an absent one is skipped with a message saying where to get it.
#pragma once

#include <filesystem>
#include <string>

#include <catch2/catch.hpp>

#include "gdr/io/scene_file.h"

namespace gdr::test {

/// Where the public scene `rel` (a path inside scenes_dir()) can be downloaded.
inline std::string public_scene_source(const std::string& rel) {
    const bool bitterli = rel.rfind("bathroom-contemporary", 0) == 0 || rel.rfind("mitsuba/classroom", 0) == 0 ||
                          rel.rfind("mitsuba/living-room", 0) == 0 || rel.rfind("mitsuba/spaceship", 0) == 0 ||
                          rel.rfind("mitsuba/veach-bidir", 0) == 0 || rel.rfind("mitsuba/dining-room", 0) == 0;
    if (rel.rfind("meshes/", 0) == 0) return "https://github.com/alecjacobson/common-3d-test-models";
    return bitterli ? "https://benedikt-bitterli.me/resources/ (Mitsuba versions)"
                    : "https://github.com/hchoi405/dppm-scenes (folder scenes/)";
}

/// The path of `rel` inside scenes_dir(), or "" where it is absent.
inline std::string public_scene(const std::string& rel) {
    const std::string p = (std::filesystem::path(scenes_dir()) / rel).string();
    return std::filesystem::exists(p) ? p : std::string();
}

/// The warning of a test (or of one of its cases) left out for want of `rel`.
/// "skipped: needs" marks a whole test case, which ctest then reports as skipped.
inline std::string public_scene_missing(const std::string& rel, bool whole_test = true) {
    return std::string(whole_test ? "skipped: needs " : "not checked: needs ") + rel + " in GDR_SCENES (" +
           scenes_dir() + "), the folder of the larger public scenes; download: " + public_scene_source(rel);
}

}  // namespace gdr::test

/// Declares `var`, the path of the public scene `rel`, or ends the test case
/// with a warning (reported by ctest as skipped) where it is absent.
#define GDR_PUBLIC_SCENE_OR_SKIP(var, rel)                                  \
    const std::string var = ::gdr::test::public_scene(rel);                 \
    if (var.empty()) {                                                      \
        WARN(::gdr::test::public_scene_missing(rel));                       \
        return;                                                             \
    }
