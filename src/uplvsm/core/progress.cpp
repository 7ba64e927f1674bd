#include "uplvsm/core/progress.h"

#include <unistd.h>

#include <cstdio>

#include <fmt/format.h>

namespace uplvsm {

std::string format_duration(double s) {
  if (!(s >= 0) || s > 1e7) return "--:--";
  int total = static_cast<int>(s + 0.5);
  if (total >= 3600) return fmt::format("{}:{:02d}:{:02d}", total / 3600, (total / 60) % 60, total % 60);
  return fmt::format("{:02d}:{:02d}", total / 60, total % 60);
}

void RecentRate::add(double seconds, int64_t done) {
  // A sample under half a second after the one before replaces the newest: a fast loop's deque stays short.
  if (samples.size() >= 2 && seconds - samples[samples.size() - 2].first < 0.5)
    samples.back() = {seconds, done};
  else
    samples.emplace_back(seconds, done);
  // The oldest goes while the next is itself a window old: the rate spans a full window once the run has one.
  while (samples.size() > 2 && seconds - samples[1].first >= window_seconds) samples.pop_front();
}

double RecentRate::per_second() const {
  if (samples.size() < 2) return 0.0;
  const double span = samples.back().first - samples.front().first;
  return span > 0 ? static_cast<double>(samples.back().second - samples.front().second) / span : 0.0;
}

ProgressBar::ProgressBar(std::string label, int64_t total, std::string unit, int64_t start)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      start_(start),
      done_(start),
      t0_(std::chrono::steady_clock::now()),
      last_draw_(t0_),
      tty_(isatty(fileno(stderr)) != 0) {
  recent_.add(0.0, start);
}

ProgressBar::~ProgressBar() { finish(); }

void ProgressBar::update(int64_t done, const std::vector<std::pair<std::string, std::string>>& fields) {
  done_ = done;
  if (!fields.empty()) fields_ = fields;
  auto now = std::chrono::steady_clock::now();
  recent_.add(std::chrono::duration<double>(now - t0_).count(), done);
  double since = std::chrono::duration<double>(now - last_draw_).count();
  if (tty_) {
    if (since >= 0.2 || done_ >= total_) draw(false);
  } else {
    int64_t decile = total_ > 0 ? (done_ * 10) / total_ : 0;
    if (decile != last_logged_decile_ || since >= 30.0) {
      last_logged_decile_ = decile;
      draw(false);
    }
  }
}

void ProgressBar::finish() {
  if (finished_) return;
  finished_ = true;
  draw(true);
}

void ProgressBar::draw(bool final_line) {
  auto now = std::chrono::steady_clock::now();
  last_draw_ = now;
  double elapsed = std::chrono::duration<double>(now - t0_).count();
  // The last line reports the whole run's average; the ones before, the recent rate.
  double rate = elapsed > 0 ? static_cast<double>(done_ - start_) / elapsed : 0.0;
  if (!final_line && recent_.per_second() > 0) rate = recent_.per_second();
  double eta = rate > 0 ? static_cast<double>(total_ - done_) / rate : -1.0;
  double frac = total_ > 0 ? static_cast<double>(done_) / static_cast<double>(total_) : 1.0;
  const int width = 24;
  int filled = static_cast<int>(frac * width + 1e-9);
  std::string bar(filled, '#');
  bar.resize(width, '.');
  std::string rate_text = rate >= 1.0 || rate == 0.0 ? fmt::format("{:.2f} {}/s", rate, unit_)
                                                     : fmt::format("{:.2f} s/{}", 1.0 / rate, unit_);
  std::string line = fmt::format("{} [{}] {}/{} {:3.0f}% | {} | {} elapsed, ETA {}", label_, bar, done_, total_,
                                 frac * 100.0, rate_text, format_duration(elapsed), format_duration(eta));
  for (const auto& [k, v] : fields_) line += fmt::format(" | {} {}", k, v);
  if (tty_)
    std::fprintf(stderr, "\r\033[K%s%s", line.c_str(), final_line ? "\n" : "");
  else
    std::fprintf(stderr, "%s\n", line.c_str());
  std::fflush(stderr);
}

}  // namespace uplvsm
