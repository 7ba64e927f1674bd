#include "uplvsm/io/torch_pickle.h"

#include <cstring>
#include <stdexcept>
#include <unordered_map>

#include <fmt/format.h>

#include "uplvsm/io/torch_pickle_globals.h"

namespace uplvsm::io {

using Kind = PyObject::Kind;
using namespace pickle_globals;

PyObject::~PyObject() {
  std::vector<PyPtr> pending;
  auto adopt_children = [&pending](PyObject& o) {
    for (auto& item : o.items) pending.push_back(std::move(item));
    for (auto& [k, v] : o.dict) {
      pending.push_back(std::move(k));
      pending.push_back(std::move(v));
    }
    o.items.clear();
    o.dict.clear();
  };
  adopt_children(*this);
  while (!pending.empty()) {
    PyPtr p = std::move(pending.back());
    pending.pop_back();
    if (p && p.use_count() == 1) adopt_children(*p);  // p's last owner: it is destroyed childless below
  }
}

const PyObject* PyObject::get(const std::string& key) const {
  if (kind != Kind::Dict) return nullptr;
  for (const auto& [k, v] : dict)
    if (k->kind == Kind::Str && k->text == key) return v.get();
  return nullptr;
}

std::string PyObject::describe() const {
  switch (kind) {
    case Kind::None: return "None";
    case Kind::Bool: return "bool";
    case Kind::Int:
    case Kind::BigInt: return "int";
    case Kind::Float: return "float";
    case Kind::Str: return "str";
    case Kind::Bytes: return "bytes";
    case Kind::List: return "list";
    case Kind::Tuple: return "tuple";
    case Kind::Set: return "set";
    case Kind::Dict: return "dict";
    case Kind::Global: return "global " + text;
    case Kind::Call: return "object " + (items.empty() ? std::string("?") : items[0]->text);
    case Kind::Storage: return "storage";
    case Kind::Tensor: return "tensor";
  }
  return "?";
}

torch::Dtype storage_type_to_dtype(const std::string& name) {
  static const std::vector<std::pair<std::string, torch::Dtype>> table = {
      {"FloatStorage", torch::kFloat32}, {"DoubleStorage", torch::kFloat64},
      {"HalfStorage", torch::kFloat16},  {"BFloat16Storage", torch::kBFloat16},
      {"LongStorage", torch::kInt64},    {"IntStorage", torch::kInt32},
      {"ShortStorage", torch::kInt16},   {"CharStorage", torch::kInt8},
      {"ByteStorage", torch::kUInt8},    {"BoolStorage", torch::kBool},
      {"UntypedStorage", torch::kUInt8}, {"float32", torch::kFloat32},
      {"float16", torch::kFloat16},      {"bfloat16", torch::kBFloat16},
      {"float64", torch::kFloat64},      {"int64", torch::kInt64},
      {"int32", torch::kInt32},          {"uint8", torch::kUInt8}};
  auto dot = name.rfind('.');
  std::string base = dot == std::string::npos ? name : name.substr(dot + 1);
  for (const auto& [n, t] : table)
    if (n == base) return t;
  throw std::runtime_error(fmt::format("unsupported tensor storage type '{}'", name));
}

namespace {

class Machine {
 public:
  Machine(const uint8_t* data, size_t size, size_t pos, const PersistentLoad& pl, const std::string& source)
      : d_(data), n_(size), p_(pos), persistent_load_(pl), source_(source) {}

