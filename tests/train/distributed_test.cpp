// Data-parallel training on c10d/Gloo: the launch variables, and two `uplvsm train` processes on loopback that end
// with identical weights equal to one process training on the combined batch.
#include "uplvsm/train/distributed.h"

#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <optional>

#include "train_test_util.h"
#include "uplvsm/io/checkpoint_io.h"

using namespace uplvsm;
namespace fs = std::filesystem;

namespace {

// Sets the variables for the scope and restores the previous environment afterwards.
struct ScopedEnv {
  explicit ScopedEnv(std::vector<std::pair<std::string, std::string>> vars) {
    for (const char* name : {"RANK", "WORLD_SIZE", "LOCAL_RANK", "MASTER_ADDR", "MASTER_PORT", "SLURM_PROCID",
                             "SLURM_NTASKS", "SLURM_LOCALID"}) {
      const char* old = std::getenv(name);
      saved.emplace_back(name, old ? std::optional<std::string>(old) : std::nullopt);
      unsetenv(name);
    }
    for (const auto& [k, v] : vars) setenv(k.c_str(), v.c_str(), 1);
  }
  ~ScopedEnv() {
    for (const auto& [k, v] : saved) v ? setenv(k.c_str(), v->c_str(), 1) : unsetenv(k.c_str());
  }
  std::vector<std::pair<std::string, std::optional<std::string>>> saved;
};

int free_loopback_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
  socklen_t len = sizeof(addr);
  getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  close(fd);
  return ntohs(addr.sin_port);
}

std::string read_text(const fs::path& path) {
  std::ifstream f(path);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

std::vector<double> logged_losses(const fs::path& run) {
  std::vector<double> out;
  std::ifstream in(run / "metrics.jsonl");
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) out.push_back(nlohmann::json::parse(line).at("loss").get<double>());
  return out;
}

}  // namespace

TEST(Distributed, EnvironmentVariables) {
  {
    ScopedEnv env({});
    auto e = train::distributed_env_from_environment();
    EXPECT_FALSE(e.distributed());
    EXPECT_EQ(e.rank, 0);
  }
  {
    ScopedEnv env({{"RANK", "1"},
                   {"WORLD_SIZE", "2"},
                   {"LOCAL_RANK", "1"},
                   {"MASTER_ADDR", "10.0.0.5"},
                   {"MASTER_PORT", "1234"}});
    auto e = train::distributed_env_from_environment();
    EXPECT_TRUE(e.distributed());
    EXPECT_EQ(e.rank, 1);
    EXPECT_EQ(e.local_rank, 1);
    EXPECT_EQ(e.master_addr, "10.0.0.5");
    EXPECT_EQ(e.master_port, 1234);
    EXPECT_EQ(train::rank_device(torch::Device("cuda"), e), torch::Device("cuda:1"));
    EXPECT_EQ(train::rank_device(torch::kCPU, e), torch::Device(torch::kCPU));
  }
  {
    ScopedEnv env({{"SLURM_PROCID", "3"}, {"SLURM_NTASKS", "4"}, {"SLURM_LOCALID", "0"}});
    auto e = train::distributed_env_from_environment();
    EXPECT_EQ(e.rank, 3);
    EXPECT_EQ(e.world_size, 4);
  }
  {
    ScopedEnv env({{"RANK", "2"}, {"WORLD_SIZE", "2"}});
    auto err = test::error_of([] { train::distributed_env_from_environment(); });
    EXPECT_NE(err.find("RANK=2"), std::string::npos) << err;
  }
  {
    ScopedEnv env({{"RANK", "0"}, {"WORLD_SIZE", "2"}, {"MASTER_PORT", "http"}});
    auto err = test::error_of([] { train::distributed_env_from_environment(); });
    EXPECT_NE(err.find("MASTER_PORT=http"), std::string::npos) << err;
  }
}

