// `uplvsm study ...`: the paper's analyses as tools. pose-pairs exports (latent pose, real pose) pairs of a split;
// pose-probe fits the paper's 2-layer MLP probe (and a linear one) latent -> SE(3) on one split and scores it on
// another (Table 7's accuracies); tsne embeds latent and real poses together (the appendix figure); attention draws
// the cross-view attention figure. The multi-run studies (scaling, pose-noise) are in cmd_study_grid.cpp.
#include <filesystem>
#include <iostream>
#include <set>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/photo.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/study/attention_map.h"
#include "uplvsm/study/pose_probe.h"
#include "uplvsm/study/pose_sensitivity.h"
#include "uplvsm/study/tsne.h"

namespace uplvsm::cli {

namespace fs = std::filesystem;

namespace {

struct PoseArgs {
  CommonOptions common;
  ModelSource model;
  std::string data, split = "test", train_split = "train", out;
  int64_t max_scenes = 0, gap = 12, iterations = 3000;
  TargetPoses target_poses = TargetPoses::Auto;
};

void add_pose_options(CLI::App* cmd, PoseArgs& a) {
  add_common_options(cmd, a.common);
  add_model_options(cmd, a.model);
  cmd->add_option("--data", a.data, "dataset root with cameras (pixelSplat chunks)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--max-scenes", a.max_scenes, "scenes per split (0: all)")->capture_default_str();
  cmd->add_option("--gap", a.gap, "context frames {0, gap} per scene; every frame between them is a target")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

// The runtime set-up and the model every study starts from.
struct StudyModel {
  Config config;
  torch::Device device = torch::kCPU;
  model::UPLVSM net{nullptr};
};
StudyModel start(const PoseArgs& a) {
  apply_common_options(a.common);
  StudyModel m;
  m.device = parse_device(a.common.device);
  m.net =
      model::require_uplvsm(model::load_model_with_config_file(a.model.checkpoint, a.model.config, m.device, &m.config),
                            "study pose-pairs/pose-probe/pose-sensitivity/tsne");
  return m;
}

study::PosePairs pairs_of(model::UPLVSM& net, const Config& config, const PoseArgs& a, const std::string& split,
                          torch::Device device) {
  data::ChunkDataset dataset(a.data, split);
  auto prep = data::preprocess_options(config);
  study::PosePairOptions opt;
  opt.max_scenes = a.max_scenes;
  opt.gap = a.gap;
  opt.device = device;
  return study::collect_pose_pairs(net, dataset, prep, opt);
}

void add_pose_pairs(CLI::App& study) {
  auto* cmd = study.add_subcommand("pose-pairs",
                                   "Export (latent pose, real pose) pairs of a split to CSV (the "
                                   "input of probes and t-SNE)");
  auto a = std::make_shared<PoseArgs>();
  add_pose_options(cmd, *a);
  cmd->add_option("--split", a->split, "dataset split")->capture_default_str();
  cmd->add_option("--out", a->out, "CSV file")->required();
  cmd->callback([a] {
    auto [config, device, net] = start(*a);
    auto pairs = pairs_of(net, config, *a, a->split, device);
    study::write_pose_pairs_csv(a->out, pairs);
    const auto scenes = std::set<std::string>(pairs.scenes.begin(), pairs.scenes.end()).size();
    std::cout << fmt::format("wrote {} pose pairs of {} scenes to {}\n", pairs.frames.size(), scenes, a->out);
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
  cmd->add_option("--train-split", a->train_split, "split the probes are fitted on")->capture_default_str();
  cmd->add_option("--split", a->split, "split the probes are scored on")->capture_default_str();
  cmd->add_option("--iterations", a->iterations, "MLP probe: full-batch Adam steps")->capture_default_str();
  cmd->add_option("--out", a->out, "output directory")->required();
  cmd->callback([a] {
    auto [config, device, net] = start(*a);
    auto train_pairs = pairs_of(net, config, *a, a->train_split, device);
    auto test_pairs = pairs_of(net, config, *a, a->split, device);
    fs::create_directories(a->out);
    study::write_pose_pairs_csv((fs::path(a->out) / ("pairs_" + a->train_split + ".csv")).string(), train_pairs);
    study::write_pose_pairs_csv((fs::path(a->out) / ("pairs_" + a->split + ".csv")).string(), test_pairs);
    auto train = study::without_canonical_views(train_pairs), test = study::without_canonical_views(test_pairs);
    study::ProbeOptions po;
    po.iterations = a->iterations;
    auto mlp = study::pose_accuracy(study::fit_and_apply_mlp_probe(train, test.latent, po), test.real);
    auto linear = study::pose_accuracy(study::fit_and_apply_linear_probe(train, test.latent), test.real);
    auto mean = study::pose_accuracy(study::mean_pose_baseline(train, test.real.size(0)), test.real);
    nlohmann::json result{{"mlp", study::to_json(mlp)},
                          {"linear", study::to_json(linear)},
                          {"mean_pose", study::to_json(mean)},
                          {"train_views", train.frames.size()},
                          {"test_views", test.frames.size()},
                          {"train_split", a->train_split},
                          {"test_split", a->split},
                          {"gap", a->gap},
                          {"checkpoint", a->model.checkpoint},
                          {"conventions",
                           "real and latent poses relative to the first context view, translations in context "
                           "baselines; translation error |t_pred - t|, rotation error 2 acos|<q_pred, q>| in "
                           "degrees; the first context view is excluded; mean_pose predicts the training views' "
                           "mean real pose (no latent used)"}};
    const auto text = result.dump(2) + "\n";
    io::write_file_atomic((fs::path(a->out) / "probe.json").string(), text.data(), text.size());
    auto row = [](const char* name, const study::PoseAccuracy& p) {
      return fmt::format("  {:<7} trans@0.1/0.2/0.3 {:5.1f} {:5.1f} {:5.1f}   rot@10/20/30 {:5.1f} {:5.1f} {:5.1f}\n",
                         name, 100 * p.translation_accuracy[0], 100 * p.translation_accuracy[1],
                         100 * p.translation_accuracy[2], 100 * p.rotation_accuracy[0], 100 * p.rotation_accuracy[1],
                         100 * p.rotation_accuracy[2]);
    };
    std::cout << fmt::format("pose probe: fitted on {} views, scored on {} views -> {}/probe.json\n",
                             train.frames.size(), test.frames.size(), a->out)
              << row("MLP", mlp) << row("linear", linear) << row("mean", mean);
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
  cmd->add_option("--split", a->split, "dataset split")->capture_default_str();
  add_target_poses_option(cmd, a->target_poses, "where the views' poses come from (auto: the model's protocol)");
  cmd->add_option("--out", a->out, "output directory")->required();
  cmd->callback([a] {
    auto [config, device, net] = start(*a);
    data::ChunkDataset dataset(a->data, a->split);
    study::SensitivityOptions opt;
    opt.max_scenes = a->max_scenes;
    opt.gap = a->gap;
    opt.device = device;
    opt.source = model::resolve_target_poses(a->target_poses, *net);
    auto report = study::measure_pose_sensitivity(net, dataset, data::preprocess_options(config), opt);
    fs::create_directories(a->out);
    study::write_sensitivity_csv((fs::path(a->out) / "views.csv").string(), report);
    auto summary = study::summarise(report);
    summary["checkpoint"] = a->model.checkpoint;
    summary["split"] = a->split;
    summary["gap"] = a->gap;
    summary["target_poses"] = uplvsm::to_string(opt.source);
    const auto text = summary.dump(2) + "\n";
    io::write_file_atomic((fs::path(a->out) / "sensitivity.json").string(), text.data(), text.size());
    print_sensitivity(summary, a->out);
  });
}

void add_tsne(CLI::App& study) {
  auto* cmd = study.add_subcommand(
      "tsne",
      "t-SNE of latent and real poses together (paper appendix figure): tsne.png with each pair in one "
      "colour, tsne.csv with the 2-D points, pairs.csv");
  auto a = std::make_shared<PoseArgs>();
  auto perplexity = std::make_shared<double>(30.0);
  add_pose_options(cmd, *a);
  cmd->add_option("--split", a->split, "dataset split")->capture_default_str();
  cmd->add_option("--perplexity", *perplexity, "t-SNE perplexity")->capture_default_str();
  cmd->add_option("--iterations", a->iterations, "t-SNE gradient steps")->capture_default_str();
  cmd->add_option("--out", a->out, "output directory")->required();
  cmd->callback([a, perplexity] {
    auto [config, device, net] = start(*a);
    auto pairs = study::without_canonical_views(pairs_of(net, config, *a, a->split, device));
    fs::create_directories(a->out);
    study::write_pose_pairs_csv((fs::path(a->out) / "pairs.csv").string(), pairs);
    study::TsneOptions o;
    o.perplexity = *perplexity;
    o.iterations = a->iterations;
    auto r = study::tsne(torch::cat({pairs.latent, pairs.real}), o);
    const int64_t n = pairs.latent.size(0);
    std::string csv = "pair,kind,scene,frame,x,y\n";
    auto e = r.embedding.contiguous();
    for (int64_t i = 0; i < 2 * n; ++i)
      csv += fmt::format("{},{},{},{},{:.6f},{:.6f}\n", i % n, i < n ? "latent" : "real", pairs.scenes[i % n],
                         pairs.frames[i % n], e[i][0].item<double>(), e[i][1].item<double>());
    io::write_file_atomic((fs::path(a->out) / "tsne.csv").string(), csv.data(), csv.size());
    const auto png = (fs::path(a->out) / "tsne.png").string();
    io::write_png(png, study::pose_pair_figure(r.embedding, fmt::format("t-SNE of {} latent/real pose pairs", n)));
    std::cout << fmt::format("t-SNE of {} pose pairs (KL {:.3f}) -> {}\n", n, r.kl_divergence, png);
  });
}

struct AttentionArgs {
  CommonOptions common;
  ModelSource model;
  std::string data, split = "test", out;
  std::vector<std::string> images;
  std::vector<int64_t> patch;  // row col; default: the centre patch
  int64_t scenes = 1;
  double fov = 60;
};

void add_attention_options(CLI::App* cmd, AttentionArgs& a) {
  add_common_options(cmd, a.common);
  add_model_options(cmd, a.model);
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

// The two views to draw, by name: the --images pair, or the first two context views of the index's scenes.
std::vector<std::pair<std::string, data::SceneViews>> attention_views(const AttentionArgs& a,
                                                                      const data::PreprocessOptions& prep) {
  std::vector<std::pair<std::string, data::SceneViews>> pairs;
  if (!a.images.empty()) {
    pairs.emplace_back("images", data::load_photos(a.images, a.fov, prep));
    return pairs;
  }
  data::ChunkDataset dataset(a.data, a.split);
  for (const auto& e : data::read_eval_index((fs::path(a.data) / "evaluation_index.json").string())) {
    if (static_cast<int64_t>(pairs.size()) >= a.scenes) break;
    const int64_t scene = dataset.find(e.key);
    if (scene >= 0 && e.context.size() >= 2)
      pairs.emplace_back(e.key, dataset.load_views(scene, {e.context[0], e.context[1]}, prep));
  }
  if (pairs.empty()) throw std::runtime_error("study attention: no scene of the evaluation index is in " + a.data);
  return pairs;
}

// A 2-D map as JSON rows.
std::vector<std::vector<double>> matrix_rows(const torch::Tensor& m) {
  auto c = m.to(torch::kFloat64).contiguous();
  std::vector<std::vector<double>> rows(c.size(0));
  for (int64_t i = 0; i < c.size(0); ++i)
    rows[i] = std::vector<double>(c[i].data_ptr<double>(), c[i].data_ptr<double>() + c.size(1));
  return rows;
}

void run_attention(const AttentionArgs& a) {
  apply_common_options(a.common);
  if (a.images.empty() == a.data.empty())
    throw std::runtime_error("study attention: give either --data (dataset scenes) or --images A B (two photos)");
  Config config;
  const auto device = parse_device(a.common.device);
  auto net = model::require_uplvsm(
      model::load_model_with_config_file(a.model.checkpoint, a.model.config, device, &config), "study attention");
  const auto prep = data::preprocess_options(config);
  const auto pairs = attention_views(a, prep);
  const int64_t grid = config.model.image_size / config.model.patch_size;
  const int64_t row = a.patch.empty() ? grid / 2 : a.patch[0], col = a.patch.empty() ? grid / 2 : a.patch[1];
  fs::create_directories(a.out);
  nlohmann::json listing = nlohmann::json::array();
  for (const auto& [name, views] : pairs) {
    auto r = study::cross_view_attention(net, views.images.to(device), views.fxfycxcy.to(device), row, col);
    const auto png = (fs::path(a.out) / ("attention_" + name + ".png")).string();
    io::write_png(png, study::attention_figure(views.images, r));
    listing.push_back({{"scene", name},
                       {"patch", {row, col}},
                       {"png", png},
                       {"attention", matrix_rows(r.attention)},
                       {"similarity", matrix_rows(r.similarity)}});
    std::cout << fmt::format("{}: patch ({}, {}), attention on view 2 sums to {:.3f} -> {}\n", name, row, col,
                             r.attention.sum().item<double>(), png);
  }
  const auto text = listing.dump(1);
  io::write_file_atomic((fs::path(a.out) / "attention.json").string(), text.data(), text.size());
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
