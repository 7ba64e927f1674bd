// Config keys that were removed (issue 62: experiments that measured no gain, see docs/research/levers.md; and
// training.pose_noise_variance, replaced by the official knob training.pose_noise_std; issue 70: the
// model.encoder_cameras diagnostic). Files
// written before keep them: shipped models, `make demo`'s checkpoints and users' runs embed a config JSON with every
// key of their day. A retired key at the value it had by default (the lever off) reads as if it were absent; at any
// other value the file asked for code that is gone, and reading it fails naming the key and the commit that had it.
#pragma once
#include <nlohmann/json.hpp>

#include <string>

namespace uplvsm {

struct RetiredKey {
  const char* section;  // "model", "model.transformer", "training", "eval"
  const char* key;
  nlohmann::json default_value;  // the value that meant "off"
  const char* commit;            // the last commit that had the key and its code
  const char* why = nullptr;     // what replaced it; null: a lever that measured no gain (docs/research/levers.md)
};

// Every retired key; null when `section`.`key` is none of them.
const RetiredKey* find_retired_key(const std::string& section, const std::string& key);

// For a key the config reader does not know: false when it was never a config key; true when it is retired at its
// default (the reader skips it). Throws when it is retired at another value, naming `where` (file and section), the
// key, its value and default, the commit and the research log.
bool accept_retired_key(const std::string& section, const std::string& key, const nlohmann::json& value,
                        const std::string& where);

// The sentence that says where a retired key went (commit, research log), for the errors above and `--set`.
std::string retired_key_note(const RetiredKey& retired);

}  // namespace uplvsm