  PyPtr run(size_t* end) {
    while (true) {
      op_at_ = p_;
      op_ = byte();
      if (op_ == '.') break;
      step();
    }
    if (stack_.size() != 1) fail(fmt::format("STOP with {} objects on the stack (expected 1)", stack_.size()));
    *end = p_;
    return stack_.back();
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(
        fmt::format("{}: invalid pickle at byte {} (opcode 0x{:02x}): {}", source_, op_at_, op_, what));
  }
  void need(size_t k) const {
    if (k > n_ - p_) fail(fmt::format("needs {} more bytes but the data ends (truncated file?)", k));
  }
  uint8_t byte() {
    need(1);
    return d_[p_++];
  }
  uint64_t uint_le(int bytes) {
    need(bytes);
    uint64_t v = 0;
    for (int i = 0; i < bytes; ++i) v |= uint64_t(d_[p_ + i]) << (8 * i);
    p_ += bytes;
    return v;
  }
  std::string take(uint64_t k) {
    if (k > n_) fail("length field larger than the file");
    need(size_t(k));
    std::string s(reinterpret_cast<const char*>(d_ + p_), size_t(k));
    p_ += size_t(k);
    return s;
  }
  std::string line() {
    size_t start = p_;
    while (p_ < n_ && d_[p_] != '\n') ++p_;
    if (p_ >= n_) fail("unterminated text line");
    std::string s(reinterpret_cast<const char*>(d_ + start), p_ - start);
    ++p_;
    return s;
  }
  PyPtr pop() {
    if (stack_.size() <= mark_floor()) fail("stack underflow");
    auto v = stack_.back();
    stack_.pop_back();
    return v;
  }
  PyPtr& top() {
    if (stack_.size() <= mark_floor()) fail("stack underflow");
    return stack_.back();
  }
  size_t mark_floor() const { return marks_.empty() ? 0 : marks_.back(); }
  std::vector<PyPtr> pop_mark() {
    if (marks_.empty()) fail("no MARK on the stack");
    size_t m = marks_.back();
    marks_.pop_back();
    std::vector<PyPtr> items(stack_.begin() + long(m), stack_.end());
    stack_.resize(m);
    return items;
  }
  void push(PyPtr v) { stack_.push_back(std::move(v)); }
  void memo_put(uint64_t key) {
    if (stack_.empty()) fail("memo put on an empty stack");
    memo_[key] = stack_.back();
  }
  void memo_get(uint64_t key) {
    auto it = memo_.find(key);
    if (it == memo_.end()) fail(fmt::format("memo key {} was never stored", key));
    push(it->second);
  }
  PyPtr tuple(std::vector<PyPtr> items) {
    auto t = make(Kind::Tuple);
    t->items = std::move(items);
    return t;
  }
  void set_items(PyObject& dict, const std::vector<PyPtr>& kv) {
    if (kv.size() % 2) fail("SETITEMS with an odd number of items");
    if (dict.kind != Kind::Dict) {
      if (dict.kind == Kind::Call) return;  // __setitem__ on an opaque object: nothing we need
      fail("SETITEM on a " + dict.describe());
    }
    for (size_t i = 0; i < kv.size(); i += 2) {
      bool replaced = false;
      if (kv[i]->kind == Kind::Str)
        for (auto& [k, v] : dict.dict)
          if (k->kind == Kind::Str && k->text == kv[i]->text) v = kv[i + 1], replaced = true;
      if (!replaced) dict.dict.emplace_back(kv[i], kv[i + 1]);
    }
  }
  void append(PyObject& list, const std::vector<PyPtr>& items) {
    if (list.kind == Kind::List || list.kind == Kind::Set)
      list.items.insert(list.items.end(), items.begin(), items.end());
    else if (list.kind != Kind::Call)
      fail("APPEND on a " + list.describe());
  }
  int64_t signed_le(const std::string& bytes) {
    int64_t v = 0;
    for (size_t i = 0; i < bytes.size(); ++i) v |= int64_t(uint8_t(bytes[i])) << (8 * i);
    if (!bytes.empty() && bytes.size() < 8 && (uint8_t(bytes.back()) & 0x80)) v -= int64_t(1) << (8 * bytes.size());
    return v;
  }
  void push_long(const std::string& bytes) {
    if (bytes.size() <= 8)
      push(make_int(signed_le(bytes)));
    else
      push(make_text(Kind::BigInt, bytes));
  }

  // One opcode. Each group below handles its opcodes and returns false for any other; an opcode no group knows is
  // refused, so the groups together accept exactly the opcodes listed in them.
  void step();
  bool step_stack();
  bool step_scalar();
  bool step_text();
  bool step_memo();
  bool step_container();
  bool step_call();

