// What a user sees when an input is hostile or a job cannot fit: a decompression bomb among --images, a config
// too large for the machine's memory, an error raised inside LibTorch. One clear line each, never a C++ backtrace
// (unless --verbose asks for it).
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>

#include "io/image_bomb.h"
#include "test_util.h"
#include "uplvsm/core/config.h"

namespace fs = std::filesystem;

namespace {

void write_bytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

bool has_backtrace(const std::string& output) {
  return output.find("Exception raised from") != std::string::npos || output.find("frame #") != std::string::npos;
}

std::string render_images(const fs::path& a, const fs::path& b, const fs::path& out, const std::string& extra = "") {
  return "render --checkpoint " + uplvsm::test::fixture("official_uplvsm/checkpoint.pt") + " --images " + a.string() +
         " " + b.string() + " --out " + out.string() + " " + (extra.empty() ? "--frames 2" : extra);
}

}  // namespace

TEST(RobustnessCli, DecompressionBombAmongImagesIsRefusedFromItsHeader) {
  UPLVSM_NEEDS_FIXTURES();
  const auto dir = uplvsm::test::temp_dir("cli_bomb");
  write_bytes(dir / "bomb.png", uplvsm::test::png_declaring(30000, 30000));
  write_bytes(dir / "ok.png", uplvsm::test::small_image_bytes(true));
  std::string out;
  EXPECT_NE(uplvsm::test::run_cli(render_images(dir / "bomb.png", dir / "ok.png", dir / "video"), &out), 0);
  EXPECT_NE(out.find((dir / "bomb.png").string() + ": image of 30000x30000 = 900000000 pixels exceeds the limit of "
                                                   "178956970 pixels"),
            std::string::npos)
      << out;
  EXPECT_FALSE(has_backtrace(out)) << out;

  // --max-image-pixels lowers (or raises) the limit, before or after the subcommand.
  EXPECT_NE(
      uplvsm::test::run_cli(
          render_images(dir / "ok.png", dir / "ok.png", dir / "video", "--frames 2 --max-image-pixels 100"), &out),
      0);
  EXPECT_NE(out.find("ok.png: image of 16x8 = 128 pixels exceeds the limit of 100 pixels"), std::string::npos) << out;
  EXPECT_NE(
      uplvsm::test::run_cli("--max-image-pixels 100 " + render_images(dir / "ok.png", dir / "ok.png", dir / "v"), &out),
      0);
  EXPECT_NE(out.find("exceeds the limit of 100 pixels"), std::string::npos) << out;
}

TEST(RobustnessCli, ConfigThatCannotFitInMemoryIsRefusedInOneLine) {
  const auto dir = uplvsm::test::temp_dir("cli_unfittable");
  auto config = uplvsm::load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/tiny.json");
  config.name = "huge";
  config.model.transformer.d = config.model.dinov2.embed_dim = 100032;
  std::ofstream(dir / "huge.json") << uplvsm::config_to_json(config).dump(2);
  std::string out;
  // --device cpu: on a CUDA machine the default (auto) would compare with the GPU's free memory instead.
  const auto cmd = "train --device cpu --config " + (dir / "huge.json").string() + " --data " + dir.string() +
                   " --run " + (dir / "run").string();
  EXPECT_NE(uplvsm::test::run_cli(cmd, &out), 0);
  EXPECT_EQ(out.rfind("error: config huge: training needs at least ", 0), 0u) << out;
  EXPECT_NE(out.find("available (MemAvailable in /proc/meminfo)"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;  // one line
  EXPECT_FALSE(fs::exists(dir / "run")) << "nothing is created for a run that cannot start";
}

TEST(RobustnessCli, LibTorchErrorsPrintTheirMessageWithoutBacktraceUnlessVerbose) {
  UPLVSM_NEEDS_FIXTURES();
  // A camera path needs a camera mapper, which the official UP-LVSM checkpoint lacks: LibTorch's TORCH_CHECK raises
  // the error deep in the renderer.
  const auto dir = uplvsm::test::temp_dir("cli_libtorch_error");
  write_bytes(dir / "a.png", uplvsm::test::small_image_bytes(true));
  const auto cmd = render_images(dir / "a.png", dir / "a.png", dir / "video", "--frames 2 --trajectory orbit");
  std::string out;
  EXPECT_NE(uplvsm::test::run_cli(cmd, &out), 0);
  EXPECT_NE(out.find("error: rendering a camera path needs a camera mapper"), std::string::npos) << out;
  EXPECT_FALSE(has_backtrace(out)) << out;

  EXPECT_NE(uplvsm::test::run_cli(cmd + " --verbose", &out), 0);
  EXPECT_NE(out.find("rendering a camera path needs a camera mapper"), std::string::npos) << out;
  EXPECT_NE(out.find("Exception raised from"), std::string::npos) << out;
}

TEST(RobustnessCli, VideoThatCannotFitInMemoryIsRefusedBeforeRendering) {
  UPLVSM_NEEDS_FIXTURES();
  // 100000 frames at 224 x 224 with side-by-side copies: ~224 GiB of frames, refused before the first one.
  const auto dir = uplvsm::test::temp_dir("cli_video_memory");
  write_bytes(dir / "a.png", uplvsm::test::small_image_bytes(true));
  std::string out;
  EXPECT_NE(uplvsm::test::run_cli(
                render_images(dir / "a.png", dir / "a.png", dir / "video", "--frames 100000 --side-by-side"), &out),
            0);
  EXPECT_NE(out.find("error: render: 100000 frames of 224x224 need at least 224.3 GiB of memory, but only "),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("(MemAvailable in /proc/meminfo); render fewer frames"), std::string::npos) << out;
}
