// Tests of io/image: JPEG decode against PIL's decode of the fixture, encode/decode and PNG round trips, layout
// conversions and error messages.
#include "uplvsm/io/image.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "io/image_bomb.h"
#include "test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/safetensors.h"

namespace uplvsm::io {
namespace {
using test::error_of;

using test::fixture;

// Restores the process-wide pixel limit when a test ends.
struct PixelLimitScope {
  ~PixelLimitScope() { set_max_image_pixels(kDefaultMaxImagePixels); }
};

// A smooth test image (JPEG-friendly).
torch::Tensor gradient_image(int h, int w) {
  auto y = torch::linspace(0, 1, h).view({h, 1, 1}).expand({h, w, 1});
  auto x = torch::linspace(0, 1, w).view({1, w, 1}).expand({h, w, 1});
  auto img = torch::cat({x, y, (x + y) / 2}, 2);
  return img.mul(255).round().to(torch::kUInt8).contiguous();
}

TEST(Image, DecodeFixtureFrameMatchesPil) {
  UPLVSM_NEEDS_FIXTURES();
  auto scenes = data::read_chunk(fixture("re10k_chunks/root/test/000000.torch"));
  const data::RawScene* scene = nullptr;
  for (const auto& s : scenes)
    if (s.key == "20e408dd375292a1") scene = &s;
  ASSERT_NE(scene, nullptr);
  const auto& bytes = scene->images[0];
  auto img = decode_jpeg(bytes.data_ptr<uint8_t>(), bytes.numel(), "frame0");
  auto truth =
      read_safetensors(fixture("re10k_chunks/truth.safetensors")).tensors.at("decoded.20e408dd375292a1.frame0");
  ASSERT_EQ(img.sizes(), truth.sizes());
  auto diff = (img.to(torch::kInt32) - truth.to(torch::kInt32)).abs();
  EXPECT_LT(diff.to(torch::kFloat64).mean().item<double>(), 1.0);
  EXPECT_LE(diff.max().item<int>(), 8);
  auto [h, w] = jpeg_size(bytes.data_ptr<uint8_t>(), bytes.numel(), "frame0");
  EXPECT_EQ(h, 360);
  EXPECT_EQ(w, 640);
}

TEST(Image, JpegRoundTripIsClose) {
  auto img = gradient_image(48, 80);
  auto bytes = encode_jpeg(img, 95);
  ASSERT_GT(bytes.size(), 100u);
  auto back = decode_jpeg(bytes.data(), bytes.size(), "roundtrip");
  ASSERT_EQ(back.sizes(), img.sizes());
  EXPECT_LT(test::max_abs_diff(back, img), 8.0);
  // Gray input encodes as a gray JPEG and decodes expanded to RGB.
  auto gray = img.select(2, 0).contiguous();
  auto gbytes = encode_jpeg(gray, 90);
  auto gback = decode_jpeg(gbytes.data(), gbytes.size(), "gray");
  EXPECT_EQ(gback.sizes(), (std::vector<int64_t>{48, 80, 3}));
  EXPECT_EQ(test::max_abs_diff(gback.select(2, 0), gback.select(2, 2)), 0.0);
}

TEST(Image, GarbageAndTruncatedJpegThrowNamingSource) {
  std::vector<uint8_t> garbage(100, 0x42);
  EXPECT_NE(
      error_of([&] { decode_jpeg(garbage.data(), garbage.size(), "scene abc frame 3"); }).find("scene abc frame 3"),
      std::string::npos);
  auto bytes = encode_jpeg(gradient_image(64, 64), 90);
  // A JPEG header followed by garbage: libjpeg's own error, with our source name.
  std::vector<uint8_t> bad(bytes.begin(), bytes.begin() + 20);
  bad.insert(bad.end(), 200, 0x00);
  auto msg = error_of([&] { decode_jpeg(bad.data(), bad.size(), "bad.jpg"); });
  EXPECT_NE(msg.find("bad.jpg"), std::string::npos) << msg;
  // Cut inside the entropy-coded data of a large, busy image (headers are a few hundred bytes).
  torch::manual_seed(0);
  auto busy = encode_jpeg(torch::randint(0, 256, {256, 256, 3}, torch::kUInt8), 90);
  std::vector<uint8_t> truncated(busy.begin(), busy.begin() + busy.size() / 2);
  msg = error_of([&] { decode_jpeg(truncated.data(), truncated.size(), "half.jpg"); });
  EXPECT_NE(msg.find("half.jpg"), std::string::npos) << msg;
  EXPECT_NE(msg.find("truncated"), std::string::npos) << msg;
}

TEST(Image, PngRoundTripAndReadImageByMagic) {
  auto dir = test::temp_dir("image_png");
  auto img = gradient_image(30, 50);
  write_png((dir / "rgb.png").string(), img);
  EXPECT_EQ(test::max_abs_diff(read_image((dir / "rgb.png").string()), img), 0.0);
  auto gray = img.select(2, 1).contiguous();
  write_png((dir / "gray.png").string(), gray);
  auto back = read_image((dir / "gray.png").string());
  EXPECT_EQ(test::max_abs_diff(back.select(2, 0), gray), 0.0);
  EXPECT_EQ(test::max_abs_diff(back.select(2, 2), gray), 0.0);
  // A JPEG saved under a .png name is still read as JPEG (magic bytes decide).
  auto bytes = encode_jpeg(img, 95);
  std::ofstream((dir / "fake.png").string(), std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  EXPECT_LT(test::max_abs_diff(read_image((dir / "fake.png").string()), img), 8.0);
  std::ofstream((dir / "text.png").string()) << "hello";
  EXPECT_NE(error_of([&] { read_image((dir / "text.png").string()); }).find("text.png"), std::string::npos);
  EXPECT_NE(error_of([&] { read_image((dir / "missing.png").string()); }).find("missing.png"), std::string::npos);
  // No temporary files are left behind by the atomic writes.
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 4);
  test::remove_tree(dir);
}

TEST(Image, DecodeImageTellsPngFromJpegInMemory) {
  auto img = gradient_image(30, 50);
  auto png = encode_png(img);
  EXPECT_EQ(image_size(png.data(), png.size(), "png"), (std::pair<int, int>{30, 50}));
  EXPECT_EQ(test::max_abs_diff(decode_image(png.data(), png.size(), "png"), img), 0.0);
  auto jpeg = encode_jpeg(img, 95);
  EXPECT_EQ(image_size(jpeg.data(), jpeg.size(), "jpeg"), (std::pair<int, int>{30, 50}));
  EXPECT_LT(test::max_abs_diff(decode_image(jpeg.data(), jpeg.size(), "jpeg"), img), 8.0);
  const std::vector<uint8_t> junk = {'G', 'I', 'F', '8', '9', 'a', 0, 0};
  EXPECT_NE(error_of([&] { decode_image(junk.data(), junk.size(), "scene x frame 3"); }).find("scene x frame 3"),
            std::string::npos);
  std::vector<uint8_t> cut(png.begin(), png.begin() + 40);
  EXPECT_NE(error_of([&] { decode_image(cut.data(), cut.size(), "cut.png"); }).find("cut.png"), std::string::npos);
}

TEST(Image, PngBombIsRefusedFromItsHeaderBeforeDecoding) {
  // The bomb: 30000 x 30000 = 900 MP (2.7 GB decoded), Pillow refuses it too.
  const auto bomb = test::png_declaring(30000, 30000);
  EXPECT_EQ(image_size(bomb.data(), bomb.size(), "bomb.png"), (std::pair<int, int>{30000, 30000}));
  const auto msg = error_of([&] { decode_image(bomb.data(), bomb.size(), "uploads/bomb.png"); });
  EXPECT_NE(msg.find("uploads/bomb.png"), std::string::npos) << msg;
  EXPECT_NE(msg.find("30000x30000 = 900000000 pixels exceeds the limit of 178956970"), std::string::npos) << msg;
  EXPECT_NE(msg.find("--max-image-pixels"), std::string::npos) << msg;

  auto dir = test::temp_dir("image_bomb");
  const auto path = (dir / "bomb.png").string();
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bomb.data()), std::streamsize(bomb.size()));
  EXPECT_NE(error_of([&] { read_image(path); }).find(path + ": image of 30000x30000"), std::string::npos);
  // Within the limit the header passes and the decoder meets the small image's data: a corrupt PNG, not a bomb.
  const auto under = test::png_declaring(300, 30);
  const auto corrupt = error_of([&] { decode_image(under.data(), under.size(), "under.png"); });
  EXPECT_EQ(corrupt.find("exceeds the limit"), std::string::npos) << corrupt;
  EXPECT_NE(corrupt.find("under.png: corrupt PNG"), std::string::npos) << corrupt;
}

