// How few posed scenes a fitted pose mapper needs (`uplvsm study mapper-scenes`): the mapper fitted to a frozen
// UP-LVSM (train/mapper_fitting.h) on the first N scenes of a posed split for each N, each scored at real cameras on
// held-out scenes. Writes mapper_scenes.json, mapper_scenes.csv and psnr.png (PSNR against scenes, log axis).
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/train/mapper_fitting.h"
#include "uplvsm/train/mapper_run.h"

namespace uplvsm::study {

struct MapperScenesOptions {
  std::vector<int64_t> scene_counts = {1, 4, 16, 64, 256};
  model::PoseMapperOptions mapper;
  train::MapperFitOptions fit;  // its loader.max_scenes is set per count
  int64_t eval_scenes = 0;      // held-out scenes scored (0: the whole index)
  std::string out_dir;
};

struct MapperScenesRow {
  int64_t scenes = 0;
  train::MapperFitReport fit;
  double psnr = 0, ssim = 0, copy_nearest_psnr = 0;
};

// `net` must be an UP-LVSM; its own pose mapper, if any, is replaced by each fitted one in turn.
std::vector<MapperScenesRow> run_mapper_scenes(model::NovelViewModel& net, const data::ChunkDataset& posed,
                                               const data::ChunkDataset& held_out, const data::PreprocessOptions& prep,
                                               const MapperScenesOptions& options);

// The study as `uplvsm study mapper-scenes` asks for it: the model and posed scenes of `run`, loaded as fit-mapper
// loads them, scored on `eval_data`'s test split; options.mapper and options.fit are taken from `run`.
std::vector<MapperScenesRow> run_mapper_scenes_study(const train::MapperRunOptions& run, const std::string& eval_data,
                                                     MapperScenesOptions options);

void write_mapper_scenes(const std::vector<MapperScenesRow>& rows, const std::string& out_dir);

}  // namespace uplvsm::study
