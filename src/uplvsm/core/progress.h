// A terminal progress bar with rate, ETA and free-form fields (loss, PSNR, ...). On a TTY it redraws one line;
// in logs (CI) it prints a line every 10% or 30 s so a run's progress stays readable.
#pragma once
#include <chrono>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace uplvsm {

class ProgressBar {
 public:
  ProgressBar(std::string label, int64_t total, std::string unit = "it", int64_t start = 0);
  ~ProgressBar();
  void update(int64_t done, const std::vector<std::pair<std::string, std::string>>& fields = {});
  void finish();

 private:
  void draw(bool final_line);
  std::string label_, unit_;
  int64_t total_, start_, done_;
  std::vector<std::pair<std::string, std::string>> fields_;
  std::chrono::steady_clock::time_point t0_, last_draw_;
  int64_t last_logged_decile_ = -1;
  bool tty_, finished_ = false;
};

std::string format_duration(double seconds);

}  // namespace uplvsm
