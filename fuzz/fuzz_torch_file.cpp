// libFuzzer target: a torch.save file (zip or legacy container, pickle VM) read as a checkpoint: the state dict
// lookup of `uplvsm convert` / `--init`, then every tensor the pickle references, as a loader would. Any exception
// is a clean rejection; a crash, a sanitizer report, a hang or an allocation beyond the limit is a bug.
#include <cstdint>
#include <exception>

#include "fuzz_util.h"
#include "uplvsm/io/torch_file.h"

namespace {

using uplvsm::io::PyObject;

// Visits the object graph (a pickle can share and nest objects; depth and visits are bounded).
void touch_tensors(const uplvsm::io::TorchFile& file, const PyObject& o, int depth, int* budget) {
  if (depth > 64 || --*budget < 0) return;
  if (o.is(PyObject::Kind::Tensor)) {
    try {
      file.tensor(o).sum();
    } catch (const std::exception&) {
    }
  }
  for (const auto& item : o.items) touch_tensors(file, *item, depth + 1, budget);
  for (const auto& [k, v] : o.dict) touch_tensors(file, *v, depth + 1, budget);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = uplvsm::fuzz::write_scratch("checkpoint.pt", data, size);
  try {
    uplvsm::io::read_torch_state_dict(path);
  } catch (const std::exception&) {
  }
  try {
    uplvsm::io::TorchFile file(path);
    int budget = 10000;
    touch_tensors(file, file.root(), 0, &budget);
  } catch (const std::exception&) {
  }
  return 0;
}
