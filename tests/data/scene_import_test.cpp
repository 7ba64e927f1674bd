// Tests of data/scene_import (bring-your-own scenes: COLMAP text models, nerfstudio transforms.json, EXIF focal
// lengths, the default field of view) and of `uplvsm dataset import`.
#include "uplvsm/data/scene_import.h"

#include <gtest/gtest.h>
#include <libexif/exif-data.h>
#include <libexif/exif-utils.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "scene_import_test_util.h"
#include "test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"

using namespace uplvsm;
using namespace uplvsm::data;
namespace fs = std::filesystem;
using test::cam;
using test::write_bytes;

namespace {

torch::Tensor test_pattern(int h, int w, int seed) {
  auto y = torch::arange(h).view({h, 1, 1}), x = torch::arange(w).view({1, w, 1}), c = torch::arange(3).view({1, 1, 3});
  return ((x * 7 + y * 5 + c * 40 + seed * 31) % 256).to(torch::kUInt8);
}

std::vector<uint8_t> jpeg_bytes(int h, int w, int seed = 0) { return io::encode_jpeg(test_pattern(h, w, seed), 95); }

void write_text(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

// An EXIF entry of the EXIF sub-IFD holding one SHORT or RATIONAL value (libexif's own entries, as cameras write).
void add_short(ExifData* ed, ExifTag tag, uint16_t v) {
  ExifEntry* e = exif_entry_new();
  e->tag = tag, e->format = EXIF_FORMAT_SHORT, e->components = 1, e->size = 2;
  e->data = static_cast<unsigned char*>(std::malloc(2));  // freed by libexif's default allocator (free)
  exif_set_short(e->data, exif_data_get_byte_order(ed), v);
  exif_content_add_entry(ed->ifd[EXIF_IFD_EXIF], e);
  exif_entry_unref(e);
}
void add_rational(ExifData* ed, ExifTag tag, uint32_t num, uint32_t den) {
  ExifEntry* e = exif_entry_new();
  e->tag = tag, e->format = EXIF_FORMAT_RATIONAL, e->components = 1, e->size = 8;
  e->data = static_cast<unsigned char*>(std::malloc(8));
  exif_set_rational(e->data, exif_data_get_byte_order(ed), ExifRational{num, den});
  exif_content_add_entry(ed->ifd[EXIF_IFD_EXIF], e);
  exif_entry_unref(e);
}

// The JPEG with an APP1 EXIF segment spliced in right after its SOI marker.
std::vector<uint8_t> with_exif(const std::vector<uint8_t>& jpeg, const std::function<void(ExifData*)>& fill) {
  ExifData* ed = exif_data_new();
  exif_data_set_byte_order(ed, EXIF_BYTE_ORDER_INTEL);
  fill(ed);
  unsigned char* buf = nullptr;
  unsigned int size = 0;
  exif_data_save_data(ed, &buf, &size);  // starts with the "Exif\0\0" header
  exif_data_unref(ed);
  EXPECT_GT(size, 6u);
  const unsigned len = size + 2;
  std::vector<uint8_t> out(jpeg.size() + 4 + size);
  std::copy(jpeg.begin(), jpeg.begin() + 2, out.begin());  // SOI
  const uint8_t app1[4] = {0xFF, 0xE1, static_cast<uint8_t>(len >> 8), static_cast<uint8_t>(len & 0xFF)};
  std::copy(app1, app1 + 4, out.begin() + 2);
  std::copy(buf, buf + size, out.begin() + 6);
  std::copy(jpeg.begin() + 2, jpeg.end(), out.begin() + 6 + size);
  std::free(buf);
  return out;
}

// A COLMAP project: <dir>/My Scene!/images/{img0.jpg, img1.png, img2.jpg} (64x48) + sparse/0/*.txt. The images are
// listed out of name order; img0 (PINHOLE) has an empty 2D-points line; img1 uses a SIMPLE_RADIAL camera.
fs::path make_colmap_project(const fs::path& dir) {
  const auto project = dir / "My Scene!";
  write_bytes(project / "images/img0.jpg", jpeg_bytes(48, 64, 0));
  io::write_png((project / "images/img1.png").string(), test_pattern(48, 64, 1));
  write_bytes(project / "images/img2.jpg", jpeg_bytes(48, 64, 2));
  write_text(project / "sparse/0/cameras.txt",
             "# Camera list with one line of data per camera:\n"
             "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
             "# Number of cameras: 2\n"
             "1 PINHOLE 64 48 50 52 31 23\n"
             "2 SIMPLE_RADIAL 64 48 40 32 24 0.01\n");
  const double c = std::sqrt(0.5);
  write_text(project / "sparse/0/images.txt",
             "# Image list with two lines of data per image:\n"
             "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
             "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
             "# Number of images: 3, mean observations per image: 1\n"
             "7 2 0 0 0 0.5 -0.25 4 2 img1.png\n"
             "10.5 20.25 -1 30.0 40.0 1\n" +
                 fmt::format("3 {} 0 0 {} 1 2 3 1 img0.jpg\n", c, c) +
                 "\n"  // img0 observes nothing: an empty points line
                 "9 1 0 0 0 -1 0 0 1 img2.jpg\n"
                 "1.0 2.0 -1\n");
  return project;
}

}  // namespace

TEST(SceneImport, ColmapTextModelReproducesIntrinsicsAndPoses) {
  const auto project = make_colmap_project(test::temp_dir("import_colmap"));
  SceneImportOptions opt;
  opt.images_dir = (project / "images").string();
  opt.colmap_dir = (project / "sparse/0").string();
  const auto r = import_scene(opt);
  EXPECT_EQ(r.scene.key, "My_Scene_");  // the project folder (the image folder is "images"), sanitised
  EXPECT_EQ(r.scene.url, "file://" + fs::absolute(project / "images").lexically_normal().string());
  EXPECT_TRUE(r.poses_known);
  EXPECT_EQ(r.intrinsics_source, "colmap");
  ASSERT_EQ(r.image_names, (std::vector<std::string>{"img0.jpg", "img1.png", "img2.jpg"}));
  ASSERT_EQ(r.scene.cameras.sizes(), (std::vector<int64_t>{3, 18}));
  EXPECT_TRUE(torch::equal(r.scene.timestamps, torch::arange(3, torch::kInt64)));
  // The frames are the files' bytes, unchanged.
  for (int i = 0; i < 3; ++i) {
    const auto bytes = io::read_file((project / "images" / r.image_names[i]).string());
    ASSERT_EQ(r.scene.images[i].numel(), static_cast<int64_t>(bytes.size()));
    EXPECT_TRUE(std::equal(bytes.begin(), bytes.end(), r.scene.images[i].data_ptr<uint8_t>()));
  }
  // img0: PINHOLE 50 52 31 23 on 64x48; quaternion 90 degrees about z; t = (1, 2, 3).
  const float expect0[18] = {50.f / 64, 52.f / 48, 31.f / 64, 23.f / 48, 0, 0, 0, -1, 0, 1, 1, 0, 0, 2, 0, 0, 1, 3};
  for (int f = 0; f < 18; ++f) EXPECT_NEAR(cam(r, 0, f), expect0[f], 1e-6) << "field " << f;
  // img1: SIMPLE_RADIAL f=40 (distortion dropped); quaternion (2,0,0,0) normalises to the identity.
  const float expect1[18] = {40.f / 64, 40.f / 48, 0.5f, 0.5f, 0, 0, 1, 0, 0, 0.5f, 0, 1, 0, -0.25f, 0, 0, 1, 4};
  for (int f = 0; f < 18; ++f) EXPECT_NEAR(cam(r, 1, f), expect1[f], 1e-6) << "field " << f;
  EXPECT_NEAR(cam(r, 2, 9), -1.0f, 1e-6);  // img2 (after the empty points line) was parsed: t_x = -1
  ASSERT_EQ(r.warnings.size(), 1u);        // the SIMPLE_RADIAL distortion
  EXPECT_NE(r.warnings[0].find("SIMPLE_RADIAL"), std::string::npos) << r.warnings[0];
}

TEST(SceneImport, TransformsJsonConvertsOpenGlCameraToWorldToOpenCvWorldToCamera) {
  const auto dir = test::temp_dir("import_transforms");
  write_bytes(dir / "images/frame_000.jpg", jpeg_bytes(48, 64, 0));
  write_bytes(dir / "images/frame_001.jpg", jpeg_bytes(48, 64, 1));
  // frame_001: rotated 90 degrees about the world y axis; it overrides the focal length.
  write_text(dir / "transforms.json", R"({
    "fl_x": 100, "fl_y": 90, "cx": 30, "cy": 20, "w": 64, "h": 48,
    "frames": [
      {"file_path": "images/frame_001.jpg", "fl_x": 80,
       "transform_matrix": [[0, 0, 1, 5], [0, 1, 0, 6], [-1, 0, 0, 7], [0, 0, 0, 1]]},
      {"file_path": "./images/frame_000.jpg",
       "transform_matrix": [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1]]}
    ]})");
  SceneImportOptions opt;
  opt.images_dir = (dir / "images").string();
  opt.transforms_path = (dir / "transforms.json").string();
  opt.scene_name = "room";
  const auto r = import_scene(opt);
  EXPECT_EQ(r.scene.key, "room");
  EXPECT_EQ(r.intrinsics_source, "transforms");
  EXPECT_TRUE(r.poses_known);
  ASSERT_EQ(r.image_names, (std::vector<std::string>{"frame_000.jpg", "frame_001.jpg"}));
  EXPECT_TRUE(r.warnings.empty());
  // A camera at (1,2,3) looking down OpenGL's -z (= OpenCV's +z after flipping y and z): w2c = [diag(1,-1,-1) |
  // -R^T c] = [diag(1,-1,-1) | (-1, 2, 3)].
  const float expect0[18] = {100.f / 64, 90.f / 48, 30.f / 64, 20.f / 48, 0, 0, 1, 0, 0, -1, 0, -1, 0, 2, 0, 0, -1, 3};
  for (int f = 0; f < 18; ++f) EXPECT_NEAR(cam(r, 0, f), expect0[f], 1e-6) << "field " << f;
  EXPECT_NEAR(cam(r, 1, 0), 80.f / 64, 1e-6);  // per-frame fl_x wins
  EXPECT_NEAR(cam(r, 1, 1), 90.f / 48, 1e-6);
  // Generic check: the chunk's c2w is the file's c2w with the y and z axes flipped.
  const auto c2w = cameras_to_c2w(r.scene.cameras, "test");
  auto gl = torch::tensor({0., 0., 1., 5., 0., 1., 0., 6., -1., 0., 0., 7., 0., 0., 0., 1.}).view({4, 4});
  auto expected = gl.matmul(torch::diag(torch::tensor({1., -1., -1., 1.})));
  EXPECT_LT(test::max_abs_diff(c2w[1], expected), 1e-6) << c2w[1];
  // A world point 2 units in front of frame_000 (OpenGL -z) lies on its optical axis, in front (z > 0).
  auto w2c = r.scene.cameras[0].slice(0, 6, 18).view({3, 4});
  auto p = w2c.matmul(torch::tensor({1.f, 2.f, 1.f, 1.f}));
  EXPECT_LT(test::max_abs_diff(p, torch::tensor({0., 0., 2.})), 1e-6) << p;

  // instant-NGP: camera_angle_x only (fl_x = 0.5 w / tan(angle / 2)), no w/h: the image's own size.
  write_text(dir / "ngp.json", R"({"camera_angle_x": 1.2, "frames": [
      {"file_path": "images/frame_000.jpg", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]},
      {"file_path": "images/frame_001.jpg", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})");
  opt.transforms_path = (dir / "ngp.json").string();
  const auto ngp = import_scene(opt);
  EXPECT_NEAR(cam(ngp, 0, 0) * 64, 0.5 * 64 / std::tan(0.6), 1e-4);
  EXPECT_NEAR(cam(ngp, 0, 1) * 48, 0.5 * 64 / std::tan(0.6), 1e-4);  // square pixels
  EXPECT_NEAR(cam(ngp, 0, 2), 0.5, 1e-6);
}

