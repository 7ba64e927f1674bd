#include "uplvsm/eval/report.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <stdexcept>

#include "uplvsm/core/json_input.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/image.h"
#include "uplvsm/io/plot.h"

namespace uplvsm::eval {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const std::vector<std::pair<std::string, std::string>> kRows = {
    {"model", "UP-LVSM (ours)"}, {"copy_nearest", "Copy nearest input"}, {"mean_colour", "Mean colour (oracle)"}};

// The model row's name: the evaluated variant (metrics.json "variant"), so a posed baseline is not called UP-LVSM.
std::string model_row_name(const nlohmann::json& m) {
  const auto variant = m.contains("variant") && m["variant"].is_string() ? m["variant"].get<std::string>() : "";
  if (variant == "lvsm") return "LVSM, cameras known";
  if (variant == "ptlvsm") return "PT-LVSM, target camera known";
  return "UP-LVSM (ours)";
}
const std::vector<std::pair<std::string, std::string>> kBuckets = {
    {"large", "Large"}, {"medium", "Medium"}, {"small", "Small"}};

const char* kCss = R"(body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{font-size:1.25em;border-bottom:1px solid #ddd;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0}th,td{border:1px solid #ccc;padding:.3em .7em;text-align:center}
th{background:#f3f3f3}td:first-child{text-align:left}img,video{max-width:100%;height:auto;border:1px solid #ddd;
image-rendering:pixelated}
pre{background:#f7f7f7;padding:.8em;overflow-x:auto;font-size:.85em}figure{margin:1em 0}
figcaption{font-size:.85em;color:#555}.note{color:#a00}.caption{font-size:.9em;color:#555})";

// Copies src to out_dir/rel; returns rel, or nothing when src is empty or missing (missing is noted).
std::optional<std::string> copy_asset(const std::string& src, const fs::path& out_dir, const std::string& rel,
                                      std::vector<std::string>& missing) {
  if (src.empty()) return std::nullopt;
  if (!fs::is_regular_file(src)) {
    spdlog::warn("report: {} does not exist; left out", src);
    missing.push_back(src);
    return std::nullopt;
  }
  const fs::path dst = out_dir / rel;
  fs::create_directories(dst.parent_path());
  std::error_code ec;
  if (!fs::exists(dst) || !fs::equivalent(src, dst, ec)) fs::copy_file(src, dst, fs::copy_options::overwrite_existing);
  return rel;
}

nlohmann::json read_metrics(const std::string& path) {
  auto j = read_json_file(path);
  if (!j.is_object() || !j.contains("table") || !j["table"].is_object())
    throw std::runtime_error(path + ": no \"table\" object (expected evaluate()'s metrics.json)");
  return j;
}

double number_or_nan(const nlohmann::json& j, const std::string& key) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : kNaN;
}

double cell(const nlohmann::json& table, const std::string& row, const std::string& metric) {
  if (!table.is_object() || !table.contains(row) || !table[row].is_object()) return kNaN;
  return number_or_nan(table[row], metric);
}

std::string format_cell(double value, bool best, int decimals) {
  if (!std::isfinite(value)) return "<td>&ndash;</td>";
  auto text = fmt::format("{:.{}f}", value, decimals);
  return best ? "<td><b>" + text + "</b></td>" : "<td>" + text + "</td>";
}

// One column group (a bucket or the full set): the table object and its header text.
struct Group {
  nlohmann::json table;
  std::string header;
};

std::vector<Group> table_groups(const nlohmann::json& m) {
  std::vector<Group> groups;
  const auto& buckets = m.contains("buckets") && m["buckets"].is_object() ? m["buckets"] : nlohmann::json::object();
  const auto& counts = m.contains("bucket_scenes") ? m["bucket_scenes"] : nlohmann::json::object();
  bool any = false;
  for (const auto& [key, name] : kBuckets) any = any || buckets.contains(key);
  if (any) {
    for (const auto& [key, name] : kBuckets) {
      const auto n = counts.contains(key) && counts[key].is_number() ? counts[key].get<int64_t>() : 0;
      groups.push_back({buckets.contains(key) ? buckets[key] : nlohmann::json::object(),
                        fmt::format("{} overlap ({} scenes)", name, n)});
    }
  }
  const auto total = m.contains("scenes") && m["scenes"].is_number() ? m["scenes"].get<int64_t>() : 0;
  groups.push_back({m.contains("table") ? m["table"] : nlohmann::json::object(),
                    fmt::format("{} ({} scenes)", any ? "Full" : "Test set", total)});
  // Interpolation / extrapolation columns only when some targets lie outside their inputs' frame span.
  const auto& spans = m.contains("spans") && m["spans"].is_object() ? m["spans"] : nlohmann::json::object();
  const auto& span_counts = m.contains("span_scenes") ? m["span_scenes"] : nlohmann::json::object();
  if (spans.contains("extrapolation")) {
    for (const auto& [key, name] : std::vector<std::pair<std::string, std::string>>{
             {"interpolation", "Interpolation"}, {"extrapolation", "Extrapolation"}}) {
      const auto n = span_counts.contains(key) && span_counts[key].is_number() ? span_counts[key].get<int64_t>() : 0;
      groups.push_back(
          {spans.contains(key) ? spans[key] : nlohmann::json::object(), fmt::format("{} ({} scenes)", name, n)});
    }
  }
  return groups;
}

std::string section(const std::string& title, const std::string& body) {
  return "<h2>" + html_escape(title) + "</h2>\n" + body + "\n";
}

// The training curve section; empty when there is no log or no point in it.
std::string curve_section(const ReportInputs& in, const fs::path& out, std::vector<std::string>& missing) {
  if (in.train_log_jsonl.empty()) return "";
  if (!fs::is_regular_file(in.train_log_jsonl)) {
    spdlog::warn("report: {} does not exist; no training curve", in.train_log_jsonl);
    missing.push_back(in.train_log_jsonl);
    return "";
  }
  copy_asset(in.train_log_jsonl, out, "train_log.jsonl", missing);
  const auto points = read_train_log(in.train_log_jsonl);
  if (points.empty()) return section("Training", "<p>The training log has no entries.</p>");
  io::write_png((out / "training_curve.png").string(), training_curve(points));
  const auto& last = points.back();
  auto caption = fmt::format("{} log entries, last step {:.0f}: loss {:.4g}, PSNR {:.2f} dB", points.size(), last.step,
                             last.loss, last.psnr);
  return section("Training", "<img src=\"training_curve.png\" alt=\"training curve\">\n<p class=\"caption\">" +
                                 html_escape(caption) + " (<a href=\"train_log.jsonl\">log</a>)</p>");
}

std::string metrics_section(const ReportInputs& in, const fs::path& out, std::vector<std::string>& missing) {
  if (in.metrics_json.empty()) return "";
  if (!fs::is_regular_file(in.metrics_json)) {
    spdlog::warn("report: {} does not exist; no results table", in.metrics_json);
    missing.push_back(in.metrics_json);
    return "";
  }
  const auto m = read_metrics(in.metrics_json);
  copy_asset(in.metrics_json, out, "metrics.json", missing);
  std::string links = "<a href=\"metrics.json\">metrics.json</a>";
  const auto dir = fs::path(in.metrics_json).parent_path();
  for (const char* csv : {"per_scene.csv", "per_view.csv"}) {
    if (!fs::is_regular_file(dir / csv)) continue;
    copy_asset((dir / csv).string(), out, csv, missing);
    links += fmt::format(", <a href=\"{0}\">{0}</a>", csv);
  }
  std::string caption =
      "PSNR (dB, higher is better), SSIM and LPIPS (lower is better) per target view, averaged "
      "per scene then over scenes. Copy nearest input: each target predicted by the input view nearest in frame "
      "index. Mean colour: each target predicted by its own mean colour (an oracle constant).";
  const auto& counts = m.contains("bucket_scenes") ? m["bucket_scenes"] : nlohmann::json::object();
  if (counts.contains("ignore") && counts["ignore"].is_number())
    caption += fmt::format(" Overlap buckets follow NoPoSplat; {} scenes with overlap above 0.8 count in Full only.",
                           counts["ignore"].get<int64_t>());
  if (m.contains("seconds") && m["seconds"].is_number())
    caption += fmt::format(" Evaluation time {}.", format_duration(m["seconds"].get<double>()));
  return section("Results",
                 results_table_html(m) + "<p class=\"caption\">" + html_escape(caption) + "</p>\n<p>" + links + "</p>");
}

std::string video_section(const ReportInputs& in, const fs::path& out, std::vector<std::string>& missing) {
  std::string body;
  for (size_t i = 0; i < in.videos.size(); ++i) {
    const auto& v = in.videos[i];
    std::string media;
    if (auto mp4 = copy_asset(v.mp4, out, fmt::format("video_{}.mp4", i), missing))
      media += "<video src=\"" + *mp4 + "\"" + pixel_width_attr(v.width, 576) +
               " controls loop autoplay muted playsinline></video>\n";
    if (auto gif = copy_asset(v.gif, out, fmt::format("video_{}.gif", i), missing))
      media += "<p><img src=\"" + *gif + "\"" + pixel_width_attr(v.width, 576) + " alt=\"rendered video (GIF)\"></p>\n";
    if (media.empty()) continue;
    body += "<figure>" + media + (v.label.empty() ? "" : "<figcaption>" + html_escape(v.label) + "</figcaption>") +
            "</figure>\n";
  }
  return body.empty() ? "" : section("Video", body);
}

std::string grids_section(const ReportInputs& in, const fs::path& out, std::vector<std::string>& missing) {
  std::string body;
  std::vector<std::string> used;
  for (size_t i = 0; i < in.scene_grids.size(); ++i) {
    std::string name = fs::path(in.scene_grids[i]).filename().string();
    if (std::find(used.begin(), used.end(), name) != used.end()) name = fmt::format("{}_{}", i, name);
    auto rel = copy_asset(in.scene_grids[i], out, "scenes/" + name, missing);
    if (!rel) continue;
    used.push_back(name);
    body += "<figure><img src=\"" + html_escape(*rel) + "\"" + pixel_width_attr(png_width(in.scene_grids[i]), 960) +
            " alt=\"" + html_escape(name) + "\"><figcaption>" + html_escape(fs::path(name).stem().string()) +
            "</figcaption></figure>\n";
  }
  if (body.empty()) return "";
  return section("Scenes",
                 "<p class=\"caption\">Rows: target views. Columns: input views, prediction, ground "
                 "truth, |error| heat map, copy-nearest baseline.</p>\n" +
                     body);
}

std::string info_section(const ReportInputs& in, const fs::path& out) {
  std::string body;
  if (in.train_seconds > 0) body += "<p>Training time: " + format_duration(in.train_seconds) + "</p>\n";
  if (!in.runtime_info.empty()) body += "<h3>Runtime</h3>\n<pre>" + html_escape(in.runtime_info) + "</pre>\n";
  if (!in.config.is_null()) {
    const auto text = in.config.dump(2);
    io::write_file_atomic((out / "config.json").string(), text.data(), text.size());
    body += "<h3>Configuration (<a href=\"config.json\">config.json</a>)</h3>\n<pre>" + html_escape(text) + "</pre>\n";
  }
  return body.empty() ? "" : section("Run", body);
}

}  // namespace

std::string pixel_width_attr(int64_t native_width, int64_t target_width) {
  if (native_width <= 0) return "";
  return fmt::format(" width=\"{}\"", native_width * std::max<int64_t>(1, target_width / native_width));
}

int64_t png_width(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return 0;
  try {
    const auto bytes = io::read_file(path);
    return io::image_size(bytes.data(), bytes.size(), path).second;
  } catch (const std::exception&) {
    return 0;  // not an image we can size: shown at its own size
  }
}

std::string html_escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char ch : text) {
    switch (ch) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += ch;
    }
  }
  return out;
}

