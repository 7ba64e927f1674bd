#include "uplvsm/io/state_dict.h"

#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm::io {

namespace {
std::string shape_str(at::IntArrayRef s) { return fmt::format("[{}]", fmt::join(s, ", ")); }

bool has_prefix(const std::string& key, const std::vector<std::string>& prefixes) {
  for (const auto& p : prefixes)
    if (key.rfind(p, 0) == 0) return true;
  return false;
}

bool contains_any(const std::string& key, const std::vector<std::string>& parts) {
  for (const auto& p : parts)
    if (key.find(p) != std::string::npos) return true;
  return false;
}

std::string list(const std::vector<std::string>& items, size_t max_items = 20) {
  std::string out;
  for (size_t i = 0; i < items.size() && i < max_items; ++i) out += "\n    " + items[i];
  if (items.size() > max_items) out += fmt::format("\n    ... and {} more", items.size() - max_items);
  return out;
}
}  // namespace

std::string LoadReport::summary(const std::string& source) const {
  std::string s = fmt::format("{}: loaded {} tensors", source, loaded);
  if (!skipped.empty()) s += fmt::format(", skipped {} known extra tensors (e.g. {})", skipped.size(), skipped.front());
  if (!defaulted.empty())
    s += fmt::format("\n  {} keys not in the file, left at their initial values:{}", defaulted.size(), list(defaulted));
  if (!missing.empty())
    s += fmt::format("\n  {} missing keys (in the model, not in the file):{}", missing.size(), list(missing));
  if (!unexpected.empty())
    s += fmt::format("\n  {} unexpected keys (in the file, not in the model):{}", unexpected.size(), list(unexpected));
  if (!mismatched.empty()) s += fmt::format("\n  {} keys with the wrong shape:{}", mismatched.size(), list(mismatched));
  return s;
}

NamedTensors state_dict(const torch::nn::Module& module) {
  NamedTensors out;
  for (const auto& item : module.named_parameters(true)) out[item.key()] = item.value().detach().cpu();
  for (const auto& item : module.named_buffers(true)) out[item.key()] = item.value().detach().cpu();
  return out;
}

LoadReport load_state_dict(torch::nn::Module& module, const NamedTensors& tensors, const std::string& source,
                           const LoadOptions& options) {
  LoadReport report;
  std::map<std::string, torch::Tensor> targets;
  for (const auto& item : module.named_parameters(true)) targets[item.key()] = item.value();
  for (const auto& item : module.named_buffers(true)) targets[item.key()] = item.value();
  torch::NoGradGuard no_grad;
  for (const auto& [key, value] : tensors) {
    if (has_prefix(key, options.skip_prefixes)) {
      report.skipped.push_back(key);
      continue;
    }
    auto it = targets.find(key);
    if (it == targets.end()) {
      report.unexpected.push_back(key);
      continue;
    }
    if (it->second.sizes() != value.sizes()) {
      report.mismatched.push_back(
          fmt::format("{}: file {} vs model {}", key, shape_str(value.sizes()), shape_str(it->second.sizes())));
      continue;
    }
    if (value.is_floating_point() && !torch::isfinite(value).all().item<bool>())
      throw std::runtime_error(fmt::format("{}: tensor '{}' contains NaN or Inf", source, key));
    it->second.copy_(value.to(it->second.dtype()));
    ++report.loaded;
  }
  for (const auto& [key, value] : targets)
    if (!tensors.count(key))
      (contains_any(key, options.allow_missing_substrings) ? report.defaulted : report.missing).push_back(key);
  if (options.strict && !report.ok()) throw std::runtime_error(report.summary(source));
  return report;
}

bool has_key(const NamedTensors& t, const std::string& key) { return t.count(key) > 0; }

bool any_prefix(const NamedTensors& t, const std::string& prefix) {
  auto it = t.lower_bound(prefix);
  return it != t.end() && it->first.rfind(prefix, 0) == 0;
}

int64_t count_indexed(const NamedTensors& t, const std::string& prefix) {
  int64_t n = 0;
  while (any_prefix(t, fmt::format("{}{}.", prefix, n))) ++n;
  return n;
}

}  // namespace uplvsm::io