TEST(SceneImport, ExifFocalLengthThenDefaultFieldOfView) {
  const auto dir = test::temp_dir("import_exif");
  const auto plain = jpeg_bytes(60, 80);
  // 28 mm equivalent, by the diagonal: fx = 28 * sqrt(80^2 + 60^2) / sqrt(36^2 + 24^2) = 64.7150 px.
  const auto exif35 = with_exif(plain, [](ExifData* ed) { add_short(ed, EXIF_TAG_FOCAL_LENGTH_IN_35MM_FILM, 28); });
  auto k = exif_intrinsics(exif35.data(), exif35.size(), 80, 60);
  ASSERT_TRUE(k.has_value());
  EXPECT_NEAR(k->fx, 64.7150, 1e-4);
  EXPECT_NEAR(k->fy, k->fx, 1e-12);
  EXPECT_NEAR(k->cx, 40, 1e-12);
  EXPECT_NEAR(k->cy, 30, 1e-12);
  // FocalLength 4.5 mm at 1000 px/cm of a 160-px-wide original: 4.5 * 100 px/mm * 80/160 = 225 px.
  const auto exif_mm = with_exif(plain, [](ExifData* ed) {
    add_rational(ed, EXIF_TAG_FOCAL_LENGTH, 9, 2);
    add_rational(ed, EXIF_TAG_FOCAL_PLANE_X_RESOLUTION, 1000, 1);
    add_short(ed, EXIF_TAG_FOCAL_PLANE_RESOLUTION_UNIT, 3);
    add_short(ed, EXIF_TAG_PIXEL_X_DIMENSION, 160);
  });
  k = exif_intrinsics(exif_mm.data(), exif_mm.size(), 80, 60);
  ASSERT_TRUE(k.has_value());
  EXPECT_NEAR(k->fx, 225.0, 1e-9);
  // A focal length without a focal-plane resolution is not enough; no EXIF at all neither.
  const auto exif_f_only = with_exif(plain, [](ExifData* ed) { add_rational(ed, EXIF_TAG_FOCAL_LENGTH, 9, 2); });
  EXPECT_FALSE(exif_intrinsics(exif_f_only.data(), exif_f_only.size(), 80, 60).has_value());
  EXPECT_FALSE(exif_intrinsics(plain.data(), plain.size(), 80, 60).has_value());

  // Images only: case-insensitive extensions, sorted by name, other files ignored; EXIF where there is one.
  write_bytes(dir / "photos/b.JPG", exif35);
  io::write_png((dir / "photos/a.png").string(), test_pattern(60, 80, 3));
  write_bytes(dir / "photos/c.jpeg", plain);
  write_text(dir / "photos/notes.txt", "not an image");
  SceneImportOptions opt;
  opt.images_dir = (dir / "photos").string() + "/";
  const auto r = import_scene(opt);
  EXPECT_EQ(r.scene.key, "photos");
  EXPECT_FALSE(r.poses_known);
  EXPECT_EQ(r.intrinsics_source, "exif+default-fov");
  ASSERT_EQ(r.image_names, (std::vector<std::string>{"a.png", "b.JPG", "c.jpeg"}));
  const double fx_default = 0.5 * 80 / std::tan(M_PI / 6);  // 60 degrees horizontal
  EXPECT_NEAR(cam(r, 0, 0) * 80, fx_default, 1e-3);
  EXPECT_NEAR(cam(r, 0, 1) * 60, fx_default, 1e-3);
  EXPECT_NEAR(cam(r, 1, 0) * 80, 64.7150, 1e-4);
  EXPECT_NEAR(cam(r, 2, 0) * 80, fx_default, 1e-3);
  for (int i = 0; i < 3; ++i)  // identity placeholder poses
    EXPECT_TRUE(torch::equal(r.scene.cameras[i].slice(0, 6, 18),
                             torch::tensor({1.f, 0.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 0.f, 1.f, 0.f})));
  opt.fov_deg = 90;  // fx = W / 2
  EXPECT_NEAR(cam(import_scene(opt), 0, 0), 0.5, 1e-6);
}

