#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/quaternion.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/posed_lvsm.h"
#include "uplvsm/render/renderer.h"
#include "uplvsm/render/trajectory.h"

using namespace uplvsm;

TEST(Trajectory, EndpointsLinearTranslationAndSlerp) {
  double s = std::sqrt(0.5);
  auto keys = torch::tensor({{0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}, {2.0, 0.0, -4.0, 0.0, 0.0, s, s}}, torch::kFloat64);
  auto path = render::interpolate_poses(keys, 5);
  ASSERT_EQ(path.sizes(), (std::vector<int64_t>{5, 7}));
  EXPECT_LE(test::max_abs_diff(path[0], keys[0]), 1e-12);
  EXPECT_LE(test::max_abs_diff(path[4], keys[1]), 1e-12);
  EXPECT_NEAR(path[2][0].item<double>(), 1.0, 1e-12);  // halfway in translation
  EXPECT_NEAR(path[2][2].item<double>(), -2.0, 1e-12);
  EXPECT_NEAR(path[2][5].item<double>(), std::sin(M_PI / 8), 1e-12);  // 45 of 90 degrees
}

TEST(Trajectory, SegmentsRepeatTheirBoundaries) {
  auto keys = torch::zeros({3, 7});
  keys.select(1, 6).fill_(1.0);
  keys[1][0] = 1.0;
  keys[2][0] = 3.0;
  auto path = render::interpolate_poses(keys, 4);
  ASSERT_EQ(path.size(0), 8);  // (K - 1) * frames, both ends included per segment (official render_video)
  EXPECT_FLOAT_EQ(path[3][0].item<float>(), 1.0f);
  EXPECT_FLOAT_EQ(path[4][0].item<float>(), 1.0f);
  auto k = render::interpolate_intrinsics(torch::tensor({{10.0, 10.0, 5.0, 5.0}, {20.0, 20.0, 5.0, 5.0}}), 3);
  EXPECT_FLOAT_EQ(k[1][0].item<float>(), 15.0f);
}

// Keys estimated under bf16 autocast come out in bf16; the path between them is float32, so consecutive frames move
// by even steps instead of snapping to bf16-representable poses (bf16 has 8 bits of mantissa: near 1, steps of
// 2^-7 = 0.0078, coarser than 60 frames over a translation of 0.3).
TEST(Trajectory, Bf16KeysGiveASmoothFloat32Path) {
  const double s = std::sqrt(0.5);
  auto keys =
      torch::tensor({{1.0, 0.0, 0.5, 0.0, 0.0, 0.0, 1.0}, {1.3, 0.1, 0.5, 0.0, s, 0.0, s}}).to(torch::kBFloat16);
  const int64_t n = 60;
  auto path = render::interpolate_poses(keys, n);
  EXPECT_EQ(path.scalar_type(), torch::kFloat32);
  auto expected = render::interpolate_poses(keys.to(torch::kFloat64), n);
  EXPECT_LE(test::max_abs_diff(path.to(torch::kFloat64), expected), 1e-6);
  // Every step of tx is the same (0.3 / 59, bf16 keys' values): none is 0 (a frame repeated) or doubled (a jump).
  auto steps = path.select(1, 0).diff();
  const double step = (keys[1][0].item<double>() - keys[0][0].item<double>()) / static_cast<double>(n - 1);
  EXPECT_LE((steps.to(torch::kFloat64) - step).abs().max().item<double>(), 1e-6);
  // The rotation turns by the same angle between every pair of frames.
  auto q = path.slice(1, 3, 7).to(torch::kFloat64);
  auto angles = (q.slice(0, 1) * q.slice(0, 0, n - 1)).sum(1).abs().clamp_max(1.0).acos();
  EXPECT_LE((angles - angles.mean()).abs().max().item<double>(), 1e-4);
  EXPECT_GT(angles.min().item<double>(), 1e-3);
  auto focal = torch::tensor({{1.0, 1.0, 0.5, 0.5}, {1.2, 1.2, 0.5, 0.5}}).to(torch::kBFloat16);
  auto k = render::interpolate_intrinsics(focal, n);
  EXPECT_EQ(k.scalar_type(), torch::kFloat32);
  const double focal_step = (focal[1][0].item<double>() - focal[0][0].item<double>()) / static_cast<double>(n - 1);
  EXPECT_LE((k.select(1, 0).diff().to(torch::kFloat64) - focal_step).abs().max().item<double>(), 1e-6);
}

