#include "uplvsm/eval/result_files.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <utility>

#include "uplvsm/io/atomic_file.h"

namespace uplvsm::eval {
namespace {

namespace fs = std::filesystem;

// A CSV number; unavailable values (LPIPS without weights) are empty fields.
std::string csv_number(double v) { return std::isnan(v) ? "" : fmt::format("{:.6f}", v); }

// The predictors' scores as CSV fields, and their column names: psnr,ssim,lpips,grad_ratio,psnr_copy,...
std::string csv_values(const PredictorScores& s) {
  std::string out, separator;  // an unavailable first value is an empty field too
  for (const auto& p : kPredictors)
    for (const auto& [name, field] : kScoreFields) out += std::exchange(separator, ",") + csv_number(s.*p.field.*field);
  return out;
}

std::string value_columns() {
  std::string out;
  for (const auto& p : kPredictors)
    for (const auto& [name, field] : kScoreFields) out += (out.empty() ? "" : ",") + std::string(name) + p.suffix;
  return out;
}

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
  std::string out = "key,bucket,overlap,num_targets," + value_columns() + "\n";
  for (const auto& r : s.per_scene) {
    const std::string overlap = r.overlap ? fmt::format("{:.6g}", *r.overlap) : "";
    out += fmt::format("{},{},{},{},{}\n", csv_field(r.key), r.bucket, overlap, r.views.size(), csv_values(r));
  }
  return out;
}

std::string per_view_csv(const EvalSummary& s) {
  std::string out = "key,frame,extrapolated," + value_columns() + "\n";
  for (const auto& r : s.per_scene)
    for (const auto& v : r.views)
      out += fmt::format("{},{},{},{}\n", csv_field(r.key), v.frame, v.extrapolated ? 1 : 0, csv_values(v));
  return out;
}

// Each predictor's scores under their names: predictor -> score -> value (NaN, unavailable LPIPS, dumps as null).
nlohmann::json table_json(const PredictorScores& scores) {
  nlohmann::json table = nlohmann::json::object();
  for (const auto& p : kPredictors)
    for (const auto& [name, field] : kScoreFields) table[p.name][name] = scores.*p.field.*field;
  return table;
}

// group (bucket, span) -> its table.
nlohmann::json tables_json(const std::map<std::string, PredictorScores>& groups) {
  nlohmann::json tables = nlohmann::json::object();
  for (const auto& [group, scores] : groups) tables[group] = table_json(scores);
  return tables;
}

}  // namespace

nlohmann::json summary_to_json(const EvalSummary& s) {
  int64_t views = 0;
  for (const auto& r : s.per_scene) views += static_cast<int64_t>(r.views.size());
  nlohmann::json j;
  j["scenes"] = s.scenes;
  j["views"] = views;
  j["skipped"] = {
      {"null_entries", s.skipped_null}, {"missing_keys", s.skipped_missing}, {"bad_frames", s.skipped_bad_frames}};
  j["resized_frames"] = s.resized_frames;  // scored, each resized from its own size as the official dataset does
  j["table"] = table_json(s.scores);
  j["buckets"] = tables_json(s.buckets);
  j["bucket_scenes"] = s.bucket_scenes;
  j["spans"] = tables_json(s.spans);
  j["span_scenes"] = s.span_scenes;
  j["lpips"] = s.lpips;
  j["pose_noise"] = s.pose_noise;  // which cameras were scored: clean, or with the official evaluation's noise
  j["seconds"] = s.seconds;
  j["scenes_per_second"] = s.seconds > 0 ? static_cast<double>(s.scenes) / s.seconds : 0.0;
  j["scene_grids"] = s.scene_grids;
  j["conventions"] = {
      {"psnr", "clamp to [0,1], MSE over C,H,W per image (float64), mse clamped at 1e-10, -10 log10(mse)"},
      {"ssim",
       "skimage structural_similarity(gt, pred, win_size=11, gaussian_weights=True, channel_axis=0, "
       "data_range=1.0)"},
      {"lpips",
       "lpips.LPIPS(net, version='0.1')(pred, gt, normalize=True), float32, unclamped; null when the "
       "backbone/lin weights were not given"},
      {"grad_ratio",
       "gradient-energy ratio mean|grad pred| / mean|grad gt|: mean absolute forward difference along x "
       "and y over all channels of the [0,1]-clamped images (float64), per image; gt floored at 1e-6"},
      {"averaging", "mean over each scene's targets, then mean over scenes"},
      {"buckets", "NoPoSplat get_overlap_tag: 0.05<=o<=0.3 small, o<=0.55 medium, o<=0.8 large, else ignore"},
      {"spans",
       "a target outside [min(context), max(context)] frame is extrapolation, else interpolation; per "
       "scene mean over its targets of each kind, then mean over the scenes that have such targets"},
      {"copy_nearest",
       "each target predicted by the input view nearest in frame index (ordered views) or in "
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

}  // namespace uplvsm::eval
