#include "uplvsm/eval/comparison_report.h"

#include <fmt/format.h>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "uplvsm/core/json_input.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::eval {

namespace {

namespace fs = std::filesystem;

// Columns side by side on a wide screen, stacked on a narrow one.
const char* kComparisonCss =
    R"(body{font-family:system-ui,sans-serif;max-width:1500px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{font-size:1.3em;margin:.2em 0}h3{font-size:1.05em;margin:1.2em 0 .4em}
.cols{display:grid;grid-template-columns:repeat(auto-fit,minmax(480px,1fr));gap:2em;align-items:start}
table{border-collapse:collapse;margin:.5em 0}th,td{border:1px solid #ccc;padding:.3em .6em;text-align:center}
th{background:#f3f3f3}td:first-child{text-align:left}
img,video{max-width:100%;height:auto;border:1px solid #ddd;image-rendering:pixelated}
figure{margin:.6em 0}figcaption,.caption{font-size:.85em;color:#555}pre{background:#f7f7f7;padding:.8em;
overflow-x:auto;font-size:.85em})";

// Small renders are scaled up by integer factors to about a column's width (CSS max-width then fits them in).
constexpr int64_t kColumnWidth = 600;
constexpr size_t kGridsPerColumn = 3;

std::string videos_html(const ComparedModel& m, const fs::path& sub, const std::string& rel) {
  std::string html;
  for (size_t i = 0; i < m.report.videos.size(); ++i) {
    const auto& v = m.report.videos[i];
    const auto name = fmt::format("video_{}.mp4", i);
    if (!fs::is_regular_file(sub / name)) continue;
    html += "<figure><video src=\"" + html_escape(rel + "/" + name) + "\"" + pixel_width_attr(v.width, kColumnWidth) +
            " controls loop autoplay muted playsinline></video><figcaption>" + html_escape(v.label) +
            "</figcaption></figure>\n";
  }
  return html.empty() ? "" : "<h3>Videos</h3>\n" + html;
}

std::string grids_html(const fs::path& sub, const std::string& rel) {
  std::vector<fs::path> grids;
  if (fs::is_directory(sub / "scenes"))
    for (const auto& e : fs::directory_iterator(sub / "scenes"))
      if (e.path().extension() == ".png") grids.push_back(e.path());
  std::sort(grids.begin(), grids.end());
  if (grids.size() > kGridsPerColumn) grids.resize(kGridsPerColumn);
  std::string html;
  for (const auto& g : grids) {
    const auto src = rel + "/scenes/" + g.filename().string();
    html += "<figure><img src=\"" + html_escape(src) + "\"" + pixel_width_attr(png_width(g.string()), kColumnWidth) +
            " alt=\"" + html_escape(g.stem().string()) + "\"><figcaption>" + html_escape(g.stem().string()) +
            "</figcaption></figure>\n";
  }
  if (html.empty()) return "";
  return "<h3>Held-out scenes</h3>\n<p class=\"caption\">Rows: target views. Columns: the two input views, "
         "prediction, ground truth, |error|, copy-nearest baseline.</p>\n" +
         html;
}

std::string column_html(const ComparedModel& m, const fs::path& sub, const std::string& rel) {
  std::string html = "<section>\n<h2>" + html_escape(m.label) + "</h2>\n";
  if (!m.caption.empty()) html += "<p class=\"caption\">" + html_escape(m.caption) + "</p>\n";
  html += "<p><a href=\"" + html_escape(rel) + "/index.html\">full report</a></p>\n";
  if (fs::is_regular_file(sub / "metrics.json"))
    html += results_table_html(read_json_file((sub / "metrics.json").string()), /*full_only=*/true);
  html += videos_html(m, sub, rel);
  html += grids_html(sub, rel);
  if (fs::is_regular_file(sub / "training_curve.png"))
    html += "<h3>Training</h3>\n<img src=\"" + html_escape(rel) + "/training_curve.png\" alt=\"training curve\">\n";
  return html + "</section>\n";
}

}  // namespace

std::string write_comparison_report(const std::string& out_dir, const std::string& title,
                                    const std::vector<ComparedModel>& models, const std::string& runtime_info) {
  const fs::path out(out_dir);
  fs::create_directories(out);
  std::string columns;
  for (size_t i = 0; i < models.size(); ++i) {
    const auto rel = fmt::format("model_{}", i);
    auto inputs = models[i].report;
    if (inputs.title.empty()) inputs.title = models[i].label;
    write_report((out / rel).string(), inputs);
    columns += column_html(models[i], out / rel, rel);
  }
  std::string body = "<h1>" + html_escape(title) + "</h1>\n<div class=\"cols\">\n" + columns + "</div>\n";
  if (!runtime_info.empty()) body += "<h3>Runtime</h3>\n<pre>" + html_escape(runtime_info) + "</pre>\n";
  const std::string html = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" +
                           html_escape(title) + "</title>\n<style>\n" + kComparisonCss +
                           "\n</style>\n</head>\n<body>\n" + body + "</body>\n</html>\n";
  const auto path = (out / "index.html").string();
  io::write_file_atomic(path, html.data(), html.size());
  return path;
}

}  // namespace uplvsm::eval
