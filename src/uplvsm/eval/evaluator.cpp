#include "uplvsm/eval/evaluator.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <chrono>
#include <filesystem>
#include <future>
#include <iterator>
#include <stdexcept>
#include <utility>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/eval/baselines.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/eval_mode.h"

namespace uplvsm::eval {
namespace {

namespace fs = std::filesystem;

// The twelve numbers of a view or scene, in the order model, copy-nearest, mean-colour x PSNR, SSIM, LPIPS, gradient-
// energy ratio; shared by ViewMetrics and SceneResult, which name the same fields.
using Values = std::array<double, 12>;
template <class M>
Values values_of(const M& m) {
  return {m.psnr,       m.ssim,      m.lpips,     m.grad_ratio,      //
          m.psnr_copy,  m.ssim_copy, m.lpips_copy, m.grad_ratio_copy,  //
          m.psnr_mean,  m.ssim_mean, m.lpips_mean, m.grad_ratio_mean};
}
template <class M>
void assign_values(M& m, const Values& v) {
  m.psnr = v[0], m.ssim = v[1], m.lpips = v[2], m.grad_ratio = v[3];
  m.psnr_copy = v[4], m.ssim_copy = v[5], m.lpips_copy = v[6], m.grad_ratio_copy = v[7];
  m.psnr_mean = v[8], m.ssim_mean = v[9], m.lpips_mean = v[10], m.grad_ratio_mean = v[11];
}
const char* const kTableRows[] = {"model", "copy_nearest", "mean_colour"};
const char* const kTableMetrics[] = {"psnr", "ssim", "lpips", "grad_ratio"};
constexpr size_t kNumMetrics = std::size(kTableMetrics);

struct Job {
  data::EvalEntry entry;
  int64_t dataset_index = -1;
  size_t position = 0;  // in index (key) order
  bool visualise = false;
};

struct Loaded {
  const Job* job = nullptr;
  data::Views views;  // context frames, then target frames
};

// Where the results of one run go while batches finish in group order (main thread only).
struct RunState {
  bool ordered_views = true;  // the dataset's frames follow a path: copy-nearest by frame index, else by direction
  std::vector<std::optional<SceneResult>> results;  // by Job::position
  std::vector<std::string> grids;
  int64_t bad_frames = 0, done = 0;
  double psnr_sum = 0, ssim_sum = 0, lpips_sum = 0;
};

std::string safe_file_name(const std::string& key) {
  std::string out = key;
  for (auto& ch : out)
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '-' && ch != '_' && ch != '.') ch = '_';
  return out.empty() ? "scene" : out;
}

std::vector<Job> plan_jobs(const data::ChunkDataset& dataset, const EvalOptions& opt, const std::string& index_path,
                           EvalSummary& summary) {
  auto entries = data::read_eval_index(index_path, &summary.skipped_null);
  std::vector<Job> jobs;
  for (auto& e : entries) {
    const int64_t i = dataset.find(e.key);
    if (i < 0) {
      if (summary.skipped_missing++ < 5) spdlog::debug("eval: key {} of {} is not in the dataset", e.key, index_path);
      continue;
    }
    if (opt.max_scenes > 0 && static_cast<int64_t>(jobs.size()) >= opt.max_scenes) continue;
    if (opt.target_poses != model::TargetPoses::Estimator && !dataset.poses_known(i))
      throw std::runtime_error(fmt::format("eval: scene {} has no ground-truth cameras (imported without poses, listed "
                                           "in {}/{}/unposed.json); target poses from '{}' need them — evaluate it "
                                           "with the estimator protocol",
                                           e.key, dataset.root(), dataset.split(), model::to_string(opt.target_poses)));
    const size_t pos = jobs.size();
    jobs.push_back({std::move(e), i, pos, static_cast<int64_t>(pos) < opt.num_visualised});
  }
  spdlog::info("eval: {} scenes from {} ({} null entries, {} keys not in {}/{}{})", jobs.size(), index_path,
               summary.skipped_null, summary.skipped_missing, dataset.root(), dataset.split(),
               opt.max_scenes > 0 ? fmt::format(", capped at {}", opt.max_scenes) : "");
  return jobs;
}

// Batches of scenes with the same numbers of context and target views (the model takes dense tensors).
std::vector<std::vector<const Job*>> make_batches(const std::vector<Job>& jobs, int64_t batch_size) {
  std::map<std::pair<size_t, size_t>, std::vector<const Job*>> groups;
  for (const auto& job : jobs) groups[{job.entry.context.size(), job.entry.target.size()}].push_back(&job);
  std::vector<std::vector<const Job*>> batches;
  const size_t bs = static_cast<size_t>(std::max<int64_t>(1, batch_size));
  for (const auto& [counts, group] : groups)
    for (size_t i = 0; i < group.size(); i += bs)
      batches.emplace_back(group.begin() + i, group.begin() + std::min(group.size(), i + bs));
  return batches;
}

// The scenes of one batch, decoded and preprocessed (on a helper thread while the previous batch runs).
struct LoadedBatch {
  std::vector<Loaded> scenes;
  int64_t bad_frames = 0;
};

LoadedBatch load_batch(const data::ChunkDataset& dataset, const std::vector<const Job*>& batch,
                       const data::PreprocessOptions& prep) {
  LoadedBatch out;
  for (const Job* job : batch) {
    std::vector<int64_t> frames = job->entry.context;
    frames.insert(frames.end(), job->entry.target.begin(), job->entry.target.end());
    try {
      out.scenes.push_back({job, dataset.load_views(job->dataset_index, frames, prep)});
    } catch (const data::BadFrameError& e) {
      // pixelSplat drops such frames; an evaluation entry names fixed frames, so the scene is dropped instead.
      spdlog::warn("eval: skipping scene {}: {}", job->entry.key, e.what());
      ++out.bad_frames;
    }
  }
  return out;
}

SceneResult scene_result(const Job& job, torch::TensorAccessor<double, 2> m) {
  SceneResult r;
  r.key = job.entry.key;
  r.context = job.entry.context;
  r.target = job.entry.target;
  r.overlap = job.entry.overlap;
  r.bucket = r.overlap ? data::overlap_bucket(*r.overlap) : "none";
  const auto [lo, hi] = std::minmax_element(r.context.begin(), r.context.end());
  for (size_t t = 0; t < r.target.size(); ++t) {
    ViewMetrics v;
    v.frame = r.target[t];
    v.extrapolated = !r.context.empty() && (v.frame < *lo || v.frame > *hi);
    Values x;
    for (size_t i = 0; i < x.size(); ++i) x[i] = m[static_cast<int64_t>(i)][static_cast<int64_t>(t)];
    assign_values(v, x);
    r.views.push_back(v);
  }
  finalise_scene(r);
  return r;
}

void write_grid(const std::string& out_dir, const SceneResult& r, const torch::Tensor& inputs,
                const torch::Tensor& pred, const torch::Tensor& gt, const torch::Tensor& copy, RunState& state) {
  const auto path = (fs::path(out_dir) / "scenes" / (safe_file_name(r.key) + ".png")).string();
  fs::create_directories(fs::path(path).parent_path());
  io::write_png(path, scene_grid(r, inputs, pred, gt, copy));
  state.grids.push_back(path);
}

// LPIPS of [b, vt, 3, H, W] pairs in chunks of `chunk` images (as the official evaluation batches it): [b, vt].
torch::Tensor lpips_of(Lpips lpips, const torch::Tensor& pred, const torch::Tensor& gt, int64_t chunk) {
  auto p = pred.flatten(0, 1).to(torch::kFloat32), g = gt.flatten(0, 1).to(torch::kFloat32);
  std::vector<torch::Tensor> parts;
  const int64_t step = std::max<int64_t>(1, chunk);
  for (int64_t i = 0; i < p.size(0); i += step) {
    const int64_t n = std::min(step, p.size(0) - i);
    parts.push_back(lpips->forward(p.narrow(0, i, n), g.narrow(0, i, n)));
  }
  return torch::cat(parts).view({pred.size(0), pred.size(1)});
}

// One forward for scenes of equal view counts and image size; scores the model and the baselines per target.
void run_batch(model::NovelViewModel& net, const std::vector<const Loaded*>& scenes, const EvalOptions& opt,
               RunState& state) {
  const int64_t vi = static_cast<int64_t>(scenes[0]->job->entry.context.size());
  const int64_t vt = static_cast<int64_t>(scenes[0]->job->entry.target.size());
  std::vector<torch::Tensor> images, intrinsics, cameras;
  std::vector<std::vector<int64_t>> in_frames, tgt_frames;
  for (const auto* s : scenes) {
    images.push_back(s->views.images);
    intrinsics.push_back(s->views.fxfycxcy);
    cameras.push_back(s->views.c2w);
    in_frames.push_back(s->job->entry.context);
    tgt_frames.push_back(s->job->entry.target);
  }
  auto all = torch::stack(images).to(opt.device, torch::kFloat32);  // [b, vi + vt, 3, H, W]
  auto k = torch::stack(intrinsics).to(opt.device, torch::kFloat32);
  auto c2w = torch::stack(cameras).to(opt.device, torch::kFloat32);
  auto in_img = all.narrow(1, 0, vi), gt = all.narrow(1, vi, vt);
  torch::Tensor pred;
  {
    AutocastGuard amp(opt.device, opt.bf16);  // only the model: SSIM's filters must not run in bf16
    model::Views inputs{in_img, k.narrow(1, 0, vi), c2w.narrow(1, 0, vi)};
    model::Views targets{gt, k.narrow(1, vi, vt), c2w.narrow(1, vi, vt)};
    pred = net->render(inputs, targets, opt.target_poses).render;
  }
  pred = pred.to(torch::kFloat32);
  auto copy = state.ordered_views ? copy_nearest_input(in_img, in_frames, tgt_frames)
                                  : copy_nearest_direction(in_img, c2w.narrow(1, 0, vi), c2w.narrow(1, vi, vt));
  auto mean = mean_colour(gt);
  auto lp = [&](const torch::Tensor& x) {
    return opt.lpips ? lpips_of(opt.lpips, x, gt, opt.lpips_chunk).to(torch::kFloat64)
                     : torch::full({x.size(0), x.size(1)}, kUnavailable, x.options().dtype(torch::kFloat64));
  };
  std::vector<torch::Tensor> rows;
  for (const auto* x : {&pred, &copy, &mean})
    for (auto&& m : {psnr(*x, gt), ssim(*x, gt), lp(*x), gradient_energy_ratio(*x, gt)})
      rows.push_back(m.to(torch::kCPU));
  auto metrics = torch::stack(rows, 1).to(torch::kFloat64).contiguous();  // [b, 12, vt], rows in Values order
  auto acc = metrics.accessor<double, 3>();
  for (size_t b = 0; b < scenes.size(); ++b) {
    const Job& job = *scenes[b]->job;
    auto r = scene_result(job, acc[static_cast<int64_t>(b)]);
    state.psnr_sum += r.psnr;
    state.ssim_sum += r.ssim;
    state.lpips_sum += r.lpips;
    const auto i = static_cast<int64_t>(b);
    if (job.visualise && !opt.out_dir.empty()) write_grid(opt.out_dir, r, in_img[i], pred[i], gt[i], copy[i], state);
    state.results[job.position] = std::move(r);
  }
}

void run_loaded(model::NovelViewModel& net, const std::vector<Loaded>& loaded, const EvalOptions& opt,
                RunState& state) {
  // Scenes of another aspect ratio preprocess to another size (square_crop off): one forward per image size.
  std::map<std::vector<int64_t>, std::vector<const Loaded*>> by_size;
  for (const auto& l : loaded) by_size[l.views.images.sizes().vec()].push_back(&l);
  for (const auto& [size, group] : by_size) run_batch(net, group, opt, state);
}

std::map<std::string, std::map<std::string, double>> mean_table(const std::vector<const SceneResult*>& scenes) {
  Values sums{};
  for (const auto* s : scenes) {
    const auto v = values_of(*s);
    for (size_t i = 0; i < sums.size(); ++i) sums[i] += v[i];
  }
  const double n = static_cast<double>(scenes.size());
  std::map<std::string, std::map<std::string, double>> table;
  for (size_t row = 0; row < std::size(kTableRows); ++row)
    for (size_t col = 0; col < kNumMetrics; ++col)
      table[kTableRows[row]][kTableMetrics[col]] = sums[kNumMetrics * row + col] / n;
  return table;
}

// A CSV number; unavailable values (LPIPS without weights) are empty fields.
std::string csv_number(double v) { return std::isnan(v) ? "" : fmt::format("{:.6f}", v); }

std::string csv_values(const Values& v) {
  std::string out;
  for (size_t i = 0; i < v.size(); ++i) out += (i ? "," : "") + csv_number(v[i]);
  return out;
}

const char* const kValueColumns =
    "psnr,ssim,lpips,grad_ratio,psnr_copy,ssim_copy,lpips_copy,grad_ratio_copy,psnr_mean,ssim_mean,lpips_mean,"
    "grad_ratio_mean";

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char ch : s) out += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return out + "\"";
}

