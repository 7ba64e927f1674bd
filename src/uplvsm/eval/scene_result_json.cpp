// One scene's results as JSON and back: how the ranks of a sharded `uplvsm eval` hand their scenes to each other
// (declared in evaluator.h). Unavailable numbers (LPIPS without weights) travel as null and come back as NaN.
#include <string>
#include <vector>

#include "uplvsm/eval/evaluator.h"

namespace uplvsm::eval {

namespace {
double number(const nlohmann::json& j, const std::string& key) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : kUnavailable;
}
}  // namespace

nlohmann::json scene_to_json(const SceneResult& r) {
  nlohmann::json views = nlohmann::json::array();
  for (const auto& v : r.views) {
    nlohmann::json view{{"frame", v.frame}, {"extrapolated", v.extrapolated}};
    for (const auto& p : kPredictors)  // "psnr", "psnr_copy", "psnr_mean", ...
      for (const auto& [name, field] : kScoreFields) view[std::string(name) + p.suffix] = v.*p.field.*field;
    views.push_back(std::move(view));
  }
  nlohmann::json j{
      {"key", r.key}, {"context", r.context}, {"target", r.target}, {"bucket", r.bucket}, {"views", views}};
  if (r.overlap) j["overlap"] = *r.overlap;
  return j;
}

SceneResult scene_from_json(const nlohmann::json& j) {
  SceneResult r;
  r.key = j.at("key").get<std::string>();
  r.context = j.at("context").get<std::vector<int64_t>>();
  r.target = j.at("target").get<std::vector<int64_t>>();
  r.bucket = j.at("bucket").get<std::string>();
  if (j.contains("overlap") && j["overlap"].is_number()) r.overlap = j["overlap"].get<double>();
  for (const auto& v : j.at("views")) {
    ViewMetrics m;
    m.frame = v.at("frame").get<int64_t>();
    for (const auto& p : kPredictors)
      for (const auto& [name, field] : kScoreFields) m.*p.field.*field = number(v, std::string(name) + p.suffix);
    m.extrapolated = v.at("extrapolated").get<bool>();
    r.views.push_back(m);
  }
  finalise_scene(r);
  return r;
}

}  // namespace uplvsm::eval
