// Evaluation index files: pixelSplat's {key: {context:[i,j], target:[...]} | null} and the NoPoSplat / official
// UP-LVSM variant with an "overlap" per entry, plus NoPoSplat's overlap buckets (small / medium / large).
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace uplvsm::data {

struct EvalEntry {
  std::string key;
  std::vector<int64_t> context, target;  // frame indices in the scene's chunk order, as in the file
  std::optional<double> overlap;
};

// Reads an index; null entries (scenes without evaluation views) are skipped and counted in *num_null when given.
// Entries are sorted by key (JSON object order is not meaningful). Throws naming the file and key for malformed
// entries (missing/empty context or target, negative or non-integer frames, non-numeric overlap).
std::vector<EvalEntry> read_eval_index(const std::string& path, int64_t* num_null = nullptr);

// Writes {key: {"context": [...], "target": [...], "overlap": o?}} atomically (keys sorted).
void write_eval_index(const std::string& path, const std::vector<EvalEntry>& entries);

// NoPoSplat's get_overlap_tag, tests applied in this order: 0.05 <= o <= 0.3 "small"; o <= 0.55 "medium" (so
// o < 0.05 is "medium" too); o <= 0.8 "large"; otherwise "ignore".
std::string overlap_bucket(double overlap);

}  // namespace uplvsm::data