void write_text(const std::string& path, const std::string& text) {
  io::write_file_atomic(path, text.data(), text.size());
}

std::string per_scene_csv(const EvalSummary& s) {
  std::string out = "key,bucket,overlap,num_targets," + std::string(kValueColumns) + "\n";
  for (const auto& r : s.per_scene)
    out += fmt::format("{},{},{},{},{}\n", csv_field(r.key), r.bucket,
                       r.overlap ? fmt::format("{:.6g}", *r.overlap) : "", r.views.size(), csv_values(values_of(r)));
  return out;
}

std::string per_view_csv(const EvalSummary& s) {
  std::string out = "key,frame,extrapolated," + std::string(kValueColumns) + "\n";
  for (const auto& r : s.per_scene)
    for (const auto& v : r.views)
      out += fmt::format("{},{},{},{}\n", csv_field(r.key), v.frame, v.extrapolated ? 1 : 0, csv_values(values_of(v)));
  return out;
}

}  // namespace

void finalise_scene(SceneResult& r) {
  if (r.views.empty()) throw std::runtime_error("eval: scene " + r.key + " has no target views");
  Values sums{};
  for (const auto& v : r.views) {
    const auto x = values_of(v);
    for (size_t i = 0; i < sums.size(); ++i) sums[i] += x[i];
  }
  for (auto& x : sums) x /= static_cast<double>(r.views.size());
  assign_values(r, sums);
}

