// `uplvsm convert`'s model (model/weight_conversion.h): an UP-LVSM's tensors come back in a model whose config is
// inferred from them and into the checkpoint written; DINOv2 weights without a config are refused.
#include <gtest/gtest.h>

#include <stdexcept>

#include "test_util.h"
#include "train/train_test_util.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/weight_conversion.h"

using namespace uplvsm;

TEST(WeightConversion, AnUplvsmComesBackWithItsConfigInferredAndIsWritten) {
  torch::manual_seed(3);
  auto original = model::make_model(test::micro_model());
  io::PretrainedWeights w;
  w.path = "official.safetensors";
  w.tensors = io::state_dict(*original);
  const auto dir = test::temp_dir("weight_conversion");
  const auto input = (dir / "official.safetensors").string();
  const auto c = model::convert_weights(w, input, "");
  EXPECT_FALSE(c.tokenizer_only);
  EXPECT_EQ(c.config.name, "official");
  EXPECT_EQ(c.net->parameter_count(), original->parameter_count());
  for (const auto& [k, v] : io::state_dict(*c.net)) EXPECT_TRUE(torch::equal(v, w.tensors.at(k))) << k;
  const auto output = (dir / "ours.safetensors").string();
  model::write_converted(output, input, w, c);
  Config read;
  auto net = model::load_model(output, torch::kCPU, &read);
  EXPECT_EQ(read.name, "official");
  for (const auto& [k, v] : io::state_dict(*net)) EXPECT_TRUE(torch::equal(v, w.tensors.at(k))) << k;
  w.source = io::WeightSource::Dinov2Meta;
  EXPECT_THROW(model::convert_weights(w, input, ""), std::runtime_error);
  test::remove_tree(dir);
}
