// A terminal progress bar with rate, ETA and free-form fields (loss, PSNR, ...). On a TTY it redraws one line;
// in logs (CI) it prints a line every 10% or 30 s so a run's progress stays readable.
#pragma once
#include <chrono>
#include <cstdint>
#include <deque>
#include <string>
#include <utility>
#include <vector>

namespace uplvsm {

// Items per second over about the last `window_seconds` of samples (the whole run until it spans that long), so the
// rate and ETA follow a run that slows or speeds up (a neighbour's load, a pause, a warm-up) instead of its average.
struct RecentRate {
  double window_seconds = 60.0;
  std::deque<std::pair<double, int64_t>> samples;  // (seconds, items done), oldest first
  void add(double seconds, int64_t done);
  double per_second() const;  // 0 until two samples lie apart in time
};

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
  RecentRate recent_;
  int64_t last_logged_decile_ = -1;
  bool tty_, finished_ = false;
};

std::string format_duration(double seconds);

}  // namespace uplvsm