TEST(SceneImport, ErrorsNameTheFileLineAndField) {
  const auto dir = test::temp_dir("import_errors");
  SceneImportOptions opt;
  fs::create_directories(dir / "empty");
  opt.images_dir = (dir / "empty").string();
  auto msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find((dir / "empty").string()), std::string::npos) << msg;

  // An image the COLMAP model does not mention: refused, or skipped and counted when asked.
  const auto project = make_colmap_project(dir);
  write_bytes(project / "images/extra.jpg", jpeg_bytes(48, 64, 9));
  opt.images_dir = (project / "images").string();
  opt.colmap_dir = (project / "sparse/0").string();
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("extra.jpg"), std::string::npos) << msg;
  EXPECT_NE(msg.find("--skip-unmatched"), std::string::npos) << msg;
  opt.skip_unmatched = true;
  const auto skipped = import_scene(opt);
  EXPECT_EQ(skipped.skipped, 1);
  EXPECT_EQ(skipped.image_names.size(), 3u);
  opt.skip_unmatched = false;
  fs::remove(project / "images/extra.jpg");

  // An undecodable photo.
  write_text(dir / "bad/x.jpg", "this is not a JPEG");
  opt = SceneImportOptions{};
  opt.images_dir = (dir / "bad").string();
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("x.jpg"), std::string::npos) << msg;
}