TEST(Trajectory, RejectsBadShapes) {
  EXPECT_THROW(render::interpolate_poses(torch::zeros({1, 7}), 4), c10::Error);
  EXPECT_THROW(render::interpolate_poses(torch::zeros({2, 6}), 4), c10::Error);
}

TEST(Trajectory, LookAtFromTheOriginAlongZIsTheIdentity) {
  auto pose = render::look_at_pose(torch::zeros({3}, torch::kFloat64), torch::tensor({0.0, 0.0, 3.0}, torch::kFloat64));
  EXPECT_LE(test::max_abs_diff(pose, torch::tensor({0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0})), 1e-12);
}

TEST(Trajectory, PresetsStartAtTheFirstViewAndLoop) {
  render::PresetOptions o;
  for (const std::string name : {"orbit", "spiral", "dolly"}) {
    auto path = render::camera_path_preset(name, 16, o);
    ASSERT_EQ(path.sizes(), (std::vector<int64_t>{16, 7})) << name;
    EXPECT_LE(test::max_abs_diff(path[0], torch::tensor({0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0})), 1e-9) << name;
    EXPECT_GT(path.slice(1, 0, 3).norm(2, 1).max().item<double>(), 0.1) << name;  // it moves
    EXPECT_LE((path.slice(1, 3, 7).norm(2, 1) - 1).abs().max().item<double>(), 1e-9) << name;
  }
  // The orbit always looks at the focus point: the viewing axis through the camera hits (0, 0, focus).
  auto orbit = render::camera_path_preset("orbit", 8, o);
  auto c2w = geometry::pose_encoding_to_c2w(orbit);
  for (int64_t i = 0; i < 8; ++i) {
    auto to_focus = torch::tensor({0.0, 0.0, o.focus_distance}, torch::kFloat64) - c2w[i].slice(0, 0, 3).select(1, 3);
    auto z = c2w[i].slice(0, 0, 3).select(1, 2);
    EXPECT_NEAR(torch::dot(to_focus / to_focus.norm(), z).item<double>(), 1.0, 1e-9);
  }
  EXPECT_THROW(render::camera_path_preset("zoom", 8, o), std::invalid_argument);
}

