// study camera-paths on the micro rooms: the truth along a path is the room seen there (its first pose, the first
// input view, gives that view's frame), positions past the inputs are counted as beyond, every frame is scored for
// each method, and rooms made with other options are refused rather than scored against another room.
#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/study/camera_paths.h"

using namespace uplvsm;

namespace {

// The options test::micro_dataset() was made with.
study::CameraPathsOptions micro_paths() {
  study::CameraPathsOptions o;
  o.room.height = 36;
  o.room.width = 64;
  o.room.frames = 12;
  o.frames = 8;
  return o;
}

}  // namespace

TEST(CameraPaths, TheTruthAlongAPathIsTheRoomSeenThere) {
  data::ChunkDataset dataset(test::micro_dataset(), "test");
  const auto entries = data::read_eval_index(test::micro_dataset() + "/evaluation_index.json");
  ASSERT_FALSE(entries.empty());
  const auto& e = entries[0];
  auto path = study::scene_path(dataset, dataset.find(e.key), e, test::micro_prep(), micro_paths());
  ASSERT_EQ(path.truth.sizes(), (std::vector<int64_t>{8, 3, 32, 32}));
  // The dolly starts at the first input view: the truth there is its frame (up to the dataset's JPEG).
  EXPECT_GT(eval::psnr(path.truth[0], path.inputs.images[0]).item<double>(), 30.0);
  EXPECT_LT(eval::psnr(path.truth[2], path.inputs.images[0]).item<double>(), 30.0);  // and moves on
  EXPECT_NEAR(path.position[0].item<double>(), 0.0, 1e-9);
  // 1.5 baselines forward and back: past input 1 and behind input 0.
  EXPECT_GT(path.position.max().item<double>(), 1.0);
  EXPECT_LT(path.position.min().item<double>(), 0.0);
  // At every frame, not only the ends: the position is where the frame's camera centre, in the world, projects on
  // the segment between the two inputs' centres (0 at input 0, 1 at input 1).
  auto world = geometry::camera_control_to_world(path.inputs.c2w.unsqueeze(0), path.poses.unsqueeze(0))[0];
  auto centres = world.narrow(1, 0, 3).select(2, 3).to(torch::kFloat64);  // [F, 3]
  auto c0 = path.inputs.c2w[0].narrow(0, 0, 3).select(1, 3).to(torch::kFloat64);
  auto base = path.inputs.c2w[1].narrow(0, 0, 3).select(1, 3).to(torch::kFloat64) - c0;
  auto expected = torch::matmul(centres - c0, base) / base.pow(2).sum();
  EXPECT_LT((expected - path.position).abs().max().item<double>(), 1e-3);
  auto other = micro_paths();
  other.room.frames = 10;  // another path, other objects: another room
  auto error = test::error_of([&] { study::scene_path(dataset, dataset.find(e.key), e, test::micro_prep(), other); });
  EXPECT_NE(error.find("not reproduced by the room options"), std::string::npos) << error;
}

TEST(CameraPaths, EveryFrameIsScoredInsideOrBeyondForEachMethod) {
  torch::manual_seed(3);
  model::UPLVSM up(test::micro_config().model);
  up->attach_pose_mapper(model::PoseMapper());
  model::NovelViewModel net(std::static_pointer_cast<model::NovelViewModelImpl>(up.ptr()));
  data::ChunkDataset dataset(test::micro_dataset(), "test");
  auto report = study::run_camera_paths(net, dataset, test::micro_prep(), micro_paths());
  EXPECT_EQ(report.scenes, dataset.size());
  EXPECT_EQ(report.frames_inside + report.frames_beyond, report.scenes * 8);
  EXPECT_GT(report.frames_inside, 0);
  EXPECT_GT(report.frames_beyond, 0);
  ASSERT_EQ(report.methods.size(), 2u);
  EXPECT_EQ(report.methods[0].method, "camera control");
  EXPECT_EQ(report.methods[1].method, "estimator reading the truth");
  EXPECT_EQ(report.frames.size(), static_cast<size_t>(report.scenes * 8 * 2));
  for (const auto& m : report.methods) {
    EXPECT_TRUE(std::isfinite(m.psnr_inside) && std::isfinite(m.psnr_beyond)) << m.method;
    EXPECT_GE(m.wobble, 0.0);
  }
  for (const auto& f : report.frames) EXPECT_EQ(f.inside, f.position >= 0 && f.position <= 1);
  // Each scene's figures for each method, what a paired comparison reads: the method's wobble is their mean.
  ASSERT_EQ(report.scene_scores.size(), static_cast<size_t>(report.scenes * 2));
  for (const auto& m : report.methods) {
    double sum = 0;
    for (const auto& s : report.scene_scores)
      if (s.method == m.method) sum += s.wobble;
    EXPECT_NEAR(m.wobble, sum / report.scenes, 1e-12) << m.method;
  }
  const auto dir = test::temp_dir("camera_paths");
  study::write_camera_paths(report, dir.string());
  EXPECT_TRUE(std::filesystem::exists(dir / "camera_paths.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir / "camera_paths.json"));
  EXPECT_TRUE(std::filesystem::exists(dir / "camera_paths_scenes.csv"));
  // Without the estimator (it does not depend on the mapper): camera control alone, the same figures.
  auto options = micro_paths();
  options.estimator = false;
  auto alone = study::run_camera_paths(net, dataset, test::micro_prep(), options);
  ASSERT_EQ(alone.methods.size(), 1u);
  EXPECT_EQ(alone.methods[0].method, "camera control");
  EXPECT_NEAR(alone.methods[0].psnr_inside, report.methods[0].psnr_inside, 1e-9);
  EXPECT_NEAR(alone.methods[0].wobble, report.methods[0].wobble, 1e-9);
}
