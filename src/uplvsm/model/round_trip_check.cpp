#include "uplvsm/model/round_trip_check.h"

#include <chrono>
#include <stdexcept>

#include "uplvsm/core/config.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"

namespace uplvsm::model {

RoundTripCheck check_round_trip(const std::string& path, const NovelViewModelImpl& written,
                                const torch::Device& device) {
  Config config;
  auto net = load_model(path, device, &config);
  auto expected = io::state_dict(written);
  for (const auto& [k, v] : io::state_dict(*net))
    if (!torch::equal(v, expected.at(k)))
      throw std::runtime_error("verify: tensor " + k + " changed in the round trip");
  torch::NoGradGuard no_grad;
  torch::manual_seed(0);
  RoundTripCheck r;
  r.tensors = static_cast<int64_t>(expected.size());
  const int64_t s = r.image_size = config.model.image_size;
  auto images = torch::rand({1, 3, 3, s, s}, torch::TensorOptions().device(device));
  auto K = torch::tensor({0.9 * s, 0.9 * s, 0.5 * s, 0.5 * s}, torch::TensorOptions().device(device)).expand({1, 3, 4});
  auto t0 = std::chrono::steady_clock::now();
  // Posed models need cameras: a camera 1 unit to the right per view.
  auto c2w = torch::eye(4, images.options()).repeat({1, 3, 1, 1});
  c2w.select(1, 1)[0][0][3] = 1.0;
  c2w.select(1, 2)[0][0][3] = 0.5;
  Views inputs{images.narrow(1, 0, 2), K.narrow(1, 0, 2), c2w.narrow(1, 0, 2)};
  Views targets{images.narrow(1, 2, 1), K.narrow(1, 2, 1), c2w.narrow(1, 2, 1)};
  auto out = net->render(inputs, targets, net->default_target_poses());
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  auto pose = out.pose_enc.defined() ? out.pose_enc.cpu().contiguous() : torch::zeros({7});
  if (!torch::isfinite(out.render).all().item<bool>() || !torch::isfinite(pose).all().item<bool>())
    throw std::runtime_error("verify: the forward pass produced NaN/Inf");
  r.pose.assign(pose.data_ptr<float>(), pose.data_ptr<float>() + 7);
  r.render_mean = out.render.mean().item<double>();
  return r;
}

}  // namespace uplvsm::model
