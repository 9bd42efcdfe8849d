# Every dependency comes from the system (Debian packages) through find_package
# or pkg-config; nothing is vendored.
find_package(glm REQUIRED)
find_package(TBB REQUIRED)
find_package(embree 3 REQUIRED)
find_package(OpenEXR 3 REQUIRED)
find_package(tinyobjloader REQUIRED)
find_package(fmt REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
# Mitsuba XML scene files.
find_package(pugixml REQUIRED)
# Mitsuba's zlib-compressed .serialized meshes.
find_package(ZLIB REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(FFTW3F REQUIRED IMPORTED_TARGET fftw3f)
pkg_check_modules(STB REQUIRED IMPORTED_TARGET stb)