TEST(SceneImport, ColmapErrorsNameTheLineAndField) {
  const auto dir = test::temp_dir("import_colmap_errors");
  const auto project = make_colmap_project(dir);
  SceneImportOptions opt;
  opt.images_dir = (project / "images").string();
  opt.colmap_dir = (project / "sparse/0").string();
  std::string msg;
  // Malformed cameras.txt line; unknown model; wrong parameter count; NaN parameter.
  const auto cameras = project / "sparse/0/cameras.txt";
  write_text(cameras, "# c\n1 PINHOLE 64 48 50 52 31 23\n2 PINHOLE 64\n");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find(cameras.string() + ":3"), std::string::npos) << msg;
  EXPECT_NE(msg.find("CAMERA_ID MODEL WIDTH HEIGHT"), std::string::npos) << msg;
  write_text(cameras, "1 PINHOLE 64 48 50 52 31 23\n2 WEIRD 64 48 1 2 3\n");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find(cameras.string() + ":2"), std::string::npos) << msg;
  EXPECT_NE(msg.find("unknown camera model 'WEIRD'"), std::string::npos) << msg;
  write_text(cameras, "1 PINHOLE 64 48 50 52 31\n2 SIMPLE_PINHOLE 64 48 40 32 24\n");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("PINHOLE expects 4 parameters (fx fy cx cy), got 3"), std::string::npos) << msg;
  write_text(cameras, "1 PINHOLE 64 48 50 nan 31 23\n2 SIMPLE_PINHOLE 64 48 40 32 24\n");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("field fy"), std::string::npos) << msg;
  // A camera of another aspect ratio than the image does not describe it.
  write_text(cameras, "1 PINHOLE 64 64 50 52 31 23\n2 SIMPLE_PINHOLE 32 24 20 16 12\n");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("img0.jpg"), std::string::npos) << msg;
  EXPECT_NE(msg.find("aspect"), std::string::npos) << msg;
  // ... while a downscaled one is rescaled (camera 2 is 32x24 for 64x48 images: f 20 -> 40).
  write_text(cameras, "1 PINHOLE 64 48 50 52 31 23\n2 SIMPLE_PINHOLE 32 24 20 16 12\n");
  const auto rescaled = import_scene(opt);
  EXPECT_NEAR(cam(rescaled, 1, 0), 40.f / 64, 1e-6);
  EXPECT_NE(rescaled.warnings.at(0).find("rescaled"), std::string::npos);
  // A bad images.txt pose line names the line and field.
  const auto images = project / "sparse/0/images.txt";
  write_text(images, "# x\n1 1 0 0 0 a 0 0 1 img0.jpg\n\n");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find(images.string() + ":2"), std::string::npos) << msg;
  EXPECT_NE(msg.find("field TX"), std::string::npos) << msg;
}

