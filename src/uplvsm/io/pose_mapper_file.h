// A fitted pose mapper's file, apart from the model it was fitted to (`uplvsm fit-mapper`): a small safetensors file
// with the mapper's tensors under "pose_mapper.*" and, in its metadata, the format, the mapper's kind and width, the
// fingerprint of the model's weights (a mapper speaks one model's latent poses only) and the fit's report. The
// format only; a mapper goes in and out of a model through model/pose_mapper_file.h.
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "uplvsm/io/state_dict.h"

namespace uplvsm::io {

inline constexpr const char* kPoseMapperFormat = "uplvsm-pose-mapper-v1";

struct PoseMapperFile {
  std::string kind;               // the mapper's kind by name ("linear", "mlp")
  int64_t hidden = 0;             // the MLP's width, 1..4096
  NamedTensors tensors;           // the mapper's state_dict (names without the "pose_mapper." prefix), float32
  std::string model_fingerprint;  // of the model the mapper was fitted to
  nlohmann::json fit;             // what fit-mapper recorded (scenes, steps, losses, seconds)
};

void write_pose_mapper_file(const std::string& path, const PoseMapperFile& file);
// Throws naming the file and what is wrong: not a mapper file, another format, metadata missing or out of range.
PoseMapperFile read_pose_mapper_file(const std::string& path);

}  // namespace uplvsm::io
