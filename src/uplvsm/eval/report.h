// A self-contained HTML report of a run: the headline results table laid out like the paper's (PSNR / SSIM per
// overlap bucket and full), the training curve, the rendered video, scene grids, the config and runtime info.
// Assets are copied next to index.html and linked relatively, so the folder can be moved or served as is.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace uplvsm::eval {

// One rendered video of a report (an MP4 and/or a GIF of the same frames).
struct VideoAsset {
  std::string label;     // e.g. "latent interpolation", "orbit (camera mapper)"
  std::string mp4, gif;  // may be empty
  int64_t width = 0;     // frame width in pixels (0: unknown), to upscale small videos without blurring
};

struct ReportInputs {
  std::string title;
  nlohmann::json config;        // shown pretty-printed and saved as config.json (null: omitted)
  std::string metrics_json;     // evaluate()'s metrics.json; its per_scene.csv / per_view.csv come along
  std::string train_log_jsonl;  // lines {"step":..,"loss":..,"psnr":..,"lr":..}; may be empty
  std::vector<std::string> scene_grids;
  std::vector<VideoAsset> videos;
  std::string runtime_info;
  double train_seconds = 0;
};

// Writes out_dir/index.html (creating out_dir), copying the assets under it (scenes/, video_N.mp4, video_N.gif,
// metrics.json, ...) and rendering training_curve.png from the log. Empty paths are omitted; paths that do not
// exist are logged, omitted and listed on the page, so a failed video never costs the rest of the report. Throws
// std::runtime_error naming the file for a metrics.json that is not valid JSON or has no "table" object.
// Returns the path of index.html.
std::string write_report(const std::string& out_dir, const ReportInputs& in);

// One line of the training log; missing numbers are NaN.
struct TrainPoint {
  double step = 0, loss = 0, psnr = 0, lr = 0;
  double eval_psnr = std::numeric_limits<double>::quiet_NaN();  // periodic held-out evaluation lines ({"eval": ..})
};
// Reads a JSONL training log; lines that are blank, not JSON (e.g. cut off by a crash) or without "step" are
// skipped (a warning counts them). Throws when the file cannot be read.
std::vector<TrainPoint> read_train_log(const std::string& path);
// Loss (log scale when all positive) above PSNR (training, and held-out when logged), vs step: uint8 [H, W, 3].
torch::Tensor training_curve(const std::vector<TrainPoint>& points);

// The headline table of a metrics.json object as an HTML <table>: rows the model (named by its "variant": UP-LVSM
// (ours), LVSM or PT-LVSM), copy nearest input, mean colour; columns PSNR / SSIM, grouped under Large / Medium /
// Small / Full when buckets exist. Best value in bold.
// full_only: just the whole test set's columns (for narrow, side-by-side layouts).
std::string results_table_html(const nlohmann::json& metrics, bool full_only = false);

std::string html_escape(const std::string& text);

// ` width="k w"` for an image/video `native_width` px wide, k the largest integer with k w <= target (at least 1),
// so small renders are shown large and (with CSS image-rendering: pixelated) never blurred; "" for an unknown width.
std::string pixel_width_attr(int64_t native_width, int64_t target_width);
// Width of a PNG/JPEG file from its header; 0 when it cannot be read.
int64_t png_width(const std::string& path);

}  // namespace uplvsm::eval