// Whether any group's table has `metric` in some row (older metrics.json files lack the gradient-energy ratio).
bool has_metric(const std::vector<Group>& groups, const std::string& metric) {
  for (const auto& g : groups)
    for (const auto& [row, name] : kRows)
      if (std::isfinite(cell(g.table, row, metric))) return true;
  return false;
}

std::string results_table_html(const nlohmann::json& m, bool full_only) {
  struct Metric {
    std::string key, header;
    int decimals;
    double (*score)(double);  // the best cell of a column has the highest score
  };
  auto higher = [](double v) { return v; };
  auto lower = [](double v) { return -v; };
  auto nearest_one = [](double v) { return -std::abs(v - 1.0); };  // as much edge as the truth, no more
  std::vector<Metric> metrics = {{"psnr", "PSNR&uarr;", 2, higher}, {"ssim", "SSIM&uarr;", 3, higher}};
  const bool has_lpips = m.contains("lpips") && m["lpips"].is_object() && m["lpips"].value("available", false);
  if (has_lpips) metrics.push_back({"lpips", "LPIPS&darr;", 3, lower});
  auto groups = table_groups(m);
  if (full_only)  // the whole set alone: no overlap buckets or interpolation/extrapolation spans
    groups = table_groups({{"table", m.value("table", nlohmann::json::object())}, {"scenes", m.value("scenes", 0)}});
  if (has_metric(groups, "grad_ratio")) metrics.push_back({"grad_ratio", "Edges&rarr;1", 2, nearest_one});
  std::string head1 = "<tr><th rowspan=\"2\">Method</th>", head2 = "<tr>";
  for (const auto& g : groups) {
    head1 += fmt::format("<th colspan=\"{}\">{}</th>", metrics.size(), html_escape(g.header));
    for (const auto& metric : metrics) head2 += "<th>" + metric.header + "</th>";
  }
  std::string html = "<table>\n" + head1 + "</tr>\n" + head2 + "</tr>\n";
  for (const auto& [row, name] : kRows) {
    html += "<tr><td>" + html_escape(row == "model" ? model_row_name(m) : name) + "</td>";
    for (const auto& g : groups) {
      for (const auto& metric : metrics) {
        double best = -std::numeric_limits<double>::infinity();
        for (const auto& [r, n] : kRows) {
          const double v = cell(g.table, r, metric.key);
          if (std::isfinite(v)) best = std::max(best, metric.score(v));
        }
        const double v = cell(g.table, row, metric.key);
        html += format_cell(v, std::isfinite(v) && metric.score(v) == best, metric.decimals);
      }
    }
    html += "</tr>\n";
  }
  html += "</table>\n";
  if (!has_lpips)
    html +=
        "<p class=\"caption\">LPIPS unavailable: the evaluation was run without LPIPS weights "
        "(<code>uplvsm eval --lpips-backbone ... --lpips-lin ...</code>).</p>\n";
  if (has_metric(groups, "grad_ratio"))
    html +=
        "<p class=\"caption\">Edges: the gradient-energy ratio mean|&nabla;prediction| / mean|&nabla;truth| "
        "(1: as much edge as the truth, 0: flat; a blur scores in between; docs/model.md).</p>\n";
  return html;
}