TEST(SceneImport, TransformsErrorsNameTheField) {
  const auto dir = test::temp_dir("import_transforms_errors");
  SceneImportOptions opt;
  std::string msg;
  // NaN (as Python's json.dump writes it) in a transform_matrix; a wrong last row; a missing image file.
  write_bytes(dir / "t/images/a.jpg", jpeg_bytes(48, 64));
  const auto tj = dir / "t/transforms.json";
  opt = SceneImportOptions{};
  opt.images_dir = (dir / "t/images").string();
  opt.transforms_path = tj.string();
  write_text(tj, R"({"fl_x": 50, "frames": [{"file_path": "images/a.jpg",
      "transform_matrix": [[1, 0, 0, NaN], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]})");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find(tj.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("frames[0].transform_matrix[0][3]"), std::string::npos) << msg;
  EXPECT_NE(msg.find("NaN"), std::string::npos) << msg;
  write_text(tj, R"({"fl_x": 50, "frames": [{"file_path": "images/a.jpg",
      "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]}]})");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("transform_matrix[3]: expected the last row 0 0 0 1"), std::string::npos) << msg;
  write_text(tj, R"({"fl_x": 50, "frames": [{"file_path": "images/a.jpg",
      "transform_matrix": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]})");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("not orthonormal"), std::string::npos) << msg;
  // A field nested deep instead of a number is described, not printed (printing recursed per level; fuzzing).
  write_text(tj, R"({"fl_x": )" + std::string(100000, '[') + std::string(100000, ']') +
                     R"(, "frames": [{"file_path": "images/a.jpg",
      "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]})");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("field 'fl_x': expected a number, got an array of 1"), std::string::npos) << msg;
  write_text(tj, R"({"fl_x": 50, "frames": [{"file_path": "images/gone.jpg",
      "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]})");
  msg = test::error_of([&] { import_scene(opt); });
  EXPECT_NE(msg.find("gone.jpg"), std::string::npos) << msg;
}

