#include "uplvsm/serve/viewer_server.h"

#include <httplib.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/data/photo.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/io/image.h"
#include "uplvsm/serve/http_error.h"
#include "uplvsm/serve/http_reply.h"
#include "uplvsm/serve/json_request.h"
#include "uplvsm/serve/web_assets.h"

namespace uplvsm::serve {

namespace {

std::string mime_of(std::string_view path) {
  auto ends = [&](std::string_view ext) {
    return path.size() >= ext.size() && path.substr(path.size() - ext.size()) == ext;
  };
  if (ends(".html")) return "text/html; charset=utf-8";
  if (ends(".js")) return "text/javascript; charset=utf-8";
  if (ends(".css")) return "text/css; charset=utf-8";
  if (ends(".svg")) return "image/svg+xml";
  if (ends(".png")) return "image/png";
  return "application/octet-stream";
}

std::vector<uint8_t> view_jpeg(const torch::Tensor& chw) { return io::encode_jpeg(io::to_u8_hwc(chw), 92); }

std::string bytes_of(const std::vector<uint8_t>& v) { return std::string(v.begin(), v.end()); }

bool is_loopback_host(const std::string& host) {
  return host == "127.0.0.1" || host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

}  // namespace

int64_t resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  int64_t size = 0, resident = 0;
  statm >> size >> resident;
  return resident * static_cast<int64_t>(sysconf(_SC_PAGESIZE));
}

ViewerServer::ViewerServer(ViewerModel& model, SceneCatalog& catalog, ServerOptions options)
    : model_(model),
      catalog_(catalog),
      options_(std::move(options)),
      sessions_(options_.sessions),
      http_(std::make_unique<httplib::Server>()) {
  const int threads = options_.http_threads;
  http_->new_task_queue = [threads] { return new httplib::ThreadPool(static_cast<size_t>(threads)); };
  // Uploads are two photos and a few form fields; anything bigger is refused from its Content-Length.
  http_->set_payload_max_length(2 * options_.uploads.max_file_bytes + (size_t{1} << 20));
  http_->set_keep_alive_max_count(1000);
  http_->set_read_timeout(10);
  http_->set_write_timeout(30);
  routes();
}

ViewerServer::~ViewerServer() = default;

bool ViewerServer::loopback() const { return is_loopback_host(options_.host); }

int ViewerServer::bind() {
  if (options_.port == 0) {
    port_ = http_->bind_to_any_port(options_.host);
    if (port_ <= 0) throw std::runtime_error("serve: cannot bind to " + options_.host);
  } else {
    if (!http_->bind_to_port(options_.host, options_.port))
      throw std::runtime_error(
          fmt::format("serve: cannot bind to {}:{} (in use? try --port 0)", options_.host, options_.port));
    port_ = options_.port;
  }
  return port_;
}

void ViewerServer::run() { http_->listen_after_bind(); }

void ViewerServer::stop() { http_->stop(); }

ViewerServer::Stats ViewerServer::stats() const {
  return {frames_.load(), superseded_.load(), encodes_.load(), waiting_.load()};
}

void ViewerServer::routes() {
  // Bound to loopback, only requests naming a loopback host are served: a web page elsewhere cannot reach the
  // viewer through DNS rebinding.
  // Runs before a request body is read. A chunked body has no length to check against the payload limit (the
  // library would store all of it), so only bodies with a Content-Length are accepted.
  http_->set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (req.has_header("Transfer-Encoding")) {
      send_error(res, 411, "send the request body with a Content-Length (chunked bodies are not accepted)");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (!loopback()) return httplib::Server::HandlerResponse::Unhandled;
    std::string host = req.get_header_value("Host");
    if (!host.empty() && host.front() == '[')
      host = host.substr(1, host.find(']') - 1);
    else
      host = host.substr(0, host.find(':'));
    if (is_loopback_host(host)) return httplib::Server::HandlerResponse::Unhandled;
    send_error(res, 403, "this viewer serves loopback hosts only (Host: " + req.get_header_value("Host") + ")");
    return httplib::Server::HandlerResponse::Handled;
  });
  // Unknown routes and the library's own refusals (e.g. 413 from Content-Length) get a JSON body too.
  http_->set_error_handler(httplib::Server::HandlerWithResponse([](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
    const char* what = res.status == 404   ? "not found"
                       : res.status == 413 ? "request too large"
                       : res.status == 400 ? "malformed request"
                                           : "request refused";
    send_error(res, res.status, what);
    return httplib::Server::HandlerResponse::Handled;
  }));
  http_->set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
    send_error(res, 500, "internal error");
  });
  static_routes();
  session_routes();
  frame_routes();
}

