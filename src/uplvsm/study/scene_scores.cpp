#include "uplvsm/study/scene_scores.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/study/csv_fields.h"

namespace uplvsm::study {

namespace {

double number_or_nan(const std::string& field) { return field.empty() ? std::nan("") : csv_number(field); }

std::string number_or_empty(double v, int digits) {
  return std::isnan(v) ? std::string() : fmt::format("{:.{}f}", v, digits);
}

std::string quoted_if_needed(const std::string& s) {
  if (s.find_first_of(",\"") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

size_t column(const std::vector<std::string>& header, const std::string& name, const std::string& path) {
  const auto it = std::find(header.begin(), header.end(), name);
  if (it == header.end()) throw std::runtime_error(fmt::format("{}: line 1 has no '{}' column", path, name));
  return static_cast<size_t>(it - header.begin());
}

}  // namespace

const std::vector<double>& SceneScores::metric(const std::string& name) const {
  if (name == "psnr") return psnr;
  if (name == "ssim") return ssim;
  if (name == "lpips") return lpips;
  throw std::invalid_argument("scene scores: unknown metric '" + name + "' (expected psnr, ssim or lpips)");
}

SceneScores read_eval_per_scene(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  if (!in || !std::getline(in, line)) throw std::runtime_error(path + ": cannot read the evaluator's per-scene file");
  const auto header = csv_fields(line);
  const size_t key = column(header, "key", path), psnr = column(header, "psnr", path),
               ssim = column(header, "ssim", path), lpips = column(header, "lpips", path);
  SceneScores s;
  for (int n = 2; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    const auto f = csv_fields(line);
    try {
      if (f.size() != header.size()) throw std::invalid_argument("fields");
      s.psnr.push_back(csv_number(f[psnr]));
      s.ssim.push_back(csv_number(f[ssim]));
      s.lpips.push_back(number_or_nan(f[lpips]));
      s.keys.push_back(f[key]);
    } catch (const std::exception&) {
      throw std::runtime_error(
          fmt::format("{} line {}: expected {} fields with numbers, got '{}'", path, n, header.size(), line));
    }
  }
  return s;
}

std::string study_scenes_csv(const std::vector<RunScenes>& runs) {
  std::string out = "series,setting,seed,scene,psnr,ssim,lpips\n";
  for (const auto& r : runs)
    for (size_t i = 0; i < r.scores.keys.size(); ++i)
      out +=
          fmt::format("{},{},{},{},{:.6f},{:.6f},{}\n", r.series, r.setting, r.seed, quoted_if_needed(r.scores.keys[i]),
                      r.scores.psnr[i], r.scores.ssim[i], number_or_empty(r.scores.lpips[i], 6));
  return out;
}

std::vector<RunScenes> read_study_scenes(const std::string& path) {
  const std::string header = "series,setting,seed,scene,psnr,ssim,lpips";
  std::ifstream in(path);
  std::string line;
  if (!in || !std::getline(in, line) || line != header)
    throw std::runtime_error(fmt::format("{}: line 1 must be '{}'", path, header));
  std::vector<RunScenes> runs;
  for (int n = 2; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    const auto f = csv_fields(line);
    try {
      if (f.size() != 7) throw std::invalid_argument("fields");
      const double seed = csv_number(f[2]);
      if (seed < 0 || seed != std::floor(seed)) throw std::invalid_argument(f[2]);
      const auto s = static_cast<int64_t>(seed);
      if (runs.empty() || runs.back().series != f[0] || runs.back().setting != f[1] || runs.back().seed != s)
        runs.push_back({f[0], f[1], s, {}});
      auto& scores = runs.back().scores;
      scores.psnr.push_back(csv_number(f[4]));
      scores.ssim.push_back(csv_number(f[5]));
      scores.lpips.push_back(number_or_nan(f[6]));
      scores.keys.push_back(f[3]);
    } catch (const std::exception&) {
      throw std::runtime_error(fmt::format("{} line {}: expected {}, got '{}'", path, n, header, line));
    }
  }
  return runs;
}

}  // namespace uplvsm::study
