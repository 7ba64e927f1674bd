#include "uplvsm/model/weight_conversion.h"

#include <filesystem>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"

namespace uplvsm::model {

Conversion convert_weights(const io::PretrainedWeights& w, const std::string& input, const std::string& config_path) {
  Conversion c;
  if (!config_path.empty()) c.config = load_config(config_path);
  if (w.source == io::WeightSource::Uplvsm) {
    if (config_path.empty()) {
      c.config.name = std::filesystem::path(input).stem().string();
      c.config.model = infer_model_config(w.tensors, c.config.model);
    }
    validate_config(c.config, config_path.empty() ? input + " (inferred config)" : config_path);
    c.net = make_model(c.config.model);
    c.load_summary = io::load_state_dict(*c.net, w.tensors, input).summary(input);
    return c;
  }
  if (config_path.empty())
    throw std::runtime_error(
        fmt::format("convert: {} holds {} weights; give --config (e.g. configs/paper_x224.json) "
                    "for the UP-LVSM model to initialise around them",
                    input, io::to_string(w.source)));
  validate_config(c.config, config_path);
  torch::manual_seed(static_cast<uint64_t>(c.config.training.seed));
  c.net = make_model(c.config.model);
  c.load_summary = load_dinov2_into_tokenizer(*c.net, w.tensors, input).summary(input);
  c.tokenizer_only = true;
  return c;
}

void write_converted(const std::string& output, const std::string& input, const io::PretrainedWeights& w,
                     const Conversion& c) {
  const nlohmann::json state = {{"step", 0}, {"converted_from", input}, {"source", io::to_string(w.source)}};
  io::write_checkpoint(output, c.config, state, io::state_dict(*c.net), {});
}

}  // namespace uplvsm::model