std::vector<TrainPoint> read_train_log(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw std::runtime_error(path + ": cannot open the training log");
  std::vector<TrainPoint> points;
  std::string line;
  int64_t bad = 0;
  while (std::getline(file, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    auto j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (!j.is_object() || !j.contains("step") || !j["step"].is_number()) {
      ++bad;
      continue;
    }
    if (j.contains("eval")) {
      points.push_back({j["step"].get<double>(), kNaN, kNaN, kNaN, number_or_nan(j["eval"], "psnr")});
      continue;
    }
    points.push_back(
        {j["step"].get<double>(), number_or_nan(j, "loss"), number_or_nan(j, "psnr"), number_or_nan(j, "lr")});
  }
  if (bad > 0) spdlog::warn("report: {}: skipped {} lines that are not log entries", path, bad);
  return points;
}

torch::Tensor training_curve(const std::vector<TrainPoint>& points) {
  io::Series loss{"loss", {}, {}}, psnr{"PSNR", {}, {}}, held_out{"held-out PSNR", {}, {}};
  bool positive = true;
  for (const auto& p : points) {
    if (std::isfinite(p.eval_psnr)) {
      held_out.x.push_back(p.step);
      held_out.y.push_back(p.eval_psnr);
      continue;
    }
    loss.x.push_back(p.step);
    loss.y.push_back(p.loss);
    psnr.x.push_back(p.step);
    psnr.y.push_back(p.psnr);
    if (std::isfinite(p.loss) && p.loss <= 0) positive = false;
  }
  io::PlotOptions top, bottom;
  top.title = "Training loss", top.xlabel = "step", top.ylabel = "loss", top.log_y = positive, top.height = 360;
  bottom.title = "Training PSNR", bottom.xlabel = "step", bottom.ylabel = "PSNR (dB)", bottom.height = 360;
  return torch::cat(
             {io::plot_lines({loss}, top), io::plot_lines(held_out.x.empty() ? std::vector<io::Series>{psnr}
                                                                             : std::vector<io::Series>{psnr, held_out},
                                                          bottom)},
             0)
      .contiguous();
}

std::string write_report(const std::string& out_dir, const ReportInputs& in) {
  const fs::path out(out_dir);
  fs::create_directories(out);
  std::vector<std::string> missing;
  std::string body = "<h1>" + html_escape(in.title.empty() ? "UP-LVSM report" : in.title) + "</h1>\n";
  body += metrics_section(in, out, missing);
  body += curve_section(in, out, missing);
  body += video_section(in, out, missing);
  body += grids_section(in, out, missing);
  body += info_section(in, out);
  if (!missing.empty()) {
    std::string list;
    for (const auto& m : missing) list += "<li>" + html_escape(m) + "</li>";
    body += section("Missing assets", "<ul class=\"note\">" + list + "</ul>");
  }
  const std::string html = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" +
                           html_escape(in.title) + "</title>\n<style>\n" + kCss + "\n</style>\n</head>\n<body>\n" +
                           body + "</body>\n</html>\n";
  const auto path = (out / "index.html").string();
  io::write_file_atomic(path, html.data(), html.size());
  return path;
}

}  // namespace uplvsm::eval
