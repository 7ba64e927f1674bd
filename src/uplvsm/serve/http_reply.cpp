#include "uplvsm/serve/http_reply.h"

#include <spdlog/spdlog.h>

#include "uplvsm/serve/http_error.h"

namespace uplvsm::serve {

void send_json(httplib::Response& res, const nlohmann::json& body, int status) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

void send_error(httplib::Response& res, int status, const std::string& message) {
  send_json(res, {{"error", message}}, status);
}

Handler guarded(Handler handler) {
  return [h = std::move(handler)](const httplib::Request& req, httplib::Response& res) {
    try {
      h(req, res);
    } catch (const HttpError& e) {
      send_error(res, e.status, e.what());
    } catch (const std::invalid_argument& e) {
      send_error(res, 400, e.what());
    } catch (const std::length_error& e) {
      send_error(res, 413, e.what());
    } catch (const std::exception& e) {
      spdlog::error("serve: {} {}: {}", req.method, req.path, e.what());
      send_error(res, 500, std::string("internal error: ") + e.what());
    }
  };
}

nlohmann::json pose_rows(const torch::Tensor& poses) {
  auto p = poses.to(torch::kCPU, torch::kFloat64).contiguous();
  nlohmann::json rows = nlohmann::json::array();
  for (int64_t i = 0; i < p.size(0); ++i)
    rows.push_back(std::vector<double>(p[i].data_ptr<double>(), p[i].data_ptr<double>() + p.size(1)));
  return rows;
}

}  // namespace uplvsm::serve
