// `uplvsm report`: one HTML page tying a run together — headline metrics vs baselines, training curve, videos,
// image grids, config and machine facts; or, with --model given several times, models side by side.
#include <filesystem>
#include <fstream>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/json_input.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/eval/comparison_report.h"
#include "uplvsm/eval/report.h"

namespace uplvsm::cli {

namespace fs = std::filesystem;

namespace {

// What one model's report shows, from the directories `train`, `eval` and `render` wrote.
struct ModelDirs {
  std::string label, caption, run, eval;
  std::vector<std::string> videos;
};

eval::ReportInputs report_inputs(const ModelDirs& d) {
  for (const auto* dir : {&d.run, &d.eval})
    if (!dir->empty() && !fs::is_directory(*dir)) throw std::runtime_error("report: no directory " + *dir);
  if (d.eval.empty()) throw std::runtime_error("report: an eval directory is required (eval=DIR / --eval DIR)");
  eval::ReportInputs in;
  in.title = d.label;
  in.metrics_json = (fs::path(d.eval) / "metrics.json").string();
  if (!d.run.empty()) {
    in.config = read_json_file((fs::path(d.run) / "config.json").string(), "report:");
    in.train_log_jsonl = (fs::path(d.run) / "metrics.jsonl").string();
  }
  if (fs::is_directory(fs::path(d.eval) / "scenes"))
    for (const auto& e : fs::directory_iterator(fs::path(d.eval) / "scenes"))
      if (e.path().extension() == ".png") in.scene_grids.push_back(e.path().string());
  std::sort(in.scene_grids.begin(), in.scene_grids.end());
  for (const auto& dir : d.videos) {
    auto videos = read_json_file((fs::path(dir) / "videos.json").string(), "report:");
    if (videos.empty()) continue;
    const auto& v = videos[0];  // the first scene's video
    in.videos.push_back({v.value("trajectory", ""), v.value("mp4", ""), v.value("gif", ""), v.value("width", 0)});
  }
  in.runtime_info = format_runtime_info(runtime_info());
  return in;
}

// "label=NAME,run=DIR,eval=DIR,video=DIR[,video=DIR...][,caption=TEXT]" (values may not contain commas).
ModelDirs parse_model_spec(const std::string& spec) {
  ModelDirs d;
  size_t start = 0;
  while (start <= spec.size()) {
    const size_t end = std::min(spec.find(',', start), spec.size());
    const auto item = spec.substr(start, end - start);
    const auto eq = item.find('=');
    const auto key = item.substr(0, eq), value = eq == std::string::npos ? "" : item.substr(eq + 1);
    if (eq == std::string::npos || value.empty())
      throw std::runtime_error(fmt::format("report --model '{}': '{}' is not KEY=VALUE", spec, item));
    if (key == "label")
      d.label = value;
    else if (key == "caption")
      d.caption = value;
    else if (key == "run")
      d.run = value;
    else if (key == "eval")
      d.eval = value;
    else if (key == "video")
      d.videos.push_back(value);
    else
      throw std::runtime_error(
          fmt::format("report --model '{}': unknown key '{}' (label, caption, run, eval, video)", spec, key));
    start = end + 1;
  }
  if (d.label.empty()) throw std::runtime_error(fmt::format("report --model '{}': label=NAME is required", spec));
  return d;
}

void print_headline(const std::string& label, const std::string& metrics_json) {
  const auto metrics = read_json_file(metrics_json, "report:");
  const auto& t = metrics.at("table");
  std::cout << fmt::format(
      "  {}: held-out PSNR {:.2f} dB | copy nearest {:.2f} dB | mean colour {:.2f} dB ({} "
      "scenes)\n",
      label, t.at("model").at("psnr").get<double>(), t.at("copy_nearest").at("psnr").get<double>(),
      t.at("mean_colour").at("psnr").get<double>(), metrics.value("scenes", 0));
}

}  // namespace

void add_report_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("report",
                                 "Write an HTML report (index.html) from a training run, an eval output and "
                                 "render outputs; or several models side by side (--model, repeated).");
  struct Args {
    ModelDirs single;
    std::vector<std::string> models;
    std::string out, title = "UP-LVSM report";
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("--run", a->single.run, "training run directory (config.json, metrics.jsonl)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--eval", a->single.eval, "directory written by `uplvsm eval`")->check(CLI::ExistingDirectory);
  cmd->add_option("--video", a->single.videos, "directories written by `uplvsm render` (one or more)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--model", a->models,
                  "a model of a side-by-side page: 'label=NAME,eval=DIR[,run=DIR][,video=DIR...][,caption=TEXT]' "
                  "(repeat for each column; replaces --run/--eval/--video)");
  cmd->add_option("--title", a->title, "page title")->capture_default_str();
  cmd->add_option("--out", a->out, "report directory")->required();
  cmd->callback([a] {
    if (a->models.empty()) {
      a->single.label = a->title;
      auto page = eval::write_report(a->out, report_inputs(a->single));
      std::cout << fmt::format("report: {}\n", fs::absolute(page).string());
      print_headline("UP-LVSM", (fs::path(a->single.eval) / "metrics.json").string());
      return;
    }
    if (!a->single.eval.empty() || !a->single.run.empty() || !a->single.videos.empty())
      throw std::runtime_error("report: give either --model (repeated) or --run/--eval/--video, not both");
    std::vector<eval::ComparedModel> models;
    std::vector<ModelDirs> dirs;
    for (const auto& spec : a->models) {
      dirs.push_back(parse_model_spec(spec));
      models.push_back({dirs.back().label, dirs.back().caption, report_inputs(dirs.back())});
    }
    auto page = eval::write_comparison_report(a->out, a->title, models, format_runtime_info(runtime_info()));
    std::cout << fmt::format("report: {}\n", fs::absolute(page).string());
    for (const auto& d : dirs) print_headline(d.label, (fs::path(d.eval) / "metrics.json").string());
  });
}

}  // namespace uplvsm::cli
