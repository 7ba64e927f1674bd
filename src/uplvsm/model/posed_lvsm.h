// The posed decoder-only LVSM (official `posedTargetLVSM`), the paper's baselines. Input views carry the Plücker rays
// of their dataset cameras, each target its own; one transformer stack renders it. Read top to bottom:
//   T   = DINOv2(inputs); T[posed views] += canonical_pose_tokenizer(Plücker(input camera))
//   Q   = target_pose_tokenizer(Plücker(target camera))                                     per target
//   img = sigmoid(head(Blocks(LN([T ; Q]))[last n]))
// PT-LVSM poses input view 0 only, LVSM every input view: the one difference between the two. Cameras are the
// official scene-normalised ones: as the training loader gives them (Views::camera_frame), else normalised here
// over inputs and targets (geometry::official_scene_normalize; evaluation's context + target views, as officially).
#pragma once
#include <torch/torch.h>

#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/model/transformer.h"

namespace uplvsm::model {

// Which input views carry their camera's rays.
enum class PosedInputs {
  First,  // PT-LVSM: view 0, as UP-LVSM's canonical marker
  All,    // LVSM: every input view
};
// The posed variant's choice (ptlvsm: First, lvsm: All); the uplvsm variant has none (an error).
PosedInputs posed_inputs(Variant variant);

struct PosedLVSMImpl : NovelViewModelImpl {
  PosedLVSMImpl(const ModelConfig& config, PosedInputs posed_inputs);

  // Renders the targets from posed inputs (both need c2w). Unless both views are in CameraFrame::Scene, the official
  // scene normalisation runs over inputs and targets; a camera path passes normalize_with_targets = false so every
  // frame shares the inputs' frame.
  torch::Tensor render_posed(const Views& inputs, const Views& targets, ForwardTrace* trace = nullptr,
                             bool normalize_with_targets = true);

  // Dataset cameras are the only target poses it knows.
  Rendered render(const Views& inputs, const Views& targets, TargetPoses source,
                  ForwardTrace* trace = nullptr) override;
  TargetPoses default_target_poses() const override { return TargetPoses::Dataset; }
  bool has_camera_control() const override { return true; }
  // Real cameras are placed in the inputs' world (camera_control_to_world): the inputs need their c2w.
  CameraRenderer camera_control(const Views& inputs) override;
  std::string name() const override { return posed_inputs == PosedInputs::All ? "LVSM" : "PT-LVSM"; }

  PosedInputs posed_inputs;
  torch::nn::ModuleList transformer_blocks{nullptr};  // official key names
  LayerNorm transformer_input_layernorm{nullptr};
};
TORCH_MODULE(PosedLVSM);

}  // namespace uplvsm::model
