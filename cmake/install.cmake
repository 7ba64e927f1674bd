# `cmake --install` (and `make install PREFIX=...`): the `uplvsm` binary, libuplvsm.so, the public headers under
# include/uplvsm/, configs/ under share/uplvsm/configs, the Python package, and a CMake package so another project
# can `find_package(uplvsm)` and link `uplvsm::uplvsm`. Installed programs find libuplvsm.so through
# $ORIGIN-relative RPATHs (the prefix can move) and OpenBLAS through DT_RPATH, as in the build tree.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# The public API: the model family (load any weight file, UP-LVSM's pieces), views, metrics, datasets, rendering,
# readers.
# Installed with every uplvsm header they include (model internals such as the transformer blocks, which the model
# classes hold as members); everything else (cli, train, study, eval's evaluator and reports, the loader, the
# fused attention kernels, the PCH) stays private. tests/install checks the set is closed under #include.
set(UPLVSM_PUBLIC_HEADERS
    uplvsm.h
    core/config.h core/runtime.h core/autocast.h core/psnr.h
    io/safetensors.h io/torch_file.h io/torch_pickle.h io/image.h io/video.h
    io/gif_writer.h io/mp4_writer.h
    geometry/camera.h geometry/camera_control.h
    data/scene.h data/preprocess.h data/photo.h data/chunk_dataset.h data/chunk_cache.h data/dataset_info.h data/lvsm_layout.h
    model/model_factory.h model/novel_view_model.h model/uplvsm.h model/posed_lvsm.h io/pretrained_weights.h
    io/checkpoint_io.h io/state_dict.h model/dinov2.h model/transformer.h model/rgb_head.h
    model/latent_plucker_learner.h model/pose_mapper.h model/pose_tokenizer.h backbones/vgg_features.h
    kernels/cast_once_linear.h
    eval/metrics.h eval/lpips.h
    render/renderer.h render/trajectory.h)
foreach(header ${UPLVSM_PUBLIC_HEADERS})
  get_filename_component(dir ${header} DIRECTORY)
  install(FILES src/uplvsm/${header} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/uplvsm/${dir})
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
