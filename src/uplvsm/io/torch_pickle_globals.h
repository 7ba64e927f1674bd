// The values the pickle interpreter (torch_pickle.cpp) builds, and what its REDUCE/NEWOBJ calls mean: the few
// callables torch.save uses (tensor and parameter rebuilds, OrderedDict, sets, latin-1 bytes) become real values;
// any other global stays an opaque `Call` and is never executed. Internal to io/.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "uplvsm/io/torch_pickle.h"

namespace uplvsm::io::pickle_globals {

PyPtr make(PyObject::Kind kind);
PyPtr make_int(int64_t v);
PyPtr make_text(PyObject::Kind kind, std::string s);

// An Int (or Bool) and a tuple/list of them; errors name `what`.
int64_t as_int(const PyObject& o, const char* what);
std::vector<int64_t> as_int_list(const PyObject& o, const char* what);

// callee(args) for a REDUCE/NEWOBJ: the known torch.save callables as values, anything else an opaque Call.
PyPtr call_global(const PyPtr& callee, const PyPtr& args);

}  // namespace uplvsm::io::pickle_globals
