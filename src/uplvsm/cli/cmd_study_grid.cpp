// `uplvsm study scaling` and `uplvsm study pose-noise`: grids of training runs. Series are model configs (UP-LVSM,
// PT-LVSM, LVSM), settings are nested training-data subsets (the paper's scalability study, Table 3) or Gaussian
// noise on the training poses (the appendix's pose-noise study), each for one or more training seeds. Every run is
// scored on one fixed test set. <out>/runs/<series>__<setting>/ is an ordinary run directory (resumable training,
// eval/); a run whose result.json exists is not redone. The grid's table, CSV, plots and README.md land in <out>/.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/json_input.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/eval/evaluator.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/study/grid_report.h"
#include "uplvsm/study/study_grid.h"
#include "uplvsm/train/run_start.h"
#include "uplvsm/train/tokenizer_start.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::cli {

namespace fs = std::filesystem;

namespace {

struct GridArgs {
  CommonOptions common;
  std::vector<std::string> configs;
  std::string data, out, vgg19, init, lpips_net = "vgg", lpips_backbone, lpips_lin;
  int64_t steps = -1, eval_scenes = 0;
  std::vector<int64_t> seeds;          // empty: each config's training.seed
  std::vector<std::string> overrides;  // --set, applied to every config
  train::VggInput vgg19_input = train::VggInput::Auto;
  bool report_only = false;                              // tables and plots from the runs already done; nothing trains
  std::string reference, reference_title = "reference";  // published numbers drawn beside ours
  std::string from_table;  // with report_only: cells from a study's table.csv instead of runs/
};

struct GridRun {
  std::string series, setting, dir_name;
  double x = 0;
  Config config;
  // dir_name of an earlier run whose result this one is (a model that never reads training cameras is trained
  // once for every pose-noise level: its runs would be identical, as tests/cli/study_grid_slow_test.cpp checks).
  std::string same_as;
};

void add_grid_options(CLI::App* cmd, GridArgs& a) {
  add_common_options(cmd, a.common);
  cmd->add_option("--config", a.configs,
                  "one config per series (model variant), e.g. configs/tiny.json "
                  "configs/tiny_ptlvsm.json configs/tiny_lvsm.json")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--data", a.data, "dataset root: train/ for training, test/ + evaluation_index.json for scoring")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", a.out, "study directory (runs/, table.md, table.csv, *.png, README.md)")->required();
  cmd->add_option("--steps", a.steps, "training steps of every run (default: each config's training.train_steps)");
  cmd->add_option("--set", a.overrides,
                  "section.field=value for every config, as for train (e.g. "
                  "training.eval_every=500 for held-out curves)");
  cmd->add_option("--seeds", a.seeds, "training seeds: every run once per seed, the table their mean ± half range")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--eval-scenes", a.eval_scenes, "test scenes scored per run (0: the whole index)")
      ->capture_default_str();
  cmd->add_option("--reference", a.reference,
                  "published numbers to plot beside ours (CSV: series,setting,x,psnr,ssim,lpips), e.g. "
                  "docs/research/data/paper_objaverse_scaling.csv")
      ->check(CLI::ExistingFile);
  cmd->add_option("--reference-title", a.reference_title, "the reference plots' title")->capture_default_str();
  auto* report_only =
      cmd->add_flag("--report-only", a.report_only,
                    "write the table, plots and curves from the runs done so far (a run without result.json reads "
                    "'(not run)'; an unfinished run's curve is shown as far as it got); nothing trains");
  cmd->add_option("--from-table", a.from_table,
                  "with --report-only: each run's scores from this table.csv of the same study (matched by series, "
                  "setting and seed) instead of runs/, to redraw a study whose runs are on another machine")
      ->check(CLI::ExistingFile)
      ->needs(report_only);
  cmd->add_option("--vgg19", a.vgg19, "VGG19 weights for the perceptual loss (as for `uplvsm train`)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--init", a.init,
                  "starting weights of every run, as for `uplvsm train` (the pretrained DINOv2 the full-size "
                  "configs' tokenizer needs)")
      ->check(CLI::ExistingFile);
  add_vgg19_input_option(cmd, a.vgg19_input);
  cmd->add_option("--lpips-net", a.lpips_net, "LPIPS backbone: vgg or alex")
      ->check(CLI::IsMember({"vgg", "alex"}))
      ->capture_default_str();
  auto* backbone = cmd->add_option("--lpips-backbone", a.lpips_backbone, "LPIPS backbone weights (as for eval)")
                       ->check(CLI::ExistingFile);
  cmd->add_option("--lpips-lin", a.lpips_lin, "LPIPS lin weights (as for eval)")
      ->check(CLI::ExistingFile)
      ->needs(backbone);
  backbone->needs("--lpips-lin");
}

