// `uplvsm serve`: the interactive novel-view viewer — a local HTTP server whose page lets a person pick a dataset
// scene or upload two photos and drag the camera through the scene (serve/viewer_server.h).
#include <atomic>
#include <chrono>
#include <csignal>
#include <iostream>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/serve/viewer_server.h"

namespace uplvsm::cli {

namespace {

struct ServeArgs {
  CommonOptions common;
  ModelSource model;
  SceneSource scenes;
  std::string host = "127.0.0.1";
  Amp amp = Amp::None;
  int port = 8080, max_sessions = 8, max_scenes = 200;
  double cache_mb = 512, session_minutes = 30, max_upload_mb = 16, max_megapixels = 40;
};

volatile std::sig_atomic_t g_stop_signal = 0;
extern "C" void on_serve_signal(int sig) { g_stop_signal = sig; }

void run_viewer(const ServeArgs& a) {
  auto model = serve::ViewerModel::load(a.model.checkpoint, a.model.config, parse_device(a.common.device),
                                        a.amp == Amp::Bf16, a.model.mapper);
  const auto& s = a.scenes;
  auto catalog = s.data.empty()
                     ? std::make_unique<serve::SceneCatalog>()
                     : std::make_unique<serve::SceneCatalog>(s.data, s.split, s.index, model.preprocess_options(),
                                                             static_cast<size_t>(a.max_scenes));
  serve::ServerOptions o;
  o.host = a.host;
  o.port = a.port;
  o.sessions = {static_cast<size_t>(a.max_sessions), static_cast<int64_t>(a.cache_mb * 1048576.0),
                a.session_minutes * 60.0};
  o.uploads = {static_cast<size_t>(a.max_upload_mb * 1048576.0), static_cast<int64_t>(a.max_megapixels * 1e6)};
  serve::ViewerServer server(model, *catalog, o);
  const int port = server.bind();
  if (!server.loopback())
    spdlog::warn(
        "serve: listening on {} — every machine that can reach it can use this viewer (no authentication); "
        "the default --host 127.0.0.1 keeps it on this computer",
        a.host);
  const std::string host = a.host.find(':') != std::string::npos ? "[" + a.host + "]" : a.host;
  std::cout << fmt::format("uplvsm viewer: {}x{} model{}{}, {} dataset scene(s)\n", model.image_size(),
                           model.image_size(), model.has_mapper() ? ", camera mapper" : "",
                           model.bf16() ? ", bf16" : "", catalog->scenes().size())
            << fmt::format("open http://{}:{}/ in a browser (Ctrl-C stops)", host, port) << std::endl;
  // Ctrl-C / SIGTERM: stop accepting, let the in-flight requests finish, then return.
  g_stop_signal = 0;
  auto old_int = std::signal(SIGINT, on_serve_signal);
  auto old_term = std::signal(SIGTERM, on_serve_signal);
  std::atomic<bool> done{false};
  std::thread watcher([&] {
    while (!done && g_stop_signal == 0) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (g_stop_signal != 0) server.stop();
  });
  server.run();
  done = true;
  watcher.join();
  std::signal(SIGINT, old_int);
  std::signal(SIGTERM, old_term);
  auto stats = server.stats();
  std::cout << fmt::format("viewer stopped: {} frame(s) rendered, {} superseded, {} scene(s) encoded\n", stats.frames,
                           stats.superseded, stats.encodes);
}

}  // namespace

void add_serve_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "serve",
      "Interactive novel-view viewer in the browser: pick a dataset scene (--data) or upload two photos, "
      "drag the camera, record a path (MP4, camera-path JSON). Serves on 127.0.0.1 unless --host says "
      "otherwise.");
  auto a = std::make_shared<ServeArgs>();
  add_common_options(cmd, a->common);
  add_model_options(cmd, a->model);
  add_mapper_option(cmd, a->model);
  add_scene_source_options(cmd, a->scenes, "dataset root whose scenes the page lists (optional: uploads always work)",
                           "evaluation index choosing each scene's two input views (default "
                           "<data>/evaluation_index.json when present, else frames 0 and n/2)");
  cmd->add_option("--max-scenes", a->max_scenes, "dataset scenes listed")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--host", a->host, "address to listen on (anything but loopback is reachable by others)")
      ->capture_default_str();
  cmd->add_option("--port", a->port, "TCP port (0: any free port)")->check(CLI::Range(0, 65535))->capture_default_str();
  add_amp_option(cmd, a->amp, "model precision: none (fp32) or bf16 autocast");
  cmd->add_option("--max-sessions", a->max_sessions, "open scenes kept (least recently used dropped first)")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  cmd->add_option("--cache-mb", a->cache_mb, "memory for the open scenes' latents and inputs, MiB")
      ->check(CLI::Range(1.0, 1e6))
      ->capture_default_str();
  cmd->add_option("--session-minutes", a->session_minutes, "an idle session expires after this long")
      ->check(CLI::Range(0.1, 1e6))
      ->capture_default_str();
  cmd->add_option("--max-upload-mb", a->max_upload_mb, "largest photo accepted, MiB")
      ->check(CLI::Range(0.01, 1024.0))
      ->capture_default_str();
  cmd->add_option("--max-megapixels", a->max_megapixels, "largest photo accepted, megapixels (checked before decoding)")
      ->check(CLI::Range(0.01, 1000.0))
      ->capture_default_str();
  cmd->callback([a] {
    apply_common_options(a->common);
    log_kernel_paths();
    run_viewer(*a);
  });
}

}  // namespace uplvsm::cli
