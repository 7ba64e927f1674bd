// The per-frame part of ViewerServer: frames (the decoder only, from the session's cached scene latents), videos
// of a recorded camera path, and the camera-path presets.
#include <httplib.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <fmt/format.h>

#include "uplvsm/io/image.h"
#include "uplvsm/io/video.h"
#include "uplvsm/render/trajectory.h"
#include "uplvsm/serve/http_error.h"
#include "uplvsm/serve/http_reply.h"
#include "uplvsm/serve/json_request.h"
#include "uplvsm/serve/viewer_server.h"

namespace uplvsm::serve {

namespace {

PoseSpace space_of(const nlohmann::json& body, const ViewerModel& model) {
  const std::string fallback = model.has_mapper() ? "real" : "latent";
  auto space = parse_pose_space(read_choice(body, "space", fallback, {"latent", "real"}));
  if (space == PoseSpace::Real && !model.has_mapper())
    throw HttpError(400, "space \"real\" needs a camera mapper, which this checkpoint lacks: use \"latent\"");
  return space;
}

// A video file's bytes, encoded through a temporary file (the MP4 muxer writes to a path).
std::string mp4_bytes(const std::vector<torch::Tensor>& frames, double fps) {
  auto path = std::filesystem::temp_directory_path() / ("uplvsm_serve_" + random_id() + ".mp4");
  io::write_mp4(path.string(), frames, fps);
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::filesystem::remove(path);
  return bytes;
}

}  // namespace

void ViewerServer::frame_routes() {
  using namespace std::placeholders;
  http_->Post(R"(/api/sessions/([^/]+)/frame)", guarded(std::bind(&ViewerServer::frame, this, _1, _2)));
  http_->Post(R"(/api/sessions/([^/]+)/video)", guarded(std::bind(&ViewerServer::video, this, _1, _2)));
  http_->Get(R"(/api/presets/([^/]+))", guarded(std::bind(&ViewerServer::preset, this, _1, _2)));
}

void ViewerServer::frame(const httplib::Request& req, httplib::Response& res) {
  auto session = session_of(req.matches[1]);
  auto body = parse_json_body(req.body);
  if (!body.contains("pose")) throw HttpError(400, "pose: missing (7 numbers tx ty tz qx qy qz qw)");
  auto pose = read_pose(body["pose"], "pose").unsqueeze(0);
  const auto space = space_of(body, model_);
  // Without "seq" (e.g. a script) a request is always rendered; with one, a newer request of the session wins.
  const bool ordered = body.contains("seq");
  const auto seq = static_cast<uint64_t>(read_number(body, "seq", 0, 0, 9e15));
  const bool png = read_choice(body, "format", "jpeg", {"jpeg", "png"}) == "png";
  const int quality = static_cast<int>(read_number(body, "quality", options_.jpeg_quality, 1, 100));
  if (ordered) session->note_request(seq);
  ++waiting_;
  std::unique_lock<std::mutex> lock(model_mutex_);
  --waiting_;
  if (ordered && session->stale(seq)) {  // a newer frame of this session arrived while this one waited
    ++superseded_;
    res.status = 204;
    res.set_header("X-Superseded", "1");
    return;
  }
  const auto start = std::chrono::steady_clock::now();
  auto image = model_.render(session->scene, pose, space)[0];
  lock.unlock();
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  ++frames_;
  auto u8 = io::to_u8_hwc(image);
  auto bytes = png ? io::encode_png(u8) : io::encode_jpeg(u8, quality);
  res.set_header("X-Render-Ms", fmt::format("{:.1f}", ms));
  res.set_header("X-Seq", std::to_string(seq));
  res.set_header("Cache-Control", "no-store");
  res.set_content(std::string(bytes.begin(), bytes.end()), png ? "image/png" : "image/jpeg");
}

void ViewerServer::video(const httplib::Request& req, httplib::Response& res) {
  auto session = session_of(req.matches[1]);
  auto body = parse_json_body(req.body);
  if (!body.contains("poses")) throw HttpError(400, "poses: missing (an array of [tx ty tz qx qy qz qw])");
  auto poses = read_poses(body["poses"], "poses", 2, static_cast<size_t>(options_.max_video_frames));
  const auto space = space_of(body, model_);
  const double fps = read_number(body, "fps", 12, 1, 60);
  if (!io::mp4_available())
    throw HttpError(501, "no MP4 encoder here (built without FFmpeg, or its FFmpeg lacks libx264 and mpeg4)");
  std::vector<torch::Tensor> frames;
  // A few frames per turn on the model, so that other clients' frames are not held up for the whole video.
  for (int64_t s = 0; s < poses.size(0); s += 4) {
    std::unique_lock<std::mutex> lock(model_mutex_);
    auto chunk = model_.render(session->scene, poses.slice(0, s, std::min(s + 4, poses.size(0))), space);
    lock.unlock();
    for (int64_t i = 0; i < chunk.size(0); ++i) frames.push_back(io::to_u8_hwc(chunk[i]));
  }
  frames_ += static_cast<int64_t>(frames.size());
  res.set_header("Content-Disposition", "attachment; filename=\"uplvsm_path.mp4\"");
  res.set_content(mp4_bytes(frames, fps), "video/mp4");
}

void ViewerServer::preset(const httplib::Request& req, httplib::Response& res) {
  const std::string name = req.matches[1];
  if (name != "orbit" && name != "spiral" && name != "dolly")
    throw HttpError(404, "unknown preset \"" + name.substr(0, 32) + "\": orbit, spiral or dolly");
  auto param = [&](const char* key, double fallback, double lo, double hi) {
    return req.has_param(key) ? parse_number(req.get_param_value(key), key, lo, hi) : fallback;
  };
  render::PresetOptions o;
  const auto frames = static_cast<int64_t>(param("frames", 48, 2, options_.max_video_frames));
  o.focus_distance = param("focus", o.focus_distance, 0.05, 100);
  o.radius = param("radius", o.radius, 0, 100);
  o.arc_degrees = param("arc", o.arc_degrees, 0, 170);
  send_json(res, {{"units", "baseline"}, {"poses", pose_rows(render::camera_path_preset(name, frames, o))}});
}

}  // namespace uplvsm::serve