// Series name: the model variant, or the config's name when two configs share a variant.
std::vector<std::pair<std::string, Config>> load_series(const GridArgs& a) {
  std::vector<std::pair<std::string, Config>> out;
  for (const auto& path : a.configs) {
    auto c = apply_config_overrides(load_config(path), a.overrides, path);
    if (a.steps > 0) c.training.train_steps = a.steps;
    out.emplace_back(to_string(c.model.variant), c);
  }
  for (auto& [name, c] : out) {
    int same = 0;
    for (const auto& other : out) same += other.first == name;
    if (same > 1) name = c.name;
  }
  for (size_t i = 0; i < out.size(); ++i)
    for (size_t j = i + 1; j < out.size(); ++j)
      if (out[i].first == out[j].first)
        throw std::runtime_error("study: configs " + a.configs[i] + " and " + a.configs[j] +
                                 " have the same variant and name '" + out[i].first + "'; give them distinct names");
  return out;
}

study::GridCell cell_from_json(const nlohmann::json& j) {
  study::GridCell c;
  c.series = j.at("series");
  c.setting = j.at("setting");
  c.x = j.at("x");
  c.psnr = j.at("psnr");
  c.ssim = j.at("ssim");
  c.lpips = j.at("lpips").is_null() ? eval::kUnavailable : j.at("lpips").get<double>();
  c.seed = j.value("seed", int64_t{0});
  return c;
}

// Trains (or resumes) one run, scores it on the test set and records result.json; a finished run is read back.
study::GridCell run_cell(const GridRun& r, const GridArgs& a, torch::Device device, const eval::Lpips& lpips) {
  const auto dir = fs::path(a.out) / "runs" / r.dir_name;
  const auto result_path = dir / "result.json";
  // A finished run (or the run it stands for) is read back, placed where this grid plots it.
  const auto done = r.same_as.empty() ? result_path : fs::path(a.out) / "runs" / r.same_as / "result.json";
  if (fs::exists(done)) {
    if (r.same_as.empty()) spdlog::info("study: {} @ {} already done ({})", r.series, r.setting, done.string());
    auto c = cell_from_json(read_json_file(done.string(), "study result"));
    c.setting = r.setting;
    c.x = r.x;
    c.scenes = study::run_scene_scores(done.parent_path().string());  // for the intervals over test scenes
    return c;
  }
  if (!r.same_as.empty())
    throw std::runtime_error(
        fmt::format("study: {} @ {} stands for {}, which has no result.json yet", r.series, r.setting, r.same_as));
  train::TrainOptions topt;
  topt.data_root = a.data;
  topt.run_dir = dir.string();
  topt.device = device;
  topt.perceptual_weights = a.vgg19;
  topt.perceptual_input = a.vgg19_input;
  topt.init_weights = a.init;
  if (r.config.training.eval_every > 0)
    topt.periodic_eval = periodic_evaluation(r.config, a.data, dir.string(), device);
  auto trained = train::train(r.config, topt);
  if (trained.interrupted) throw std::runtime_error("study interrupted by a signal (rerun the same command to resume)");

  Config config;
  auto net = model::load_model(dir.string(), device, &config);
  data::ChunkDataset test(a.data, "test");
  const auto prep = data::preprocess_options(config);
  eval::EvalOptions eopt;
  eopt.max_scenes = a.eval_scenes;
  eopt.device = device;
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
  io::write_file_atomic(result_path.string(), text.data(), text.size());
  auto c = cell_from_json(j);
  c.scenes = study::run_scene_scores(dir.string());
  return c;
}

