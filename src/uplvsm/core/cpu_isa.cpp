#include "uplvsm/core/cpu_isa.h"

#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>

namespace uplvsm {

namespace {

constexpr Isa kLevels[] = {Isa::Scalar, Isa::Avx2, Isa::Avx512, Isa::Avx512Bf16};

Isa read_cpu() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) return Isa::Scalar;
  if (!__builtin_cpu_supports("avx512f") || !__builtin_cpu_supports("avx512bw") ||
      !__builtin_cpu_supports("avx512vl") || !__builtin_cpu_supports("avx512dq"))
    return Isa::Avx2;
  return __builtin_cpu_supports("avx512bf16") ? Isa::Avx512Bf16 : Isa::Avx512;
#else
  return Isa::Scalar;
#endif
}

// The cap as an int (-1: none), first read from UPLVSM_MAX_ISA.
constexpr int kNoCap = -1;
int cap_from_environment() {
  const char* env = std::getenv("UPLVSM_MAX_ISA");
  if (env == nullptr || *env == '\0') return kNoCap;
  const auto isa = parse_isa(env);
  if (!isa)
    throw std::runtime_error(std::string("UPLVSM_MAX_ISA=") + env +
                             ": expected one of scalar, avx2, avx512, avx512-bf16 (the highest vector level the "
                             "kernels may use)");
  return static_cast<int>(*isa);
}

std::atomic<int>& cap() {
  static std::atomic<int> value{cap_from_environment()};
  return value;
}

}  // namespace

std::string isa_name(Isa isa) {
  switch (isa) {
    case Isa::Scalar: return "scalar";
    case Isa::Avx2: return "avx2";
    case Isa::Avx512: return "avx512";
    case Isa::Avx512Bf16: return "avx512-bf16";
  }
  return "scalar";
}

std::optional<Isa> parse_isa(const std::string& name) {
  for (Isa isa : kLevels)
    if (isa_name(isa) == name) return isa;
  return std::nullopt;
}

Isa detected_isa() {
  static const Isa isa = read_cpu();
  return isa;
}

// CPUID leaf 7 EDX bit 22 (AMX-BF16), and the OS saving the tile state (XCR0 bits 17, 18). GCC 12's
// __builtin_cpu_supports("amx-bf16") answers false on a CPU that has it (seen here), hence CPUID directly.
bool cpu_has_amx_bf16() {
#if defined(__x86_64__) || defined(__i386__)
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  if (!__get_cpuid_count(7, 0, &eax, &ebx, &ecx, &edx) || !((edx >> 22) & 1u)) return false;
  if (!__get_cpuid(1, &eax, &ebx, &ecx, &edx) || !((ecx >> 27) & 1u)) return false;  // OSXSAVE: xgetbv allowed
  uint32_t xcr0_low = 0, xcr0_high = 0;
  __asm__("xgetbv" : "=a"(xcr0_low), "=d"(xcr0_high) : "c"(0));
  return ((xcr0_low >> 17) & 3u) == 3u;
#else
  return false;
#endif
}

namespace detail {
std::atomic<int> active_level{-1};

int read_active_level() {
  const int c = cap().load();
  const int level = static_cast<int>(c == kNoCap ? detected_isa() : std::min(detected_isa(), static_cast<Isa>(c)));
  active_level.store(level);
  return level;
}
}  // namespace detail

bool amx_bf16_active() {
  static const bool amx = cpu_has_amx_bf16();
  return amx && isa_at_least(Isa::Avx512Bf16);
}

void set_max_isa(std::optional<Isa> level) {
  cap().store(level ? static_cast<int>(*level) : kNoCap);
  detail::read_active_level();
}

std::optional<Isa> max_isa() {
  const int c = cap().load();
  return c == kNoCap ? std::nullopt : std::optional<Isa>(static_cast<Isa>(c));
}

std::vector<Isa> runnable_isas() {
  std::vector<Isa> levels;
  for (Isa isa : kLevels)
    if (isa <= detected_isa()) levels.push_back(isa);
  return levels;
}

}  // namespace uplvsm
