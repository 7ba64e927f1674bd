// `uplvsm serve`'s HTTP server (cpp-httplib): the viewer page (assets embedded in the binary), the scene list,
// uploads, sessions and frames. One model, shared by every client: model calls are serialised, each session keeps
// its scene latents (only the decoder runs per frame), and a frame request that a newer one of its session
// overtook while waiting is answered 204 without rendering (the newest drag wins).
//
// API (JSON unless said; errors: 4xx/5xx with {"error": message}):
//   GET  /api/info                       model and limits
//   GET  /api/scenes                     {"scenes": [{"id", "name", "thumbnail"}]}
//   GET  /api/scenes/<id>/thumbnail      JPEG [context view 0 | view 1]
//   POST /api/sessions {"scene": id}     encode a dataset scene -> session description
//   POST /api/upload (multipart: image0, image1, fov)   encode two photos -> session description
//   GET  /api/sessions/<sid>             session description;  DELETE frees it
//   GET  /api/sessions/<sid>/inputs/<0|1>                JPEG of an input view
//   POST /api/sessions/<sid>/frame {"pose": [7], "space": "latent"|"real", "seq": n, "format": "jpeg"|"png"}
//   POST /api/sessions/<sid>/video {"poses": [[7]...], "space", "fps"}  -> video/mp4
//   GET  /api/presets/<orbit|spiral|dolly>?frames=&focus=&radius=&arc=  camera path in camera-control units
//   GET  /api/stats                      sessions, memory, frames rendered / superseded
#pragma once
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include <nlohmann/json.hpp>

#include "uplvsm/serve/scene_sources.h"
#include "uplvsm/serve/session_store.h"
#include "uplvsm/serve/viewer_model.h"

namespace httplib {
class Server;
struct Request;
struct Response;
}  // namespace httplib

namespace uplvsm::serve {

struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;  // 0: any free port (bind() returns it)
  SessionLimits sessions;
  UploadLimits uploads;
  int jpeg_quality = 90;
  int max_video_frames = 600;
  int http_threads = 16;
};

class ViewerServer {
 public:
  // `catalog` may hold no scenes (no --data): the page then offers uploads only.
  ViewerServer(ViewerModel& model, SceneCatalog& catalog, ServerOptions options);
  ~ViewerServer();

  int bind();   // binds host:port; returns the port (throws when it cannot bind)
  void run();   // serves until stop(); returns after the in-flight requests finished
  void stop();  // safe from any thread
  bool loopback() const;

  struct Stats {
    int64_t frames = 0, superseded = 0, encodes = 0, waiting = 0;
  };
  Stats stats() const;
  SessionStore& sessions() { return sessions_; }
  // Tests: hold the model so that frame requests queue up behind it.
  std::unique_lock<std::mutex> hold_model() { return std::unique_lock<std::mutex>(model_mutex_); }

 private:
  void routes();
  void static_routes();
  void session_routes();
  void frame_routes();
  std::shared_ptr<Session> session_of(const std::string& id);
  nlohmann::json describe(const Session& s) const;
  std::string open_session(std::shared_ptr<Session> session, const data::SceneViews& views, bool posed);
  nlohmann::json open_upload(const httplib::Request& req);
  void frame(const httplib::Request& req, httplib::Response& res);
  void video(const httplib::Request& req, httplib::Response& res);
  void preset(const httplib::Request& req, httplib::Response& res);

  ViewerModel& model_;
  SceneCatalog& catalog_;
  ServerOptions options_;
  SessionStore sessions_;
  std::unique_ptr<httplib::Server> http_;
  std::mutex model_mutex_;
  std::atomic<int64_t> frames_{0}, superseded_{0}, encodes_{0}, waiting_{0};
  int port_ = 0;
};

// Resident memory of this process in bytes (/proc/self/statm), for stats and the load test.
int64_t resident_bytes();

}  // namespace uplvsm::serve
