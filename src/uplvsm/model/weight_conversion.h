// `uplvsm convert`'s model: the authors' UP-LVSM weights (dimensions inferred unless a config is given) or DINOv2
// weights placed in a freshly initialised UP-LVSM, and the checkpoint of ours written from it, so their weights run
// through every command that reads our checkpoints.
#pragma once
#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/io/pretrained_weights.h"
#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::model {

struct Conversion {
  Config config;
  NovelViewModel net{nullptr};
  std::string load_summary;     // what was loaded and what was not, named by the input
  bool tokenizer_only = false;  // DINOv2: the rest of the model freshly initialised with config.training.seed
};

// The model of `weights` (read from `input`); `config_path` empty: inferred from an UP-LVSM's tensors (an error for
// DINOv2 weights, which say nothing of the rest of the model).
Conversion convert_weights(const io::PretrainedWeights& weights, const std::string& input,
                           const std::string& config_path);

// Our checkpoint of `c` at `output`: its weights and config, at step 0, naming the input and its source.
void write_converted(const std::string& output, const std::string& input, const io::PretrainedWeights& weights,
                     const Conversion& c);

}  // namespace uplvsm::model
