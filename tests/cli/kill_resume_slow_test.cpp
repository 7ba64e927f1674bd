// A training process killed with SIGKILL (no chance to checkpoint) and restarted with --resume auto continues from
// its last checkpoint and logs exactly the loss curve of an uninterrupted run.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>

#include "train/train_test_util.h"

namespace fs = std::filesystem;

namespace {
// Starts `uplvsm train ...` as a child process with its output in `log`.
pid_t start_training(const std::string& cfg, const std::string& data, const std::string& run, const std::string& log) {
  pid_t pid = fork();
  if (pid == 0) {
    FILE* f = freopen(log.c_str(), "w", stdout);
    (void)f;
    dup2(fileno(stdout), fileno(stderr));
    execl(UPLVSM_CLI, UPLVSM_CLI, "train", "--config", cfg.c_str(), "--data", data.c_str(), "--run", run.c_str(),
          "--resume", "auto", static_cast<char*>(nullptr));
    _exit(127);
  }
  return pid;
}

int wait_exit(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

std::vector<std::pair<int64_t, double>> loss_curve(const std::string& run) {
  std::vector<std::pair<int64_t, double>> out;
  std::ifstream in(fs::path(run) / "metrics.jsonl");
  std::string line;
  while (std::getline(in, line))
    if (!line.empty()) {
      auto j = nlohmann::json::parse(line);
      if (j.contains("loss")) out.emplace_back(j.at("step").get<int64_t>(), j.at("loss").get<double>());
    }
  return out;
}

size_t lines_in(const fs::path& path) {
  std::ifstream in(path);
  return static_cast<size_t>(std::count(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>(), '\n'));
}
}  // namespace

TEST(KillResume, SigkillThenResumeAutoReproducesTheUninterruptedLossCurve) {
  auto dir = uplvsm::test::temp_dir("kill_resume");
  auto config = uplvsm::test::micro_config();
  config.training.train_steps = 120;
  config.training.checkpoint_every = 25;
  const auto cfg = (dir / "micro.json").string();
  std::ofstream(cfg) << uplvsm::config_to_json(config).dump(2);
  const auto data = uplvsm::test::micro_dataset();

  const auto straight = (dir / "straight").string();
  ASSERT_EQ(wait_exit(start_training(cfg, data, straight, (dir / "straight.log").string())), 0);
  const auto expected = loss_curve(straight);
  ASSERT_EQ(expected.size(), 120u);

  // Kill once the run is past its first checkpoint and between two others.
  const auto killed = (dir / "killed").string();
  pid_t pid = start_training(cfg, data, killed, (dir / "killed_1.log").string());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(5);
  while (lines_in(fs::path(killed) / "metrics.jsonl") < 60 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  kill(pid, SIGKILL);
  const int status = wait_exit(pid);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the run ended before it could be killed";
  const auto before = loss_curve(killed);
  ASSERT_GE(before.size(), 60u);
  ASSERT_LT(before.size(), 120u);

  ASSERT_EQ(wait_exit(start_training(cfg, data, killed, (dir / "killed_2.log").string())), 0);
  std::ifstream log(dir / "killed_2.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("resumed from"), std::string::npos) << text;
  EXPECT_EQ(loss_curve(killed), expected);  // lines past the checkpoint were dropped and redone identically
}