EvalSummary summarise(std::vector<SceneResult> scenes) {
  EvalSummary s;
  s.scenes = static_cast<int64_t>(scenes.size());
  s.per_scene = std::move(scenes);
  std::vector<const SceneResult*> all;
  std::map<std::string, std::vector<const SceneResult*>> by_bucket;
  for (const auto& r : s.per_scene) {
    all.push_back(&r);
    if (r.bucket != "none") by_bucket[r.bucket].push_back(&r);
  }
  s.table = mean_table(all);  // NaN (null in JSON) without scenes, so every row/column is always present
  for (const auto& [bucket, members] : by_bucket) {
    s.buckets[bucket] = mean_table(members);
    s.bucket_scenes[bucket] = static_cast<int64_t>(members.size());
  }
  // Each scene restricted to its interpolated / extrapolated targets.
  std::map<std::string, std::vector<SceneResult>> parts;
  for (const auto& r : s.per_scene) {
    SceneResult inter = r, extra = r;
    inter.views.clear();
    extra.views.clear();
    for (const auto& v : r.views) (v.extrapolated ? extra : inter).views.push_back(v);
    for (auto* part : {&inter, &extra}) {
      if (part->views.empty()) continue;
      finalise_scene(*part);
      parts[part == &inter ? "interpolation" : "extrapolation"].push_back(std::move(*part));
    }
  }
  for (const auto& [span, members] : parts) {
    std::vector<const SceneResult*> ptrs;
    for (const auto& m : members) ptrs.push_back(&m);
    s.spans[span] = mean_table(ptrs);
    s.span_scenes[span] = static_cast<int64_t>(members.size());
  }
  return s;
}