TEST(SceneImport, CliImportsPosedAndUnposedScenesIntoChunksAndIndices) {
  const auto dir = test::temp_dir("import_cli");
  const auto project = make_colmap_project(dir);
  const auto root = dir / "dataset";
  write_bytes(dir / "holiday/p1.jpg", jpeg_bytes(48, 64, 4));
  write_bytes(dir / "holiday/p2.jpg", jpeg_bytes(48, 64, 5));
  std::string out;
  ASSERT_EQ(test::run_cli(fmt::format("dataset import --images '{}' --colmap '{}' --scene garden --out '{}' "
                                      "--context 0 2 --target 1",
                                      (project / "images").string(), (project / "sparse/0").string(), root.string()),
                          &out),
            0);
  EXPECT_NE(out.find("imported 'garden': 3 frames, intrinsics colmap, poses known"), std::string::npos) << out;
  ASSERT_EQ(test::run_cli(fmt::format("dataset import --images '{}' --out '{}' --context 0 1 --target 1",
                                      (dir / "holiday").string(), root.string()),
                          &out),
            0);
  EXPECT_NE(out.find("poses unknown"), std::string::npos) << out;
  EXPECT_NE(out.find("posed variants"), std::string::npos) << out;

  EXPECT_EQ(read_chunk_index((root / "test").string()),
            (std::map<std::string, std::string>{{"garden", "garden.torch"}, {"holiday", "holiday.torch"}}));
  std::ifstream unposed_in(root / "test/unposed.json");
  EXPECT_EQ(nlohmann::json::parse(unposed_in), nlohmann::json({"holiday"}));
  const auto eval = read_eval_index((root / "evaluation_index.json").string());
  ASSERT_EQ(eval.size(), 2u);
  EXPECT_EQ(eval[0].key, "garden");
  EXPECT_EQ(eval[0].context, (std::vector<int64_t>{0, 2}));
  EXPECT_EQ(eval[0].target, (std::vector<int64_t>{1}));

  // The chunk reads back through the dataset: cameras as imported (img0: 90 degrees about z, t = (1,2,3)).
  ChunkDataset ds(root.string(), "test");
  const int64_t g = ds.find("garden");
  ASSERT_GE(g, 0);
  EXPECT_EQ(ds.num_frames(g), 3);
  const auto views = ds.load_views(g, {0, 2}, PreprocessOptions{28, 14, true});
  EXPECT_EQ(views.images.sizes(), (std::vector<int64_t>{2, 3, 28, 28}));
  auto w2c = torch::tensor({0., -1., 0., 1., 1., 0., 0., 2., 0., 0., 1., 3., 0., 0., 0., 1.}).view({4, 4});
  EXPECT_LT(test::max_abs_diff(views.c2w[0], torch::inverse(w2c)), 1e-5) << views.c2w[0];
  EXPECT_TRUE(ds.poses_known(g));
  ASSERT_GE(ds.find("holiday"), 0);
  EXPECT_FALSE(ds.poses_known(ds.find("holiday")));

  // The same key again: refused without --force; an out-of-range frame is refused before anything is written.
  const auto args = fmt::format("dataset import --images '{}' --out '{}'", (dir / "holiday").string(), root.string());
  EXPECT_NE(test::run_cli(args, &out), 0);
  EXPECT_NE(out.find("--force"), std::string::npos) << out;
  EXPECT_NE(test::run_cli(args + " --scene other --context 0 1 --target 5", &out), 0);
  EXPECT_NE(out.find("out of range"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(root / "test/other.torch"));
  EXPECT_EQ(test::run_cli(args + " --force", &out), 0) << out;
}
