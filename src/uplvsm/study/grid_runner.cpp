// The grid studies' runs trained, scored and reported (study/grid_runner.h).
#include "uplvsm/study/grid_runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/json_input.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/eval/evaluator.h"
#include "uplvsm/eval/training_evaluation.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/train/run_start.h"
#include "uplvsm/train/tokenizer_start.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::study {

namespace fs = std::filesystem;

namespace {

GridCell cell_from_json(const nlohmann::json& j) {
  GridCell c;
  c.series = j.at("series");
  c.setting = j.at("setting");
  c.x = j.at("x");
  c.psnr = j.at("psnr");
  c.ssim = j.at("ssim");
  c.lpips = j.at("lpips").is_null() ? eval::kUnavailable : j.at("lpips").get<double>();
  c.seed = j.value("seed", int64_t{0});
  return c;
}

// Trains (or resumes) one run in `dir`; throws when a signal interrupted it.
train::TrainResult train_run(const GridRun& r, const GridOptions& a, const fs::path& dir) {
  train::TrainOptions topt;
  topt.data_root = a.data;
  topt.run_dir = dir.string();
  topt.device = a.device;
  topt.perceptual_weights = a.vgg19;
  topt.perceptual_input = a.vgg19_input;
  topt.init_weights = a.init;
  topt.progress = a.progress;
  if (r.config.training.eval_every > 0)
    topt.periodic_eval = eval::periodic_evaluation(r.config, a.data, dir.string(), a.device);
  auto trained = train::train(r.config, topt);
  if (trained.interrupted) throw std::runtime_error("study interrupted by a signal (rerun the same command to resume)");
  return trained;
}

// Scores a trained run on the test set and records its result.json.
nlohmann::json score_run(const GridRun& r, const GridOptions& a, const fs::path& dir, const train::TrainResult& trained,
                         const eval::Lpips& lpips) {
  Config config;
  auto net = model::load_model(dir.string(), a.device, &config);
  data::ChunkDataset test(a.data, "test");
  const auto prep = data::preprocess_options(config);
  eval::EvalOptions eopt;
  eopt.max_scenes = a.eval_scenes;
  eopt.device = a.device;
  eopt.num_visualised = 2;
  eopt.out_dir = (dir / "eval").string();
  eopt.bf16 = config.training.amp == Amp::Bf16;
  eopt.target_poses = net->default_target_poses();
  eopt.lpips = lpips;
  eopt.extra = {{"checkpoint", trained.last_checkpoint}, {"series", r.series}, {"setting", r.setting}};
  auto summary = eval::evaluate(net, test, prep, eopt);
  const auto& row = summary.scores.model;
  auto finite_or_null = [](double v) { return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v); };
  nlohmann::json j = {{"series", r.series},
                      {"setting", r.setting},
                      {"x", r.x},
                      {"seed", r.config.training.seed},
                      {"psnr", row.psnr},
                      {"ssim", row.ssim},
                      {"lpips", finite_or_null(row.lpips)},
                      {"steps", trained.step},
                      {"scenes", summary.scenes},
                      {"copy_nearest_psnr", summary.scores.copy_nearest.psnr}};
  const auto text = j.dump(2);
  io::write_file_atomic((dir / "result.json").string(), text.data(), text.size());
  return j;
}

// Trains (or resumes) one run, scores it on the test set and records result.json; a finished run is read back.
GridCell run_cell(const GridRun& r, const GridOptions& a, const eval::Lpips& lpips) {
  const auto dir = fs::path(a.out) / "runs" / r.dir_name;
  // A finished run (or the run it stands for) is read back, placed where this grid plots it.
  const auto done = r.same_as.empty() ? dir / "result.json" : fs::path(a.out) / "runs" / r.same_as / "result.json";
  if (fs::exists(done)) {
    if (r.same_as.empty()) spdlog::info("study: {} @ {} already done ({})", r.series, r.setting, done.string());
    auto c = cell_from_json(read_json_file(done.string(), "study result"));
    c.setting = r.setting;
    c.x = r.x;
    c.scenes = run_scene_scores(done.parent_path().string());  // for the intervals over test scenes
    return c;
  }
  if (!r.same_as.empty())
    throw std::runtime_error(
        fmt::format("study: {} @ {} stands for {}, which has no result.json yet", r.series, r.setting, r.same_as));
  const auto trained = train_run(r, a, dir);
  auto c = cell_from_json(score_run(r, a, dir, trained, lpips));
  c.scenes = run_scene_scores(dir.string());
  return c;
}

// The trained runs' periodic evaluations, for the report's curves (a run standing in for others counts once).
std::vector<RunCurve> run_curves(const std::vector<GridRun>& runs, const GridOptions& a) {
  std::vector<RunCurve> curves;
  for (const auto& r : runs)
    if (r.same_as.empty())
      curves.push_back({r.series, r.setting, (fs::path(a.out) / "runs" / r.dir_name / "metrics.jsonl").string(),
                        r.config.training.seed});
  return curves;
}