  const uint8_t* d_;
  size_t n_, p_, op_at_ = 0;
  uint8_t op_ = 0;
  const PersistentLoad& persistent_load_;
  const std::string& source_;
  std::vector<PyPtr> stack_;
  std::vector<size_t> marks_;
  std::unordered_map<uint64_t, PyPtr> memo_;
};

void Machine::step() {
  if (step_stack() || step_scalar() || step_text() || step_memo() || step_container() || step_call()) return;
  fail("unsupported opcode");
}

// The opcode handlers are written as tables, one opcode per line.
// clang-format off
// Framing, marks and plain stack manipulation.
bool Machine::step_stack() {
  switch (op_) {
    case 0x80: byte(); break;          // PROTO
    case 0x95: uint_le(8); break;      // FRAME: framing is only a read-ahead hint
    case '(': marks_.push_back(stack_.size()); break;
    case '0': pop(); break;
    case '1': pop_mark(); break;
    case '2': push(top()); break;
    default: return false;
  }
  return true;
}

// None, booleans, integers (binary, long and protocol-0 text) and floats.
bool Machine::step_scalar() {
  switch (op_) {
    case 'N': push(make(Kind::None)); break;
    case 0x88: case 0x89: { auto b = make(Kind::Bool); b->boolean = op_ == 0x88; push(b); break; }
    case 'J': push(make_int(int32_t(uint32_t(uint_le(4))))); break;
    case 'K': push(make_int(int64_t(uint_le(1)))); break;
    case 'M': push(make_int(int64_t(uint_le(2)))); break;
    case 0x8a: push_long(take(uint_le(1))); break;
    case 0x8b: push_long(take(uint_le(4))); break;
    case 'I': case 'L': {  // text ints (protocol 0), "I01\n" is True
      auto s = line();
      if (!s.empty() && s.back() == 'L') s.pop_back();
      if (s == "01" || s == "00") { auto b = make(Kind::Bool); b->boolean = s == "01"; push(b); break; }
      try { push(make_int(std::stoll(s))); } catch (const std::exception&) { fail("bad text integer '" + s + "'"); }
      break;
    }
    case 'G': {
      uint64_t bits = 0;
      need(8);
      for (int i = 0; i < 8; ++i) bits = (bits << 8) | d_[p_ + i];  // big-endian
      p_ += 8;
      auto f = make(Kind::Float);
      std::memcpy(&f->real, &bits, 8);
      push(f);
      break;
    }
    default: return false;
  }
  return true;
}

// Strings, bytes and globals (module.name).
bool Machine::step_text() {
  switch (op_) {
    case 'X': push(make_text(Kind::Str, take(uint_le(4)))); break;
    case 0x8c: push(make_text(Kind::Str, take(uint_le(1)))); break;
    case 0x8d: push(make_text(Kind::Str, take(uint_le(8)))); break;
    case 'T': push(make_text(Kind::Str, take(uint_le(4)))); break;
    case 'U': push(make_text(Kind::Str, take(uint_le(1)))); break;
    case 'B': push(make_text(Kind::Bytes, take(uint_le(4)))); break;
    case 'C': push(make_text(Kind::Bytes, take(uint_le(1)))); break;
    case 0x8e: case 0x96: push(make_text(Kind::Bytes, take(uint_le(8)))); break;
    case 'c': { auto module = line(); auto name = line(); push(make_text(Kind::Global, module + "." + name)); break; }
    case 0x93: {
      auto name = pop(), module = pop();
      if (!name->is(Kind::Str) || !module->is(Kind::Str)) fail("STACK_GLOBAL needs two strings");
      push(make_text(Kind::Global, module->text + "." + name->text));
      break;
    }
    default: return false;
  }
  return true;
}

// The memo: PUT / GET in their binary and text forms.
bool Machine::step_memo() {
  switch (op_) {
    case 'q': memo_put(uint_le(1)); break;
    case 'r': memo_put(uint_le(4)); break;
    case 0x94: memo_put(memo_.size()); break;
    case 'p': { auto s = line(); try { memo_put(std::stoull(s)); } catch (const std::exception&) { fail("bad PUT"); } break; }
    case 'h': memo_get(uint_le(1)); break;
    case 'j': memo_get(uint_le(4)); break;
    case 'g': { auto s = line(); try { memo_get(std::stoull(s)); } catch (const std::logic_error&) { fail("bad GET"); } break; }
    default: return false;
  }
  return true;
}

// Tuples, lists, dicts and sets: empty ones, built from the stack, and filled in place.
bool Machine::step_container() {
  switch (op_) {
    case '}': push(make(Kind::Dict)); break;
    case ']': push(make(Kind::List)); break;
    case ')': push(make(Kind::Tuple)); break;
    case 0x8f: push(make(Kind::Set)); break;
    case 't': push(tuple(pop_mark())); break;
    case 0x85: { auto a = pop(); push(tuple({a})); break; }
    case 0x86: { auto b = pop(), a = pop(); push(tuple({a, b})); break; }
    case 0x87: { auto c = pop(), b = pop(), a = pop(); push(tuple({a, b, c})); break; }
    case 'l': { auto l = make(Kind::List); l->items = pop_mark(); push(l); break; }
    case 'd': { auto items = pop_mark(); auto dict = make(Kind::Dict); set_items(*dict, items); push(dict); break; }
    case 'a': { auto v = pop(); append(*top(), {v}); break; }
    case 'e': case 0x90: { auto items = pop_mark(); append(*top(), items); break; }
    case 's': { auto v = pop(), k = pop(); set_items(*top(), {k, v}); break; }
    case 'u': { auto items = pop_mark(); set_items(*top(), items); break; }
    case 0x91: { auto s = make(Kind::Set); s->items = pop_mark(); push(s); break; }
    default: return false;
  }
  return true;
}

// Calls (REDUCE / NEWOBJ), object state and persistent ids (the tensors' storages).
bool Machine::step_call() {
  switch (op_) {
    case 'R': case 0x81: {  // REDUCE / NEWOBJ
      auto args = pop(), callee = pop();
      try { push(call_global(callee, args)); } catch (const std::runtime_error& e) { fail(e.what()); }
      break;
    }
    case 0x92: { auto kwargs = pop(), args = pop(), callee = pop(); push(call_global(callee, args)); break; }
    case 'b': pop(); top(); break;  // BUILD: object state (OrderedDict._metadata, ...) is not needed for weights
    case 'Q': {
      auto pid = pop();
      try { push(persistent_load_(*pid)); } catch (const std::runtime_error& e) { fail(e.what()); }
      break;
    }
    case 'P': fail("text persistent ids (protocol 0) are not used by torch.save");
    default: return false;
  }
  return true;
}
// clang-format on

}  // namespace

PyPtr unpickle(const uint8_t* data, size_t size, size_t* pos, const PersistentLoad& persistent_load,
               const std::string& source) {
  if (*pos > size) throw std::runtime_error(fmt::format("{}: pickle starts past the end of the data", source));
  Machine m(data, size, *pos, persistent_load, source);
  return m.run(pos);
}

}  // namespace uplvsm::io
