#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "test_util.h"
#include "uplvsm/study/scene_scores.h"

using namespace uplvsm;

// The evaluator's per_scene.csv: columns found by name, a quoted key with a comma kept whole, an empty LPIPS NaN; a
// short line refused naming the file and the line.
TEST(SceneScores, ReadsTheEvaluatorsPerSceneFile) {
  const auto dir = test::temp_dir("scene_scores_eval");
  std::ofstream(dir / "per_scene.csv") << "key,bucket,overlap,num_targets,psnr,ssim,lpips,grad_ratio,psnr_copy\n"
                                       << "01560e59,medium,0.42,3,27.289774,0.694961,,0.48,19.3\n"
                                       << "\"room, \"\"b\"\"\",large,0.7,3,30.5,0.8,0.12,0.6,24.9\n";
  const auto s = study::read_eval_per_scene((dir / "per_scene.csv").string());
  ASSERT_EQ(s.keys.size(), 2u);
  EXPECT_EQ(s.keys[1], "room, \"b\"");
  EXPECT_DOUBLE_EQ(s.psnr[0], 27.289774);
  EXPECT_TRUE(std::isnan(s.lpips[0]));
  EXPECT_DOUBLE_EQ(s.metric("lpips")[1], 0.12);
  EXPECT_THROW(s.metric("fid"), std::invalid_argument);
  std::ofstream(dir / "short.csv") << "key,psnr,ssim,lpips\na,20,0.5,\nb,21\n";
  const auto msg = test::error_of([&] { study::read_eval_per_scene((dir / "short.csv").string()); });
  EXPECT_NE(msg.find("short.csv line 3"), std::string::npos) << msg;
  std::ofstream(dir / "no_psnr.csv") << "key,ssim,lpips\n";
  EXPECT_NE(test::error_of([&] { study::read_eval_per_scene((dir / "no_psnr.csv").string()); }).find("'psnr'"),
            std::string::npos);
  test::remove_tree(dir);
}

// A study's scenes.csv reads back run for run, scene for scene, as it was written (to its printed digits).
TEST(SceneScores, StudyScenesReadBackWhatWasWritten) {
  const auto dir = test::temp_dir("scene_scores_study");
  study::SceneScores a{{"k1", "k,2"}, {25.1234567, 26.5}, {0.6123456, 0.7}, {std::nan(""), std::nan("")}};
  study::SceneScores b{{"k1", "k,2"}, {27.0, 28.0}, {0.7, 0.8}, {0.2, 0.1}};
  std::ofstream(dir / "scenes.csv") << study::study_scenes_csv(
      {{"uplvsm", "125 scenes", 777, a}, {"lvsm", "125 scenes", 778, b}});
  const auto runs = study::read_study_scenes((dir / "scenes.csv").string());
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].series, "uplvsm");
  EXPECT_EQ(runs[1].seed, 778);
  EXPECT_EQ(runs[0].scores.keys, a.keys);
  EXPECT_NEAR(runs[0].scores.psnr[0], 25.123457, 1e-9);
  EXPECT_NEAR(runs[0].scores.ssim[0], 0.612346, 1e-9);  // to the six digits written
  EXPECT_TRUE(std::isnan(runs[0].scores.lpips[1]));
  EXPECT_DOUBLE_EQ(runs[1].scores.lpips[1], 0.1);
  std::ofstream(dir / "bad.csv") << "series,setting,seed,scene,psnr,ssim,lpips\nlvsm,a,7.5,k,20,0.5,\n";
  EXPECT_NE(test::error_of([&] { study::read_study_scenes((dir / "bad.csv").string()); }).find("bad.csv line 2"),
            std::string::npos);
  test::remove_tree(dir);
}
