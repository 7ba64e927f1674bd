// JSON replies of the viewer's HTTP layer: success bodies, {"error": message} bodies with their status, and the
// wrapper that turns anything a handler throws into such an error (the server keeps serving).
#pragma once
#include <httplib.h>
#include <torch/torch.h>

#include <functional>
#include <string>

#include <nlohmann/json.hpp>

namespace uplvsm::serve {

using Handler = std::function<void(const httplib::Request&, httplib::Response&)>;

void send_json(httplib::Response& res, const nlohmann::json& body, int status = 200);
void send_error(httplib::Response& res, int status, const std::string& message);
// HttpError -> its status; std::invalid_argument -> 400; std::length_error -> 413; anything else -> 500 (logged).
Handler guarded(Handler handler);
// poses [N, 7] -> [[tx, ty, tz, qx, qy, qz, qw], ...]
nlohmann::json pose_rows(const torch::Tensor& poses);

}  // namespace uplvsm::serve
