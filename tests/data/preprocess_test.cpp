// Tests of data/preprocess: the official resize-width rule, the 224 crop of a fixture frame against numbers from
// Pillow, intrinsics, camera row conversions and errors. Bit-exactness against Pillow on more images is checked by
// PreprocessPillow.MatchesDump when UPLVSM_PIL_CHECK_DIR points at the output of tools/check_preprocess.py.
#include "uplvsm/data/preprocess.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include <nlohmann/json.hpp>

#include "test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/image.h"

namespace uplvsm::data {
namespace {
using test::error_of;

using test::fixture;

// Frame 0 of test scene 20e408dd375292a1, decoded, and its camera row.
std::pair<torch::Tensor, torch::Tensor> fixture_frame0() {
  for (const auto& s : read_chunk(fixture("re10k_chunks/root/test/000000.torch")))
    if (s.key == "20e408dd375292a1")
      return {io::decode_jpeg(s.images[0].data_ptr<uint8_t>(), s.images[0].numel(), "frame0"),
              s.cameras.slice(0, 0, 1)};
  throw std::runtime_error("fixture scene missing");
}

TEST(Preprocess, ResizedWidthFollowsOfficialRounding) {
  EXPECT_EQ(resized_width(360, 640, 224, 14), 392);
  EXPECT_EQ(resized_width(360, 640, 518, 14), 924);
  EXPECT_EQ(resized_width(224, 35, 224, 14), 28);    // int 35 / 14 = 2.5 -> 2 (Python rounds half to even)
  EXPECT_EQ(resized_width(224, 49, 224, 14), 56);    // 3.5 -> 4
  EXPECT_EQ(resized_width(100, 150, 224, 14), 336);  // upscaling
  EXPECT_THROW(resized_width(0, 10, 224, 14), std::runtime_error);
}

TEST(Preprocess, FixtureCropMatchesPillow) {
  UPLVSM_NEEDS_FIXTURES();
  auto [frame, cams] = fixture_frame0();
  SceneViews v = preprocess({frame}, cams, PreprocessOptions{});
  ASSERT_EQ(v.images.sizes(), (std::vector<int64_t>{1, 3, 224, 224}));
  auto u8 = io::to_u8_hwc(v.images[0]);
  // Reference numbers from tools/check_preprocess.py (PIL 9.4: Image.open(jpeg).convert("RGB")
  // .resize((392, 224), Image.LANCZOS), then columns 84..307): pixels (row, col) and the sum of the whole crop.
  const std::vector<std::tuple<int, int, std::array<int, 3>>> pil = {
      {0, 0, {118, 135, 124}}, {100, 150, {80, 82, 50}}, {223, 223, {46, 32, 19}}, {57, 191, {99, 104, 66}}};
  for (const auto& [r, c, rgb] : pil)
    for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(u8[r][c][ch].item<int>(), rgb[ch]) << r << "," << c << " ch " << ch;
  EXPECT_EQ(u8.to(torch::kInt64).sum().item<int64_t>(), 11065923);
  // Intrinsics: normalised * (W0, H0), scaled by (392/640, 224/360), cx shifted by the crop start 84.
  auto c = cams.to(torch::kFloat64)[0];
  EXPECT_NEAR(v.fxfycxcy[0][0].item<double>(), c[0].item<double>() * 640 * 392 / 640, 1e-3);
  EXPECT_NEAR(v.fxfycxcy[0][1].item<double>(), c[1].item<double>() * 360 * 224 / 360, 1e-3);
  EXPECT_NEAR(v.fxfycxcy[0][2].item<double>(), c[2].item<double>() * 392 - 84, 1e-3);
  EXPECT_NEAR(v.fxfycxcy[0][3].item<double>(), c[3].item<double>() * 224, 1e-3);
  EXPECT_NEAR(v.fxfycxcy[0][2].item<double>(), 112.0, 1e-3);  // cx = W/2 in the fixture: centred after the crop
  // Without the crop: 392 wide, cx not shifted.
  PreprocessOptions wide;
  wide.square_crop = false;
  SceneViews w = preprocess({frame}, cams, wide);
  EXPECT_EQ(w.images.sizes(), (std::vector<int64_t>{1, 3, 224, 392}));
  EXPECT_NEAR(w.fxfycxcy[0][2].item<double>(), 196.0, 1e-3);
  EXPECT_TRUE(torch::equal(w.images.slice(3, 84, 308), v.images));
}

TEST(Preprocess, CameraConversionsRoundTrip) {
  auto rot = torch::tensor({0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0}, torch::kFloat64).view({3, 3});
  auto w2c = torch::eye(4, torch::kFloat64);
  w2c.slice(0, 0, 3).slice(1, 0, 3).copy_(rot);
  w2c[0][3] = 1.5, w2c[1][3] = -2.0, w2c[2][3] = 0.25;
  auto k = torch::tensor({{100.0, 110.0, 64.0, 36.0}});
  auto cams = make_cameras18(k, w2c.unsqueeze(0), 128, 72);
  EXPECT_EQ(cams.sizes(), (std::vector<int64_t>{1, 18}));
  EXPECT_NEAR(cams[0][0].item<float>(), 100.0f / 128, 1e-7);
  EXPECT_EQ(cams[0][4].item<float>(), 0.0f);
  EXPECT_LT(test::max_abs_diff(cameras_to_fxfycxcy(cams, 128, 72), k), 1e-4);
  auto c2w = cameras_to_c2w(cams, "roundtrip");
  EXPECT_LT(test::max_abs_diff(c2w[0], torch::linalg_inv(w2c)), 1e-6);
}

TEST(Preprocess, BadCamerasAndFramesThrow) {
  auto img = torch::zeros({20, 30, 3}, torch::kUInt8);
  auto cams = torch::zeros({2, 18});
  cams.select(1, 6).fill_(1), cams.select(1, 11).fill_(1), cams.select(1, 16).fill_(1);
  cams.slice(1, 0, 4).fill_(0.5);
  PreprocessOptions opt;
  opt.image_size = 28;
  EXPECT_EQ(preprocess({img, img}, cams, opt, "scene s").images.sizes(), (std::vector<int64_t>{2, 3, 28, 28}));
  auto nan = cams.clone();
  nan[1][3] = std::numeric_limits<float>::infinity();
  auto msg = error_of([&] { preprocess({img, img}, nan, opt, "scene s"); });
  EXPECT_NE(msg.find("scene s"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cameras"), std::string::npos) << msg;
  EXPECT_NE(msg.find("frame 1"), std::string::npos) << msg;
  msg = error_of([&] { cameras_to_c2w(torch::zeros({2, 18}), "scene s"); });
  EXPECT_NE(msg.find("singular"), std::string::npos) << msg;
  EXPECT_NE(msg.find("frame 0"), std::string::npos) << msg;
  msg = error_of([&] { preprocess({img}, torch::zeros({1, 16}), opt, "scene s"); });
  EXPECT_NE(msg.find("[N,18]"), std::string::npos) << msg;
  msg = error_of([&] { preprocess({img, img}, cams.slice(0, 0, 1), opt, "scene s"); });
  EXPECT_NE(msg.find("camera rows"), std::string::npos) << msg;
  // Frames whose outputs differ in size cannot be stacked.
  auto tall = torch::zeros({30, 20, 3}, torch::kUInt8);
  PreprocessOptions nocrop = opt;
  nocrop.square_crop = false;
  EXPECT_THROW(preprocess({img, tall}, cams, nocrop, "scene s"), std::runtime_error);
}

TEST(Preprocess, ResizeKeepsConstantImagesAndSizes) {
  auto img = torch::full({37, 53, 3}, 200, torch::kUInt8);
  for (auto [w, h] : std::vector<std::pair<int, int>>{{20, 10}, {53, 80}, {100, 37}, {7, 3}}) {
    auto out = resize_lanczos_pil(img, w, h);
    EXPECT_EQ(out.sizes(), (std::vector<int64_t>{h, w, 3}));
    EXPECT_EQ(out.min().item<int>(), 200);
    EXPECT_EQ(out.max().item<int>(), 200);
  }
  EXPECT_TRUE(torch::equal(resize_lanczos_pil(img, 53, 37), img));
}

// Bit-exact comparison with Pillow on the images written by tools/check_preprocess.py (developer check).
TEST(PreprocessPillow, MatchesDump) {
  const char* dir = std::getenv("UPLVSM_PIL_CHECK_DIR");
  if (!dir) GTEST_SKIP() << "set UPLVSM_PIL_CHECK_DIR to the output folder of tools/check_preprocess.py";
  std::ifstream in(std::string(dir) + "/manifest.json");
  auto manifest = nlohmann::json::parse(in);
  ASSERT_GT(manifest.size(), 0u);
  for (const auto& m : manifest) {
    auto input = io::read_image(std::string(dir) + "/" + m["input"].get<std::string>());
    auto expected = io::read_image(std::string(dir) + "/" + m["expected"].get<std::string>());
    auto out = resize_lanczos_pil(input, m["width"].get<int>(), m["height"].get<int>());
    ASSERT_EQ(out.sizes(), expected.sizes()) << m.dump();
    EXPECT_EQ(test::max_abs_diff(out, expected), 0.0) << m.dump();
  }
}

}  // namespace
}  // namespace uplvsm::data