// Every run once per seed (its directory named after the seed); as given without seeds.
std::vector<GridRun> for_each_seed(const std::vector<GridRun>& runs, const std::vector<int64_t>& seeds) {
  if (seeds.empty()) return runs;
  std::vector<GridRun> out;
  for (int64_t seed : seeds)
    for (auto r : runs) {
      r.config.training.seed = seed;
      r.dir_name += fmt::format("__seed{}", seed);
      if (!r.same_as.empty()) r.same_as += fmt::format("__seed{}", seed);
      out.push_back(r);
    }
  return out;
}

// report_only's cells: each run's row of from_table (matched by series, setting and seed; placed at the plan's
// x, as a result.json is), else its result.json, else a planned cell that reads "(not run)".
std::vector<GridCell> done_cells(const std::vector<GridRun>& runs, const GridOptions& a, const eval::Lpips& lpips) {
  const auto table = a.from_table.empty() ? std::vector<GridCell>{} : read_table_cells(a.from_table);
  std::vector<GridCell> cells;
  size_t from_table = 0;
  for (const auto& r : runs) {
    const auto row = std::find_if(table.begin(), table.end(), [&](const GridCell& c) {
      return c.series == r.series && c.setting == r.setting && c.seed == r.config.training.seed;
    });
    if (row != table.end()) {
      cells.push_back(*row), cells.back().x = r.x, ++from_table;
    } else if (fs::exists(fs::path(a.out) / "runs" / (r.same_as.empty() ? r.dir_name : r.same_as) / "result.json")) {
      cells.push_back(run_cell(r, a, lpips));
    } else {  // planned, not done (runs 0, no metrics)
      const double none = std::nan("");
      cells.push_back({r.series, r.setting, r.x, none, none, none, r.config.training.seed, 0});
    }
  }
  if (!a.from_table.empty() && from_table < table.size())
    spdlog::warn("study --from-table {}: {} of its {} rows match no run of this study (series, setting, seed)",
                 a.from_table, table.size() - from_table, table.size());
  return cells;
}

// <out>/study.json: every run's series, setting, directory and config.
void write_study_plan(const std::vector<GridRun>& runs, const GridOptions& a, const std::string& title) {
  fs::create_directories(a.out);
  nlohmann::json plan = nlohmann::json::array();
  for (const auto& r : runs)
    plan.push_back({{"series", r.series},
                    {"setting", r.setting},
                    {"dir", "runs/" + (r.same_as.empty() ? r.dir_name : r.same_as)},
                    {"config", config_to_json(r.config)}});
  const auto plan_text = nlohmann::json{{"study", title}, {"data", a.data}, {"runs", plan}}.dump(2);
  io::write_file_atomic((fs::path(a.out) / "study.json").string(), plan_text.data(), plan_text.size());
}

}  // namespace

GridResult run_grid(const GridPlan& grid, const GridOptions& a) {
  auto fig = grid.figure;
  if (!a.reference.empty()) fig.reference = read_reference_cells(a.reference);
  fig.reference_title = a.reference_title;
  const auto runs = for_each_seed(grid.runs, a.seeds);
  // Every run's loss and tokenizer checked before the first trains: a later run's missing --vgg19 or --init would
  // otherwise stop the study hours in.
  for (const auto& r : runs) {
    train::require_perceptual_weights(r.config, a.vgg19);
    const auto dir = (fs::path(a.out) / "runs" / r.dir_name).string();
    train::require_tokenizer_start(r.config, a.init, train::run_resumes(dir, "auto"));
  }
  eval::Lpips lpips{nullptr};
  if (!a.lpips_backbone.empty()) {
    lpips = eval::load_lpips(eval::parse_lpips_net(a.lpips_net), a.lpips_backbone, a.lpips_lin);
    lpips->to(a.device);
  }
  write_study_plan(runs, a, fig.title);
  GridResult result;
  if (a.report_only) {
    result.cells = done_cells(runs, a, lpips);
    const auto done = std::count_if(result.cells.begin(), result.cells.end(), [](const auto& c) { return c.runs > 0; });
    spdlog::info("study: --report-only: {} of {} runs done", done, runs.size());
  } else {
    const auto t0 = std::chrono::steady_clock::now();
    for (size_t i = 0; i < runs.size(); ++i) {
      spdlog::info("study: run {}/{}: {} @ {}", i + 1, runs.size(), runs[i].series, runs[i].setting);
      result.cells.push_back(run_cell(runs[i], a, lpips));
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      spdlog::info("study: {}/{} runs done, {} elapsed, ETA {} | {} @ {}: PSNR {:.2f}, SSIM {:.4f}", i + 1, runs.size(),
                   format_duration(elapsed), format_duration(elapsed / (i + 1) * (runs.size() - i - 1)), runs[i].series,
                   runs[i].setting, result.cells.back().psnr, result.cells.back().ssim);
    }
  }
  result.table = write_grid_report(result.cells, run_curves(runs, a), a.out, fig, grid.description);
  return result;
}

}  // namespace uplvsm::study
