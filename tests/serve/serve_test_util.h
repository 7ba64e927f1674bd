// A viewer server on an ephemeral loopback port for the serve tests: the tiny config's model (random weights,
// seeded; with or without a camera mapper), a built-in dataset of a few scenes, and an HTTP client.
#pragma once
#include <httplib.h>

#include <memory>
#include <string>
#include <thread>

#include "test_util.h"
#include "uplvsm/core/config.h"
#include "uplvsm/data/synthetic/room_scenes.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/serve/viewer_server.h"

namespace uplvsm::test {

inline Config tiny_config(bool mapper) {
  Config c = load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/tiny.json");
  c.model.pose_mapper = mapper;
  return c;
}

inline serve::ViewerModel tiny_viewer_model(bool mapper, bool bf16 = false) {
  torch::manual_seed(7);
  Config c = tiny_config(mapper);
  model::UPLVSM net(c.model);
  return serve::ViewerModel(net.ptr(), c, bf16);
}

// root/test: `scenes` built-in scenes of 8 frames at 48x64, with an evaluation index (context frames 0 and 4).
inline std::string tiny_dataset(const std::string& name, int scenes) {
  auto root = temp_dir(name) / "data";
  data::RoomSceneOptions opt;
  opt.height = 48;
  opt.width = 64;
  opt.frames = 8;
  opt.eval_gap = 4;
  data::write_builtin_dataset(root.string(), 1, scenes, 3, opt);
  return root.string();
}

struct TestServer {
  serve::ViewerModel model;
  serve::SceneCatalog catalog;
  std::unique_ptr<serve::ViewerServer> server;
  std::thread thread;
  int port = 0;

  TestServer(serve::ViewerModel m, const std::string& data, serve::ServerOptions options)
      : model(std::move(m)),
        catalog(data, "test", "", {static_cast<int>(model.image_size()), static_cast<int>(model.patch_size()), true},
                100) {
    options.port = 0;
    server = std::make_unique<serve::ViewerServer>(model, catalog, options);
    port = server->bind();
    thread = std::thread([this] { server->run(); });
  }
  ~TestServer() {
    server->stop();
    thread.join();
  }
  httplib::Client client() const {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(60);
    return c;
  }
};

}  // namespace uplvsm::test