TEST(Distributed, TwoGlooRanksMatchOneProcessWithTheCombinedBatch) {
  if (!train::gloo_available()) GTEST_SKIP() << "uplvsm was built without Gloo (no Gloo headers beside LibTorch)";
  const auto dir = test::temp_dir("distributed");
  auto config = test::micro_config();
  config.training.train_steps = 4;
  config.training.batch_size = 2;  // per rank
  std::ofstream(dir / "rank_config.json") << config_to_json(config).dump(2);
  config.training.batch_size = 4;
  std::ofstream(dir / "single_config.json") << config_to_json(config).dump(2);
  const std::string cli = UPLVSM_CLI, data = test::micro_dataset();
  auto train_cmd = [&](const std::string& cfg, const fs::path& run) {
    return cli + " train --device cpu --threads 1 --config " + (dir / cfg).string() + " --data " + data + " --run " +
           run.string();
  };
  const int port = free_loopback_port();
  std::string script;
  for (int rank = 0; rank < 2; ++rank)
    script += "RANK=" + std::to_string(rank) + " LOCAL_RANK=" + std::to_string(rank) +
              " WORLD_SIZE=2 MASTER_ADDR=127.0.0.1 MASTER_PORT=" + std::to_string(port) + " " +
              train_cmd("rank_config.json", dir / "dp") + " > " +
              (dir / ("rank" + std::to_string(rank) + ".log")).string() + " 2>&1 & p" + std::to_string(rank) + "=$!; ";
  script += "wait $p0; r0=$?; wait $p1; r1=$?; exit $((r0 | r1))";
  const int rc = std::system(("bash -c '" + script + "'").c_str());
  const auto log0 = read_text(dir / "rank0.log"), log1 = read_text(dir / "rank1.log");
  ASSERT_EQ(rc, 0) << "rank 0:\n" << log0 << "\nrank 1:\n" << log1;
  for (const auto& log : {log0, log1})
    EXPECT_NE(log.find("parameters identical on all 2 ranks"), std::string::npos) << log;

  ASSERT_EQ(
      std::system(
          (train_cmd("single_config.json", dir / "single") + " > " + (dir / "single.log").string() + " 2>&1").c_str()),
      0)
      << read_text(dir / "single.log");
  // Same samples per step (the loader keys samples by global index), so the same losses and weights up to float
  // summation order.
  auto dp = logged_losses(dir / "dp"), single = logged_losses(dir / "single");
  ASSERT_EQ(dp.size(), 4u);
  ASSERT_EQ(single.size(), 4u);
  for (size_t i = 0; i < dp.size(); ++i) EXPECT_NEAR(dp[i], single[i], 1e-5 * single[i]) << "step " << i + 1;
  auto a = io::read_checkpoint((dir / "dp").string()).model, b = io::read_checkpoint((dir / "single").string()).model;
  ASSERT_EQ(a.size(), b.size());
  double diff = 0, norm = 0;
  for (const auto& [k, v] : a) {
    diff += (v - b.at(k)).to(torch::kFloat64).pow(2).sum().item<double>();
    norm += v.to(torch::kFloat64).pow(2).sum().item<double>();
  }
  EXPECT_LT(std::sqrt(diff / norm), 1e-4) << "relative L2 difference of the weights";
  if (!std::getenv("UPLVSM_KEEP_TEST_OUTPUT")) test::remove_tree(dir);
}

TEST(Distributed, TwoGlooEvalShardsMergeToTheSingleProcessResults) {
  if (!train::gloo_available()) GTEST_SKIP() << "uplvsm was built without Gloo (no Gloo headers beside LibTorch)";
  const auto dir = test::temp_dir("distributed_eval");
  auto config = test::micro_config();
  config.training.train_steps = 2;
  std::ofstream(dir / "config.json") << config_to_json(config).dump(2);
  const std::string cli = UPLVSM_CLI, data = test::micro_dataset();
  ASSERT_EQ(std::system((cli + " train --threads 1 --config " + (dir / "config.json").string() + " --data " + data +
                         " --run " + (dir / "run").string() + " > " + (dir / "train.log").string() + " 2>&1")
                            .c_str()),
            0)
      << read_text(dir / "train.log");
  auto eval_cmd = [&](const fs::path& out) {
    return cli + " eval --device cpu --threads 1 --batch 1 --checkpoint " + (dir / "run").string() + " --data " + data +
           " --out " + out.string();
  };
  const int port = free_loopback_port();
  std::string script;
  for (int rank = 0; rank < 2; ++rank)
    script += "RANK=" + std::to_string(rank) + " LOCAL_RANK=" + std::to_string(rank) +
              " WORLD_SIZE=2 MASTER_ADDR=127.0.0.1 MASTER_PORT=" + std::to_string(port) + " " + eval_cmd(dir / "dp") +
              " > " + (dir / ("eval" + std::to_string(rank) + ".log")).string() + " 2>&1 & p" + std::to_string(rank) +
              "=$!; ";
  script += "wait $p0; r0=$?; wait $p1; r1=$?; exit $((r0 | r1))";
  const int rc = std::system(("bash -c '" + script + "'").c_str());
  ASSERT_EQ(rc, 0) << read_text(dir / "eval0.log") << "\n" << read_text(dir / "eval1.log");
  ASSERT_EQ(std::system((eval_cmd(dir / "single") + " > " + (dir / "single.log").string() + " 2>&1").c_str()), 0)
      << read_text(dir / "single.log");
  // Each scene is scored by one rank; the merged per-scene rows and means equal one process's.
  EXPECT_EQ(read_text(dir / "dp/per_scene.csv"), read_text(dir / "single/per_scene.csv"));
  EXPECT_EQ(read_text(dir / "dp/per_view.csv"), read_text(dir / "single/per_view.csv"));
  auto a = nlohmann::json::parse(read_text(dir / "dp/metrics.json"));
  auto b = nlohmann::json::parse(read_text(dir / "single/metrics.json"));
  EXPECT_EQ(a.at("scenes"), b.at("scenes"));
  EXPECT_EQ(a.at("table"), b.at("table"));
  EXPECT_NE(read_text(dir / "eval0.log").find("evaluated"), std::string::npos);
  EXPECT_EQ(read_text(dir / "eval1.log").find("evaluated"), std::string::npos);  // only rank 0 reports
  if (!std::getenv("UPLVSM_KEEP_TEST_OUTPUT")) test::remove_tree(dir);
}
