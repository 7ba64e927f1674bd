#include "uplvsm/train/train_request.h"

#include <algorithm>
#include <filesystem>
#include <stdexcept>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/subset.h"
#include "uplvsm/data/view_sampler.h"
#include "uplvsm/train/perceptual_loss.h"
#include "uplvsm/train/run_start.h"
#include "uplvsm/train/tokenizer_start.h"

namespace uplvsm::train {

namespace {

// What the plan says of the data a run of `config` on `data` draws from: the subset's scenes, then the first
// max_train_scenes of them, and how the views are drawn.
void describe_training_data(const Config& config, const std::string& data, RunPlan& plan) {
  data::ChunkDataset dataset(data, "train");
  if (!config.training.subset.empty()) dataset.keep_only(data::read_subset_manifest(config.training.subset).scenes);
  plan.ordered_views = data::uses_ordered_views(config.training.view_sampler, dataset.info());
  const int64_t cap = config.training.max_train_scenes;
  plan.scenes = cap > 0 ? std::min(cap, dataset.size()) : dataset.size();
  plan.split_scenes = dataset.size();
}

}  // namespace

Config train_config(const TrainRequest& request) {
  auto config = apply_config_overrides(load_config(request.config_path), request.set, request.config_path);
  if (request.steps > 0) config.training.train_steps = request.steps;
  if (!request.amp.empty()) config.training.amp = parse_amp(request.amp, "--amp");
  // Absolute, so a resume from another working directory reads the same manifest from the run's config.
  if (!request.subset.empty()) config.training.subset = std::filesystem::absolute(request.subset).string();
  if (request.stage == "mapper") {
    if (request.init.empty() && request.resume == "none")
      throw std::runtime_error("train --stage mapper: give the trained UP-LVSM to start from with --init");
    config.model.pose_mapper = true;
    config.training.target_poses = TargetPoses::Mapper;
    validate_config(config, request.config_path + " (--stage mapper)");
  }
  return config;
}

RunPlan dry_run_plan(const TrainRequest& request, const Config& config, int64_t ranks, const std::string& device) {
  RunPlan plan;
  plan.config = config;
  plan.batch = plan_batch(config.training, ranks, request.config_path);
  plan.device = device;
  plan.perceptual_weights = request.vgg19;
  plan.init = request.init;
  plan.resuming = !request.run.empty() && run_resumes(request.run, request.resume);
  plan.data_root = request.data;
  if (!request.data.empty()) describe_training_data(config, request.data, plan);
  return plan;
}

void require_run_starts(const RunPlan& plan) {
  require_perceptual_weights(plan.config, plan.perceptual_weights);
  require_tokenizer_start(plan.config, plan.init, plan.resuming);
}

}  // namespace uplvsm::train
