#include <gtest/gtest.h>

#include <filesystem>

#include "test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/train/perceptual_loss.h"
#include "uplvsm/train/vgg19_extraction.h"

using namespace uplvsm;

TEST(Vgg19Extraction, KeepsTheFeaturesUnderTorchvisionNamesMarkedMatConvNet) {
  const auto dir = test::temp_dir("vgg19_extraction");
  io::PretrainedWeights w;
  w.path = "official.pt";
  const std::string prefix = "loss_computer.perceptual_loss_module.vgg.";
  w.tensors[prefix + "features.0.weight"] = torch::ones({2, 3, 3, 3});
  w.tensors[prefix + "features.0.bias"] = torch::zeros({2});
  w.tensors[prefix + "classifier.0.weight"] = torch::ones({4, 4});
  w.tensors[prefix + "blocks.0.weight"] = torch::ones({2, 3, 3, 3});
  w.tensors["transformer.0.weight"] = torch::ones({4});
  const auto r = train::write_vgg19_extras(w, (dir / "model.safetensors").string());
  EXPECT_EQ(r.tensors, 2);
  EXPECT_EQ(r.path, (dir / "model.vgg19.safetensors").string());
  const auto header = io::read_safetensors_header(r.path);
  ASSERT_EQ(header.size(), 2u);
  EXPECT_TRUE(header.count("features.0.weight"));
  EXPECT_TRUE(header.count("features.0.bias"));
  EXPECT_EQ(train::resolve_vgg_input(r.path, train::VggInput::Auto), train::VggInput::MatConvNet);
  test::remove_tree(dir);
}

TEST(Vgg19Extraction, WritesNothingWithoutAVgg19) {
  const auto dir = test::temp_dir("vgg19_extraction_none");
  io::PretrainedWeights w;
  w.tensors["transformer.0.weight"] = torch::ones({4});
  const auto r = train::write_vgg19_extras(w, (dir / "model.safetensors").string());
  EXPECT_EQ(r.tensors, 0);
  EXPECT_FALSE(std::filesystem::exists(dir / "model.vgg19.safetensors"));
  test::remove_tree(dir);
}
