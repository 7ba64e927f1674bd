// `dataset import`'s writing through data:: without the binary: photos without poses become a chunk in the split's
// index, listed as unposed, with their evaluation entry; a scene already there needs force, frames must exist.
#include "uplvsm/data/dataset_import.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "test_util.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/io/image.h"

using namespace uplvsm;
namespace fs = std::filesystem;

TEST(DatasetImport, PhotosBecomeAnUnposedChunkWithTheirEvaluationEntry) {
  const auto dir = test::temp_dir("dataset_import");
  fs::create_directories(dir / "room");
  for (int i = 0; i < 3; ++i)
    io::write_png((dir / "room" / ("p" + std::to_string(i) + ".png")).string(),
                  torch::full({24, 32, 3}, 40 * (i + 1), torch::kUInt8));
  data::DatasetImportOptions o;
  o.import.images_dir = (dir / "room").string();
  o.out = (dir / "data").string();
  o.context = {0, 2};
  o.target = {1};
  const auto imported = data::import_into_dataset(o);
  EXPECT_EQ(imported.result.scene.key, "room");
  EXPECT_FALSE(imported.result.poses_known);
  EXPECT_EQ(imported.chunk_path, (dir / "data" / "test" / "room.torch").string());
  EXPECT_TRUE(fs::exists(imported.chunk_path));
  EXPECT_EQ(data::read_chunk_index((dir / "data" / "test").string()).at("room"), "room.torch");
  EXPECT_EQ(data::read_unposed_keys((dir / "data" / "test").string()), std::vector<std::string>{"room"});
  std::ifstream in(dir / "data" / "evaluation_index.json");
  const auto index = nlohmann::json::parse(in);
  EXPECT_EQ(index.at("room").at("context"), nlohmann::json({0, 2}));
  EXPECT_ANY_THROW(data::import_into_dataset(o));  // already there
  o.force = true;
  EXPECT_NO_THROW(data::import_into_dataset(o));
  o.target = {3};  // the scene has frames 0..2
  EXPECT_ANY_THROW(data::import_into_dataset(o));
  o.target = {};
  EXPECT_ANY_THROW(data::import_into_dataset(o));  // context without target
}
