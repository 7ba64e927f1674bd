// A scene result with made-up scores, shared by the aggregation tests (evaluator_test) and the file tests
// (result_files_test).
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "uplvsm/data/eval_index.h"
#include "uplvsm/eval/evaluator.h"

namespace uplvsm::test {

// Targets scoring `psnrs` (SSIM 0.5), copy-nearest 5 dB less (SSIM 0.25), mean colour 10 dB (SSIM 0.01); LPIPS
// unavailable, no extrapolated targets; the bucket follows `overlap`.
inline eval::SceneResult fake_scene(const std::string& key, std::optional<double> overlap, std::vector<double> psnrs) {
  eval::SceneResult r;
  r.key = key;
  r.overlap = overlap;
  r.bucket = overlap ? data::overlap_bucket(*overlap) : "none";
  for (size_t i = 0; i < psnrs.size(); ++i) {
    eval::ViewMetrics v;
    v.frame = static_cast<int64_t>(i);
    v.model.psnr = psnrs[i], v.model.ssim = 0.5;
    v.copy_nearest.psnr = psnrs[i] - 5, v.copy_nearest.ssim = 0.25;
    v.mean_colour.psnr = 10, v.mean_colour.ssim = 0.01;
    r.views.push_back(v);
  }
  eval::finalise_scene(r);
  return r;
}

}  // namespace uplvsm::test
