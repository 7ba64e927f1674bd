// data::load_photos: users' photo files as views (what `render --images`, the Python module and the C++ example
// feed the model): sizes, the field-of-view camera, identity poses, and errors naming the file or the argument; a
// phone's portrait photo stored sideways turned upright by its EXIF orientation, its field of view from EXIF (the 35 mm
// equivalent by the diagonal; an implausible one rejected by name).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <stdexcept>

#include "io/exif_jpeg.h"
#include "test_util.h"
#include "uplvsm/data/photo.h"
#include "uplvsm/io/image.h"

using namespace uplvsm;

namespace {

std::string write_photo(const std::filesystem::path& dir, const std::string& name, const std::vector<uint8_t>& bytes) {
  const auto path = (dir / name).string();
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  return path;
}

std::string write_photo(const std::filesystem::path& dir, const std::string& name, int64_t h, int64_t w) {
  const auto path = (dir / name).string();
  io::write_png(path, torch::randint(0, 256, {h, w, 3}, torch::kUInt8));
  return path;
}

}  // namespace

TEST(LoadPhotos, ViewsWithTheFieldOfViewCameraAndIdentityPoses) {
  const auto dir = test::temp_dir("load_photos");
  const auto a = write_photo(dir, "a.png", 40, 60), b = write_photo(dir, "b.png", 40, 60);
  auto views = data::load_photos({a, b}, /*fov_degrees=*/90.0, {28, 14, true});
  EXPECT_EQ(views.images.sizes(), torch::IntArrayRef({2, 3, 28, 28}));
  EXPECT_EQ(views.frames, (std::vector<int64_t>{0, 1}));
  // fov 90: fx = W / 2 of the resized (42 wide) photo; the principal point at the centre of the 28x28 crop.
  EXPECT_TRUE(torch::allclose(views.fxfycxcy, torch::tensor({21.0f, 21.0f, 14.0f, 14.0f}).expand({2, 4}), 0, 1e-4))
      << views.fxfycxcy;
  EXPECT_TRUE(torch::equal(views.c2w, torch::eye(4).expand({2, 4, 4})));
}

TEST(LoadPhotos, ErrorsNameTheFileOrTheArgument) {
  const auto dir = test::temp_dir("load_photos_errors");
  const auto a = write_photo(dir, "a.png", 40, 60), tall = write_photo(dir, "tall.png", 60, 40);
  EXPECT_THROW(data::load_photos({a}, 180.0, {}), std::invalid_argument);
  EXPECT_NE(test::error_of([&] { data::load_photos({a}, 0.0, {}); }).find("field of view must be in (0, 180)"),
            std::string::npos);
  EXPECT_THROW(data::load_photos({}, 60.0, {}), std::invalid_argument);
  const auto missing = (dir / "missing.jpg").string();
  EXPECT_NE(test::error_of([&] { data::load_photos({missing}, 60.0, {}); }).find(missing), std::string::npos);
  const auto msg = test::error_of([&] { data::load_photos({a, tall}, 60.0, {28, 14, false}); });
  EXPECT_NE(msg.find(tall), std::string::npos) << msg;
  EXPECT_NE(msg.find("photos of one scene need the same aspect"), std::string::npos) << msg;
}

// A portrait photo (48 wide, 80 tall, red over blue) stored sideways with EXIF orientation 6 and a 26 mm (35 mm
// equivalent) focal length: upright before the resize and crop, its field of view from the focal length.
TEST(LoadPhotos, ExifOrientationTurnsThePhotoUprightAndExifFocalLengthGivesTheFieldOfView) {
  const auto dir = test::temp_dir("load_photos_exif");
  const auto stored = test::stored_for_orientation_6(test::red_over_blue(80, 48));
  ASSERT_FALSE(test::is_red_over_blue(stored));  // sideways as stored: red left, blue right
  const auto portrait = write_photo(dir, "portrait.jpg", test::jpeg_with_exif(stored, 6, 26));
  auto photos = data::read_photos({portrait, portrait}, std::nullopt);
  const auto& info = photos[0].info;
  EXPECT_EQ(photos[0].hwc_u8.sizes(), torch::IntArrayRef({80, 48, 3}));
  EXPECT_TRUE(test::is_red_over_blue(photos[0].hwc_u8));
  EXPECT_EQ(info.orientation, 6);
  // f = 26 mm * sqrt(80^2 + 48^2) / sqrt(36^2 + 24^2) = 56.06 pixels (the diagonal convention), seen across the
  // upright width of 48: 46.35 degrees (the long-side reading, 26 / 36 * 80 = 57.78 px, would give 45.11).
  const double fov = 2 * std::atan(24.0 / (26.0 * std::hypot(80, 48) / std::hypot(36, 24))) * 180 / M_PI;
  EXPECT_NEAR(fov, 46.35, 1e-2);
  EXPECT_NEAR(info.fov_deg, fov, 1e-9);
  EXPECT_EQ(info.fov_source, "exif");
  EXPECT_NE(data::describe_photo(info, "--fov").find("turned upright (EXIF orientation 6)"), std::string::npos);
  EXPECT_NE(data::describe_fov(info, "--fov").find("from EXIF FocalLengthIn35mmFilm"), std::string::npos);

  auto views = data::photo_views(photos, {28, 14, true});
  EXPECT_TRUE(test::is_red_over_blue(views.images[0]));
  // A portrait photo fills the 28 x 28 square (resized to 28 columns, not rows), and the view's camera has the
  // photo's field of view across them: fx = 14 / tan(fov / 2), the principal point at the centre.
  EXPECT_EQ(views.images.sizes(), torch::IntArrayRef({2, 3, 28, 28}));
  EXPECT_NEAR(views.fxfycxcy[0][0].item<double>(), 14.0 / std::tan(fov * M_PI / 360), 1e-3);
  EXPECT_NEAR(views.fxfycxcy[0][2].item<double>(), 14.0, 1e-4);
  EXPECT_NEAR(views.fxfycxcy[0][3].item<double>(), 14.0, 1e-4);
  auto json = data::to_json(info, "--fov");
  EXPECT_EQ(json["exif_orientation"], 6);
  EXPECT_EQ(json["fov_source"], "exif");
}

