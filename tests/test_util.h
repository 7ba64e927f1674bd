// Shared helpers for the tests: where the fixtures are, temporary directories, tensor comparison.
#pragma once
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <ftw.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>

#include "uplvsm/core/runtime.h"

namespace uplvsm::test {

inline std::string fixture(const std::string& relative) { return std::string(UPLVSM_FIXTURES) + "/" + relative; }

// Why the reference fixture pack (outside this repository) cannot be used, or nothing when its directory exists.
inline std::optional<std::string> missing_fixtures() {
  if (std::filesystem::is_directory(UPLVSM_FIXTURES)) return std::nullopt;
  return std::string("reference fixture pack not found: ") + UPLVSM_FIXTURES +
         " (configure with -DUPLVSM_FIXTURES=DIR; what it holds and how it is made: docs/development.md, "
         "\"The reference fixture pack\")";
}

// CI runs every test: with CI=true (or 1) or UPLVSM_REQUIRE_FIXTURES=1 a missing pack fails instead of skipping.
inline bool fixtures_required() {
  const char* ci = std::getenv("CI");
  const char* required = std::getenv("UPLVSM_REQUIRE_FIXTURES");
  return (ci && (std::string(ci) == "true" || std::string(ci) == "1")) || (required && std::string(required) == "1");
}

// The first statement of a test (or SetUp) that reads fixture(...).
#define UPLVSM_NEEDS_FIXTURES()                                            \
  do {                                                                     \
    if (const auto uplvsm_missing_ = ::uplvsm::test::missing_fixtures()) { \
      if (::uplvsm::test::fixtures_required()) FAIL() << *uplvsm_missing_; \
      GTEST_SKIP() << *uplvsm_missing_;                                    \
    }                                                                      \
  } while (false)

// Why the OpenBLAS checks do not apply (LibTorch loads no shared BLAS: PyPI's has MKL built in), or nothing. A
// reference libblas.so.3 is a shared BLAS, so the checks still run there and fail.
inline std::optional<std::string> no_shared_blas() {
  const auto info = runtime_info();
  if (!info.blas_config.empty() || info.blas_library != "unknown") return std::nullopt;
  return std::string("LibTorch loads no shared BLAS library (") + (at::hasMKL() ? "MKL is built in" : "none found") +
         "): the OpenBLAS checks apply to LibTorch builds that load OpenBLAS (Debian's)";
}

// Removes `path` and everything under it, like std::filesystem::remove_all, which the tests cannot call: PyPI's
// LibTorch 2.11 (libtorch.so) exports its own copy of it, which binds before libstdc++'s and jumps to address 0
// (seen on a lent H200, 2026-11-27; the library never calls it). POSIX nftw, children first, links not followed; a
// missing path is no error.
inline void remove_tree(const std::filesystem::path& path) {
  const auto remove_entry = [](const char* entry, const struct stat*, int, struct FTW*) { return std::remove(entry); };
  nftw(path.c_str(), remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

// A fresh, empty directory under the system temp dir, unique per test.
inline std::filesystem::path temp_dir(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / ("uplvsm_test_" + name + "_" + std::to_string(::getpid()));
  remove_tree(dir);
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
