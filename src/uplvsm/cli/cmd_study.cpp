// `uplvsm study ...`: the paper's analyses as tools (study/pose_studies.h runs them). pose-pairs exports (latent pose,
// real pose) pairs of a split; pose-probe fits the paper's 2-layer MLP probe (and a linear one) latent -> SE(3) on
// one split and scores it on another (Table 7's accuracies); tsne embeds latent and real poses together (the
// appendix figure); attention draws the cross-view attention figure. The multi-run studies (scaling, pose-noise) are
// in cmd_study_grid.cpp.
#include <iostream>
#include <set>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/study/pose_studies.h"

namespace uplvsm::cli {

namespace {

struct PoseArgs {
  CommonOptions common;
  ModelSource model;
  study::PoseStudyOptions study;
};

void add_pose_options(CLI::App* cmd, PoseArgs& p) {
  add_common_options(cmd, p.common);
  add_model_options(cmd, p.model);
  auto& a = p.study;
  cmd->add_option("--data", a.data, "dataset root with cameras (pixelSplat chunks)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--max-scenes", a.max_scenes, "scenes per split (0: all)")->capture_default_str();
  cmd->add_option("--gap", a.gap, "context frames {0, gap} per scene; every frame between them is a target")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

// The runtime set-up and the model every study starts from; the parsed options with the device and checkpoint.
struct StudyModel {
  Config config;
  model::UPLVSM net{nullptr};
  study::PoseStudyOptions options;
};
StudyModel start(const PoseArgs& a) {
  apply_common_options(a.common);
  StudyModel m;
  m.options = a.study;
  m.options.device = parse_device(a.common.device);
  m.options.checkpoint = a.model.checkpoint;
  m.net = model::require_uplvsm(
      model::load_model_with_config_file(a.model.checkpoint, a.model.config, m.options.device, &m.config),
      "study pose-pairs/pose-probe/pose-sensitivity/tsne");
  return m;
}

void add_pose_pairs(CLI::App& study) {
  auto* cmd = study.add_subcommand("pose-pairs",
                                   "Export (latent pose, real pose) pairs of a split to CSV (the "
                                   "input of probes and t-SNE)");
  auto a = std::make_shared<PoseArgs>();
  add_pose_options(cmd, *a);
  cmd->add_option("--split", a->study.split, "dataset split")->capture_default_str();
  cmd->add_option("--out", a->study.out, "CSV file")->required();
  cmd->callback([a] {
    auto [config, net, o] = start(*a);
    auto pairs = study::pose_pairs_of_split(net, config, o, o.split);
    study::write_pose_pairs_csv(o.out, pairs);
    const auto scenes = std::set<std::string>(pairs.scenes.begin(), pairs.scenes.end()).size();
    std::cout << fmt::format("wrote {} pose pairs of {} scenes to {}\n", pairs.frames.size(), scenes, o.out);
  });
}

void add_pose_probe(CLI::App& study) {
  auto* cmd = study.add_subcommand(
      "pose-probe",
      "Probe the latent poses (paper Table 7): fit a 2-layer MLP (and a linear map) latent -> real pose "
      "on --train-split, report translation accuracy @0.1/0.2/0.3 baselines and rotation accuracy "
      "@10/20/30 degrees on --split; writes probe.json and the pair CSVs");
  auto a = std::make_shared<PoseArgs>();
  add_pose_options(cmd, *a);
  cmd->add_option("--train-split", a->study.train_split, "split the probes are fitted on")->capture_default_str();
  cmd->add_option("--split", a->study.split, "split the probes are scored on")->capture_default_str();
  cmd->add_option("--iterations", a->study.iterations, "MLP probe: full-batch Adam steps")->capture_default_str();
  cmd->add_option("--out", a->study.out, "output directory")->required();
  cmd->callback([a] {
    auto [config, net, o] = start(*a);
    const auto s = study::run_pose_probe(net, config, o);
    auto row = [](const char* name, const study::PoseAccuracy& p) {
      return fmt::format("  {:<7} trans@0.1/0.2/0.3 {:5.1f} {:5.1f} {:5.1f}   rot@10/20/30 {:5.1f} {:5.1f} {:5.1f}\n",
                         name, 100 * p.translation_accuracy[0], 100 * p.translation_accuracy[1],
                         100 * p.translation_accuracy[2], 100 * p.rotation_accuracy[0], 100 * p.rotation_accuracy[1],
                         100 * p.rotation_accuracy[2]);
    };
    std::cout << fmt::format("pose probe: fitted on {} views, scored on {} views -> {}/probe.json\n", s.train_views,
                             s.test_views, o.out)
              << row("MLP", s.mlp) << row("linear", s.linear) << row("mean", s.mean);
  });
}

void print_sensitivity(const nlohmann::json& s, const std::string& out) {
  auto row = [](const char* name, const nlohmann::json& m) {
    return fmt::format("  {:<22} {:4} views  sensitivity {:.3f}  PSNR {:6.2f}  edges {:.3f}\n", name,
                       m.at("views").get<int64_t>(), m.at("sensitivity").get<double>(), m.at("psnr").get<double>(),
                       m.at("grad_ratio").get<double>());
  };
  std::cout << fmt::format("pose sensitivity -> {}/sensitivity.json\n", out) << row("targets", s.at("targets"))
            << row("inputs (reconstructed)", s.at("inputs"))
            << row("all but the first input", s.at("all_but_first_input"));
}

void add_pose_sensitivity(CLI::App& study) {
  auto* cmd =
      study.add_subcommand("pose-sensitivity",
                           "Does the decoder use the latent pose? Each view rendered at its own pose and at the first "
                           "input's: render change against truth change (0: the pose is ignored), and how well the "
                           "input views themselves are reconstructed; writes sensitivity.json and views.csv");
  auto a = std::make_shared<PoseArgs>();
  add_pose_options(cmd, *a);
  cmd->add_option("--split", a->study.split, "dataset split")->capture_default_str();
  add_target_poses_option(cmd, a->study.target_poses, "where the views' poses come from (auto: the model's protocol)");
  cmd->add_option("--out", a->study.out, "output directory")->required();
  cmd->callback([a] {
    auto [config, net, o] = start(*a);
    print_sensitivity(study::run_pose_sensitivity(net, config, o), o.out);
  });
}

void add_tsne(CLI::App& study) {
  auto* cmd = study.add_subcommand(
      "tsne",
      "t-SNE of latent and real poses together (paper appendix figure): tsne.png with each pair in one "
      "colour, tsne.csv with the 2-D points, pairs.csv");
  auto a = std::make_shared<PoseArgs>();
  add_pose_options(cmd, *a);
  cmd->add_option("--split", a->study.split, "dataset split")->capture_default_str();
  cmd->add_option("--perplexity", a->study.perplexity, "t-SNE perplexity")->capture_default_str();
  cmd->add_option("--iterations", a->study.iterations, "t-SNE gradient steps")->capture_default_str();
  cmd->add_option("--out", a->study.out, "output directory")->required();
  cmd->callback([a] {
    auto [config, net, o] = start(*a);
    const auto r = study::run_tsne(net, config, o);
    std::cout << fmt::format("t-SNE of {} pose pairs (KL {:.3f}) -> {}\n", r.pairs, r.kl_divergence, r.png);
  });
}

struct AttentionArgs {
  CommonOptions common;
  ModelSource model;
  study::AttentionOptions study;
};

void add_attention_options(CLI::App* cmd, AttentionArgs& p) {
  add_common_options(cmd, p.common);
  add_model_options(cmd, p.model);
  auto& a = p.study;
  cmd->add_option("--data", a.data, "dataset root: the evaluation index's context views of the first --scenes")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--split", a.split, "dataset split")->capture_default_str();
  cmd->add_option("--scenes", a.scenes, "scenes of the evaluation index")->capture_default_str();
  cmd->add_option("--images", a.images, "two image files (JPEG/PNG) instead of dataset scenes")->expected(2);
  cmd->add_option("--fov", a.fov, "horizontal field of view in degrees for --images")->capture_default_str();
  cmd->add_option("--patch", a.patch, "query patch of view 1: ROW COL in the patch grid (default: the centre)")
      ->expected(2);
  cmd->add_option("--out", a.out, "output directory")->required();
}

void run_attention(const AttentionArgs& a) {
  apply_common_options(a.common);
  if (a.study.images.empty() == a.study.data.empty())
    throw std::runtime_error("study attention: give either --data (dataset scenes) or --images A B (two photos)");
  Config config;
  auto options = a.study;
  options.device = parse_device(a.common.device);
  auto net = model::require_uplvsm(
      model::load_model_with_config_file(a.model.checkpoint, a.model.config, options.device, &config),
      "study attention");
  for (const auto& d : study::run_attention(net, config, options))
    std::cout << fmt::format("{}: patch ({}, {}), attention on view 2 sums to {:.3f} -> {}\n", d.scene, d.row, d.col,
                             d.attention_sum, d.png);
}

void add_attention(CLI::App& study) {
  auto* cmd =
      study.add_subcommand("attention",
                           "Cross-view attention figure (paper): for a patch of input view 1, the last encoder layer's "
                           "attention over view 2 (mean over heads) beside the tokenizer-feature cosine similarity; "
                           "attention_<scene>.png per scene and attention.json with the maps");
  auto a = std::make_shared<AttentionArgs>();
  add_attention_options(cmd, *a);
  cmd->callback([a] { run_attention(*a); });
}

}  // namespace

void add_study_command(CLI::App& app) {
  auto* study = app.add_subcommand(
      "study",
      "The paper's analyses as tools (pose-pairs, pose-probe, pose-sensitivity, tsne, attention, scaling, "
      "pose-noise), mapper-scenes and camera-paths");
  study->require_subcommand(1);
  add_pose_pairs(*study);
  add_pose_probe(*study);
  add_pose_sensitivity(*study);
  add_tsne(*study);
  add_attention(*study);
  add_study_grid_commands(*study);
  add_mapper_scenes_command(*study);
  add_camera_paths_command(*study);
}

}  // namespace uplvsm::cli