TEST(Image, JpegBombIsRefusedFromItsHeaderBeforeDecoding) {
  const auto bomb = test::jpeg_declaring(60000, 50000);
  EXPECT_EQ(jpeg_size(bomb.data(), bomb.size(), "bomb.jpg"), (std::pair<int, int>{50000, 60000}));
  for (const auto& msg : {error_of([&] { decode_jpeg(bomb.data(), bomb.size(), "bomb.jpg"); }),
                          error_of([&] { decode_image(bomb.data(), bomb.size(), "bomb.jpg"); })})
    EXPECT_NE(msg.find("bomb.jpg: image of 60000x50000 = 3000000000 pixels exceeds the limit"), std::string::npos)
        << msg;
}

TEST(Image, PixelLimitCanBeRaisedLoweredOrSwitchedOff) {
  PixelLimitScope restore;
  EXPECT_EQ(max_image_pixels(), kDefaultMaxImagePixels);
  const auto png = test::small_image_bytes(true), jpeg = test::small_image_bytes(false);  // 16 x 8 = 128 pixels
  set_max_image_pixels(127);
  EXPECT_NE(error_of([&] { decode_image(png.data(), png.size(), "p"); }).find("limit of 127 pixels"),
            std::string::npos);
  EXPECT_NE(error_of([&] { decode_image(jpeg.data(), jpeg.size(), "j"); }).find("limit of 127 pixels"),
            std::string::npos);
  set_max_image_pixels(128);
  EXPECT_EQ(decode_image(png.data(), png.size(), "p").sizes(), (std::vector<int64_t>{8, 16, 3}));
  EXPECT_EQ(decode_image(jpeg.data(), jpeg.size(), "j").sizes(), (std::vector<int64_t>{8, 16, 3}));
  set_max_image_pixels(0);  // no limit
  EXPECT_EQ(error_of([&] { check_image_pixels(30000, 30000, "x"); }), "(no exception)");
  EXPECT_THROW(set_max_image_pixels(-1), std::invalid_argument);
  EXPECT_NE(error_of([&] { check_image_pixels(0, 5, "empty.png"); }).find("empty.png"), std::string::npos);
}

