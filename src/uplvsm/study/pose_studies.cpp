// The single-model analyses of `uplvsm study` (study/pose_studies.h).
#include "uplvsm/study/pose_studies.h"

#include <filesystem>

#include <fmt/format.h>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/photo.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/study/attention_map.h"
#include "uplvsm/study/pose_sensitivity.h"
#include "uplvsm/study/tsne.h"

namespace uplvsm::study {

namespace fs = std::filesystem;

namespace {

void write_study_file(const fs::path& path, const std::string& text) {
  io::write_file_atomic(path.string(), text.data(), text.size());
}

// The two views to draw, by name: the photos, or the first two context views of the index's scenes.
std::vector<std::pair<std::string, data::SceneViews>> attention_input_views(const AttentionOptions& a,
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
std::vector<std::vector<double>> json_rows(const torch::Tensor& m) {
  auto c = m.to(torch::kFloat64).contiguous();
  std::vector<std::vector<double>> rows(c.size(0));
  for (int64_t i = 0; i < c.size(0); ++i)
    rows[i] = std::vector<double>(c[i].data_ptr<double>(), c[i].data_ptr<double>() + c.size(1));
  return rows;
}

}  // namespace

PosePairs pose_pairs_of_split(model::UPLVSM& net, const Config& config, const PoseStudyOptions& a,
                              const std::string& split) {
  data::ChunkDataset dataset(a.data, split);
  auto prep = data::preprocess_options(config);
  PosePairOptions opt;
  opt.max_scenes = a.max_scenes;
  opt.gap = a.gap;
  opt.device = a.device;
  return collect_pose_pairs(net, dataset, prep, opt);
}

ProbeScores run_pose_probe(model::UPLVSM& net, const Config& config, const PoseStudyOptions& a) {
  auto train_pairs = pose_pairs_of_split(net, config, a, a.train_split);
  auto test_pairs = pose_pairs_of_split(net, config, a, a.split);
  fs::create_directories(a.out);
  write_pose_pairs_csv((fs::path(a.out) / ("pairs_" + a.train_split + ".csv")).string(), train_pairs);
  write_pose_pairs_csv((fs::path(a.out) / ("pairs_" + a.split + ".csv")).string(), test_pairs);
  auto train = without_canonical_views(train_pairs), test = without_canonical_views(test_pairs);
  ProbeOptions po;
  po.iterations = a.iterations;
  ProbeScores s;
  s.mlp = pose_accuracy(fit_and_apply_mlp_probe(train, test.latent, po), test.real);
  s.linear = pose_accuracy(fit_and_apply_linear_probe(train, test.latent), test.real);
  s.mean = pose_accuracy(mean_pose_baseline(train, test.real.size(0)), test.real);
  s.train_views = train.frames.size();
  s.test_views = test.frames.size();
  nlohmann::json result{{"mlp", to_json(s.mlp)},
                        {"linear", to_json(s.linear)},
                        {"mean_pose", to_json(s.mean)},
                        {"train_views", s.train_views},
                        {"test_views", s.test_views},
                        {"train_split", a.train_split},
                        {"test_split", a.split},
                        {"gap", a.gap},
                        {"checkpoint", a.checkpoint},
                        {"conventions",
                         "real and latent poses relative to the first context view, translations in context "
                         "baselines; translation error |t_pred - t|, rotation error 2 acos|<q_pred, q>| in "
                         "degrees; the first context view is excluded; mean_pose predicts the training views' "
                         "mean real pose (no latent used)"}};
  write_study_file(fs::path(a.out) / "probe.json", result.dump(2) + "\n");
  return s;
}

nlohmann::json run_pose_sensitivity(model::UPLVSM& net, const Config& config, const PoseStudyOptions& a) {
  data::ChunkDataset dataset(a.data, a.split);
  SensitivityOptions opt;
  opt.max_scenes = a.max_scenes;
  opt.gap = a.gap;
  opt.device = a.device;
  opt.source = model::resolve_target_poses(a.target_poses, *net);
  auto report = measure_pose_sensitivity(net, dataset, data::preprocess_options(config), opt);
  fs::create_directories(a.out);
  write_sensitivity_csv((fs::path(a.out) / "views.csv").string(), report);
  auto summary = summarise(report);
  summary["checkpoint"] = a.checkpoint;
  summary["split"] = a.split;
  summary["gap"] = a.gap;
  summary["target_poses"] = uplvsm::to_string(opt.source);
  write_study_file(fs::path(a.out) / "sensitivity.json", summary.dump(2) + "\n");
  return summary;
}

TsneRun run_tsne(model::UPLVSM& net, const Config& config, const PoseStudyOptions& a) {
  auto pairs = without_canonical_views(pose_pairs_of_split(net, config, a, a.split));
  fs::create_directories(a.out);
  write_pose_pairs_csv((fs::path(a.out) / "pairs.csv").string(), pairs);
  TsneOptions o;
  o.perplexity = a.perplexity;
  o.iterations = a.iterations;
  auto r = tsne(torch::cat({pairs.latent, pairs.real}), o);
  const int64_t n = pairs.latent.size(0);
  std::string csv = "pair,kind,scene,frame,x,y\n";
  auto e = r.embedding.contiguous();
  for (int64_t i = 0; i < 2 * n; ++i)
    csv += fmt::format("{},{},{},{},{:.6f},{:.6f}\n", i % n, i < n ? "latent" : "real", pairs.scenes[i % n],
                       pairs.frames[i % n], e[i][0].item<double>(), e[i][1].item<double>());
  write_study_file(fs::path(a.out) / "tsne.csv", csv);
  const auto png = (fs::path(a.out) / "tsne.png").string();
  io::write_png(png, pose_pair_figure(r.embedding, fmt::format("t-SNE of {} latent/real pose pairs", n)));
  return {n, r.kl_divergence, png};
}

std::vector<AttentionDrawn> run_attention(model::UPLVSM& net, const Config& config, const AttentionOptions& a) {
  const auto pairs = attention_input_views(a, data::preprocess_options(config));
  const int64_t grid = config.model.image_size / config.model.patch_size;
  const int64_t row = a.patch.empty() ? grid / 2 : a.patch[0], col = a.patch.empty() ? grid / 2 : a.patch[1];
  fs::create_directories(a.out);
  nlohmann::json listing = nlohmann::json::array();
  std::vector<AttentionDrawn> drawn;
  for (const auto& [name, views] : pairs) {
    auto r = cross_view_attention(net, views.images.to(a.device), views.fxfycxcy.to(a.device), row, col);
    const auto png = (fs::path(a.out) / ("attention_" + name + ".png")).string();
    io::write_png(png, attention_figure(views.images, r));
    listing.push_back({{"scene", name},
                       {"patch", {row, col}},
                       {"png", png},
                       {"attention", json_rows(r.attention)},
                       {"similarity", json_rows(r.similarity)}});
    drawn.push_back({name, png, row, col, r.attention.sum().item<double>()});
  }
  write_study_file(fs::path(a.out) / "attention.json", listing.dump(1));
  return drawn;
}

}  // namespace uplvsm::study
