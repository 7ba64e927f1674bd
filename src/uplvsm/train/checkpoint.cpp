#include "uplvsm/train/checkpoint.h"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/json_input.h"
#include "uplvsm/train/optimizer.h"

namespace uplvsm::train {

namespace fs = std::filesystem;

nlohmann::json TrainState::to_json() const {
  return {{"step", step},
          {"scheduler_step", scheduler_step},
          {"param_update_step", param_update_step},
          {"skipped_nonfinite", skipped_nonfinite},
          {"skipped_gradnorm", skipped_gradnorm},
          {"train_seconds", train_seconds}};
}

TrainState TrainState::from_json(const nlohmann::json& j) {
  auto integer = [&](const char* key, bool required) -> int64_t {
    if (!j.contains(key)) {
      if (!required) return 0;
      throw std::runtime_error(std::string("training state: missing field '") + key + "'");
    }
    return json_integer(j.at(key), std::string("training state ") + key);
  };
  TrainState s;
  s.step = integer("step", true);
  s.scheduler_step = integer("scheduler_step", true);
  s.param_update_step = integer("param_update_step", true);
  s.skipped_nonfinite = integer("skipped_nonfinite", false);
  s.skipped_gradnorm = integer("skipped_gradnorm", false);
  s.train_seconds = j.value("train_seconds", 0.0);
  return s;
}

std::string checkpoint_name(int64_t step) { return fmt::format("ckpt_{:016d}.safetensors", step); }

std::map<std::string, torch::Tensor> named_trainable_parameters(const torch::nn::Module& module) {
  std::map<std::string, torch::Tensor> out;
  for (const auto& item : module.named_parameters(true))
    if (item.value().requires_grad()) out[item.key()] = item.value();
  return out;
}

io::NamedTensors optimizer_state(torch::optim::AdamW& opt, const torch::nn::Module& module) {
  io::NamedTensors out;
  auto& states = opt.state();
  for (const auto& [name, p] : named_trainable_parameters(module)) {
    auto it = states.find(state_key(states, p));
    if (it == states.end()) continue;  // an optimiser made elsewhere, before its first step
    auto& s = static_cast<torch::optim::AdamWParamState&>(*it->second);
    out["exp_avg/" + name] = s.exp_avg().detach().cpu();
    out["exp_avg_sq/" + name] = s.exp_avg_sq().detach().cpu();
    out["step/" + name] = torch::tensor(static_cast<int64_t>(s.step()), torch::kInt64);
  }
  return out;
}

void restore_optimizer_state(torch::optim::AdamW& opt, const torch::nn::Module& module, const io::NamedTensors& state,
                             const std::string& source) {
  auto& states = opt.state();
  int64_t restored = 0;
  for (const auto& [name, p] : named_trainable_parameters(module)) {
    auto m = state.find("exp_avg/" + name), v = state.find("exp_avg_sq/" + name), s = state.find("step/" + name);
    if (m == state.end() || v == state.end() || s == state.end()) continue;
    if (m->second.sizes() != p.sizes() || v->second.sizes() != p.sizes())
      throw std::runtime_error(fmt::format("{}: optimiser state of '{}' has shape [{}] but the parameter is [{}]",
                                           source, name, fmt::join(m->second.sizes(), ","), fmt::join(p.sizes(), ",")));
    auto ps = std::make_unique<torch::optim::AdamWParamState>();
    ps->step(s->second.item<int64_t>());
    ps->exp_avg(m->second.to(p.options()).clone());
    ps->exp_avg_sq(v->second.to(p.options()).clone());
    states[state_key(states, p)] = std::move(ps);
    ++restored;
  }
  if (restored == 0 && !state.empty())
    throw std::runtime_error(fmt::format("{}: optimiser state matches no parameter of the model", source));
}

std::string save_training_checkpoint(const std::string& dir, const Config& config, const TrainState& state,
                                     torch::nn::Module& module, torch::optim::AdamW& opt, int64_t keep) {
  fs::create_directories(dir);
  auto path = (fs::path(dir) / checkpoint_name(state.step)).string();
  io::write_checkpoint(path, config, state.to_json(), io::state_dict(module), optimizer_state(opt, module));
  const auto all = training_checkpoints(dir);
  for (size_t i = 0; keep > 0 && i + static_cast<size_t>(keep) < all.size(); ++i) fs::remove(all[i]);
  return path;
}

std::vector<std::string> training_checkpoints(const std::string& dir) {
  std::vector<std::string> all;
  if (!fs::is_directory(dir)) return all;
  for (const auto& e : fs::directory_iterator(dir)) {
    auto name = e.path().filename().string();
    if (e.is_regular_file() && name.rfind("ckpt_", 0) == 0 && e.path().extension() == ".safetensors")
      all.push_back(e.path().string());
  }
  std::sort(all.begin(), all.end());  // zero-padded steps: name order is step order
  return all;
}

std::optional<io::CheckpointFile> read_newest_valid_checkpoint(const std::string& dir) {
  const auto all = training_checkpoints(dir);
  std::string reasons;
  for (auto it = all.rbegin(); it != all.rend(); ++it) {
    try {
      auto ckpt = io::read_checkpoint(*it);
      TrainState::from_json(ckpt.state);
      return ckpt;
    } catch (const std::exception& e) {
      spdlog::warn("checkpoint {} does not read ({}); trying the previous one", *it, e.what());
      reasons += fmt::format("\n  {}: {}", *it, e.what());
    }
  }
  if (all.empty()) return std::nullopt;
  throw std::runtime_error(
      fmt::format("--resume auto: none of the {} checkpoints in {} reads (pass --resume none to "
                  "start over):{}",
                  all.size(), dir, reasons));
}

}  // namespace uplvsm::train