TEST(Trajectory, CameraPathFilesReadPosesAndMatricesWithPreciseErrors) {
  auto dir = test::temp_dir("camera_path");
  auto write = [&](const std::string& name, const std::string& text) {
    auto p = (dir / name).string();
    std::ofstream(p) << text;
    return p;
  };
  auto path = render::read_camera_path(
      write("ok.json", R"({"frames": [{"pose": [0, 0, 1, 0, 0, 0, 2], "fxfycxcy": [0.9, 1.6, 0.5, 0.5]},
                                {"c2w": [[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
                                 "fxfycxcy": [0.9, 1.6, 0.5, 0.5]}]})"));
  ASSERT_EQ(path.poses.sizes(), (std::vector<int64_t>{2, 7}));
  EXPECT_NEAR(path.poses[0][6].item<double>(), 1.0, 1e-12);  // quaternion normalised
  EXPECT_NEAR(path.poses[1][0].item<double>(), 0.5, 1e-12);
  ASSERT_TRUE(path.fxfycxcy_normalized.defined());
  auto error = [&](const std::string& text) {
    return test::error_of([&] { render::read_camera_path(write("bad.json", text)); });
  };
  EXPECT_NE(error(R"({"frames": [{"pose": [0, 0, 1]}]})").find("frames[0].pose"), std::string::npos);
  EXPECT_NE(error(R"({"frames": [{"c2w": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]}]})").find("orthonormal"),
            std::string::npos);
  EXPECT_NE(
      error(
          R"({"frames": [{"pose": [0, 0, 1, 0, 0, 0, 1]}, {"pose": [0, 0, 1, 0, 0, 0, 1], "fxfycxcy": [1, 1, 0.5, 0.5]}]})")
          .find("every frame"),
      std::string::npos);
  EXPECT_NE(error(R"({"frames": []})").find("frames"), std::string::npos);
  EXPECT_NE(error("{").find("invalid JSON"), std::string::npos);
  // Nesting deeper than rows of numbers is an error, not a recursion (a file of '[' overflowed the stack).
  const auto deep = error(R"({"frames": [{"pose": )" + std::string(100000, '[') + std::string(100000, ']') + "}]}");
  EXPECT_NE(deep.find("frames[0].pose: expected numbers or rows of numbers, got an array of 1"), std::string::npos)
      << deep;
  // A path longer than any video may be is refused before a pose is read.
  std::string many = R"({"frames": [)";
  for (int64_t i = 0; i <= render::kMaxVideoFrames; ++i) many += i ? ",{}" : "{}";
  EXPECT_NE(error(many + "]}").find("100001 frames, more than the 100000"), std::string::npos);
  EXPECT_NE(error(R"({"units": "metres", "frames": [{"pose": [0, 0, 1, 0, 0, 0, 1]}]})").find("latent"),
            std::string::npos);
  EXPECT_FALSE(path.latent);
  EXPECT_TRUE(render::read_camera_path(write("latent.json", R"({"units": "latent", "scene": "x",
                                                                "frames": [{"pose": [0, 0, 1, 0, 0, 0, 1]}]})"))
                  .latent);
}

// A camera path in latent units (recorded in the viewer) renders exactly the frames of the same latent poses in
// the interpolation video.
TEST(RenderLatentPath, MatchesTheInterpolationAtTheSamePoses) {
  torch::manual_seed(0);
  auto images = torch::rand({2, 3, 32, 32});
  auto k = torch::tensor({30.0, 30.0, 16.0, 16.0}).expand({2, 4}).contiguous();
  model::UPLVSM up(test::micro_model("uplvsm"));
  auto video = render::render_interpolation(up, images, k, 5);
  auto frames = render::render_latent_path(up, images, k, video.poses, k[0].expand({5, 4}), 2);
  EXPECT_LE(test::max_abs_diff(frames, video.frames), 1e-5);
}

namespace {
ModelConfig micro_model(const std::string& variant, bool mapper) {
  auto m = test::micro_model(variant);
  m.transformer.n_layer = 1;
  m.pose_mapper = mapper;
  return m;
}
}  // namespace

TEST(RenderCameraPath, MapperAndPosedVariantsRenderEveryFrameInChunks) {
  torch::manual_seed(0);
  auto images = torch::rand({2, 3, 32, 32});
  auto k = torch::tensor({30.0, 30.0, 16.0, 16.0}).expand({2, 4}).contiguous();
  auto c2w = torch::eye(4).expand({2, 4, 4}).clone();
  c2w[1][0][3] = 2.0;  // baseline 2
  auto poses = render::camera_path_preset("orbit", 5);
  auto kk = k[0].expand({5, 4});
  auto up = model::make_model(micro_model("uplvsm", true));
  auto frames = render::render_camera_path(up, {images, k, {}, {}}, poses, kk, 2);
  EXPECT_EQ(frames.sizes(), (std::vector<int64_t>{5, 3, 32, 32}));
  // Chunking does not change frames.
  EXPECT_LE(test::max_abs_diff(frames, render::render_camera_path(up, {images, k, {}, {}}, poses, kk, 5)), 1e-5);
  auto no_mapper = model::make_model(micro_model("uplvsm", false));
  EXPECT_NE(test::error_of([&] {
              render::render_camera_path(no_mapper, {images, k, {}, {}}, poses, kk);
            }).find("--stage mapper"),
            std::string::npos);
  // A posed variant places the path in the inputs' world: its first frame is input view 0's camera.
  auto pt = model::make_model(micro_model("ptlvsm", false));
  auto posed = render::render_camera_path(pt, {images, k, c2w, {}}, poses, kk, 2);
  model::Views in{images.unsqueeze(0), k.unsqueeze(0), c2w.unsqueeze(0)};
  model::Views first{torch::zeros({1, 1, 3, 32, 32}), k.slice(0, 0, 1).unsqueeze(0), c2w.slice(0, 0, 1).unsqueeze(0)};
  torch::NoGradGuard no_grad;
  auto* pt_lvsm = dynamic_cast<model::PosedLVSMImpl*>(pt.get());
  ASSERT_NE(pt_lvsm, nullptr);
  EXPECT_LE(test::max_abs_diff(posed[0], pt_lvsm->render_posed(in, first, nullptr, false)[0][0]), 1e-5);
  EXPECT_LE(test::max_abs_diff(posed, render::render_camera_path(pt, {images, k, c2w, {}}, poses, kk, 5)), 1e-5);
  EXPECT_NE(test::error_of([&] {
              render::render_camera_path(pt, {images, k, {}, {}}, poses, kk);
            }).find("c2w"),
            std::string::npos);
  EXPECT_EQ(render::side_by_side(images, frames).sizes(), (std::vector<int64_t>{5, 3, 32, 96}));
}
