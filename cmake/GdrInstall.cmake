# Installs the libraries, headers and a CMake package so that outside
# projects can find_package(gdr) and link gdr::gdr, or find_package(gdr
# COMPONENTS reconstruct) and link gdr::reconstruct alone.
include(CMakePackageConfigHelpers)
install(TARGETS gdr gdr_reconstruct gdr_path EXPORT gdrTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(DIRECTORY include/gdr DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT gdrTargets NAMESPACE gdr:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/gdr)
configure_package_config_file(${CMAKE_CURRENT_SOURCE_DIR}/cmake/gdrConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/gdrConfig.cmake INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/gdr)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/gdrConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/gdrConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/gdrConfigVersion.cmake
              ${CMAKE_CURRENT_SOURCE_DIR}/cmake/GdrDependencies.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/gdr)
