// fit-mapper's flow through train:: without the binary: a micro UP-LVSM's checkpoint gets a mapper file that
// belongs to it, fitted on the views the options ask for, and comes back with the mapper attached.
#include "uplvsm/train/mapper_run.h"

#include <gtest/gtest.h>

#include "train_test_util.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/pose_mapper_file.h"

using namespace uplvsm;
namespace fs = std::filesystem;

TEST(MapperRun, FitsAndSavesAMapperForACheckpoint) {
  const auto dir = test::temp_dir("mapper_run");
  train::FitMapperOptions o;
  static_cast<train::MapperRunOptions&>(o) = test::micro_mapper_run(dir, 16);
  const auto run = o.checkpoint;
  o.scenes = 3;
  o.out = (dir / "mapper.safetensors").string();
  const auto r = train::fit_mapper(o);
  EXPECT_EQ(r.report.scenes, 3);
  EXPECT_GE(r.report.calibration_views, 16);
  EXPECT_EQ(r.model.fit.loader.num_target_views, 3);  // the config trains with 2
  EXPECT_EQ(r.model.fit.loader.batch_size, 3);
  ASSERT_TRUE(r.model.up->pose_mapper);
  EXPECT_FALSE(r.model.up->pose_mapper->reads_scene());  // linear
  // The file reads back onto the same model (its fingerprint matches), not onto another.
  auto same = model::require_uplvsm(model::load_model(run, torch::kCPU), "test");
  model::attach_pose_mapper_file(*same, o.out);
  EXPECT_TRUE(same->pose_mapper);
  torch::manual_seed(9);
  auto other = model::require_uplvsm(model::make_model(test::micro_model()), "test");
  EXPECT_ANY_THROW(model::attach_pose_mapper_file(*other, o.out));
}
