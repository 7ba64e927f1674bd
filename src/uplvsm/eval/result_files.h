// What `uplvsm eval` writes to disk besides the scene grids: metrics.json (the summary table, buckets, spans, skipped
// counts and the metric conventions), per_scene.csv and per_view.csv. Kept apart from eval/evaluator.h so the
// evaluation itself reads without file formats; reports (eval/report.h) read these files back.
#pragma once
#include <nlohmann/json.hpp>

#include <string>

#include "uplvsm/eval/evaluator.h"

namespace uplvsm::eval {

// metrics.json content: scenes, views, skipped counts, table, buckets, bucket_scenes, spans, span_scenes, lpips,
// pose_noise, seconds, conventions.
nlohmann::json summary_to_json(const EvalSummary& summary);
// Writes metrics.json (summary_to_json merged with `extra`, e.g. checkpoint/config info), per_scene.csv and
// per_view.csv into out_dir (created if needed), atomically.
void write_results(const std::string& out_dir, const EvalSummary& summary, const nlohmann::json& extra = {});

}  // namespace uplvsm::eval
