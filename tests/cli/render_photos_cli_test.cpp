// `uplvsm render --images` with a user's own photos: a portrait phone photo stored sideways (EXIF orientation 6)
// renders upright with its EXIF field of view (logged and in videos.json), an explicit --fov wins and says so, and
// a mistyped or broken photo is reported before the checkpoint is read.
#include <gtest/gtest.h>

#include <fstream>

#include <nlohmann/json.hpp>

#include "io/exif_jpeg.h"
#include "test_util.h"
#include "uplvsm/io/image.h"

namespace fs = std::filesystem;
using namespace uplvsm;

namespace {

fs::path save_file(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  return path;
}

// A 48 x 80 portrait (red over blue) stored sideways, with a 26 mm (35 mm equivalent) focal length.
fs::path write_portrait(const fs::path& dir) {
  return save_file(dir / "portrait.jpg",
                   test::jpeg_with_exif(test::stored_for_orientation_6(test::red_over_blue(80, 48)), 6, 26));
}

std::string render_args(const std::string& checkpoint, const fs::path& a, const fs::path& b, const fs::path& out) {
  return "render --checkpoint " + checkpoint + " --images " + a.string() + " " + b.string() + " --out " + out.string() +
         " --frames 2";
}

}  // namespace

TEST(RenderPhotosCli, APortraitPhotoWithExifOrientationRendersUpright) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = test::temp_dir("cli_render_portrait");
  const auto portrait = write_portrait(dir);
  std::string out;
  ASSERT_EQ(
      test::run_cli(render_args(test::fixture("official_uplvsm/checkpoint.pt"), portrait, portrait, dir / "v"), &out),
      0);
  EXPECT_NE(out.find("portrait.jpg: 48x80, turned upright (EXIF orientation 6); horizontal field of view"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("from EXIF FocalLengthIn35mmFilm"), std::string::npos) << out;
  // The model's input as written next to the video: upright, red at the top.
  EXPECT_TRUE(test::is_red_over_blue(io::read_image((dir / "v" / "input_0.png").string())));
  auto listing = nlohmann::json::parse(std::ifstream(dir / "v" / "videos.json"));
  const auto& input = listing[0]["inputs"][0];
  EXPECT_EQ(input["exif_orientation"], 6);
  EXPECT_EQ(input["fov_source"], "exif");
  EXPECT_EQ(input["width"], 48);
  EXPECT_EQ(input["height"], 80);
}

// The photos are read first: a checkpoint that does not exist is never reached while a photo is bad, and what is
// logged about a good photo (an explicit --fov over its EXIF one) comes before the checkpoint error.
TEST(RenderPhotosCli, PhotosAreCheckedBeforeTheCheckpointIsRead) {
  const auto dir = test::temp_dir("cli_render_photo_first");
  const auto portrait = write_portrait(dir);
  const auto checkpoint = (dir / "no_such_checkpoint.pt").string();
  const auto text = save_file(dir / "notes.jpg", {'n', 'o', 't', 'e', 's'});
  for (const auto& bad : {dir / "mistyped.jpg", text}) {
    std::string out;
    EXPECT_NE(test::run_cli(render_args(checkpoint, portrait, bad, dir / "v"), &out), 0);
    EXPECT_NE(out.find(bad.string()), std::string::npos) << out;
    EXPECT_EQ(out.find("no_such_checkpoint"), std::string::npos) << out;
  }
  std::string out;
  EXPECT_NE(test::run_cli(render_args(checkpoint, portrait, portrait, dir / "v") + " --fov 50", &out), 0);
  EXPECT_NE(out.find("50.0° from --fov (overrides the"), std::string::npos) << out;
  EXPECT_NE(out.find("no_such_checkpoint"), std::string::npos) << out;
}
