#include "uplvsm/train/distributed.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <map>
#include <stdexcept>

// Debian's LibTorch has Gloo but its CMake config does not export the flag that enables the Gloo header. PyPI's
// LibTorch links Gloo in but ships no Gloo headers, and keeps nccl.h in its own package: each backend is compiled
// where its headers are, and a missing one is a clear error at run time.
#if __has_include(<gloo/algorithm.h>)
#define UPLVSM_HAVE_GLOO
#ifndef USE_C10D_GLOO
#define USE_C10D_GLOO
#endif
#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#endif
#include <torch/csrc/distributed/c10d/TCPStore.hpp>
#if defined(USE_C10D_NCCL) && __has_include(<nccl.h>)
#define UPLVSM_HAVE_NCCL
#include <torch/csrc/distributed/c10d/ProcessGroupNCCL.hpp>
#endif

namespace uplvsm::train {
namespace {

// An integer environment variable; `fallback` when unset, an error naming it when malformed or out of range.
int env_int(const char* name, int fallback, int lo, int hi) {
  const char* v = std::getenv(name);
  if (!v || !*v) return fallback;
  char* end = nullptr;
  const long x = std::strtol(v, &end, 10);
  if (*end != '\0' || x < lo || x > hi)
    throw std::runtime_error(
        fmt::format("environment variable {}={}: expected an integer in [{}, {}]", name, v, lo, hi));
  return static_cast<int>(x);
}

bool is_set(const char* name) {
  const char* v = std::getenv(name);
  return v && *v;
}

}  // namespace

DistributedEnv distributed_env_from_environment() {
  DistributedEnv env;
  const bool torchrun = is_set("WORLD_SIZE"), slurm = !torchrun && is_set("SLURM_NTASKS");
  if (!torchrun && !slurm) return env;
  env.world_size = env_int(torchrun ? "WORLD_SIZE" : "SLURM_NTASKS", 1, 1, 1 << 20);
  env.rank = env_int(torchrun ? "RANK" : "SLURM_PROCID", 0, 0, env.world_size - 1);
  env.local_rank = env_int(torchrun ? "LOCAL_RANK" : "SLURM_LOCALID", 0, 0, 1 << 20);
  if (env.world_size > 1 && torchrun && !is_set("RANK"))
    throw std::runtime_error("WORLD_SIZE is set but RANK is not (torchrun sets both)");
  if (const char* addr = std::getenv("MASTER_ADDR"); addr && *addr) env.master_addr = addr;
  env.master_port = env_int("MASTER_PORT", env.master_port, 1, 65535);
  return env;
}

bool gloo_available() {
#ifdef UPLVSM_HAVE_GLOO
  return true;
#else
  return false;
#endif
}

torch::Device rank_device(torch::Device requested, const DistributedEnv& env) {
  if (requested.is_cuda() && !requested.has_index() && env.distributed())
    return torch::Device(torch::kCUDA, static_cast<c10::DeviceIndex>(env.local_rank));
  return requested;
}

struct Communicator::Impl {
  c10::intrusive_ptr<c10d::Store> store;
  // The group's collectives, bound to its concrete type (LibTorch 2.x made the backends separate classes).
  std::function<c10::intrusive_ptr<c10d::Work>(std::vector<at::Tensor>&, const c10d::AllreduceOptions&)> allreduce;
  std::function<c10::intrusive_ptr<c10d::Work>(std::vector<at::Tensor>&, const c10d::BroadcastOptions&)> broadcast;
  std::function<c10::intrusive_ptr<c10d::Work>()> barrier;
  std::shared_ptr<void> keep_alive;
};

namespace {

template <class Group>
void bind_group(Communicator::Impl& impl, c10::intrusive_ptr<Group> group) {
  impl.allreduce = [group](std::vector<at::Tensor>& t, const c10d::AllreduceOptions& o) {
    return group->allreduce(t, o);
  };
  impl.broadcast = [group](std::vector<at::Tensor>& t, const c10d::BroadcastOptions& o) {
    return group->broadcast(t, o);
  };
  impl.barrier = [group] { return group->barrier(); };
}

#ifdef UPLVSM_HAVE_GLOO
std::shared_ptr<::gloo::transport::Device> gloo_device(const DistributedEnv& env) {
  if (const char* ifname = std::getenv("GLOO_SOCKET_IFNAME"); ifname && *ifname)
    return c10d::ProcessGroupGloo::createDeviceForInterface(ifname);
  // Single-host runs on loopback bind there; otherwise the host's own address (as torch.distributed does).
  if (env.master_addr == "localhost" || env.master_addr.rfind("127.", 0) == 0)
    return c10d::ProcessGroupGloo::createDeviceForHostname(env.master_addr);
  return c10d::ProcessGroupGloo::createDefaultDevice();
}
#endif

}  // namespace

Communicator::Communicator(const DistributedEnv& env, torch::Device device, std::chrono::seconds timeout)
    : impl_(std::make_unique<Impl>()), env_(env), device_(device) {
  c10d::TCPStoreOptions store_opt;
  store_opt.port = static_cast<std::uint16_t>(env.master_port);
  store_opt.isServer = env.rank == 0;
  store_opt.numWorkers = static_cast<std::size_t>(env.world_size);
  store_opt.timeout = timeout;
  try {
    impl_->store = c10::make_intrusive<c10d::TCPStore>(env.master_addr, store_opt);
  } catch (const std::exception& e) {
    throw std::runtime_error(fmt::format("rank {}: cannot join the TCPStore at {}:{} (MASTER_ADDR/MASTER_PORT): {}",
                                         env.rank, env.master_addr, env.master_port, e.what()));
  }
  if (device.is_cuda()) {
#ifdef UPLVSM_HAVE_NCCL
    auto opts = c10d::ProcessGroupNCCL::Options::create();
    opts->timeout = timeout;
    bind_group(*impl_, c10::make_intrusive<c10d::ProcessGroupNCCL>(impl_->store, env.rank, env.world_size, opts));
    backend_ = "nccl";
#else
    throw std::runtime_error(
        "multi-process training on CUDA needs a LibTorch built with NCCL (USE_C10D_NCCL) and "
        "nccl.h on the include path; this uplvsm was built without them");
#endif
  } else {
#ifdef UPLVSM_HAVE_GLOO
    auto opts = c10d::ProcessGroupGloo::Options::create(timeout);
    opts->devices.push_back(gloo_device(env));
    bind_group(*impl_, c10::make_intrusive<c10d::ProcessGroupGloo>(impl_->store, env.rank, env.world_size, opts));
    backend_ = "gloo";
#else
    throw std::runtime_error(
        "multi-process training on the CPU needs Gloo's headers (Debian: libgloo-dev); this "
        "uplvsm was built against a LibTorch without them");
#endif
  }
  spdlog::info("rank {}/{} joined {}:{} ({}, local rank {})", env.rank, env.world_size, env.master_addr,
               env.master_port, backend_, env.local_rank);
}

Communicator::~Communicator() = default;

void Communicator::allreduce_sum(const std::vector<torch::Tensor>& tensors) {
  if (tensors.empty()) return;
  torch::NoGradGuard no_grad;
  // One collective per dtype over a flat buffer: far fewer round trips than one per tensor.
  std::map<c10::ScalarType, std::vector<torch::Tensor>> by_type;
  for (const auto& t : tensors) by_type[t.scalar_type()].push_back(t);
  for (auto& [type, group] : by_type) {
    std::vector<torch::Tensor> flat_parts;
    for (const auto& t : group) flat_parts.push_back(t.reshape({-1}));
    std::vector<at::Tensor> buffer = {torch::cat(flat_parts)};
    c10d::AllreduceOptions opt;
    opt.reduceOp = c10d::ReduceOp::SUM;
    impl_->allreduce(buffer, opt)->wait();
    int64_t offset = 0;
    for (auto& t : group) {
      t.copy_(buffer[0].narrow(0, offset, t.numel()).view_as(t));
      offset += t.numel();
    }
  }
}

std::vector<std::string> Communicator::all_gather(const std::string& mine) {
  // Sizes, then the bytes, each through a sum where only the owner's slots are non-zero.
  auto sizes = torch::zeros({env_.world_size}, torch::TensorOptions().dtype(torch::kInt64).device(device_));
  sizes[env_.rank] = static_cast<int64_t>(mine.size());
  allreduce_sum({sizes});
  auto sizes_cpu = sizes.cpu();
  std::vector<int64_t> offsets(env_.world_size + 1, 0);
  for (int r = 0; r < env_.world_size; ++r) offsets[r + 1] = offsets[r] + sizes_cpu[r].item<int64_t>();
  auto bytes = torch::zeros({std::max<int64_t>(1, offsets.back())}, torch::kInt32);
  int32_t* slot = bytes.data_ptr<int32_t>() + offsets[env_.rank];
  for (size_t i = 0; i < mine.size(); ++i) slot[i] = static_cast<unsigned char>(mine[i]);
  auto shared = bytes.to(device_);
  allreduce_sum({shared});
  auto all = shared.cpu().contiguous();
  const int32_t* data = all.data_ptr<int32_t>();
  std::vector<std::string> out;
  for (int r = 0; r < env_.world_size; ++r) {
    std::string s(static_cast<size_t>(offsets[r + 1] - offsets[r]), '\0');
    for (size_t i = 0; i < s.size(); ++i) s[i] = static_cast<char>(data[offsets[r] + static_cast<int64_t>(i)]);
    out.push_back(std::move(s));
  }
  return out;
}

void Communicator::allreduce_max(torch::Tensor& tensor) {
  std::vector<at::Tensor> buffer = {tensor.to(device_).contiguous()};
  c10d::AllreduceOptions opt;
  opt.reduceOp = c10d::ReduceOp::MAX;
  impl_->allreduce(buffer, opt)->wait();
  tensor.copy_(buffer[0]);
}

void Communicator::broadcast(const std::vector<torch::Tensor>& tensors, int root) {
  torch::NoGradGuard no_grad;
  for (const auto& t : tensors) {
    std::vector<at::Tensor> buffer = {t.contiguous()};
    c10d::BroadcastOptions opt;
    opt.rootRank = root;
    impl_->broadcast(buffer, opt)->wait();
    if (!buffer[0].is_same(t)) t.copy_(buffer[0]);
  }
}

void Communicator::barrier() { impl_->barrier()->wait(); }

void average_gradients(Communicator& comm, const std::vector<torch::Tensor>& params) {
  std::vector<torch::Tensor> grads;
  for (const auto& p : params) {
    if (!p.grad().defined()) p.mutable_grad() = torch::zeros_like(p);
    grads.push_back(p.grad());
  }
  torch::NoGradGuard no_grad;
  comm.allreduce_sum(grads);
  for (auto& g : grads) g.div_(static_cast<double>(comm.world_size()));
}

void check_parameters_in_sync(Communicator& comm, const std::vector<torch::Tensor>& params) {
  torch::NoGradGuard no_grad;
  double sum = 0, sq = 0;
  for (const auto& p : params) {
    auto d = p.detach().to(torch::kCPU, torch::kFloat64);
    sum += d.sum().item<double>();
    sq += d.pow(2).sum().item<double>();
  }
  // max(x) and max(-x) over ranks: equal on every rank iff max == min.
  auto mine = torch::tensor({sum, -sum, sq, -sq}, torch::kFloat64);
  auto all = mine.clone();
  comm.allreduce_max(all);
  auto a = all.accessor<double, 1>();
  if (a[0] != -a[1] || a[2] != -a[3])
    throw std::runtime_error(
        fmt::format("rank {}: parameters differ across ranks (sum in [{}, {}], sum of squares in "
                    "[{}, {}])",
                    comm.rank(), -a[1], a[0], -a[3], a[2]));
}

}  // namespace uplvsm::train