nlohmann::json summary_to_json(const EvalSummary& s) {
  int64_t views = 0;
  for (const auto& r : s.per_scene) views += static_cast<int64_t>(r.views.size());
  nlohmann::json j;
  j["scenes"] = s.scenes;
  j["views"] = views;
  j["skipped"] = {{"null_entries", s.skipped_null}, {"missing_keys", s.skipped_missing},
                  {"bad_frames", s.skipped_bad_frames}};
  j["table"] = s.table;
  j["buckets"] = s.buckets;
  j["bucket_scenes"] = s.bucket_scenes;
  j["spans"] = s.spans;
  j["span_scenes"] = s.span_scenes;
  j["lpips"] = s.lpips;
  j["seconds"] = s.seconds;
  j["scenes_per_second"] = s.seconds > 0 ? static_cast<double>(s.scenes) / s.seconds : 0.0;
  j["scene_grids"] = s.scene_grids;
  j["conventions"] = {
      {"psnr", "clamp to [0,1], MSE over C,H,W per image (float64), mse clamped at 1e-10, -10 log10(mse)"},
      {"ssim", "skimage structural_similarity(gt, pred, win_size=11, gaussian_weights=True, channel_axis=0, "
               "data_range=1.0)"},
      {"lpips", "lpips.LPIPS(net, version='0.1')(pred, gt, normalize=True), float32, unclamped; null when the "
                "backbone/lin weights were not given"},
      {"grad_ratio", "gradient-energy ratio mean|grad pred| / mean|grad gt|: mean absolute forward difference along x "
                     "and y over all channels of the [0,1]-clamped images (float64), per image; gt floored at 1e-6"},
      {"averaging", "mean over each scene's targets, then mean over scenes"},
      {"buckets", "NoPoSplat get_overlap_tag: 0.05<=o<=0.3 small, o<=0.55 medium, o<=0.8 large, else ignore"},
      {"spans", "a target outside [min(context), max(context)] frame is extrapolation, else interpolation; per "
                "scene mean over its targets of each kind, then mean over the scenes that have such targets"},
      {"copy_nearest", "each target predicted by the input view nearest in frame index (ordered views) or in "
                       "viewing direction (unordered views: dataset.json view_order)"},
      {"mean_colour", "oracle: each target predicted by its own per-channel mean colour"}};
  return j;
}

