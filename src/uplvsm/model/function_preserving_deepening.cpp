#include "uplvsm/model/function_preserving_deepening.h"

#include <fmt/format.h>

#include <map>
#include <set>

#include "uplvsm/model/transformer.h"

namespace uplvsm::model {
namespace {

// How many of the block's parameters and buffers `tensors` holds, and how many it has.
std::pair<size_t, size_t> keys_held(const torch::nn::Module& block, const std::string& name,
                                    const NamedTensors& tensors) {
  size_t held = 0, total = 0;
  auto count = [&](const std::string& key) {
    ++total;
    held += tensors.count(name + "." + key);
  };
  for (const auto& p : block.named_parameters()) count(p.key());
  for (const auto& b : block.named_buffers()) count(b.key());
  return {held, total};
}

// "a.b.3" -> {"a.b", 3}; a block that is not a numbered child of a stack gets index -1.
std::pair<std::string, int64_t> stack_and_index(const std::string& name) {
  const auto dot = name.rfind('.');
  const std::string last = dot == std::string::npos ? name : name.substr(dot + 1);
  if (last.empty() || last.find_first_not_of("0123456789") != std::string::npos) return {name, -1};
  return {dot == std::string::npos ? "" : name.substr(0, dot), std::stoll(last)};
}

}  // namespace

std::vector<std::string> blocks_absent_from(const torch::nn::Module& net, const NamedTensors& tensors,
                                            const std::string& source) {
  std::vector<std::string> absent;
  std::map<std::string, int64_t> last_held;  // per stack: the highest block index the file holds
  for (const auto& item : net.named_modules("", /*include_self=*/false)) {
    if (!dynamic_cast<const TransformerBlockImpl*>(item.value().get())) continue;
    const auto [held, total] = keys_held(*item.value(), item.key(), tensors);
    if (held > 0 && held < total)
      throw std::runtime_error(fmt::format("{}: transformer block {} is only partly in the file ({} of {} tensors)",
                                           source, item.key(), held, total));
    const auto [stack, index] = stack_and_index(item.key());
    if (held == 0)
      absent.push_back(item.key());
    else
      last_held[stack] = std::max(last_held.count(stack) ? last_held[stack] : -1, index);
  }
  for (const auto& name : absent) {
    const auto [stack, index] = stack_and_index(name);
    if (index < 0)
      throw std::runtime_error(fmt::format(
          "{}: transformer block {} is absent from the file and not a numbered block of a stack", source, name));
    if (last_held.count(stack) && last_held[stack] > index)
      throw std::runtime_error(fmt::format(
          "{}: transformer block {} is absent from the file but a later block of its stack is in it; only blocks "
          "appended after the file's blocks can start as the identity",
          source, name));
  }
  return absent;
}

void make_blocks_identity(torch::nn::Module& net, const std::vector<std::string>& block_names) {
  const std::set<std::string> wanted(block_names.begin(), block_names.end());
  torch::NoGradGuard no_grad;
  size_t done = 0;
  for (const auto& item : net.named_modules("", /*include_self=*/false)) {
    if (!wanted.count(item.key())) continue;
    auto* block = dynamic_cast<TransformerBlockImpl*>(item.value().get());
    if (!block)
      throw std::runtime_error(fmt::format("make_blocks_identity: {} is not a transformer block", item.key()));
    auto* fc2 = block->mlp->mlp[2]->as<torch::nn::LinearImpl>();
    for (torch::nn::LinearImpl* out : {static_cast<torch::nn::LinearImpl*>(block->attn->fc.get()), fc2}) {
      out->weight.zero_();
      if (out->bias.defined()) out->bias.zero_();
    }
    ++done;
  }
  if (done != wanted.size())
    throw std::runtime_error(fmt::format("make_blocks_identity: {} of {} named blocks found", done, wanted.size()));
}

}  // namespace uplvsm::model