void ViewerServer::static_routes() {
  const Handler asset = [](const httplib::Request& req, httplib::Response& res) {
    const std::string path = req.path == "/" ? "/index.html" : req.path;
    for (const auto& a : web_assets()) {
      if (a.path != path) continue;
      res.set_content(std::string(a.data), mime_of(a.path).c_str());
      res.set_header("Cache-Control", "no-cache");
      res.set_header("X-Content-Type-Options", "nosniff");
      res.set_header("Content-Security-Policy",
                     "default-src 'self'; img-src 'self' blob: data:; media-src 'self' blob:; object-src 'none'");
      return;
    }
    send_error(res, 404, "not found: " + path);
  };
  http_->Get("/", guarded(asset));
  http_->Get(R"(/[A-Za-z0-9_\-]+\.(html|js|css|svg|png))", guarded(asset));
  http_->Get("/api/info", guarded([this](const httplib::Request&, httplib::Response& res) {
               send_json(res, {{"image_size", model_.image_size()},
                               {"has_mapper", model_.has_mapper()},
                               {"amp", model_.bf16() ? "bf16" : "none"},
                               {"parameters", model_.parameter_count()},
                               {"config_name", model_.config().name},
                               {"scenes", catalog_.scenes().size()},
                               {"max_upload_bytes", options_.uploads.max_file_bytes},
                               {"max_upload_pixels", options_.uploads.max_pixels},
                               {"max_video_frames", options_.max_video_frames}});
             }));
  http_->Get("/api/stats", guarded([this](const httplib::Request&, httplib::Response& res) {
               auto s = sessions_.stats();
               auto f = stats();
               send_json(res, {{"sessions", s.sessions},
                               {"session_bytes", s.bytes},
                               {"evicted", s.evicted},
                               {"expired", s.expired},
                               {"frames", f.frames},
                               {"superseded", f.superseded},
                               {"encodes", f.encodes},
                               {"resident_bytes", resident_bytes()}});
             }));
  http_->Get("/api/scenes", guarded([this](const httplib::Request&, httplib::Response& res) {
               nlohmann::json list = nlohmann::json::array();
               for (const auto& s : catalog_.scenes())
                 list.push_back({{"id", s.id}, {"name", s.name}, {"thumbnail", "/api/scenes/" + s.id + "/thumbnail"}});
               send_json(res, {{"scenes", list}});
             }));
  http_->Get(R"(/api/scenes/([^/]+)/thumbnail)", guarded([this](const httplib::Request& req, httplib::Response& res) {
               const auto* scene = catalog_.find(req.matches[1]);
               if (!scene)
                 throw HttpError(404, "unknown scene id \"" + std::string(req.matches[1]).substr(0, 64) + "\"");
               auto jpeg = catalog_.thumbnail(*scene);
               res.set_content(bytes_of(jpeg), "image/jpeg");
             }));
}

std::shared_ptr<Session> ViewerServer::session_of(const std::string& id) {
  auto s = sessions_.get(id);
  if (!s) throw HttpError(404, "unknown or expired session; open the scene again");
  return s;
}

nlohmann::json ViewerServer::describe(const Session& s) const {
  const auto& e = s.scene;
  auto k = e.fxfycxcy;
  nlohmann::json j = {{"session", s.id},
                      {"name", s.name},
                      {"width", e.width},
                      {"height", e.height},
                      {"fxfycxcy",
                       {k[0].item<double>() / e.width, k[1].item<double>() / e.height, k[2].item<double>() / e.width,
                        k[3].item<double>() / e.height}},
                      {"has_mapper", model_.has_mapper()},
                      {"key_latent", pose_rows(e.key_latent)},
                      {"key_real", e.key_real.defined() ? pose_rows(e.key_real) : nlohmann::json()},
                      {"key_real_estimated", e.key_real_estimated},
                      {"key_real_residual",
                       std::isfinite(e.key_real_residual) ? nlohmann::json(e.key_real_residual) : nlohmann::json()},
                      {"inputs", {"/api/sessions/" + s.id + "/inputs/0", "/api/sessions/" + s.id + "/inputs/1"}},
                      {"photos", s.photos}};
  return j;
}

