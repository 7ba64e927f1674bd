// data/scene_import with photos' EXIF (`uplvsm dataset import` without a model): a portrait phone photo stored
// sideways is stored upright with the camera of the upright image; an implausible focal-length tag falls back to the
// default field of view with a warning naming the tag and its value; a model's images keep their pixels as stored.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "io/exif_jpeg.h"
#include "scene_import_test_util.h"
#include "test_util.h"
#include "uplvsm/data/scene_import.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/exif.h"
#include "uplvsm/io/image.h"

using namespace uplvsm;
using namespace uplvsm::data;
namespace fs = std::filesystem;
using test::cam;
using test::write_bytes;

namespace {

torch::Tensor frame_pixels(const ImportedScene& s, int64_t i) {
  const auto& bytes = s.scene.images[i];
  return io::decode_image(bytes.data_ptr<uint8_t>(), bytes.numel(), "frame " + std::to_string(i));
}

bool any_contains(const std::vector<std::string>& lines, const std::string& part) {
  return std::any_of(lines.begin(), lines.end(),
                     [&](const std::string& l) { return l.find(part) != std::string::npos; });
}

// A portrait photo (48 wide, 80 tall, red over blue) as a phone stores it: 80 x 48 sideways, EXIF orientation 6.
std::vector<uint8_t> sideways_portrait(int focal_35mm) {
  return test::jpeg_with_exif(test::stored_for_orientation_6(test::red_over_blue(80, 48)), 6, focal_35mm);
}

}  // namespace

TEST(SceneImportExif, PortraitPhotosAreStoredUprightWithTheUprightCamera) {
  const auto dir = test::temp_dir("import_exif_upright");
  write_bytes(dir / "photos/p1.jpg", sideways_portrait(26));
  write_bytes(dir / "photos/p2.jpg", sideways_portrait(26));
  SceneImportOptions opt;
  opt.images_dir = (dir / "photos").string();
  const auto r = import_scene(opt);
  EXPECT_EQ(r.turned_upright, 2);
  EXPECT_EQ(r.intrinsics_source, "exif");
  EXPECT_TRUE(r.warnings.empty()) << ::testing::PrintToString(r.warnings);
  for (int64_t i = 0; i < 2; ++i) {
    const auto upright = frame_pixels(r, i);
    EXPECT_EQ(upright.sizes(), torch::IntArrayRef({80, 48, 3}));
    EXPECT_TRUE(test::is_red_over_blue(upright));
    // The stored frame carries no orientation tag: nothing turns it a second time.
    EXPECT_EQ(exif_orientation(r.scene.images[i].data_ptr<uint8_t>(), r.scene.images[i].numel()), 1);
  }
  // f = 26 * sqrt(80^2 + 48^2) / sqrt(36^2 + 24^2) = 56.0635 px, normalised by the upright 48 x 80 image.
  EXPECT_NEAR(cam(r, 0, 0), 56.0635 / 48, 1e-5);
  EXPECT_NEAR(cam(r, 0, 1), 56.0635 / 80, 1e-5);
  EXPECT_NEAR(cam(r, 0, 2), 0.5, 1e-6);
  EXPECT_NEAR(cam(r, 0, 3), 0.5, 1e-6);
  // Without a focal-length tag the default 60-degree view spans the upright width: fx = 24 / tan(30 deg).
  write_bytes(dir / "photos/p1.jpg", sideways_portrait(0));
  const auto d = import_scene(opt);
  EXPECT_NEAR(cam(d, 0, 0) * 48, 24 / std::tan(M_PI / 6), 1e-4);
}

// The principal point follows the pixels through each of the 8 orientations: a pixel marked at the stored
// principal point lands, after io::apply_exif_orientation, at the upright one.
TEST(SceneImportExif, UprightIntrinsicsFollowThePixels) {
  const PinholeIntrinsics stored{50, 60, 2.5, 1.5, 6, 4};  // the centre of pixel (2, 1) of a 6 x 4 image
  for (int orientation = 1; orientation <= 8; ++orientation) {
    SCOPED_TRACE("orientation " + std::to_string(orientation));
    auto img = torch::zeros({4, 6, 3}, torch::kUInt8);
    img[1][2].fill_(255);
    const auto up = io::apply_exif_orientation(img, orientation);
    const auto k = upright_intrinsics(stored, orientation);
    EXPECT_EQ(k.width, up.size(1));
    EXPECT_EQ(k.height, up.size(0));
    const auto hit = up.select(2, 0).nonzero();
    ASSERT_EQ(hit.size(0), 1);
    EXPECT_EQ(k.cx - 0.5, hit[0][1].item<double>());
    EXPECT_EQ(k.cy - 0.5, hit[0][0].item<double>());
    EXPECT_EQ(k.fx, orientation >= 5 ? 60 : 50);  // a quarter turn swaps the axes
  }
}

