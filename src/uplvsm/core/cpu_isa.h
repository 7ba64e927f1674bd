// The one CPU detector every kernel dispatches on: the vector instruction level this process may use, from the CPU
// (scalar < AVX2+FMA < AVX-512 F/BW/VL/DQ < AVX-512 BF16; AMX-BF16 as a flag beside it), capped by UPLVSM_MAX_ISA or
// set_max_isa so a weaker path can be run and tested on a stronger CPU. Kernels read it at each dispatch (never a
// copy in a static), so a cap set at run time takes effect on the next call.
#pragma once
#include <atomic>
#include <optional>
#include <string>
#include <vector>

namespace uplvsm {

enum class Isa { Scalar = 0, Avx2 = 1, Avx512 = 2, Avx512Bf16 = 3 };

// "scalar", "avx2", "avx512", "avx512-bf16" (the values UPLVSM_MAX_ISA takes).
std::string isa_name(Isa isa);
std::optional<Isa> parse_isa(const std::string& name);

// What the CPU supports (the OS saving the registers included).
Isa detected_isa();
bool cpu_has_amx_bf16();

namespace detail {
// The active level as an int, -1 until first read (constant-initialised, so reading it is safe from any static
// initialiser); set_max_isa rewrites it.
extern std::atomic<int> active_level;
int read_active_level();
}  // namespace detail

// The level kernels use: the detected one, capped. The cap starts from UPLVSM_MAX_ISA when it is set (a value not
// among isa_name's is a clear error at the first dispatch).
inline Isa active_isa() {
  const int level = detail::active_level.load(std::memory_order_relaxed);
  return static_cast<Isa>(level >= 0 ? level : detail::read_active_level());
}
inline bool isa_at_least(Isa level) { return active_isa() >= level; }
// AMX-BF16 tiles, and only when the active level keeps AVX-512 BF16.
bool amx_bf16_active();

// Caps the level process-wide (a cap above the CPU's level runs the CPU's); nullopt lifts it.
void set_max_isa(std::optional<Isa> cap);
std::optional<Isa> max_isa();

// Every level from scalar up to the detected one: the paths a test can run on this CPU.
std::vector<Isa> runnable_isas();

// Sets a cap for a scope and restores the previous one (tests, benchmarks).
class ScopedMaxIsa {
 public:
  explicit ScopedMaxIsa(Isa cap) : previous_(max_isa()) { set_max_isa(cap); }
  ~ScopedMaxIsa() { set_max_isa(previous_); }
  ScopedMaxIsa(const ScopedMaxIsa&) = delete;
  ScopedMaxIsa& operator=(const ScopedMaxIsa&) = delete;

 private:
  std::optional<Isa> previous_;
};

}  // namespace uplvsm
