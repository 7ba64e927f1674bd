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
  const auto o = test::micro_mapper_run(dir, 8);
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
