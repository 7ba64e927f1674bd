// The public C++ API of uplvsm in one include (what `find_package(uplvsm)` installs under include/uplvsm/):
//   model::load_model      any weight file (our checkpoints, the authors' .pt/.safetensors) -> a ready model
//   model::NovelViewModel  the family's interface: render(inputs, targets, target poses) (novel_view_model.h)
//   model::UPLVSM          encode_scene, estimate_poses, render_views (model/uplvsm.h; model::require_uplvsm)
//   model::PosedLVSM       the posed PT-LVSM / LVSM baselines (model/posed_lvsm.h)
//   render::               render_interpolation, render_camera_path, camera paths, write_video
//   eval::psnr / ssim      the community's exact metrics; eval::load_lpips for LPIPS
//   data::ChunkDataset     pixelSplat chunks or the LVSM layout; data::load_photos for your own photos
//   io::                   safetensors, torch.save files (no Python), images, MP4/GIF
//   init_runtime           threads and allocator as the `uplvsm` binary sets them (core/runtime.h)
// Nothing in the library includes this file; users may include the single headers instead.
#pragma once

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/config.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/photo.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/eval/lpips.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/image.h"
#include "uplvsm/io/pretrained_weights.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/torch_file.h"
#include "uplvsm/io/video.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/model/posed_lvsm.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/render/renderer.h"
#include "uplvsm/render/trajectory.h"
