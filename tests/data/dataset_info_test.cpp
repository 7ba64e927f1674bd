// Tests of data/dataset_info: defaults without the file, a round trip, and clear errors for malformed files.
#include "uplvsm/data/dataset_info.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "test_util.h"

namespace uplvsm::data {
namespace {

namespace fs = std::filesystem;

TEST(DatasetInfo, DefaultsRoundTripAndErrors) {
  const auto dir = test::temp_dir("dataset_info");
  auto missing = read_dataset_info(dir.string());
  EXPECT_TRUE(missing.ordered_views);
  EXPECT_EQ(missing.generator, "");
  write_dataset_info(dir.string(), {"objects", false});
  auto back = read_dataset_info(dir.string());
  EXPECT_EQ(back.generator, "objects");
  EXPECT_FALSE(back.ordered_views);
  auto expect_error = [&](const std::string& text, const std::string& needle) {
    std::ofstream(dir / "dataset.json") << text;
    try {
      read_dataset_info(dir.string());
      FAIL() << "no error for " << text;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("dataset.json"), std::string::npos) << e.what();
    }
  };
  expect_error("{\"view_order\": \"shuffled\"}", "view_order");
  expect_error("[1, 2]", "JSON object");
  expect_error("{not json", "JSON object");
  expect_error("{\"generator\": 3}", "generator");
  test::remove_tree(dir);
}

}  // namespace
}  // namespace uplvsm::data
