# cmake --install BUILD --prefix P: what a C/C++ consumer or a packager needs.
#   P/include/rbcloth.h
#   P/LIBDIR/librbcloth.so.1.MINOR, the SONAME link librbcloth.so.1, librbcloth.so
#   P/LIBDIR/../libexec/rbcloth/rbcloth-import   (where the library looks for it:
#                                                 abi/rbcloth.h, rbc_mesh_import)
#   P/bin/rbcloth                                (with the extras: the CLI)
#   Windows: P/bin/rbcloth.dll (RUNTIME), P/lib/librbcloth.dll.a (ARCHIVE: the
#   import library; rbcloth.lib with MSVC), no helper
#   P/LIBDIR/cmake/rbcloth/rbclothConfig.cmake, rbclothConfigVersion.cmake,
#     rbclothTargets.cmake                       (find_package(rbcloth 1.9): the
#                                                 imported target rbcloth::rbcloth)
#   P/LIBDIR/pkgconfig/rbcloth.pc                (pkg-config rbcloth; relocatable)
# The package version is the ABI's (major.minor from the header): a consumer asks for
# the minor whose functions it calls, and any later minor of the major will do.
include(CMakePackageConfigHelpers)
set(RBC_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/rbcloth)
# The helper's folder relative to the library's, as the library computes it.
cmake_path(SET RBC_HELPER_DIR NORMALIZE "${CMAKE_INSTALL_LIBDIR}/../libexec/rbcloth")

install(TARGETS rbcloth EXPORT rbclothTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(FILES ${PROJECT_SOURCE_DIR}/abi/rbcloth.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# (Windows builds have no import helper: plugin/CMakeLists.txt.)
if(TARGET rbcloth-import)
  install(TARGETS rbcloth-import RUNTIME DESTINATION ${RBC_HELPER_DIR})
endif()
if(TARGET rbcloth_cli)
  install(TARGETS rbcloth_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()

install(EXPORT rbclothTargets NAMESPACE rbcloth:: DESTINATION ${RBC_CMAKE_DIR})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/rbclothConfig.cmake.in
  ${CMAKE_BINARY_DIR}/rbclothConfig.cmake INSTALL_DESTINATION ${RBC_CMAKE_DIR})
write_basic_package_version_file(${CMAKE_BINARY_DIR}/rbclothConfigVersion.cmake
  VERSION ${RBC_ABI_MAJOR}.${RBC_ABI_MINOR} COMPATIBILITY SameMajorVersion)
install(FILES ${CMAKE_BINARY_DIR}/rbclothConfig.cmake ${CMAKE_BINARY_DIR}/rbclothConfigVersion.cmake
  DESTINATION ${RBC_CMAKE_DIR})

# ${pcfiledir}: the .pc finds its tree wherever --prefix put it.
file(RELATIVE_PATH RBC_PC_UP /${CMAKE_INSTALL_LIBDIR}/pkgconfig /)
configure_file(${CMAKE_CURRENT_LIST_DIR}/rbcloth.pc.in ${CMAKE_BINARY_DIR}/rbcloth.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/rbcloth.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
