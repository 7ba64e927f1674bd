// One scene's results as JSON and back: how the ranks of a sharded `uplvsm eval` hand their scenes to each other
// (declared in evaluator.h). Unavailable numbers (LPIPS without weights) travel as null and come back as NaN.
#include <string>
#include <vector>

#include "uplvsm/eval/evaluator.h"

namespace uplvsm::eval {

namespace {
double number(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : kUnavailable;
}
}  // namespace

nlohmann::json scene_to_json(const SceneResult& r) {
  nlohmann::json views = nlohmann::json::array();
  for (const auto& v : r.views)
    views.push_back({{"frame", v.frame},
                     {"psnr", v.psnr},
                     {"ssim", v.ssim},
                     {"lpips", v.lpips},
                     {"psnr_copy", v.psnr_copy},
                     {"ssim_copy", v.ssim_copy},
                     {"lpips_copy", v.lpips_copy},
                     {"psnr_mean", v.psnr_mean},
                     {"ssim_mean", v.ssim_mean},
                     {"lpips_mean", v.lpips_mean},
                     {"grad_ratio", v.grad_ratio},
                     {"grad_ratio_copy", v.grad_ratio_copy},
                     {"grad_ratio_mean", v.grad_ratio_mean},
                     {"extrapolated", v.extrapolated}});
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
    m.psnr = number(v, "psnr"), m.ssim = number(v, "ssim"), m.lpips = number(v, "lpips");
    m.psnr_copy = number(v, "psnr_copy"), m.ssim_copy = number(v, "ssim_copy"), m.lpips_copy = number(v, "lpips_copy");
    m.psnr_mean = number(v, "psnr_mean"), m.ssim_mean = number(v, "ssim_mean"), m.lpips_mean = number(v, "lpips_mean");
    m.grad_ratio = number(v, "grad_ratio"), m.grad_ratio_copy = number(v, "grad_ratio_copy");
    m.grad_ratio_mean = number(v, "grad_ratio_mean");
    m.extrapolated = v.at("extrapolated").get<bool>();
    r.views.push_back(m);
  }
  finalise_scene(r);
  return r;
}

}  // namespace uplvsm::eval
