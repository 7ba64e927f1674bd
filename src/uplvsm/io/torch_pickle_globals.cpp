#include "uplvsm/io/torch_pickle_globals.h"

#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm::io::pickle_globals {

using Kind = PyObject::Kind;

PyPtr make(Kind kind) {
  auto p = std::make_shared<PyObject>();
  p->kind = kind;
  return p;
}
PyPtr make_int(int64_t v) {
  auto p = make(Kind::Int);
  p->integer = v;
  return p;
}
PyPtr make_text(Kind kind, std::string s) {
  auto p = make(kind);
  p->text = std::move(s);
  return p;
}

int64_t as_int(const PyObject& o, const char* what) {
  if (o.kind == Kind::Int) return o.integer;
  if (o.kind == Kind::Bool) return o.boolean;
  throw std::runtime_error(fmt::format("{}: expected an int, got {}", what, o.describe()));
}

std::vector<int64_t> as_int_list(const PyObject& o, const char* what) {
  if (o.kind != Kind::Tuple && o.kind != Kind::List)
    throw std::runtime_error(fmt::format("{}: expected a tuple of ints, got {}", what, o.describe()));
  std::vector<int64_t> out;
  for (const auto& item : o.items) out.push_back(as_int(*item, what));
  return out;
}

namespace {

// torch._utils._rebuild_tensor_v2(storage, storage_offset, size, stride, requires_grad, backward_hooks, ...)
PyPtr rebuild_tensor(const PyObject& args) {
  if (args.kind != Kind::Tuple || args.items.size() < 4)
    throw std::runtime_error("_rebuild_tensor: expected (storage, offset, size, stride, ...)");
  const auto& storage = *args.items[0];
  if (storage.kind != Kind::Storage)
    throw std::runtime_error(
        fmt::format("_rebuild_tensor: first argument is {}, expected a storage", storage.describe()));
  auto t = make(Kind::Tensor);
  t->tensor = storage.tensor;
  t->tensor.offset = as_int(*args.items[1], "tensor storage offset");
  t->tensor.sizes = as_int_list(*args.items[2], "tensor size");
  t->tensor.strides = as_int_list(*args.items[3], "tensor stride");
  if (t->tensor.sizes.size() != t->tensor.strides.size())
    throw std::runtime_error("_rebuild_tensor: size and stride have different lengths");
  // The furthest element addressed must lie inside the storage, and the element count must be representable
  // (a view of stride 0 can claim any number of elements of one stored value).
  int64_t last = t->tensor.offset, numel = 1;
  bool empty = false;
  for (size_t i = 0; i < t->tensor.sizes.size(); ++i) {
    if (t->tensor.sizes[i] < 0 || t->tensor.strides[i] < 0)
      throw std::runtime_error("_rebuild_tensor: negative size or stride");
    int64_t span = 0;
    if (t->tensor.sizes[i] == 0)
      empty = true;
    else if (__builtin_mul_overflow(t->tensor.sizes[i] - 1, t->tensor.strides[i], &span) ||
             __builtin_add_overflow(last, span, &last) || __builtin_mul_overflow(numel, t->tensor.sizes[i], &numel) ||
             numel > (int64_t(1) << 48))
      throw std::runtime_error("_rebuild_tensor: view extent overflows");
  }
  if (t->tensor.offset < 0 || (!empty && last >= storage.tensor.storage_numel))
    throw std::runtime_error(fmt::format("_rebuild_tensor: view reaches element {} of a storage with {} elements", last,
                                         storage.tensor.storage_numel));
  return t;
}

// The bytes a latin-1 text stands for (the unpickler holds text as UTF-8): code points 0..255, one byte each.
std::string latin1_bytes(const std::string& utf8) {
  std::string out;
  for (size_t i = 0; i < utf8.size(); ++i) {
    const auto c = static_cast<unsigned char>(utf8[i]);
    if (c < 0x80) {
      out.push_back(static_cast<char>(c));
    } else if ((c & 0xFE) == 0xC2 && i + 1 < utf8.size() && (static_cast<unsigned char>(utf8[i + 1]) & 0xC0) == 0x80) {
      out.push_back(static_cast<char>(((c & 0x03) << 6) | (static_cast<unsigned char>(utf8[++i]) & 0x3F)));
    } else {
      throw std::runtime_error("_codecs.encode: text is not latin-1 (a character beyond U+00FF or bad UTF-8)");
    }
  }
  return out;
}

}  // namespace

// What REDUCE/NEWOBJ build: the few callables torch.save uses become real values, everything else stays opaque.
PyPtr call_global(const PyPtr& callee, const PyPtr& args) {
  const std::string name = callee->kind == Kind::Global ? callee->text : "";
  // Protocol 2 has no bytes opcode for Python 3 bytes: they arrive as _codecs.encode(<latin-1 text>, "latin1").
  if (name == "_codecs.encode" && args->kind == Kind::Tuple && args->items.size() == 2 &&
      args->items[0]->kind == Kind::Str && args->items[1]->kind == Kind::Str &&
      (args->items[1]->text == "latin1" || args->items[1]->text == "latin-1"))
    return make_text(Kind::Bytes, latin1_bytes(args->items[0]->text));
  if (name == "collections.OrderedDict" || name == "builtins.dict" || name == "__builtin__.dict") {
    auto dict = make(Kind::Dict);
    // Old files call OrderedDict([[key, value], ...]); newer ones fill it with SETITEMS afterwards.
    if (args->kind == Kind::Tuple && !args->items.empty())
      for (const auto& pair : args->items[0]->items) {
        if ((pair->kind != Kind::List && pair->kind != Kind::Tuple) || pair->items.size() != 2)
          throw std::runtime_error("OrderedDict(...) argument is not a list of (key, value) pairs");
        dict->dict.emplace_back(pair->items[0], pair->items[1]);
      }
    return dict;
  }
  if (name == "torch._utils._rebuild_tensor_v2" || name == "torch._utils._rebuild_tensor") return rebuild_tensor(*args);
  if (name == "torch._utils._rebuild_parameter" || name == "torch._utils._rebuild_parameter_with_state") {
    if (args->kind != Kind::Tuple || args->items.empty()) throw std::runtime_error("_rebuild_parameter: no data");
    return args->items[0];
  }
  // LibTorch's own pickler (torch::pickle_save) wraps containers in their TorchScript type: the value is args[0].
  if (name == "torch.jit._pickle.restore_type_tag" && args->kind == Kind::Tuple && !args->items.empty())
    return args->items[0];
  if ((name == "builtins.set" || name == "__builtin__.set") && args->kind == Kind::Tuple) {
    auto s = make(Kind::Set);
    if (!args->items.empty()) s->items = args->items[0]->items;
    return s;
  }
  auto c = make(Kind::Call);
  c->items = {callee, args};
  return c;
}

}  // namespace uplvsm::io::pickle_globals
