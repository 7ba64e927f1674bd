// fit-mapper's procedure on a micro UP-LVSM: the least-squares linear map, the MLP fitted further from it (its residual
// falls below the linear one's, the model's weights do not move), and the errors a user's data can raise.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "train_test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/train/mapper_fitting.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {

train::MapperFitOptions micro_fit(int64_t steps) {
  train::MapperFitOptions o;
  o.calibration_views = 48;
  o.regression_steps = steps;
  o.loader.batch_size = 2;
  o.loader.num_views = 4;
  o.loader.num_target_views = 2;
  o.loader.min_frame_dist = 2;
  o.loader.max_frame_dist = 6;
  o.loader.threads = 1;
  o.loader.chunks_per_shuffle = 0;
  o.loader.preprocess = test::micro_prep();
  return o;
}

model::UPLVSM micro_uplvsm() {
  torch::manual_seed(5);
  return model::require_uplvsm(model::make_model(test::micro_model()), "test");
}

// The micro dataset's train split copied with every camera of a scene set to its first (no baseline anywhere).
std::string dataset_without_baselines() {
  const auto root = test::temp_dir("mapper_no_baseline");
  data::ChunkDataset source(test::micro_dataset(), "train");
  std::vector<data::RawScene> scenes;
  for (int64_t i = 0; i < source.size(); ++i) {
    auto s = source.scene(i);
    s.cameras = s.cameras.narrow(0, 0, 1).expand_as(s.cameras).contiguous();
    scenes.push_back(s);
  }
  fs::create_directories(root / "train");
  data::write_chunk((root / "train" / "000000.torch").string(), scenes);
  return root.string();
}

}  // namespace

TEST(MapperFitting, TheMlpFitsCloserThanTheLinearMapAndTheModelIsUnchanged) {
  auto net = micro_uplvsm();
  // Copies: state_dict's CPU tensors share the parameters' storage, so a comparison with them could not fail.
  auto before = io::state_dict(*net);
  for (auto& [name, t] : before) t = t.clone();
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  model::PoseMapper linear, mlp(model::PoseMapperOptions{model::PoseMapperKind::Mlp, 16});
  auto lr = train::fit_mapper_to_model(*net, *linear, dataset, micro_fit(300));
  auto mr = train::fit_mapper_to_model(*net, *mlp, dataset, micro_fit(300));
  EXPECT_GE(lr.calibration_views, 48);
  EXPECT_EQ(lr.scenes, dataset.size());
  EXPECT_EQ(lr.skipped_samples, 0);
  EXPECT_EQ(lr.fit_rms, lr.least_squares_rms);  // the linear mapper is its least-squares fit
  EXPECT_GT(lr.least_squares_rms, 0);
  EXPECT_LT(mr.fit_rms, 0.9 * mr.least_squares_rms);
  // The check is on a scene the fit never saw: the last of six, all its views and only its views.
  EXPECT_TRUE(std::isfinite(mr.held_out_rms));
  EXPECT_EQ(mr.held_out_scenes, std::vector<std::string>{dataset.key(5)});
  EXPECT_GT(mr.held_out_views, 0);
  EXPECT_LT(mr.held_out_views, mr.calibration_views / 2);
  EXPECT_TRUE(std::isnan(lr.held_out_rms));
  EXPECT_TRUE(lr.held_out_scenes.empty());
  for (const auto& [name, t] : io::state_dict(*net)) EXPECT_TRUE(torch::equal(t, before.at(name))) << name;
  // Deterministic: the same data and options give the same mapper.
  model::PoseMapper again;
  train::fit_mapper_to_model(*net, *again, dataset, micro_fit(0));
  EXPECT_TRUE(torch::equal(again->A, linear->A) && torch::equal(again->b, linear->b));
  EXPECT_FALSE(torch::equal(linear->A, torch::eye(7)));
}

TEST(MapperFitting, TheKeptMlpIsTheBestHeldOutCheckNeverWorseThanItsStart) {
  auto net = micro_uplvsm();
  data::ChunkDataset dataset(test::micro_dataset(), "train");
  // Few views, a wide MLP, many fast steps: it over-fits, and the map kept is the best check, not the last step.
  auto opt = micro_fit(3000);
  opt.calibration_views = 40;
  opt.regression_lr = 3e-2;
  model::PoseMapper mapper(model::PoseMapperOptions{model::PoseMapperKind::Mlp, 256});
  auto report = train::fit_mapper_to_model(*net, *mapper, dataset, opt);
  ASSERT_TRUE(std::isfinite(report.held_out_rms) && std::isfinite(report.start_held_out_rms));
  EXPECT_LE(report.held_out_rms, report.start_held_out_rms + 1e-9);
}

TEST(MapperFitting, ScenesWithoutCamerasOrWithoutABaselineAreNamed) {
  auto net = micro_uplvsm();
  model::PoseMapper mapper;
  // Imported photos without poses are listed in unposed.json.
  const auto root = test::temp_dir("mapper_unposed");
  fs::copy(test::micro_dataset(), root, fs::copy_options::recursive);
  data::ChunkDataset posed(root.string(), "train");
  std::ofstream(root / "train" / "unposed.json") << "[\"" << posed.key(1) << "\"]";
  data::ChunkDataset unposed(root.string(), "train");
  auto error = test::error_of([&] { train::fit_mapper_to_model(*net, *mapper, unposed, micro_fit(0)); });
  EXPECT_NE(error.find("scene " + posed.key(1)), std::string::npos) << error;
  EXPECT_NE(error.find("has no cameras"), std::string::npos) << error;

  data::ChunkDataset flat(dataset_without_baselines(), "train");
  error = test::error_of([&] { train::fit_mapper_to_model(*net, *mapper, flat, micro_fit(0)); });
  EXPECT_NE(error.find("no baseline to measure the cameras in"), std::string::npos) << error;
}

TEST(MapperFitting, WholeScenesAreHeldOut) {
  EXPECT_FALSE(train::held_out_scene(0, 1));  // one scene: nothing to check on
  EXPECT_TRUE(train::held_out_scene(3, 4));
  EXPECT_FALSE(train::held_out_scene(2, 4));
  int64_t held = 0;
  for (int64_t i = 0; i < 400; ++i) held += train::held_out_scene(i, 400);
  EXPECT_EQ(held, 40);
  EXPECT_TRUE(train::held_out_scene(9, 400) && train::held_out_scene(399, 400) && !train::held_out_scene(10, 400));
}