std::string ViewerServer::open_session(std::shared_ptr<Session> session, const data::SceneViews& views, bool posed) {
  {
    std::lock_guard<std::mutex> lock(model_mutex_);
    session->scene = model_.encode(views, posed);
  }
  ++encodes_;
  session->input_jpegs = {view_jpeg(views.images[0]), view_jpeg(views.images[1])};
  auto id = sessions_.add(session);
  spdlog::info("serve: session {}… for {} ({} sessions open)", id.substr(0, 8), session->name,
               sessions_.stats().sessions);
  return id;
}

// Two uploaded photos as a session: each turned upright by its EXIF orientation; the field of view from the "fov"
// field when it holds a number (it wins), else each photo's EXIF focal length, else 60 degrees. What was done with
// each photo is logged and returned in the session description ("photos"), for the page to show.
nlohmann::json ViewerServer::open_upload(const httplib::Request& req) {
  if (!req.is_multipart_form_data())
    throw HttpError(400, "upload: expected multipart/form-data with the fields image0, image1 (and fov)");
  std::optional<double> fov;
  if (req.has_file("fov")) {
    const auto& text = req.get_file_value("fov").content;
    // An empty field is the page's "automatic": EXIF, else the default.
    if (text.find_first_not_of(" \t") != std::string::npos) fov = parse_number(text, "fov", 1, 179);
  }
  auto session = std::make_shared<Session>();
  session->name = "upload";
  session->photos = nlohmann::json::array();
  std::vector<data::Photo> photos;
  for (const char* field : {"image0", "image1"}) {
    if (!req.has_file(field)) throw HttpError(400, std::string("upload: missing the photo field ") + field);
    photos.push_back(decode_upload(req.get_file_value(field).content, options_.uploads, fov, field));
    spdlog::info("serve: upload {}", data::describe_photo(photos.back().info, "the FoV field"));
    session->photos.push_back(data::to_json(photos.back().info, "the FoV field"));
  }
  // Square views of the model's size, as `render --images` makes them; the unposed photos have no cameras.
  auto views = data::photo_views(photos, model_.preprocess_options());
  views.c2w = torch::Tensor();
  open_session(session, views, false);
  return describe(*session);
}

void ViewerServer::session_routes() {
  http_->Post("/api/sessions", guarded([this](const httplib::Request& req, httplib::Response& res) {
                auto body = parse_json_body(req.body);
                if (!body.contains("scene") || !body["scene"].is_string())
                  throw HttpError(400, "scene: expected a scene id (a string from /api/scenes)");
                const auto* scene = catalog_.find(body["scene"].get<std::string>());
                if (!scene)
                  throw HttpError(404, "unknown scene id \"" + body["scene"].get<std::string>().substr(0, 64) + "\"");
                bool posed = false;
                auto views = catalog_.load(*scene, &posed);
                auto session = std::make_shared<Session>();
                session->name = scene->name;
                open_session(session, views, posed);
                send_json(res, describe(*session));
              }));
  http_->Post("/api/upload", guarded([this](const httplib::Request& req, httplib::Response& res) {
                send_json(res, open_upload(req));
              }));
  http_->Get(R"(/api/sessions/([^/]+))", guarded([this](const httplib::Request& req, httplib::Response& res) {
               send_json(res, describe(*session_of(req.matches[1])));
             }));
  http_->Delete(R"(/api/sessions/([^/]+))", guarded([this](const httplib::Request& req, httplib::Response& res) {
                  if (!sessions_.remove(req.matches[1])) throw HttpError(404, "unknown or expired session");
                  send_json(res, {{"deleted", true}});
                }));
  http_->Get(R"(/api/sessions/([^/]+)/inputs/([01]))",
             guarded([this](const httplib::Request& req, httplib::Response& res) {
               auto s = session_of(req.matches[1]);
               res.set_content(bytes_of(s->input_jpegs.at(req.matches[2] == "1" ? 1 : 0)), "image/jpeg");
             }));
}

}  // namespace uplvsm::serve