// A 1 mm FocalLengthIn35mmFilm (a 173-degree view across a 4:3 photo) is refused: that photo gets the --fov camera,
// the others their EXIF one, and the warning names the file, the tag, its value and the accepted range.
TEST(SceneImportExif, AnImplausibleFocalLengthFallsBackToTheFieldOfViewWithAWarning) {
  const auto dir = test::temp_dir("import_exif_bad_focal");
  const auto bad = test::jpeg_with_exif(test::red_over_blue(30, 40), 1, 1);
  write_bytes(dir / "photos/a.jpg", bad);
  write_bytes(dir / "photos/b.jpg", test::jpeg_with_exif(test::red_over_blue(30, 40), 1, 26));
  std::string rejected;
  EXPECT_FALSE(exif_intrinsics(bad.data(), bad.size(), 40, 30, &rejected));
  EXPECT_NE(rejected.find("FocalLengthIn35mmFilm = 1 mm"), std::string::npos) << rejected;
  SceneImportOptions opt;
  opt.images_dir = (dir / "photos").string();
  opt.fov_deg = 90;
  const auto r = import_scene(opt);
  EXPECT_EQ(r.intrinsics_source, "exif+default-fov");
  EXPECT_NEAR(cam(r, 0, 0), 0.5, 1e-6);                                      // 90 degrees: fx = W / 2
  EXPECT_NEAR(cam(r, 1, 0) * 40, 26 * 50 / io::kFullFrameDiagonalMm, 1e-4);  // 30.0463 px
  const auto where = (dir / "photos/a.jpg").string() + ": EXIF FocalLengthIn35mmFilm = 1 mm rejected";
  EXPECT_TRUE(any_contains(r.warnings, where)) << ::testing::PrintToString(r.warnings);
  EXPECT_TRUE(any_contains(r.warnings, "[8, 3000] mm")) << ::testing::PrintToString(r.warnings);
  EXPECT_TRUE(any_contains(r.warnings, "a 90 degree horizontal field of view used"))
      << ::testing::PrintToString(r.warnings);
}

// A model's cameras and poses were solved on the pixels as stored (COLMAP does not apply the orientation): its
// images are kept byte for byte, and a warning says which orientation was left alone.
TEST(SceneImportExif, AModelsImagesKeepTheirPixelsAsStored) {
  const auto dir = test::temp_dir("import_exif_model");
  const auto sideways = sideways_portrait(26);
  write_bytes(dir / "images/p1.jpg", sideways);
  write_bytes(dir / "images/p2.jpg", sideways);
  std::ofstream(dir / "transforms.json") << R"({"fl_x": 50, "w": 80, "h": 48, "frames": [
      {"file_path": "images/p1.jpg", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]},
      {"file_path": "images/p2.jpg", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})";
  SceneImportOptions opt;
  opt.images_dir = (dir / "images").string();
  opt.transforms_path = (dir / "transforms.json").string();
  const auto r = import_scene(opt);
  EXPECT_EQ(r.turned_upright, 0);
  ASSERT_EQ(r.scene.images[0].numel(), static_cast<int64_t>(sideways.size()));
  EXPECT_TRUE(std::equal(sideways.begin(), sideways.end(), r.scene.images[0].data_ptr<uint8_t>()));
  EXPECT_NEAR(cam(r, 0, 0), 50.0 / 80, 1e-6);
  EXPECT_TRUE(any_contains(r.warnings, "2 image(s) have an EXIF orientation that was not applied"))
      << ::testing::PrintToString(r.warnings);
  EXPECT_TRUE(any_contains(r.warnings, "p1.jpg (orientation 6)")) << ::testing::PrintToString(r.warnings);
}
