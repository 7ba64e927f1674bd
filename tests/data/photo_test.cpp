// data::load_photos: users' photo files as views (what `render --images`, the Python module and the C++ example
// feed the model): sizes, the field-of-view camera, identity poses, and errors naming the file or the argument.
#include <gtest/gtest.h>

#include <stdexcept>

#include "test_util.h"
#include "uplvsm/data/photo.h"
#include "uplvsm/io/image.h"

using namespace uplvsm;

namespace {

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