TEST(LoadPhotos, AnExplicitFieldOfViewWinsAndNoExifMeansSixtyDegrees) {
  const auto dir = test::temp_dir("load_photos_fov");
  const auto with_exif = write_photo(dir, "exif.jpg", test::jpeg_with_exif(test::red_over_blue(40, 30), 1, 26));
  const auto plain = write_photo(dir, "plain.png", 40, 30);
  auto photos = data::read_photos({with_exif, plain}, 50.0);
  EXPECT_EQ(photos[0].info.fov_deg, 50.0);
  EXPECT_EQ(photos[0].info.fov_source, "explicit");
  ASSERT_TRUE(photos[0].info.exif_fov_deg);
  EXPECT_NE(data::describe_fov(photos[0].info, "--fov").find("50.0° from --fov (overrides the"), std::string::npos)
      << data::describe_fov(photos[0].info, "--fov");
  photos = data::read_photos({with_exif, plain}, std::nullopt);
  EXPECT_EQ(photos[0].info.fov_source, "exif");
  EXPECT_EQ(photos[1].info.fov_source, "default");
  EXPECT_EQ(photos[1].info.fov_deg, data::kDefaultPhotoFovDeg);
  EXPECT_NE(data::describe_fov(photos[1].info, "--fov").find("the default (no EXIF focal length; set --fov)"),
            std::string::npos);
}

// A 1 mm FocalLengthIn35mmFilm (a 173-degree view across this 4:3 photo) is no camera's: the photo goes on with the
// default field of view, and its description and JSON name the tag, its value and the accepted range.
TEST(LoadPhotos, AnImplausibleExifFocalLengthIsRejectedNamingTheTagAndValue) {
  const auto dir = test::temp_dir("load_photos_bad_focal");
  const auto bad = write_photo(dir, "bad.jpg", test::jpeg_with_exif(test::red_over_blue(30, 40), 1, 1));
  auto photos = data::read_photos({bad}, std::nullopt);
  const auto& info = photos[0].info;
  EXPECT_EQ(info.fov_source, "default");
  EXPECT_EQ(info.fov_deg, data::kDefaultPhotoFovDeg);
  EXPECT_FALSE(info.exif_fov_deg);
  EXPECT_EQ(info.exif_tag, "FocalLengthIn35mmFilm");
  const std::string why = "EXIF FocalLengthIn35mmFilm = 1 mm rejected";
  EXPECT_NE(info.exif_rejected.find(why), std::string::npos) << info.exif_rejected;
  EXPECT_NE(info.exif_rejected.find("[8, 3000] mm"), std::string::npos) << info.exif_rejected;
  const auto line = data::describe_fov(info, "--fov");
  EXPECT_NE(line.find("60.0°, the default (" + why), std::string::npos) << line;
  EXPECT_NE(line.find("; set --fov)"), std::string::npos) << line;
  const auto json = data::to_json(info, "--fov");
  EXPECT_TRUE(json["exif_fov_deg"].is_null());
  EXPECT_NE(json["exif_rejected"].get<std::string>().find(why), std::string::npos) << json;
  // A plausible tag leaves exif_rejected null; an explicit field of view still records the rejection.
  const auto good = write_photo(dir, "good.jpg", test::jpeg_with_exif(test::red_over_blue(30, 40), 1, 26));
  EXPECT_TRUE(data::to_json(data::read_photos({good}, std::nullopt)[0].info, "--fov")["exif_rejected"].is_null());
  photos = data::read_photos({bad}, 50.0);
  EXPECT_EQ(photos[0].info.fov_deg, 50.0);
  EXPECT_NE(photos[0].info.exif_rejected.find(why), std::string::npos);
}

// read_photos runs before the checkpoint is loaded (`render --images`): every bad file is named.
TEST(LoadPhotos, ReadPhotosNamesTheBadFile) {
  const auto dir = test::temp_dir("read_photos_errors");
  const auto ok = write_photo(dir, "ok.png", 20, 20);
  const auto text = write_photo(dir, "notes.jpg", {'h', 'e', 'l', 'l', 'o'});
  const auto missing = (dir / "mistyped.jpg").string();
  for (const auto& bad : {missing, text, dir.string()}) {
    const auto msg = test::error_of([&] { data::read_photos({ok, bad}, std::nullopt); });
    EXPECT_NE(msg.find(bad), std::string::npos) << msg;
  }
}

// With a square crop a portrait and a landscape photo make views of the same (the model's) size.
TEST(LoadPhotos, PortraitAndLandscapePhotosFillTheSameSquare) {
  const auto dir = test::temp_dir("load_photos_mixed");
  const auto portrait = write_photo(dir, "portrait.png", 90, 40), landscape = write_photo(dir, "landscape.png", 40, 70);
  auto views = data::load_photos({portrait, landscape}, std::nullopt, {28, 14, true});
  EXPECT_EQ(views.images.sizes(), torch::IntArrayRef({2, 3, 28, 28}));
  EXPECT_TRUE(torch::allclose(views.fxfycxcy.slice(1, 2), torch::full({2, 2}, 14.0f)));
}
