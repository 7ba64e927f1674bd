#include "uplvsm/study/mapper_scenes.h"

#include <filesystem>
#include <sstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "uplvsm/eval/evaluator.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/io/plot.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::study {

namespace fs = std::filesystem;

namespace {

MapperScenesRow fit_and_score(model::NovelViewModel& net, const data::ChunkDataset& posed,
                              const data::ChunkDataset& held_out, const data::PreprocessOptions& prep,
                              const MapperScenesOptions& opt, int64_t scenes) {
  auto up = model::require_uplvsm(net, "study mapper-scenes");
  MapperScenesRow row;
  row.scenes = scenes;
  auto fit = opt.fit;
  fit.loader.max_scenes = scenes;
  model::PoseMapper mapper(opt.mapper);
  row.fit = train::fit_mapper_to_model(*up, *mapper, posed, fit);
  up->attach_pose_mapper(mapper);
  eval::EvalOptions eo;
  eo.max_scenes = opt.eval_scenes;
  eo.device = fit.device;
  eo.bf16 = fit.bf16;
  eo.num_visualised = 0;
  eo.target_poses = model::TargetPoses::Mapper;
  auto summary = eval::evaluate(net, held_out, prep, eo);
  row.psnr = summary.scores.model.psnr;
  row.ssim = summary.scores.model.ssim;
  row.copy_nearest_psnr = summary.scores.copy_nearest.psnr;
  spdlog::info("mapper-scenes: {} posed scene(s): held-out PSNR {:.2f} dB, SSIM {:.4f}", scenes, row.psnr, row.ssim);
  return row;
}

void write_mapper_scenes_file(const fs::path& path, const std::string& text) {
  io::write_file_atomic(path.string(), text.data(), text.size());
}

}  // namespace

std::vector<MapperScenesRow> run_mapper_scenes(model::NovelViewModel& net, const data::ChunkDataset& posed,
                                               const data::ChunkDataset& held_out, const data::PreprocessOptions& prep,
                                               const MapperScenesOptions& opt) {
  std::vector<MapperScenesRow> rows;
  for (int64_t n : opt.scene_counts) {
    if (n < 1 || n > posed.size())
      throw std::runtime_error(fmt::format("study mapper-scenes: --scenes {}: the posed split of {} has {} scenes", n,
                                           posed.root(), posed.size()));
    rows.push_back(fit_and_score(net, posed, held_out, prep, opt, n));
    if (!opt.out_dir.empty()) write_mapper_scenes(rows, opt.out_dir);  // what is done survives an interruption
  }
  return rows;
}

void write_mapper_scenes(const std::vector<MapperScenesRow>& rows, const std::string& out_dir) {
  const fs::path out(out_dir);
  fs::create_directories(out);
  nlohmann::json listing = nlohmann::json::array();
  std::ostringstream csv;
  csv << "scenes,psnr,ssim,copy_nearest_psnr,calibration_views,least_squares_rms,fit_rms,held_out_rms,fit_seconds\n";
  io::Series psnr{"fitted mapper", {}, {}}, copy{"copy nearest input", {}, {}};
  for (const auto& r : rows) {
    auto fit = r.fit.to_json();
    listing.push_back({{"scenes", r.scenes},
                       {"psnr", r.psnr},
                       {"ssim", r.ssim},
                       {"copy_nearest_psnr", r.copy_nearest_psnr},
                       {"fit", fit}});
    csv << fmt::format("{},{:.4f},{:.4f},{:.4f},{},{:.5f},{:.5f},{:.5f},{:.1f}\n", r.scenes, r.psnr, r.ssim,
                       r.copy_nearest_psnr, r.fit.calibration_views, r.fit.least_squares_rms, r.fit.fit_rms,
                       r.fit.held_out_rms, r.fit.seconds);
    psnr.x.push_back(static_cast<double>(r.scenes));
    psnr.y.push_back(r.psnr);
    copy.x.push_back(static_cast<double>(r.scenes));
    copy.y.push_back(r.copy_nearest_psnr);
  }
  write_mapper_scenes_file(out / "mapper_scenes.json", listing.dump(2) + "\n");
  write_mapper_scenes_file(out / "mapper_scenes.csv", csv.str());
  io::PlotOptions po;
  po.title = "Fitted pose mapper: held-out PSNR at real cameras";
  po.xlabel = "posed scenes used for the fit";
  po.ylabel = "PSNR (dB)";
  po.log_x = true;
  io::write_png((out / "psnr.png").string(), io::plot_lines({psnr, copy}, po));
}

std::vector<MapperScenesRow> run_mapper_scenes_study(const train::MapperRunOptions& run, const std::string& eval_data,
                                                     MapperScenesOptions options) {
  data::ChunkDataset posed(run.data, run.split), held_out(eval_data, "test");
  auto s = train::load_for_mapper_fit(run, posed);
  options.mapper = train::mapper_options(run);
  options.fit = s.fit;
  return run_mapper_scenes(s.net, posed, held_out, data::preprocess_options(s.config), options);
}

}  // namespace uplvsm::study
