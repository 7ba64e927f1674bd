// HTTP-level tests of `uplvsm serve`'s server on an ephemeral loopback port: page, scene list, sessions, frames,
// uploads, bad requests (each a 4xx JSON error, the server still serving), concurrent clients, newest-frame-wins.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/exif_jpeg.h"
#include "serve_test_util.h"
#include "uplvsm/io/image.h"
#include "uplvsm/io/video.h"
#include "uplvsm/serve/http_error.h"
#include "uplvsm/serve/scene_sources.h"

namespace uplvsm::test {
namespace {

using nlohmann::json;

serve::ServerOptions small_limits() {
  serve::ServerOptions o;
  o.uploads.max_file_bytes = 256 << 10;
  o.uploads.max_pixels = 1'000'000;
  o.sessions.max_sessions = 16;
  o.max_video_frames = 8;
  return o;
}

class ViewerServerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    server_ = new TestServer(tiny_viewer_model(false), tiny_dataset("serve_http", 3), small_limits());
  }
  static void TearDownTestSuite() {
    delete server_;
    server_ = nullptr;
  }
  static json post(const std::string& path, const json& body, int expect = 200) {
    auto cli = server_->client();
    auto r = cli.Post(path.c_str(), body.dump(), "application/json");
    EXPECT_TRUE(r) << path;
    if (!r) return {};
    EXPECT_EQ(r->status, expect) << path << ": " << r->body;
    return r->get_header_value("Content-Type") == "application/json" ? json::parse(r->body) : json();
  }
  static json open_scene(const std::string& id = "0") { return post("/api/sessions", {{"scene", id}}); }
  static httplib::Result frame(const std::string& session, const json& body) {
    auto cli = server_->client();
    return cli.Post(("/api/sessions/" + session + "/frame").c_str(), body.dump(), "application/json");
  }
  // A 4xx/5xx answer with a JSON {"error": ...} that mentions `words`.
  static void expect_error(const httplib::Result& r, int status, const std::string& words) {
    ASSERT_TRUE(r) << "no response (httplib error " << static_cast<int>(r.error()) << ") where " << status << " "
                   << words << " was expected";
    EXPECT_EQ(r->status, status) << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
    auto j = json::parse(r->body, nullptr, false);
    ASSERT_TRUE(j.is_object() && j.contains("error")) << r->body;
    EXPECT_NE(j["error"].get<std::string>().find(words), std::string::npos) << r->body;
  }
  static TestServer* server_;
};
TestServer* ViewerServerTest::server_ = nullptr;

// Sends `request` on a fresh connection and returns what comes back until the JSON body closes (or 5 s pass).
std::string raw_request(int port, const std::string& request) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  timeval timeout{5, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  std::string reply;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0 &&
      ::send(fd, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size())) {
    char buf[4096];
    ssize_t n;
    while (reply.find("\"}") == std::string::npos && (n = ::recv(fd, buf, sizeof(buf), 0)) > 0) reply.append(buf, n);
  }
  ::close(fd);
  return reply;
}

torch::Tensor decode(const std::string& bytes) {
  return io::decode_image(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), "response");
}

TEST_F(ViewerServerTest, ServesThePageFromTheBinary) {
  auto cli = server_->client();
  auto page = cli.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("uplvsm viewer"), std::string::npos);
  EXPECT_NE(page->get_header_value("Content-Security-Policy").find("default-src 'self'"), std::string::npos);
  for (const char* asset : {"/viewer.js", "/camera.js", "/plot.js", "/viewer.css"}) {
    auto r = cli.Get(asset);
    ASSERT_TRUE(r) << asset;
    EXPECT_EQ(r->status, 200) << asset;
    EXPECT_GT(r->body.size(), 500u) << asset;
  }
  expect_error(cli.Get("/missing.js"), 404, "not found");
  expect_error(cli.Get("/../../etc/passwd"), 404, "not found");
  expect_error(cli.Get("/api/nothing"), 404, "not found");
}

