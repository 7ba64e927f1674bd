// Shared helpers for the tests: where the fixtures are, temporary directories, tensor comparison.
#pragma once
#include <torch/torch.h>

#include <filesystem>
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
