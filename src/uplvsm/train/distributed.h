// Data-parallel training on PyTorch's own collective library (c10d): one process per device, joined through a
// TCPStore at MASTER_ADDR:MASTER_PORT, Gloo on CPU and NCCL on CUDA (when LibTorch was built with it). The launch
// contract is torchrun's (RANK, WORLD_SIZE, LOCAL_RANK, MASTER_ADDR, MASTER_PORT), or SLURM's (SLURM_PROCID,
// SLURM_NTASKS, SLURM_LOCALID) with MASTER_ADDR/MASTER_PORT given.
#pragma once
#include <torch/torch.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace uplvsm::train {

struct DistributedEnv {
  int rank = 0, world_size = 1, local_rank = 0;
  std::string master_addr = "127.0.0.1";
  int master_port = 29500;
  bool distributed() const { return world_size > 1; }
};

// Reads the launch variables; a single process when none are set. Errors name the variable and its value.
DistributedEnv distributed_env_from_environment();

// Whether CPU ranks can join: the Gloo backend is compiled only where Gloo's headers are (PyPI's LibTorch has none).
bool gloo_available();

// The device of this rank: `requested`, except that "cuda" means cuda:LOCAL_RANK for a multi-process run.
torch::Device rank_device(torch::Device requested, const DistributedEnv& env);

class Communicator {
 public:
  // Joins the process group (blocks until every rank has joined or the timeout passes).
  Communicator(const DistributedEnv& env, torch::Device device,
               std::chrono::seconds timeout = std::chrono::seconds(600));
  ~Communicator();

  int rank() const { return env_.rank; }
  int world_size() const { return env_.world_size; }
  const char* backend() const { return backend_; }

  // In-place sum over ranks of every tensor (coalesced into one flat buffer per dtype).
  void allreduce_sum(const std::vector<torch::Tensor>& tensors);
  // Element-wise max over ranks, in place (any device).
  void allreduce_max(torch::Tensor& tensor);
  // Every rank gets rank `root`'s values, in place.
  void broadcast(const std::vector<torch::Tensor>& tensors, int root = 0);
  void barrier();
  // Every rank's string, in rank order, on every rank (results of sharded work, e.g. evaluation).
  std::vector<std::string> all_gather(const std::string& mine);

  struct Impl;  // the backend's process group; public so the .cpp's free helpers can bind it

 private:
  std::unique_ptr<Impl> impl_;
  DistributedEnv env_;
  torch::Device device_;  // where collectives run (NCCL needs CUDA tensors)
  const char* backend_ = "gloo";
};

// Averages the gradients of `params` over ranks (undefined gradients count as zeros and become defined).
void average_gradients(Communicator& comm, const std::vector<torch::Tensor>& params);

// A checksum of the parameters (float64 sum and sum of squares) that differs when any rank's weights drift; throws
// naming the ranks' values when they disagree.
void check_parameters_in_sync(Communicator& comm, const std::vector<torch::Tensor>& params);

}  // namespace uplvsm::train
