// `uplvsm report`: one HTML page tying a run together — headline metrics vs baselines, training curve, video,
// image grids, config and machine facts.
#include <filesystem>
#include <fstream>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/eval/report.h"

namespace uplvsm::cli {

namespace fs = std::filesystem;

namespace {
nlohmann::json read_json_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("report: cannot open " + path);
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(fmt::format("report: {} is not valid JSON ({})", path, e.what()));
  }
}
}  // namespace

void add_report_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("report", "Write an HTML report (index.html) from a training run, an eval output and "
                                           "a render output.");
  struct Args {
    std::string run, eval, video, out, title = "UP-LVSM report";
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("--run", a->run, "training run directory (config.json, metrics.jsonl)")->check(CLI::ExistingDirectory);
  cmd->add_option("--eval", a->eval, "directory written by `uplvsm eval`")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--video", a->video, "directory written by `uplvsm render`")->check(CLI::ExistingDirectory);
  cmd->add_option("--title", a->title, "page title")->capture_default_str();
  cmd->add_option("--out", a->out, "report directory")->required();
  cmd->callback([a] {
    eval::ReportInputs in;
    in.title = a->title;
    in.metrics_json = (fs::path(a->eval) / "metrics.json").string();
    auto metrics = read_json_file(in.metrics_json);
    if (!a->run.empty()) {
      in.config = read_json_file((fs::path(a->run) / "config.json").string());
      in.train_log_jsonl = (fs::path(a->run) / "metrics.jsonl").string();
    }
    if (fs::is_directory(fs::path(a->eval) / "scenes"))
      for (const auto& e : fs::directory_iterator(fs::path(a->eval) / "scenes"))
        if (e.path().extension() == ".png") in.scene_grids.push_back(e.path().string());
    std::sort(in.scene_grids.begin(), in.scene_grids.end());
    if (!a->video.empty()) {
      auto videos = read_json_file((fs::path(a->video) / "videos.json").string());
      if (!videos.empty()) {
        in.video_mp4 = videos[0].value("mp4", "");
        in.video_gif = videos[0].value("gif", "");
      }
    }
    in.runtime_info = format_runtime_info(runtime_info());
    auto page = eval::write_report(a->out, in);
    const auto& t = metrics.at("table");
    std::cout << fmt::format("report: {}\n  held-out PSNR: UP-LVSM {:.2f} dB | copy nearest {:.2f} dB | mean colour "
                             "{:.2f} dB ({} scenes)\n",
                             fs::absolute(page).string(), t.at("model").at("psnr").get<double>(),
                             t.at("copy_nearest").at("psnr").get<double>(), t.at("mean_colour").at("psnr").get<double>(),
                             metrics.value("scenes", 0));
  });
}

}  // namespace uplvsm::cli