// The trained runs' periodic evaluations, for the report's curves (a run standing in for others counts once).
std::vector<study::RunCurve> run_curves(const std::vector<GridRun>& runs, const GridArgs& a) {
  std::vector<study::RunCurve> curves;
  for (const auto& r : runs)
    if (r.same_as.empty())
      curves.push_back({r.series, r.setting, (fs::path(a.out) / "runs" / r.dir_name / "metrics.jsonl").string(),
                        r.config.training.seed});
  return curves;
}

// Every run once per --seeds seed (its directory named after the seed); as given without --seeds.
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

// --report-only's cells: each run's row of --from-table (matched by series, setting and seed; placed at the plan's
// x, as a result.json is), else its result.json, else a planned cell that reads "(not run)".
std::vector<study::GridCell> done_cells(const std::vector<GridRun>& runs, const GridArgs& a, torch::Device device,
                                        const eval::Lpips& lpips) {
  const auto table = a.from_table.empty() ? std::vector<study::GridCell>{} : study::read_table_cells(a.from_table);
  std::vector<study::GridCell> cells;
  size_t from_table = 0;
  for (const auto& r : runs) {
    const auto row = std::find_if(table.begin(), table.end(), [&](const study::GridCell& c) {
      return c.series == r.series && c.setting == r.setting && c.seed == r.config.training.seed;
    });
    if (row != table.end()) {
      cells.push_back(*row), cells.back().x = r.x, ++from_table;
    } else if (fs::exists(fs::path(a.out) / "runs" / (r.same_as.empty() ? r.dir_name : r.same_as) / "result.json")) {
      cells.push_back(run_cell(r, a, device, lpips));
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

void run_grid(const std::vector<GridRun>& grid, const GridArgs& a, study::GridFigure fig,
              const std::string& description) {
  apply_common_options(a.common);
  if (!a.reference.empty()) fig.reference = study::read_reference_cells(a.reference);
  fig.reference_title = a.reference_title;
  const auto runs = for_each_seed(grid, a.seeds);
  // Every run's loss and tokenizer checked before the first trains: a later run's missing --vgg19 or --init would
  // otherwise stop the study hours in.
  for (const auto& r : runs) {
    train::require_perceptual_weights(r.config, a.vgg19);
    const auto dir = (fs::path(a.out) / "runs" / r.dir_name).string();
    train::require_tokenizer_start(r.config, a.init, train::run_resumes(dir, "auto"));
  }
  const auto device = parse_device(a.common.device);
  eval::Lpips lpips{nullptr};
  if (!a.lpips_backbone.empty()) {
    lpips = eval::load_lpips(eval::parse_lpips_net(a.lpips_net), a.lpips_backbone, a.lpips_lin);
    lpips->to(device);
  }
  fs::create_directories(a.out);
  nlohmann::json plan = nlohmann::json::array();
  for (const auto& r : runs)
    plan.push_back({{"series", r.series},
                    {"setting", r.setting},
                    {"dir", "runs/" + (r.same_as.empty() ? r.dir_name : r.same_as)},
                    {"config", config_to_json(r.config)}});
  const auto plan_text = nlohmann::json{{"study", fig.title}, {"data", a.data}, {"runs", plan}}.dump(2);
  io::write_file_atomic((fs::path(a.out) / "study.json").string(), plan_text.data(), plan_text.size());

  std::vector<study::GridCell> cells;
  if (a.report_only) {
    cells = done_cells(runs, a, device, lpips);
    const auto done = std::count_if(cells.begin(), cells.end(), [](const auto& c) { return c.runs > 0; });
    spdlog::info("study: --report-only: {} of {} runs done", done, runs.size());
    const auto table = study::write_grid_report(cells, run_curves(runs, a), a.out, fig, description);
    std::cout << "\n" << table << fmt::format("\nstudy results -> {}/README.md\n", a.out);
    return;
  }
  const auto t0 = std::chrono::steady_clock::now();
  for (size_t i = 0; i < runs.size(); ++i) {
    spdlog::info("study: run {}/{}: {} @ {}", i + 1, runs.size(), runs[i].series, runs[i].setting);
    cells.push_back(run_cell(runs[i], a, device, lpips));
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    spdlog::info("study: {}/{} runs done, {} elapsed, ETA {} | {} @ {}: PSNR {:.2f}, SSIM {:.4f}", i + 1, runs.size(),
                 format_duration(elapsed), format_duration(elapsed / (i + 1) * (runs.size() - i - 1)), runs[i].series,
                 runs[i].setting, cells.back().psnr, cells.back().ssim);
  }
  const auto table = study::write_grid_report(cells, run_curves(runs, a), a.out, fig, description);
  std::cout << "\n" << table << fmt::format("\nstudy results -> {}/README.md\n", a.out);
}

// "100", "full" -> scene counts (0: every training scene), checked against the train split's size.
std::vector<int64_t> parse_subsets(const std::vector<std::string>& tokens, int64_t available) {
  std::vector<int64_t> out;
  for (const auto& t : tokens) {
    int64_t n = 0;
    if (t != "full") {
      try {
        size_t used = 0;
        n = std::stoll(t, &used);
        if (used != t.size() || n <= 0) throw std::invalid_argument(t);
      } catch (const std::exception&) {
        throw std::runtime_error("--subsets: expected scene counts or 'full', got '" + t + "'");
      }
      if (n > available)
        throw std::runtime_error(fmt::format("--subsets {}: the train split has only {} scenes", n, available));
    }
    out.push_back(n);
  }
  return out;
}

// Each series on each subset; subset i trains steps x growth^i steps, every run with the given pose noise.
std::vector<GridRun> scaling_runs(const GridArgs& a, const std::vector<int64_t>& sizes, int64_t available,
                                  double growth, double noise_std) {
  std::vector<GridRun> runs;
  for (const auto& [series, config] : load_series(a))
    for (size_t i = 0; i < sizes.size(); ++i) {
      const int64_t n = sizes[i];
      GridRun r{series,
                n == 0 ? fmt::format("full ({})", available) : fmt::format("{} scenes", n),
                fmt::format("{}__{}", series, n == 0 ? std::string("full") : std::to_string(n)),
                static_cast<double>(n == 0 ? available : n),
                config,
                {}};
      r.config.training.max_train_scenes = n;
      r.config.training.pose_noise_std = noise_std;
      r.config.training.train_steps =
          std::llround(static_cast<double>(config.training.train_steps) * std::pow(growth, static_cast<double>(i)));
      runs.push_back(r);
    }
  return runs;
}

void add_scaling(CLI::App& study) {
  auto* cmd = study.add_subcommand(
      "scaling",
      "Scalability study (paper Table 3): train each --config on nested subsets of the training scenes "
      "(the first N of the train split) with the same step budget, score all on one test set; table with "
      "the average gain per 4x data (the paper's least-squares slope) and its interval, plots vs scenes (log x)");
  auto a = std::make_shared<GridArgs>();
  auto subsets = std::make_shared<std::vector<std::string>>();
  auto growth = std::make_shared<double>(1.0);
  auto noise = std::make_shared<double>(0.0);
  add_grid_options(cmd, *a);
  cmd->add_option("--subsets", *subsets, "training scenes per subset, small to large, e.g. 25 100 400 or full")
      ->required();
  cmd->add_option("--steps-growth", *growth,
                  "training steps multiplied by this from one subset to the next "
                  "(1: the same budget for all)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--noise-std", *noise, "pose noise on the training cameras of every run (training.pose_noise_std)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->callback([a, subsets, growth, noise] {
    const int64_t available = data::ChunkDataset(a->data, "train").size();
    const auto runs = scaling_runs(*a, parse_subsets(*subsets, available), available, *growth, *noise);
    const auto budget = *growth == 1
                            ? fmt::format("the same {} training steps", runs.front().config.training.train_steps)
                            : fmt::format("{} training steps on the smallest subset, {:g}x more on each next",
                                          runs.front().config.training.train_steps, *growth);
    const auto noise_note = *noise > 0 ? fmt::format(", training cameras with pose noise sd {:g}", *noise) : "";
    const auto description = fmt::format(
        "Each run: {} on the first N training scenes of {}{}; scored on its test split. Avg. gain: the paper's, the "
        "least-squares slope per 4x data over every subset (improvement positive; LPIPS lower is better).",
        budget, a->data, noise_note);
    study::GridFigure fig;
    fig.title = "Scalability", fig.xlabel = "training scenes", fig.log_x = true, fig.with_gain = true;
    run_grid(runs, *a, fig, description);
  });
}

// Whether training a config reads the training cameras (what pose noise acts on): the posed variants, and UP-LVSM
// told its targets' cameras (the dataset-pose ablation or the mapper).
bool reads_training_cameras(const Config& c) {
  return c.model.variant != Variant::UPLVSM ||
         (c.training.target_poses != TargetPoses::Auto && c.training.target_poses != TargetPoses::Estimator);
}

// The noise levels as standard deviations (the official noise_scale), from --noise-std and --noise-variance (its
// square roots: the paper's caption writes sigma^2), each labelled with how it was given; sorted, repeats once.
std::vector<std::pair<double, std::string>> noise_levels(const std::vector<double>& stds,
                                                         const std::vector<double>& variances) {
  std::vector<std::pair<double, std::string>> levels;
  for (double v : stds) levels.emplace_back(v, fmt::format("sd {:g}", v));
  for (double v : variances) levels.emplace_back(std::sqrt(v), fmt::format("var {:g}", v));
  std::stable_sort(levels.begin(), levels.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<std::pair<double, std::string>> out;
  for (const auto& l : levels) {
    if (!(l.first >= 0) || !std::isfinite(l.first))
      throw std::runtime_error("--noise-std/--noise-variance: levels must be finite numbers >= 0, got " + l.second);
    if (!out.empty() && std::abs(out.back().first - l.first) <= 1e-12 * std::max(1.0, l.first))
      out.back().second += " = " + l.second;
    else
      out.push_back(l);
  }
  return out;
}

std::vector<GridRun> pose_noise_runs(const GridArgs& a, const std::vector<std::pair<double, std::string>>& levels) {
  std::vector<GridRun> runs;
  for (const auto& [series, config] : load_series(a)) {
    const auto first_dir = fmt::format("{}__noise_sd{:g}", series, levels.front().first);
    for (size_t i = 0; i < levels.size(); ++i) {
      const auto& [sd, label] = levels[i];
      GridRun r{series, "noise " + label, fmt::format("{}__noise_sd{:g}", series, sd), sd, config, {}};
      r.config.training.pose_noise_std = sd;
      if (i > 0 && !reads_training_cameras(config)) r.same_as = first_dir;
      runs.push_back(r);
    }
  }
  return runs;
}

void add_pose_noise(CLI::App& study) {
  auto* cmd = study.add_subcommand(
      "pose-noise",
      "Pose-noise study (paper appendix): train each --config with Gaussian noise of each level added to the "
      "(translation, quaternion) encodings of its training cameras as the official noise_scale does, score all "
      "with clean test cameras. UP-LVSM never reads training poses: it is trained once and stands at every level");
  auto a = std::make_shared<GridArgs>();
  auto stds = std::make_shared<std::vector<double>>();
  auto variances = std::make_shared<std::vector<double>>();
  add_grid_options(cmd, *a);
  cmd->add_option("--noise-std", *stds, "noise levels as standard deviations sigma (the official noise_scale)");
  cmd->add_option("--noise-variance", *variances,
                  "noise levels as variances sigma^2 (the paper's caption), "
                  "e.g. 0.001 0.01 0.1");
  cmd->callback([a, stds, variances] {
    auto levels = noise_levels(*stds, *variances);
    if (levels.empty()) levels = noise_levels({0, 0.001, 0.01, 0.1}, {});
    const auto runs = pose_noise_runs(*a, levels);
    const std::string axis = "pose noise sd (the official noise_scale; log axis, no noise at the left)";
    const auto description = fmt::format(
        "Each run: {} training steps on {} with N(0, sd^2) added to the 7-D (t, q) encoding of the input and, drawn "
        "apart, the target cameras after the scene normalisation (the official noise_scale; 'var v' is sd = sqrt(v));"
        " scored with clean test cameras. A model that never reads training cameras is trained once per seed and "
        "stands at every level.",
        runs.front().config.training.train_steps, a->data);
    study::GridFigure fig;
    fig.title = "Pose noise", fig.xlabel = axis, fig.log_x = true;
    run_grid(runs, *a, fig, description);
  });
}

}  // namespace

void add_study_grid_commands(CLI::App& study) {
  add_scaling(study);
  add_pose_noise(study);
}

}  // namespace uplvsm::cli