TEST(Image, FloatConversions) {
  auto img = gradient_image(5, 7);
  auto f = to_float_chw(img);
  EXPECT_EQ(f.sizes(), (std::vector<int64_t>{3, 5, 7}));
  EXPECT_EQ(f.scalar_type(), torch::kFloat32);
  EXPECT_FLOAT_EQ(f[0][0][6].item<float>(), img[0][6][0].item<uint8_t>() / 255.0f);
  EXPECT_EQ(test::max_abs_diff(to_u8_hwc(f), img), 0.0);
  auto out_of_range = torch::tensor({-0.5f, 0.5f, 1.5f, 0.4999f, 0.502f, 1.0f}).view({3, 1, 2});
  auto u8 = to_u8_hwc(out_of_range);
  EXPECT_EQ(u8[0][0][0].item<uint8_t>(), 0);    // clamped
  EXPECT_EQ(u8[0][1][0].item<uint8_t>(), 128);  // 0.5 * 255 = 127.5 -> 128 (torch.round, half to even)
  EXPECT_EQ(u8[0][1][1].item<uint8_t>(), 127);  // 0.4999 * 255 = 127.47
  EXPECT_EQ(u8[0][0][1].item<uint8_t>(), 255);  // clamped
  EXPECT_THROW(to_float_chw(torch::zeros({3, 4, 4})), std::runtime_error);
  EXPECT_THROW(to_u8_hwc(torch::zeros({4, 4, 3})), std::runtime_error);
}

}  // namespace
}  // namespace uplvsm::io