void write_results(const std::string& out_dir, const EvalSummary& s, const nlohmann::json& extra) {
  fs::create_directories(out_dir);
  auto j = summary_to_json(s);
  if (extra.is_object()) j.update(extra);
  write_text((fs::path(out_dir) / "metrics.json").string(), j.dump(2) + "\n");
  write_text((fs::path(out_dir) / "per_scene.csv").string(), per_scene_csv(s));
  write_text((fs::path(out_dir) / "per_view.csv").string(), per_view_csv(s));
}

// Every shard's scenes, bad-frame counts and grids into every rank's state (results by index position).
static void merge_shards(const EvalOptions& opt, RunState& state) {
  nlohmann::json mine{{"bad_frames", state.bad_frames}, {"grids", state.grids}, {"scenes", nlohmann::json::array()}};
  for (size_t pos = 0; pos < state.results.size(); ++pos)
    if (state.results[pos]) mine["scenes"].push_back({{"position", pos}, {"scene", scene_to_json(*state.results[pos])}});
  const auto all = opt.gather(mine.dump());
  TORCH_CHECK(static_cast<int>(all.size()) == opt.shard_count, "eval: gathered ", all.size(), " shards, expected ",
              opt.shard_count);
  state.bad_frames = 0;
  state.grids.clear();
  for (const auto& text : all) {
    const auto j = nlohmann::json::parse(text);
    state.bad_frames += j.at("bad_frames").get<int64_t>();
    for (const auto& g : j.at("grids")) state.grids.push_back(g.get<std::string>());
    for (const auto& e : j.at("scenes"))
      state.results.at(e.at("position").get<size_t>()) = scene_from_json(e.at("scene"));
  }
}