TEST_F(ViewerServerTest, ListsScenesWithThumbnails) {
  auto cli = server_->client();
  auto r = cli.Get("/api/scenes");
  ASSERT_TRUE(r);
  auto scenes = json::parse(r->body)["scenes"];
  ASSERT_EQ(scenes.size(), 3u);
  EXPECT_EQ(scenes[0]["id"], "0");
  auto thumb = cli.Get(scenes[1]["thumbnail"].get<std::string>().c_str());
  ASSERT_TRUE(thumb);
  EXPECT_EQ(thumb->get_header_value("Content-Type"), "image/jpeg");
  EXPECT_EQ(decode(thumb->body).sizes(), (std::vector<int64_t>{48, 96, 3}));  // two 48x48 views side by side
  expect_error(cli.Get("/api/scenes/7/thumbnail"), 404, "unknown scene id");
  auto info = json::parse(cli.Get("/api/info")->body);
  EXPECT_EQ(info["image_size"], 48);
  EXPECT_EQ(info["has_mapper"], false);
}

// The frame served from the cached scene latents equals a render from a fresh encode of the same views.
TEST_F(ViewerServerTest, FramesFromCachedLatentsMatchAFreshRender) {
  auto s = open_scene("1");
  ASSERT_EQ(s["key_latent"].size(), 2u);
  EXPECT_TRUE(s["key_real"].is_null());
  EXPECT_TRUE(s["key_real_residual"].is_null());
  const std::vector<double> pose = s["key_latent"][1];
  auto r = frame(s["session"], {{"pose", pose}, {"space", "latent"}, {"seq", 1}, {"format", "png"}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->get_header_value("Content-Type"), "image/png");
  auto served = decode(r->body);

  bool posed = false;
  auto views = server_->catalog.load(*server_->catalog.find("1"), &posed);
  auto fresh = server_->model.encode(views, posed);
  auto expected = io::to_u8_hwc(
      server_->model.render(fresh, torch::tensor(pose, torch::kFloat64).unsqueeze(0), serve::PoseSpace::Latent)[0]);
  EXPECT_TRUE(torch::equal(served, expected));

  auto jpeg = frame(s["session"], {{"pose", s["key_latent"][0]}, {"seq", 2}});
  ASSERT_TRUE(jpeg);
  EXPECT_EQ(jpeg->get_header_value("Content-Type"), "image/jpeg");
  auto other = decode(jpeg->body);
  EXPECT_EQ(other.sizes(), served.sizes());
  EXPECT_GT((other.to(torch::kFloat32) - served.to(torch::kFloat32)).abs().mean().item<double>(), 0.5);
  auto input = server_->client().Get(s["inputs"][1].get<std::string>().c_str());
  EXPECT_EQ(decode(input->body).sizes(), (std::vector<int64_t>{48, 48, 3}));
}

TEST_F(ViewerServerTest, BadRequestsGetJsonErrorsAndTheServerKeepsServing) {
  const std::string sid = open_scene()["session"];
  const std::vector<double> pose{0, 0, 0, 0, 0, 0, 1};
  auto cli = server_->client();
  auto raw = [&](const std::string& body) {
    return cli.Post(("/api/sessions/" + sid + "/frame").c_str(), body, "application/json");
  };
  expect_error(raw("{not json"), 400, "not valid JSON");
  expect_error(raw(std::string(100, '[') + std::string(100, ']')), 400, "nests deeper");
  expect_error(raw("[1, 2]"), 400, "JSON object");
  expect_error(frame(sid, json::object()), 400, "pose: missing");
  expect_error(frame(sid, {{"pose", {1, 2, 3}}}), 400, "7 numbers");
  expect_error(frame(sid, {{"pose", {0, 0, 0, 0, 0, 0, 0}}}), 400, "zero quaternion");
  expect_error(frame(sid, {{"pose", {1e9, 0, 0, 0, 0, 0, 1}}}), 400, "out of range");
  expect_error(frame(sid, {{"pose", {"a", 0, 0, 0, 0, 0, 1}}}), 400, "finite numbers");
  expect_error(frame(sid, {{"pose", pose}, {"space", "real"}}), 400, "camera mapper");
  expect_error(frame(sid, {{"pose", pose}, {"space", "world"}}), 400, "space");
  expect_error(frame(sid, {{"pose", pose}, {"format", "gif"}}), 400, "format");
  expect_error(frame(sid, {{"pose", pose}, {"seq", -1}}), 400, "seq");
  expect_error(frame("0123456789abcdef0123456789abcdef", {{"pose", pose}}), 404, "unknown or expired session");
  expect_error(frame("../../etc", {{"pose", pose}}), 404, "");
  expect_error(cli.Post("/api/sessions", json({{"scene", "99"}}).dump(), "application/json"), 404, "unknown scene id");
  expect_error(cli.Post("/api/sessions", json({{"scene", "../../etc/passwd"}}).dump(), "application/json"), 404,
               "unknown scene id");
  expect_error(cli.Post("/api/sessions", json({{"scene", 0}}).dump(), "application/json"), 400, "scene id");
  expect_error(cli.Get("/api/presets/circle"), 404, "unknown preset");
  expect_error(cli.Get("/api/presets/orbit?frames=abc"), 400, "frames");
  expect_error(cli.Get("/api/presets/orbit?frames=100000"), 400, "frames");
  expect_error(
      cli.Post(("/api/sessions/" + sid + "/video").c_str(), json({{"poses", {pose}}}).dump(), "application/json"), 400,
      "2 to 8 poses");
  // A request that names another host (DNS rebinding) is refused while the server is on loopback.
  httplib::Headers evil{{"Host", "attacker.example:8080"}};
  expect_error(cli.Get("/api/info", evil), 403, "loopback");
  // Chunked bodies have no length to check up front: refused as soon as the headers are read.
  auto chunked =
      raw_request(server_->port, "POST /api/upload HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n\r\n");
  EXPECT_EQ(chunked.rfind("HTTP/1.1 411", 0), 0u) << chunked;
  EXPECT_NE(chunked.find("Content-Length"), std::string::npos) << chunked;
  auto ok = cli.Get("/api/info");
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
}

httplib::MultipartFormDataItems photos(const std::string& a, const std::string& b, const std::string& fov = "60") {
  return {{"image0", a, "a.png", "image/png"}, {"image1", b, "b.png", "image/png"}, {"fov", fov, "", ""}};
}

std::string png_of(const torch::Tensor& hwc) {
  auto bytes = io::encode_png(hwc);
  return std::string(bytes.begin(), bytes.end());
}

TEST_F(ViewerServerTest, UploadsTwoPhotosAndRendersThem) {
  auto views = server_->catalog.load(*server_->catalog.find("2"), nullptr);
  const auto a = png_of(io::to_u8_hwc(views.images[0])), b = png_of(io::to_u8_hwc(views.images[1]));
  auto cli = server_->client();
  auto r = cli.Post("/api/upload", photos(a, b));
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  auto s = json::parse(r->body);
  EXPECT_EQ(s["name"], "upload");
  auto f = frame(s["session"], {{"pose", s["key_latent"][0]}});
  ASSERT_TRUE(f);
  EXPECT_EQ(f->status, 200);

  expect_error(cli.Post("/api/upload", photos(a, "not an image at all")), 400, "image1");
  expect_error(cli.Post("/api/upload", photos(a, b, "500")), 400, "fov");
  expect_error(cli.Post("/api/upload", httplib::MultipartFormDataItems{{"image0", a, "a.png", "image/png"}}), 400,
               "image1");
  expect_error(cli.Post("/api/upload", a, "image/png"), 400, "multipart");
  // Checked before decoding: 1200 x 1000 pixels (a small file of zeros) is over the 1 MP limit.
  expect_error(cli.Post("/api/upload", photos(a, png_of(torch::zeros({1200, 1000, 3}, torch::kUInt8)))), 413, "pixels");
  std::string big(300 << 10, '\x7f');
  expect_error(cli.Post("/api/upload", photos(a, big)), 413, "bytes");
  // Over the whole request limit: refused from Content-Length, the body is never stored.
  std::string huge(2 * (256 << 10) + (1 << 20) + 1, 'x');
  expect_error(cli.Post("/api/upload", huge, "application/octet-stream"), 413, "too large");
  EXPECT_EQ(cli.Get("/api/info")->status, 200);
}

// A portrait phone photo stored sideways with EXIF orientation 6: the session's input (what the model sees and the
// page shows) is upright, and the photo's field of view comes from its EXIF focal length unless the fov field is set.
TEST_F(ViewerServerTest, UploadedPhotosAreTurnedUprightByTheirExifOrientation) {
  const auto jpeg = jpeg_with_exif(stored_for_orientation_6(red_over_blue(96, 64)), 6, 26);
  const std::string portrait(jpeg.begin(), jpeg.end());
  auto cli = server_->client();
  httplib::MultipartFormDataItems form = {{"image0", portrait, "portrait.jpg", "image/jpeg"},
                                          {"image1", portrait, "portrait.jpg", "image/jpeg"},
                                          {"fov", "", "", ""}};
  auto r = cli.Post("/api/upload", form);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  auto s = json::parse(r->body);
  auto input = cli.Get(s["inputs"][0].get<std::string>().c_str());
  ASSERT_TRUE(input);
  ASSERT_EQ(input->status, 200);
  const auto shown = io::decode_image(reinterpret_cast<const uint8_t*>(input->body.data()), input->body.size(), "in0");
  EXPECT_TRUE(is_red_over_blue(shown));
  ASSERT_EQ(s["photos"].size(), 2u);
  EXPECT_EQ(s["photos"][0]["exif_orientation"], 6);
  EXPECT_EQ(s["photos"][0]["fov_source"], "exif");
  // The 35 mm equivalent by the diagonal: f = 26 * sqrt(96^2 + 64^2) / sqrt(36^2 + 24^2) px, across 64 columns.
  EXPECT_NEAR(s["photos"][0]["fov_deg"].get<double>(),
              2 * std::atan(32.0 / (26.0 * std::hypot(96, 64) / std::hypot(36, 24))) * 180 / M_PI, 1e-9);
  form[2].content = "50";
  r = cli.Post("/api/upload", form);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  s = json::parse(r->body);
  EXPECT_EQ(s["photos"][1]["fov_source"], "explicit");
  EXPECT_EQ(s["photos"][1]["fov_deg"], 50.0);
  EXPECT_NE(s["photos"][1]["note"].get<std::string>().find("from the FoV field (overrides"), std::string::npos);
  // Dataset scenes have no photos to describe.
  EXPECT_TRUE(open_scene()["photos"].is_null());
}

// An upload is decoded under the process-wide decompression-bomb limit (--max-image-pixels) when it is lower than
// the server's own, refused from the header with 413.
TEST(DecodeUpload, TheProcessPixelLimitAppliesWhenLower) {
  const auto png = io::encode_png(torch::zeros({40, 30, 3}, torch::kUInt8));
  const std::string bytes(png.begin(), png.end());
  serve::UploadLimits limits;
  EXPECT_EQ(serve::decode_upload(bytes, limits, std::nullopt, "image0").hwc_u8.sizes(),
            (std::vector<int64_t>{40, 30, 3}));
  const int64_t before = io::max_image_pixels();
  io::set_max_image_pixels(1000);
  int status = 0;
  std::string msg;
  try {
    serve::decode_upload(bytes, limits, std::nullopt, "image0");
  } catch (const serve::HttpError& e) {
    status = e.status;
    msg = e.what();
  }
  io::set_max_image_pixels(before);
  EXPECT_EQ(status, 413);
  EXPECT_NE(msg.find("image0: 30x40 pixels, more than the 1000 allowed"), std::string::npos) << msg;
}

TEST_F(ViewerServerTest, ConcurrentClientsAllGetTheirFrames) {
  const int clients = 6, frames = 8;
  std::atomic<int> ok{0}, bad{0};
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c)
    threads.emplace_back([&, c] {
      auto s = open_scene(std::to_string(c % 3));
      for (int i = 1; i <= frames; ++i) {
        std::vector<double> pose{0.05 * i, 0, 0, 0, 0, 0, 1};
        auto r = frame(s["session"], {{"pose", pose}, {"seq", i}});
        (r && r->status == 200 && decode(r->body).size(0) == 48 ? ok : bad)++;
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(ok.load(), clients * frames);
  EXPECT_EQ(bad.load(), 0);
}

// While the model is busy, three frames of one session queue up: only the newest is rendered.
TEST_F(ViewerServerTest, NewestFrameWinsStaleOnesAreDropped) {
  const std::string sid = open_scene()["session"];
  const auto before = server_->server->stats();
  std::vector<int> status(3, 0);
  std::vector<std::thread> threads;
  {
    auto hold = server_->server->hold_model();
    for (int i = 0; i < 3; ++i) {
      threads.emplace_back([&, i] {
        std::vector<double> pose{0.1 * i, 0, 0, 0, 0, 0, 1};
        auto r = frame(sid, {{"pose", pose}, {"seq", 100 + i}});
        status[i] = r ? r->status : -1;
      });
      while (server_->server->stats().waiting < i + 1) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(status, (std::vector<int>{204, 204, 200}));
  EXPECT_EQ(server_->server->stats().superseded - before.superseded, 2);
  // A request without a sequence number (a script, curl) is always rendered.
  auto plain = frame(sid, {{"pose", {0, 0, 0, 0, 0, 0, 1}}});
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->status, 200);
}

TEST_F(ViewerServerTest, RecordedPathBecomesAnMp4AndPresetsArePoses) {
  if (!io::mp4_available()) GTEST_SKIP() << "no MP4 output here (no encoder in this FFmpeg, or built without FFmpeg)";
  auto s = open_scene();
  auto cli = server_->client();
  json poses = {s["key_latent"][0], s["key_latent"][1], s["key_latent"][0]};
  auto r = cli.Post(("/api/sessions/" + s["session"].get<std::string>() + "/video").c_str(),
                    json({{"poses", poses}, {"space", "latent"}, {"fps", 6}}).dump(), "application/json");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(r->get_header_value("Content-Type"), "video/mp4");
  ASSERT_GT(r->body.size(), 100u);
  EXPECT_EQ(r->body.substr(4, 4), "ftyp");
  auto preset = json::parse(cli.Get("/api/presets/orbit?frames=5&focus=3")->body);
  ASSERT_EQ(preset["poses"].size(), 5u);
  EXPECT_EQ(preset["units"], "baseline");
  EXPECT_NEAR(preset["poses"][0][6].get<double>(), 1.0, 1e-9);  // the loop starts at input 1
}

TEST_F(ViewerServerTest, DeletedSessionIsGone) {
  const std::string sid = open_scene()["session"];
  auto cli = server_->client();
  EXPECT_EQ(cli.Get(("/api/sessions/" + sid).c_str())->status, 200);
  EXPECT_EQ(cli.Delete(("/api/sessions/" + sid).c_str())->status, 200);
  expect_error(cli.Get(("/api/sessions/" + sid).c_str()), 404, "unknown or expired");
}

}  // namespace
}  // namespace uplvsm::test
