# `cmake --install` (and `make install PREFIX=...`): the `uplvsm` binary, libuplvsm.so, the public headers under
# include/uplvsm/, configs/ under share/uplvsm/configs, the Python package, and a CMake package so another project
# can `find_package(uplvsm)` and link `uplvsm::uplvsm`. Installed programs find libuplvsm.so through
# $ORIGIN-relative RPATHs (the prefix can move) and OpenBLAS through DT_RPATH, as in the build tree.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# The public API is a folder rule: every header of the rooms a user builds on (core, io, geometry, data, model,
# backbones, eval, render) and uplvsm.h; the rooms above them (train, study, serve, cli), the kernels below model
# (reached only through model's modules) and the precompiled header stay private. tests/install checks that the
# installed set is closed under #include and that private headers stay out.
set(UPLVSM_PUBLIC_ROOMS core io geometry data model backbones eval render)
install(FILES src/uplvsm/uplvsm.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/uplvsm)
foreach(room ${UPLVSM_PUBLIC_ROOMS})
  install(DIRECTORY src/uplvsm/${room}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/uplvsm/${room}
          FILES_MATCHING PATTERN "*.h" PATTERN "pch.h" EXCLUDE)
endforeach()

file(RELATIVE_PATH UPLVSM_BIN_TO_LIB /${CMAKE_INSTALL_BINDIR} /${CMAKE_INSTALL_LIBDIR})
set_target_properties(uplvsm_cli PROPERTIES INSTALL_RPATH "$ORIGIN/${UPLVSM_BIN_TO_LIB}")
install(TARGETS uplvsm_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS uplvsm EXPORT uplvsmTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

set(UPLVSM_INSTALL_CONFIGS_DIR ${CMAKE_INSTALL_DATADIR}/uplvsm/configs)
install(DIRECTORY configs/ DESTINATION ${UPLVSM_INSTALL_CONFIGS_DIR} FILES_MATCHING PATTERN "*.json")

set(UPLVSM_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/uplvsm)
install(EXPORT uplvsmTargets NAMESPACE uplvsm:: DESTINATION ${UPLVSM_CMAKE_DIR})
configure_package_config_file(cmake/uplvsmConfig.cmake.in ${CMAKE_BINARY_DIR}/uplvsmConfig.cmake
                              INSTALL_DESTINATION ${UPLVSM_CMAKE_DIR} PATH_VARS UPLVSM_INSTALL_CONFIGS_DIR)
write_basic_package_version_file(${CMAKE_BINARY_DIR}/uplvsmConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/uplvsmConfig.cmake ${CMAKE_BINARY_DIR}/uplvsmConfigVersion.cmake
        DESTINATION ${UPLVSM_CMAKE_DIR})