EvalSummary evaluate(model::NovelViewModel& net, const data::ChunkDataset& dataset, const data::PreprocessOptions& prep,
                     const EvalOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string index_path =
      opt.index_path.empty() ? (fs::path(dataset.root()) / "evaluation_index.json").string() : opt.index_path;
  EvalSummary counts;
  TORCH_CHECK(opt.shard_count >= 1 && opt.shard_rank >= 0 && opt.shard_rank < opt.shard_count,
              "eval: shard ", opt.shard_rank, " of ", opt.shard_count, " is not a valid shard");
  const auto all_jobs = plan_jobs(dataset, opt, index_path, counts);
  std::vector<Job> jobs;  // this shard's
  for (const auto& job : all_jobs)
    if (static_cast<int>(job.position % static_cast<size_t>(opt.shard_count)) == opt.shard_rank) jobs.push_back(job);
  RunState state;
  state.ordered_views = dataset.info().ordered_views;
  state.results.resize(all_jobs.size());
  {
    model::EvalModeGuard mode(*net);
    torch::NoGradGuard no_grad;
    ProgressBar bar("eval", static_cast<int64_t>(jobs.size()), "scene");
    const auto batches = make_batches(jobs, opt.batch_size);
    auto load = [&](size_t k) {
      return std::async(std::launch::async, [&, k] { return load_batch(dataset, batches[k], prep); });
    };
    std::future<LoadedBatch> next;
    if (!batches.empty()) next = load(0);
    for (size_t k = 0; k < batches.size(); ++k) {
      LoadedBatch current = next.get();
      if (k + 1 < batches.size()) next = load(k + 1);  // decode the next batch while this one runs
      state.bad_frames += current.bad_frames;
      if (!current.scenes.empty()) run_loaded(net, current.scenes, opt, state);
      state.done += static_cast<int64_t>(batches[k].size());
      const auto ok = static_cast<double>(state.done - state.bad_frames);
      std::vector<std::pair<std::string, std::string>> fields = {
          {"psnr", fmt::format("{:.2f}", ok > 0 ? state.psnr_sum / ok : 0.0)},
          {"ssim", fmt::format("{:.4f}", ok > 0 ? state.ssim_sum / ok : 0.0)}};
      if (opt.lpips) fields.emplace_back("lpips", fmt::format("{:.4f}", ok > 0 ? state.lpips_sum / ok : 0.0));
      bar.update(state.done, fields);
    }
    bar.finish();
  }
  if (opt.shard_count > 1 && opt.gather) merge_shards(opt, state);
  std::vector<SceneResult> results;
  for (auto& r : state.results)
    if (r) results.push_back(std::move(*r));
  EvalSummary s = summarise(std::move(results));
  s.skipped_null = counts.skipped_null;
  s.skipped_missing = counts.skipped_missing;
  s.skipped_bad_frames = state.bad_frames;
  s.scene_grids = std::move(state.grids);
  if (opt.lpips)
    s.lpips = {{"available", true}, {"net", opt.lpips->net == LpipsNet::Vgg ? "vgg" : "alex"}};
  else
    s.lpips = {{"available", false}, {"reason", "no LPIPS weights given (--lpips-backbone, --lpips-lin)"}};
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (s.scenes == 0) {
    spdlog::warn("eval: no scene was evaluated ({})", index_path);
  } else {
    spdlog::info("eval: {} scenes in {}: PSNR {:.3f} SSIM {:.4f} edges {:.3f} LPIPS {} | copy nearest {:.3f} / {:.4f} "
                 "| mean colour {:.3f} / {:.4f}",
                 s.scenes, format_duration(s.seconds), s.table["model"]["psnr"], s.table["model"]["ssim"],
                 s.table["model"]["grad_ratio"],
                 opt.lpips ? fmt::format("{:.4f}", s.table["model"]["lpips"]) : "unavailable",
                 s.table["copy_nearest"]["psnr"], s.table["copy_nearest"]["ssim"], s.table["mean_colour"]["psnr"],
                 s.table["mean_colour"]["ssim"]);
  }
  if (!opt.out_dir.empty() && opt.shard_rank == 0) write_results(opt.out_dir, s, opt.extra);
  return s;
}

}  // namespace uplvsm::eval
