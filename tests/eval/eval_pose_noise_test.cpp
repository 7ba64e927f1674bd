// Tests of the official evaluation's pose noise (eval/eval_pose_noise.h, `uplvsm eval --pose-noise-std`): the noise
// is the training loader's function in the scene frame, of the expected size, seeded per scene; the evaluator hands
// the noisy cameras to a posed model (and only to a model that reads cameras), and records what it did.
#include "uplvsm/eval/eval_pose_noise.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/eval/evaluator.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/posed_lvsm.h"

namespace uplvsm::eval {
namespace {

namespace fs = std::filesystem;
constexpr double kStd = 0.05;

// `n` cameras with random rotations and translations, [n, 4, 4].
torch::Tensor random_cameras(int64_t n) {
  auto q = torch::nn::functional::normalize(torch::randn({n, 4}), torch::nn::functional::NormalizeFuncOptions().dim(1));
  return geometry::pose_encoding_to_c2w(torch::cat({torch::randn({n, 3}), q}, 1));
}

TEST(EvalPoseNoise, IsTheTrainingNoiseInTheSceneFrameOfTheExpectedSize) {
  torch::manual_seed(3);
  const int64_t vi = 200, vt = 200;
  auto c2w = random_cameras(vi + vt);
  const auto told = noisy_scene_cameras(c2w, vi, kStd, 11, "scene-a");
  // The training loader's function on the scene-normalised cameras, inputs first, from the scene's stream.
  auto frame = geometry::official_scene_normalize(c2w);
  std::mt19937_64 rng(pose_noise_scene_seed(11, "scene-a"));
  EXPECT_TRUE(torch::equal(told.inputs, data::with_pose_noise(frame.narrow(0, 0, vi), kStd, rng)));
  EXPECT_TRUE(torch::equal(told.targets, data::with_pose_noise(frame.narrow(0, vi, vt), kStd, rng)));
  // Translations are encoded as they are: the difference is the noise itself, N(0, kStd^2).
  const std::vector<std::pair<torch::Tensor, torch::Tensor>> noisy_clean = {{told.inputs, frame.narrow(0, 0, vi)},
                                                                            {told.targets, frame.narrow(0, vi, vt)}};
  for (const auto& [noisy, clean] : noisy_clean) {
    auto dt = (noisy - clean).narrow(1, 0, 3).select(2, 3).to(torch::kFloat64);
    EXPECT_NEAR(dt.std().item<double>(), kStd, 0.12 * kStd);
    EXPECT_NEAR(dt.mean().item<double>(), 0.0, 0.2 * kStd);
    const double rotation_change = (noisy - clean).narrow(1, 0, 3).narrow(2, 0, 3).abs().mean().item<double>();
    EXPECT_GT(rotation_change, 0.1 * kStd);
    EXPECT_LT(rotation_change, 10 * kStd);
  }
  // Inputs and targets are drawn apart: the same clean cameras get different noise.
  auto twice = torch::cat({c2w.narrow(0, 0, 1), c2w.narrow(0, 0, 1)});
  const auto same_camera = noisy_scene_cameras(twice, 1, kStd, 11, "scene-a");
  EXPECT_FALSE(torch::allclose(same_camera.inputs, same_camera.targets));
}

TEST(EvalPoseNoise, SeededBySeedAndSceneKeyOnly) {
  torch::manual_seed(4);
  auto c2w = random_cameras(5);
  const auto a = noisy_scene_cameras(c2w, 2, kStd, 1, "k");
  EXPECT_TRUE(torch::equal(a.inputs, noisy_scene_cameras(c2w, 2, kStd, 1, "k").inputs));
  EXPECT_FALSE(torch::equal(a.inputs, noisy_scene_cameras(c2w, 2, kStd, 2, "k").inputs));
  EXPECT_FALSE(torch::equal(a.inputs, noisy_scene_cameras(c2w, 2, kStd, 1, "l").inputs));
  EXPECT_NE(pose_noise_scene_seed(0, "ab"), pose_noise_scene_seed(0, "ba"));
}

TEST(EvalPoseNoise, RefusesANegativeOrNonFiniteStdNamingTheFlag) {
  for (double bad : {-0.01, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    try {
      check_pose_noise_std(bad);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("--pose-noise-std"), std::string::npos) << e.what();
    }
  }
  EXPECT_NO_THROW(check_pose_noise_std(0));
  EXPECT_NO_THROW(check_pose_noise_std(0.1));
}

// Three 6-frame scenes with random 32x32 frames and rotating, moving cameras; index: context {0, 5}, targets {2, 3, 4}.
fs::path write_scenes(const std::string& name) {
  const auto dir = test::temp_dir(name);
  std::vector<data::RawScene> scenes;
  std::vector<data::EvalEntry> entries;
  std::map<std::string, std::string> chunk_index;
  torch::manual_seed(5);
  for (int s = 0; s < 3; ++s) {
    data::RawScene r;
    r.key = fmt::format("abcd00000000000{}", s);
    r.url = "test://noise";
    r.timestamps = torch::arange(6, torch::kInt64);
    r.cameras = torch::zeros({6, 18});
    for (int i = 0; i < 6; ++i) {
      const double a = 0.08 * i + 0.3 * s;
      r.cameras[i].slice(0, 0, 4) = torch::tensor({0.8, 0.8, 0.5, 0.5});
      r.cameras[i].slice(0, 6, 18) = torch::tensor({std::cos(a), 0.0, std::sin(a), 0.1 * i, 0.0, 1.0, 0.0, 0.02 * s,
                                                    -std::sin(a), 0.0, std::cos(a), -0.1 * i - 1});
      auto bytes = io::encode_jpeg(torch::randint(0, 256, {32, 32, 3}).to(torch::kUInt8), 95);
      r.images.push_back(torch::from_blob(bytes.data(), {static_cast<int64_t>(bytes.size())}, torch::kUInt8).clone());
    }
    entries.push_back({r.key, {0, 5}, {2, 3, 4}, std::nullopt});
    chunk_index[r.key] = "000000.torch";
    scenes.push_back(std::move(r));
  }
  fs::create_directories(dir / "test");
  data::write_chunk((dir / "test" / "000000.torch").string(), scenes);
  data::write_chunk_index((dir / "test").string(), chunk_index);
  data::write_eval_index((dir / "index.json").string(), entries);
  std::reverse(entries.begin(), entries.end());
  data::write_eval_index((dir / "reversed.json").string(), entries);
  return dir;
}

// LVSM that keeps the cameras it is told.
struct RecordingLVSM : model::PosedLVSMImpl {
  RecordingLVSM() : PosedLVSMImpl(test::micro_model("lvsm"), model::PosedInputs::All) {}
  model::Rendered render(const model::Views& in, const model::Views& tg, model::TargetPoses source,
                         model::ForwardTrace* trace) override {
    inputs.push_back(in.c2w.clone());
    targets.push_back(tg.c2w.clone());
    in_scene_frame.push_back(in.camera_frame == model::CameraFrame::Scene &&
                             tg.camera_frame == model::CameraFrame::Scene);
    return PosedLVSMImpl::render(in, tg, source, trace);
  }
  std::vector<torch::Tensor> inputs, targets;
  std::vector<bool> in_scene_frame;
};

// Each scene's model PSNR by key (the index may list the scenes in any order).
std::map<std::string, double> scene_psnrs(const EvalSummary& s) {
  std::map<std::string, double> out;
  for (const auto& r : s.per_scene) out[r.key] = r.model.psnr;
  return out;
}

// The wiring: with S > 0 the evaluator gives LVSM each scene's noisy cameras (noisy_scene_cameras, in the scene
// frame), the model's scores move and the baselines do not; S = 0 gives the clean dataset cameras as before; the same
// seed gives the same scores whatever the batch size or scene order.
TEST(EvalPoseNoise, EvaluatorTellsAPosedModelTheNoisyCameras) {
  const auto dir = write_scenes("eval_pose_noise_lvsm");
  data::ChunkDataset dataset(dir.string(), "test");
  torch::manual_seed(0);
  auto recorder = std::make_shared<RecordingLVSM>();
  model::NovelViewModel net{std::shared_ptr<model::NovelViewModelImpl>(recorder)};
  EvalOptions opt;
  opt.index_path = (dir / "index.json").string();
  opt.num_visualised = 0;
  opt.target_poses = model::TargetPoses::Dataset;
  const auto clean = evaluate(net, dataset, test::micro_prep(), opt);
  ASSERT_EQ(clean.scenes, 3);
  ASSERT_EQ(recorder->inputs.size(), 1u);  // one batch of the three scenes, in index order
  EXPECT_FALSE(recorder->in_scene_frame[0]);
  EXPECT_EQ(clean.pose_noise.at("std"), 0.0);
  for (int64_t b = 0; b < 3; ++b) {
    auto c2w = dataset.load_views(dataset.find(clean.per_scene[b].key), {0, 5, 2, 3, 4}, test::micro_prep()).c2w;
    EXPECT_TRUE(torch::equal(recorder->inputs[0][b], c2w.narrow(0, 0, 2)));  // clean, as without the option
  }

  opt.pose_noise_std = kStd;
  opt.pose_noise_seed = 9;
  const auto noisy = evaluate(net, dataset, test::micro_prep(), opt);
  ASSERT_EQ(recorder->inputs.size(), 2u);
  EXPECT_TRUE(recorder->in_scene_frame[1]);
  for (int64_t b = 0; b < 3; ++b) {
    const auto& key = noisy.per_scene[b].key;
    auto c2w = dataset.load_views(dataset.find(key), {0, 5, 2, 3, 4}, test::micro_prep()).c2w;
    const auto told = noisy_scene_cameras(c2w, 2, kStd, 9, key);
    EXPECT_TRUE(torch::equal(recorder->inputs[1][b], told.inputs)) << key;
    EXPECT_TRUE(torch::equal(recorder->targets[1][b], told.targets)) << key;
    EXPECT_NE(noisy.per_scene[b].model.psnr, clean.per_scene[b].model.psnr) << key;
    EXPECT_EQ(noisy.per_scene[b].copy_nearest.psnr, clean.per_scene[b].copy_nearest.psnr)
        << key;  // baselines: clean cameras
  }
  EXPECT_EQ(noisy.pose_noise.at("std"), kStd);
  EXPECT_EQ(noisy.pose_noise.at("seed"), 9);
  EXPECT_TRUE(noisy.pose_noise.at("reaches_model").get<bool>());

  EXPECT_EQ(scene_psnrs(evaluate(net, dataset, test::micro_prep(), opt)),
            scene_psnrs(noisy));  // same seed, same scores
  opt.batch_size = 1;
  opt.index_path = (dir / "reversed.json").string();
  const auto reordered = scene_psnrs(evaluate(net, dataset, test::micro_prep(), opt));
  for (const auto& [key, psnr] : scene_psnrs(noisy)) EXPECT_NEAR(reordered.at(key), psnr, 1e-4) << key;
  opt.pose_noise_seed = 10;
  for (const auto& [key, psnr] : scene_psnrs(evaluate(net, dataset, test::micro_prep(), opt)))
    EXPECT_NE(psnr, reordered.at(key)) << key;  // same batching, another seed
  opt.pose_noise_std = -1;
  EXPECT_THROW(evaluate(net, dataset, test::micro_prep(), opt), std::invalid_argument);
  test::remove_tree(dir);
}

// UP-LVSM reads no dataset camera with the estimator's target poses: the noise cannot move its scores (as in the
// official code), and metrics.json says so; with dataset target poses it reads them, and the noise reaches it.
TEST(EvalPoseNoise, ReachesUplvsmOnlyWhenItReadsDatasetCameras) {
  const auto dir = write_scenes("eval_pose_noise_uplvsm");
  data::ChunkDataset dataset(dir.string(), "test");
  torch::manual_seed(0);
  auto net = model::make_model(test::micro_model("uplvsm"));
  EvalOptions opt;
  opt.index_path = (dir / "index.json").string();
  opt.num_visualised = 0;
  opt.out_dir = (dir / "out").string();
  for (auto poses : {model::TargetPoses::Estimator, model::TargetPoses::Dataset}) {
    opt.target_poses = poses;
    opt.pose_noise_std = 0;
    const auto clean = scene_psnrs(evaluate(net, dataset, test::micro_prep(), opt));
    opt.pose_noise_std = kStd;
    const auto noisy = evaluate(net, dataset, test::micro_prep(), opt);
    const bool reads = poses == model::TargetPoses::Dataset;
    EXPECT_EQ(scene_psnrs(noisy) != clean, reads) << uplvsm::to_string(poses);
    std::ifstream f(dir / "out" / "metrics.json");
    const auto j = nlohmann::json::parse(f).at("pose_noise");
    EXPECT_EQ(j.at("std"), kStd);
    EXPECT_EQ(j.at("reaches_model").get<bool>(), reads);
  }
  test::remove_tree(dir);
}

}  // namespace
}  // namespace uplvsm::eval
