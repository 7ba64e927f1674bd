#include "uplvsm/study/camera_paths_summary.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/study/csv_fields.h"

namespace uplvsm::study {

namespace fs = std::filesystem;

CameraPathsRun parse_camera_paths_run(const std::string& arg) {
  const auto eq = arg.find('=');
  if (eq != std::string::npos) return {arg.substr(0, eq), arg.substr(eq + 1)};
  return {fs::path(arg).lexically_normal().filename().string(), arg};
}

namespace {

double path_field_or_nan(const std::string& field) { return field.empty() ? std::nan("") : csv_number(field); }

// Each line of `path` past its header, split; the header must be `header`.
template <typename Row>
std::vector<Row> read_rows(const std::string& path, const std::string& header, size_t fields,
                           Row (*parse)(const std::vector<std::string>&)) {
  std::ifstream in(path);
  std::string line;
  if (!in || !std::getline(in, line) || line != header)
    throw std::runtime_error(path + ": not a camera-paths file (expected the header '" + header + "')");
  std::vector<Row> rows;
  for (int n = 2; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    const auto f = csv_fields(line);
    try {
      if (f.size() != fields) throw std::invalid_argument(fmt::format("{} fields, expected {}", f.size(), fields));
      rows.push_back(parse(f));
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(fmt::format("{}:{}: {}", path, n, e.what()));
    }
  }
  return rows;
}

PathSceneScore parse_scene_row(const std::vector<std::string>& f) {
  return {f[0],
          f[1],
          csv_number(f[2]),
          path_field_or_nan(f[3]),
          path_field_or_nan(f[4]),
          path_field_or_nan(f[5]),
          path_field_or_nan(f[6]),
          csv_number(f[7])};
}

PathFrameScore parse_frame_row(const std::vector<std::string>& f) {
  return {f[0],
          f[1],
          static_cast<int64_t>(csv_number(f[2])),
          csv_number(f[3]),
          f[4] == "1",
          csv_number(f[5]),
          csv_number(f[6])};
}

}  // namespace

std::vector<PathSceneScore> read_camera_paths_scenes(const std::string& path) {
  return read_rows(path, "scene,method,psnr,psnr_inside,psnr_beyond,ssim_inside,ssim_beyond,wobble", 8,
                   parse_scene_row);
}

std::vector<PathFrameScore> read_camera_paths_frames(const std::string& path) {
  return read_rows(path, "scene,method,frame,position,inside,psnr,ssim", 7, parse_frame_row);
}

std::string summary_method_name(const std::string& label, const std::string& method) {
  return method == "camera control" ? label : label + " (" + method + ")";
}

namespace {

double metric_of(const PathSceneScore& s, const std::string& metric) {
  if (metric == "wobble") return s.wobble;
  if (metric == "psnr_inside") return s.psnr_inside;
  if (metric == "psnr_beyond") return s.psnr_beyond;
  return s.psnr;
}

using SceneTable = std::map<std::string, std::map<std::string, PathSceneScore>>;  // method -> scene -> scores

// Methods a (and b, when not empty) as scored runs over the scenes where each has a finite `metric`, in one order.
std::vector<ScoredRun> paired_runs(const SceneTable& table, const std::string& metric, const std::string& a,
                                   const std::string& b) {
  std::vector<ScoredRun> runs;
  for (const auto& m : {a, b})
    if (!m.empty()) runs.push_back({m, 0, 0, 0, {}});
  for (const auto& [scene, scores] : table.at(a)) {
    const double va = metric_of(scores, metric);
    const double vb = b.empty() ? 0.0 : metric_of(table.at(b).at(scene), metric);
    if (!std::isfinite(va) || !std::isfinite(vb)) continue;
    runs[0].scenes.push_back(va);
    if (!b.empty()) runs[1].scenes.push_back(vb);
  }
  for (auto& r : runs) {
    double sum = 0;
    for (double v : r.scenes) sum += v;
    r.value = r.scenes.empty() ? std::nan("") : sum / r.scenes.size();
  }
  return runs;
}

std::vector<PathMetricStat> interval_stats(const SceneTable& table, const std::vector<std::string>& methods,
                                           const BootstrapOptions& options) {
  std::vector<PathMetricStat> out;
  for (const std::string metric : {"wobble", "psnr_inside", "psnr_beyond"}) {
    for (const auto& m : methods)
      out.push_back({metric, m, "", bootstrap_interval(paired_runs(table, metric, m, ""), mean_value, options)});
    for (size_t i = 0; i < methods.size(); ++i)
      for (size_t j = i + 1; j < methods.size(); ++j) {
        const auto difference = [a = methods[i], b = methods[j]](const std::vector<ScoredRun>& r) {
          return mean_value(runs_of(r, a)) - mean_value(runs_of(r, b));
        };
        out.push_back({metric, methods[i], methods[j],
                       bootstrap_interval(paired_runs(table, metric, methods[i], methods[j]), difference, options)});
      }
  }
  return out;
}

// Mean PSNR of each method's frames per bin of their baseline position (bins centred on multiples of bin_width).
std::vector<io::Series> psnr_by_position(const std::vector<std::pair<std::string, std::vector<PathFrameScore>>>& frames,
                                         const std::set<std::string>& scenes, double bin_width) {
  std::vector<io::Series> out;
  for (const auto& [method, rows] : frames) {
    std::map<int64_t, std::pair<double, int64_t>> bins;
    for (const auto& f : rows) {
      if (!scenes.count(f.scene)) continue;
      auto& [sum, n] = bins[std::llround(f.position / bin_width)];
      sum += f.psnr;
      ++n;
    }
    io::Series s;
    s.name = method;
    for (const auto& [bin, acc] : bins) {
      s.x.push_back(bin * bin_width);
      s.y.push_back(acc.first / acc.second);
    }
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace

CameraPathsSummary summarise_camera_paths(const std::vector<CameraPathsRun>& runs, double bin_width,
                                          const BootstrapOptions& options) {
  if (runs.empty()) throw std::invalid_argument("camera-paths-summary: no run given");
  CameraPathsSummary summary;
  SceneTable table;
  std::vector<std::pair<std::string, std::vector<PathFrameScore>>> frames;
  for (const auto& run : runs) {
    const auto dir = fs::path(run.dir);
    std::map<std::string, std::vector<PathFrameScore>> by_method;
    for (auto& f : read_camera_paths_frames((dir / "camera_paths.csv").string())) by_method[f.method].push_back(f);
    for (const auto& s : read_camera_paths_scenes((dir / "camera_paths_scenes.csv").string())) {
      const auto name = summary_method_name(run.label, s.method);
      if (!table.count(name)) {
        if (by_method.count(s.method) == 0)
          throw std::runtime_error(run.dir + ": method '" + s.method + "' has no frames");
        summary.methods.push_back(name);
        frames.emplace_back(name, by_method[s.method]);
      }
      if (!table[name].emplace(s.scene, s).second)
        throw std::runtime_error(
            fmt::format("{}: two methods are named '{}' (give the runs other labels)", run.dir, name));
    }
  }
  // Paired: only the scenes every method scored.
  std::set<std::string> common;
  for (const auto& [scene, s] : table.at(summary.methods.front())) common.insert(scene);
  for (auto& [method, scenes] : table) {
    for (auto it = common.begin(); it != common.end();) it = scenes.count(*it) ? std::next(it) : common.erase(it);
  }
  if (common.empty()) throw std::runtime_error("camera-paths-summary: the runs share no scene");
  for (auto& [method, scenes] : table)
    for (auto it = scenes.begin(); it != scenes.end();) it = common.count(it->first) ? std::next(it) : scenes.erase(it);
  summary.stats = interval_stats(table, summary.methods, options);
  summary.psnr_position = psnr_by_position(frames, common, bin_width);
  return summary;
}

void write_camera_paths_summary(const CameraPathsSummary& summary, const std::string& out_dir) {
  const fs::path out(out_dir);
  fs::create_directories(out);
  auto number = [](double v) { return std::isfinite(v) ? fmt::format("{:.4f}", v) : std::string(); };
  // A label may hold a comma ("MLP, noisy"): quoted as csv_fields() reads it back.
  auto field = [](const std::string& v) {
    if (v.find_first_of(",\"") == std::string::npos) return v;
    std::string q = "\"";
    for (char c : v) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  std::ostringstream csv;
  csv << "metric,a,b,estimate,lo,hi,scenes\n";
  nlohmann::json stats = nlohmann::json::array();
  for (const auto& s : summary.stats) {
    const auto& i = s.interval;
    csv << fmt::format("{},{},{},{},{},{},{}\n", s.metric, field(s.a), field(s.b), number(i.estimate), number(i.lo),
                       number(i.hi), i.scenes);
    auto json_number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
    stats.push_back({{"metric", s.metric},
                     {"a", s.a},
                     {"b", s.b},
                     {"estimate", json_number(i.estimate)},
                     {"lo", json_number(i.lo)},
                     {"hi", json_number(i.hi)},
                     {"scenes", i.scenes}});
  }
  const auto text = csv.str();
  io::write_file_atomic((out / "differences.csv").string(), text.data(), text.size());
  const auto json = nlohmann::json{{"methods", summary.methods},
                                   {"interval", "95 % percentile bootstrap over the scenes, paired"},
                                   {"stats", stats}}
                        .dump(2) +
                    "\n";
  io::write_file_atomic((out / "summary.json").string(), json.data(), json.size());
  io::PlotOptions po;
  po.title = "PSNR along the camera path";
  po.xlabel = "position along the inputs' baseline (0: input 0, 1: input 1; shaded: between them)";
  po.ylabel = "PSNR (dB)";
  po.width = 900;
  po.height = 520;
  po.x_bands = {{0.0, 1.0}};
  auto lines = summary.psnr_position;
  for (auto& s : lines) s.markers = true;
  io::write_png((out / "psnr_position.png").string(), io::plot_lines(lines, po));
}

}  // namespace uplvsm::study
