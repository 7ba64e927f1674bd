// A training process killed with SIGKILL (no chance to checkpoint) and restarted with --resume auto continues from
// its last checkpoint and logs exactly the loss curve of an uninterrupted run; when the newest checkpoint was damaged
// on top of that (a full disk, an interrupted copy), from the one before it, with the same curve.
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

struct Setup {
  fs::path dir;
  std::string cfg, data;
  std::vector<std::pair<int64_t, double>> expected;  // the uninterrupted run's loss curve
};

// The config, the dataset and the uninterrupted run, shared by the tests of this file.
const Setup& setup() {
  static const Setup s = [] {
    Setup s;
    s.dir = uplvsm::test::temp_dir("kill_resume");
    auto config = uplvsm::test::micro_config();
    config.training.train_steps = 120;
    config.training.checkpoint_every = 25;
    s.cfg = (s.dir / "micro.json").string();
    std::ofstream(s.cfg) << uplvsm::config_to_json(config).dump(2);
    s.data = uplvsm::test::micro_dataset();
    const auto straight = (s.dir / "straight").string();
    EXPECT_EQ(wait_exit(start_training(s.cfg, s.data, straight, (s.dir / "straight.log").string())), 0);
    s.expected = loss_curve(straight);
    return s;
  }();
  return s;
}

// Starts a run and kills it once it is past its second checkpoint (step 50) and before the end.
void start_and_kill(const std::string& run, const std::string& log) {
  const auto& s = setup();
  pid_t pid = start_training(s.cfg, s.data, run, log);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(5);
  while (lines_in(fs::path(run) / "metrics.jsonl") < 60 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  kill(pid, SIGKILL);
  const int status = wait_exit(pid);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the run ended before it could be killed";
  const auto before = loss_curve(run);
  ASSERT_GE(before.size(), 60u);
  ASSERT_LT(before.size(), 120u);
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
}  // namespace

TEST(KillResume, SigkillThenResumeAutoReproducesTheUninterruptedLossCurve) {
  const auto& s = setup();
  ASSERT_EQ(s.expected.size(), 120u);
  const auto killed = (s.dir / "killed").string();
  start_and_kill(killed, (s.dir / "killed_1.log").string());

  ASSERT_EQ(wait_exit(start_training(s.cfg, s.data, killed, (s.dir / "killed_2.log").string())), 0);
  const auto text = read_text(s.dir / "killed_2.log");
  EXPECT_NE(text.find("resumed from"), std::string::npos) << text;
  EXPECT_EQ(loss_curve(killed), s.expected);  // lines past the checkpoint were dropped and redone identically
}

TEST(KillResume, TruncatedNewestCheckpointAfterSigkillResumesFromThePreviousOne) {
  const auto& s = setup();
  ASSERT_EQ(s.expected.size(), 120u);
  const auto run = (s.dir / "damaged").string();
  start_and_kill(run, (s.dir / "damaged_1.log").string());

  const auto ckpts = fs::path(run) / "checkpoints";
  const auto newest = (ckpts / "ckpt_0000000000000050.safetensors").string();
  const auto previous = (ckpts / "ckpt_0000000000000025.safetensors").string();
  ASSERT_TRUE(fs::exists(newest) && fs::exists(previous));
  fs::resize_file(newest, fs::file_size(newest) / 2);

  ASSERT_EQ(wait_exit(start_training(s.cfg, s.data, run, (s.dir / "damaged_2.log").string())), 0);
  const auto text = read_text(s.dir / "damaged_2.log");
  EXPECT_NE(text.find("checkpoint " + newest + " does not read"), std::string::npos) << text;
  EXPECT_NE(text.find("resumed from " + previous + " at step 25"), std::string::npos) << text;
  EXPECT_EQ(loss_curve(run), s.expected);  // steps 26.. redone, identically
}
