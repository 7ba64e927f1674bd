// `study mapper-scenes` through study:: without the binary: a micro UP-LVSM's checkpoint gets one row per scene
// count asked for, each fitted on that many posed scenes and scored on the held-out ones, and the study's files.
#include "uplvsm/study/mapper_scenes.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "train/train_test_util.h"

using namespace uplvsm;
namespace fs = std::filesystem;

TEST(MapperScenes, OneRowPerSceneCountFromACheckpoint) {
  const auto dir = test::temp_dir("mapper_scenes");
  auto config = test::micro_config();
  config.training.train_steps = 1;
  const auto run = (dir / "run").string();
  ASSERT_FALSE(train::train(config, test::micro_run_options(run)).last_checkpoint.empty());
  train::MapperRunOptions o;
  o.checkpoint = run;
  o.data = test::micro_dataset();
  o.kind = "linear";
  o.batch = 3;
  o.targets = 3;
  o.min_frame_dist = 2;
  o.max_frame_dist = 6;
  o.fit.calibration_views = 8;
  study::MapperScenesOptions opt;
  opt.scene_counts = {1, 2};
  opt.eval_scenes = 1;
  opt.out_dir = (dir / "study").string();
  const auto rows = study::run_mapper_scenes_study(o, test::micro_dataset(), opt);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].scenes, 1);
  EXPECT_EQ(rows[1].scenes, 2);
  EXPECT_GE(rows[0].fit.calibration_views, 8);
  EXPECT_GT(rows[1].psnr, 0);
  EXPECT_TRUE(fs::exists(dir / "study" / "mapper_scenes.json"));
  test::remove_tree(dir);
}
