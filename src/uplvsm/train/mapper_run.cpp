// fit-mapper's flow (train/mapper_run.h).
#include "uplvsm/train/mapper_run.h"

#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/pose_mapper_file.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::train {

namespace {

// The view sampling: the checkpoint's training views unless overridden (an official checkpoint carries the paper's).
data::LoaderOptions fit_loader_options(const MapperRunOptions& a, const Config& config,
                                       const data::ChunkDataset& dataset) {
  auto lo = loader_options(config, dataset, nullptr);
  lo.batch_size = a.batch;
  lo.micro_batches_per_step = 1;
  lo.pose_noise_std = a.pose_noise_std;
  lo.chunks_per_shuffle = 0;
  if (a.targets > 0) {
    lo.num_target_views = static_cast<int>(a.targets);
    lo.num_views = lo.num_input_views + lo.num_target_views;
  }
  if (a.min_frame_dist > 0) lo.min_frame_dist = static_cast<int>(a.min_frame_dist);
  if (a.max_frame_dist > 0) lo.max_frame_dist = static_cast<int>(a.max_frame_dist);
  lo.frame_dist_curriculum_steps = 0;
  if (a.seed > 0) lo.seed = a.seed;
  return lo;
}

}  // namespace

MapperSetup load_for_mapper_fit(const MapperRunOptions& a, const data::ChunkDataset& dataset) {
  MapperSetup s;
  s.net = model::load_model_with_config_file(a.checkpoint, a.config, a.device, &s.config);
  s.up = model::require_uplvsm(s.net, "fit-mapper (camera control through latent poses)");
  s.fit = a.fit;
  s.fit.loader = fit_loader_options(a, s.config, dataset);
  s.fit.device = a.device;
  s.fit.bf16 = a.bf16;
  return s;
}

model::PoseMapperOptions mapper_options(const MapperRunOptions& a) {
  return {model::parse_pose_mapper_kind(a.kind), a.hidden};
}

FitMapperResult fit_mapper(const FitMapperOptions& a) {
  data::ChunkDataset dataset(a.data, a.split);
  FitMapperResult r;
  r.model = load_for_mapper_fit(a, dataset);
  r.model.fit.loader.max_scenes = a.scenes;
  model::PoseMapper mapper(mapper_options(a));
  r.report = fit_mapper_to_model(*r.model.up, *mapper, dataset, r.model.fit);
  auto fit = r.report.to_json();
  fit["kind"] = a.kind;
  fit["data"] = a.data;
  fit["checkpoint"] = a.checkpoint;
  model::save_pose_mapper(a.out, *mapper, model::model_fingerprint(*r.model.up), fit);
  r.model.up->attach_pose_mapper(mapper);
  return r;
}

}  // namespace uplvsm::train
