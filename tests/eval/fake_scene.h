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
  for (size_t i = 0; i < psnrs.size(); ++i)
    r.views.push_back({static_cast<int64_t>(i), psnrs[i], 0.5, psnrs[i] - 5, 0.25, 10, 0.01});
  eval::finalise_scene(r);
  return r;
}

}  // namespace uplvsm::test
