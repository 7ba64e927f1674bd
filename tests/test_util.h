// Shared helpers for the tests: where the fixtures are, temporary directories, tensor comparison.
#pragma once
#include <torch/torch.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

namespace uplvsm::test {

inline std::string fixture(const std::string& relative) { return std::string(UPLVSM_FIXTURES) + "/" + relative; }

// A fresh, empty directory under the system temp dir, unique per test.
inline std::filesystem::path temp_dir(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / ("uplvsm_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// Runs the uplvsm binary with `args` (stderr merged); returns its exit status, the output in *out. A failing run
// prints its command and output, so a test's failure shows why.
inline int run_cli(const std::string& args, std::string* out = nullptr) {
  const std::string cmd = std::string(UPLVSM_CLI) + " " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  char buf[4096];
  size_t n;
  std::string text;
  while ((n = fread(buf, 1, sizeof(buf), pipe)) > 0) text.append(buf, n);
  if (out) *out = text;
  const int status = pclose(pipe);
  if (status != 0) std::cerr << cmd << "\n" << text;
  return status;
}

// The message of the exception f() throws, or "(no exception)".
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

inline double max_abs_diff(const torch::Tensor& a, const torch::Tensor& b) {
  return (a.to(torch::kFloat64) - b.to(torch::kFloat64)).abs().max().item<double>();
}

}  // namespace uplvsm::test
