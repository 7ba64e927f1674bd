#include "uplvsm/eval/evaluator.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <future>
#include <iterator>
#include <stdexcept>
#include <utility>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/eval_mode.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/eval/baselines.h"
#include "uplvsm/eval/eval_pose_noise.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/eval/result_files.h"
#include "uplvsm/io/image.h"

namespace uplvsm::eval {
namespace {

namespace fs = std::filesystem;

struct Job {
  data::EvalEntry entry;
  int64_t dataset_index = -1;
  size_t position = 0;  // in index (key) order
  bool visualise = false;
};

struct Loaded {
  const Job* job = nullptr;
  data::SceneViews views;  // context frames, then target frames
};

// Where the results of one run go while batches finish in group order (main thread only).
struct RunState {
  bool ordered_views = true;  // the dataset's frames follow a path: copy-nearest by frame index, else by direction
  std::vector<std::optional<SceneResult>> results;  // by Job::position
  std::vector<std::string> grids;
  int64_t bad_frames = 0, resized_frames = 0, done = 0;
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
      throw std::runtime_error(
          fmt::format("eval: scene {} has no ground-truth cameras (imported without poses, listed "
                      "in {}/{}/unposed.json); target poses from '{}' need them — evaluate it "
                      "with the estimator protocol",
                      e.key, dataset.root(), dataset.split(), uplvsm::to_string(opt.target_poses)));
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
  int64_t bad_frames = 0, resized_frames = 0;
};

LoadedBatch load_batch(const data::ChunkDataset& dataset, const std::vector<const Job*>& batch,
                       const data::PreprocessOptions& prep) {
  LoadedBatch out;
  for (const Job* job : batch) {
    std::vector<int64_t> frames = job->entry.context;
    frames.insert(frames.end(), job->entry.target.begin(), job->entry.target.end());
    try {
      // A frame of another size than frame 0 is resized from its own size, as the official dataset does (each
      // frame on its own), and the scene scored; only frames that cannot be stacked drop the scene.
      out.scenes.push_back({job, dataset.load_views(job->dataset_index, frames, prep, data::FrameSizePolicy::Resize)});
      const int64_t resized = out.scenes.back().views.resized_frames;
      if (resized > 0)
        spdlog::info("eval: scene {}: {} frame(s) of another size than frame 0, resized as the official dataset does",
                     job->entry.key, resized);
      out.resized_frames += resized;
    } catch (const data::BadFrameError& e) {
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
    int64_t row = 0;  // the rows of `m` follow kPredictors x kScoreFields
    for (const auto& p : kPredictors)
      for (const auto& [name, field] : kScoreFields) v.*p.field.*field = m[row++][static_cast<int64_t>(t)];
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

// The batch's cameras as the model is told them under the official evaluation's pose noise: per scene in its scene
// frame with its own seeded noise (eval_pose_noise.h), so the posed models take them as they are.
void tell_noisy_cameras(const std::vector<const Loaded*>& scenes, const EvalOptions& opt, model::Views& inputs,
                        model::Views& targets) {
  std::vector<torch::Tensor> in, tg;
  for (const auto* s : scenes) {
    auto told = noisy_scene_cameras(s->views.c2w, inputs.images.size(1), opt.pose_noise_std, opt.pose_noise_seed,
                                    s->job->entry.key);
    in.push_back(told.inputs);
    tg.push_back(told.targets);
  }
  inputs.c2w = torch::stack(in).to(opt.device);
  targets.c2w = torch::stack(tg).to(opt.device);
  inputs.camera_frame = targets.camera_frame = model::CameraFrame::Scene;
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
  model::Views inputs{in_img, k.narrow(1, 0, vi), c2w.narrow(1, 0, vi)};
  model::Views targets{gt, k.narrow(1, vi, vt), c2w.narrow(1, vi, vt)};
  // Only the model is told noisy cameras (made outside autocast, in fp32): the baselines keep the clean ones.
  if (opt.pose_noise_std > 0 && pose_noise_reaches_model(opt.target_poses))
    tell_noisy_cameras(scenes, opt, inputs, targets);
  torch::Tensor pred;
  {
    Bf16Autocast amp(opt.device, opt.bf16);  // only the model: SSIM's filters must not run in bf16
    pred = opt.pose_refinement.steps != 0    // a negative count reaches the refinement's own check
               ? render_at_refined_poses(*model::as_uplvsm(*net), inputs, targets, opt.pose_refinement).render
               : net->render(inputs, targets, opt.target_poses).render;
  }
  pred = pred.to(torch::kFloat32);
  auto copy = state.ordered_views ? copy_nearest_input(in_img, in_frames, tgt_frames)
                                  : copy_nearest_direction(in_img, c2w.narrow(1, 0, vi), c2w.narrow(1, vi, vt));
  auto mean = mean_colour(gt);
  auto lp = [&](const torch::Tensor& x) {
    return opt.lpips ? lpips_of(opt.lpips, x, gt, opt.lpips_chunk).to(torch::kFloat64)
                     : torch::full({x.size(0), x.size(1)}, kUnavailable, x.options().dtype(torch::kFloat64));
  };
  std::vector<torch::Tensor> rows;  // kPredictors' order x kScoreFields' order
  for (const auto* x : {&pred, &copy, &mean})
    for (auto&& m : {psnr(*x, gt), ssim(*x, gt), lp(*x), gradient_energy_ratio(*x, gt)})
      rows.push_back(m.to(torch::kCPU));
  auto metrics = torch::stack(rows, 1).to(torch::kFloat64).contiguous();  // [b, 12, vt]
  auto acc = metrics.accessor<double, 3>();
  for (size_t b = 0; b < scenes.size(); ++b) {
    const Job& job = *scenes[b]->job;
    auto r = scene_result(job, acc[static_cast<int64_t>(b)]);
    state.psnr_sum += r.model.psnr;
    state.ssim_sum += r.model.ssim;
    state.lpips_sum += r.model.lpips;
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

}  // namespace

void finalise_scene(SceneResult& r) {
  if (r.views.empty()) throw std::runtime_error("eval: scene " + r.key + " has no target views");
  static_cast<PredictorScores&>(r) = mean_scores(r.views);
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
  s.scores = mean_scores(all);  // NaN (null in JSON) without scenes, so every predictor and score is present
  for (const auto& [bucket, members] : by_bucket) {
    s.buckets[bucket] = mean_scores(members);
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
    s.spans[span] = mean_scores(ptrs);
    s.span_scenes[span] = static_cast<int64_t>(members.size());
  }
  return s;
}

// Every shard's scenes, bad-frame counts and grids into every rank's state (results by index position).
static void merge_shards(const EvalOptions& opt, RunState& state) {
  nlohmann::json mine{{"bad_frames", state.bad_frames},
                      {"resized_frames", state.resized_frames},
                      {"grids", state.grids},
                      {"scenes", nlohmann::json::array()}};
  for (size_t pos = 0; pos < state.results.size(); ++pos)
    if (state.results[pos])
      mine["scenes"].push_back({{"position", pos}, {"scene", scene_to_json(*state.results[pos])}});
  const auto all = opt.gather(mine.dump());
  TORCH_CHECK(static_cast<int>(all.size()) == opt.shard_count, "eval: gathered ", all.size(), " shards, expected ",
              opt.shard_count);
  state.bad_frames = state.resized_frames = 0;
  state.grids.clear();
  for (const auto& text : all) {
    const auto j = nlohmann::json::parse(text);
    state.bad_frames += j.at("bad_frames").get<int64_t>();
    state.resized_frames += j.at("resized_frames").get<int64_t>();
    for (const auto& g : j.at("grids")) state.grids.push_back(g.get<std::string>());
    for (const auto& e : j.at("scenes"))
      state.results.at(e.at("position").get<size_t>()) = scene_from_json(e.at("scene"));
  }
}

// This shard's scenes in batches, in eval mode without gradients; the next batch is decoded on a helper thread
// while one runs.
static void run_jobs(model::NovelViewModel& net, const data::ChunkDataset& dataset, const data::PreprocessOptions& prep,
                     const std::vector<Job>& jobs, const EvalOptions& opt, RunState& state) {
  EvalModeGuard mode(*net);
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
    state.resized_frames += current.resized_frames;
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

// Refuses options that do not fit the model, and says which cameras a pose-noise evaluation moves.
static void check_options(model::NovelViewModel& net, const EvalOptions& opt) {
  TORCH_CHECK(
      opt.pose_refinement.steps == 0 || (model::as_uplvsm(*net) && opt.target_poses == model::TargetPoses::Estimator),
      "eval: pose refinement refines the latent poses UP-LVSM's estimator reads from the targets; this is ",
      net->name(), " with target poses '", uplvsm::to_string(opt.target_poses), "'");
  check_pose_noise_std(opt.pose_noise_std);
  TORCH_CHECK(opt.shard_count >= 1 && opt.shard_rank >= 0 && opt.shard_rank < opt.shard_count, "eval: shard ",
              opt.shard_rank, " of ", opt.shard_count, " is not a valid shard");
  if (opt.pose_noise_std > 0)
    spdlog::info(
        "eval: {} with pose noise sd {} (seed {}) on: {}", net->name(), opt.pose_noise_std, opt.pose_noise_seed,
        pose_noise_record(opt.pose_noise_std, opt.pose_noise_seed, opt.target_poses)["cameras"].get<std::string>());
}

EvalSummary evaluate(model::NovelViewModel& net, const data::ChunkDataset& dataset, const data::PreprocessOptions& prep,
                     const EvalOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string index_path =
      opt.index_path.empty() ? (fs::path(dataset.root()) / "evaluation_index.json").string() : opt.index_path;
  EvalSummary counts;
  check_options(net, opt);
  const auto all_jobs = plan_jobs(dataset, opt, index_path, counts);
  std::vector<Job> jobs;  // this shard's
  for (const auto& job : all_jobs)
    if (static_cast<int>(job.position % static_cast<size_t>(opt.shard_count)) == opt.shard_rank) jobs.push_back(job);
  RunState state;
  state.ordered_views = dataset.info().ordered_views;
  state.results.resize(all_jobs.size());
  run_jobs(net, dataset, prep, jobs, opt, state);
  if (opt.shard_count > 1 && opt.gather) merge_shards(opt, state);
  std::vector<SceneResult> results;
  for (auto& r : state.results)
    if (r) results.push_back(std::move(*r));
  EvalSummary s = summarise(std::move(results));
  s.skipped_null = counts.skipped_null;
  s.skipped_missing = counts.skipped_missing;
  s.skipped_bad_frames = state.bad_frames;
  s.resized_frames = state.resized_frames;
  s.scene_grids = std::move(state.grids);
  if (opt.lpips)
    s.lpips = {{"available", true}, {"net", opt.lpips->net == LpipsNet::Vgg ? "vgg" : "alex"}};
  else
    s.lpips = {{"available", false}, {"reason", "no LPIPS weights given (--lpips-backbone, --lpips-lin)"}};
  s.pose_noise = pose_noise_record(opt.pose_noise_std, opt.pose_noise_seed, opt.target_poses);
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (s.scenes == 0) {
    spdlog::warn("eval: no scene was evaluated ({})", index_path);
  } else {
    spdlog::info(
        "eval: {} scenes in {}: PSNR {:.3f} SSIM {:.4f} edges {:.3f} LPIPS {} | copy nearest {:.3f} / {:.4f} "
        "| mean colour {:.3f} / {:.4f}",
        s.scenes, format_duration(s.seconds), s.scores.model.psnr, s.scores.model.ssim, s.scores.model.grad_ratio,
        opt.lpips ? fmt::format("{:.4f}", s.scores.model.lpips) : "unavailable", s.scores.copy_nearest.psnr,
        s.scores.copy_nearest.ssim, s.scores.mean_colour.psnr, s.scores.mean_colour.ssim);
  }
  if (!opt.out_dir.empty() && opt.shard_rank == 0) write_results(opt.out_dir, s, opt.extra);
  return s;
}

}  // namespace uplvsm::eval
