# Every dependency comes from the system (Debian packages) through find_package
# or pkg-config; nothing is vendored.
# gdr::reconstruct needs GLM, TBB and FFTW only; GDR_FIND_RECONSTRUCT_ONLY
# (set by gdrConfig.cmake for find_package(gdr COMPONENTS reconstruct))
# skips the rest.
find_package(glm REQUIRED)
find_package(TBB REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(FFTW3F REQUIRED IMPORTED_TARGET fftw3f)
if(GDR_FIND_RECONSTRUCT_ONLY)
  return()
endif()
find_package(embree 3 REQUIRED)
# Debian 12's Imath package exports the target of its Python binding
# (Imath::PyImath_Python3_11) without installing that library, and CMake then
# prints a long note that the file "does not exist", which reads like a
# failure. gdr does not use the binding: Imath is looked up first with that
# note held back (OpenEXR then finds it already loaded), and one line says it.
set(_gdr_log_level "${CMAKE_MESSAGE_LOG_LEVEL}")
set(CMAKE_MESSAGE_LOG_LEVEL NOTICE)
find_package(Imath QUIET)
set(CMAKE_MESSAGE_LOG_LEVEL "${_gdr_log_level}")
if(CMAKE_VERSION VERSION_GREATER_EQUAL 3.21)
  get_directory_property(_gdr_imported IMPORTED_TARGETS)
  foreach(_gdr_t IN LISTS _gdr_imported)
    if(_gdr_t MATCHES "^Imath::PyImath_")
      get_target_property(_gdr_loc ${_gdr_t} IMPORTED_LOCATION_NONE)
      if(_gdr_loc AND NOT EXISTS "${_gdr_loc}")
        message(STATUS "Imath: its Python binding ${_gdr_t} is listed but not installed; gdr does not use it (harmless)")
      endif()
    endif()
  endforeach()
endif()
find_package(OpenEXR 3 REQUIRED)
find_package(tinyobjloader REQUIRED)
find_package(fmt REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
# Mitsuba XML scene files.
find_package(pugixml REQUIRED)
# Mitsuba's zlib-compressed .serialized meshes.
find_package(ZLIB REQUIRED)
pkg_check_modules(STB REQUIRED IMPORTED_TARGET stb)
