#include "uplvsm/kernels/bf16_linear.h"

#include <ATen/Parallel.h>
#include <ATen/record_function.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "uplvsm/kernels/bf16_micro_kernel.h"
#include "uplvsm/kernels/bf16_simd.h"

namespace uplvsm::kernels {
namespace {

using torch::autograd::AutogradContext;
using torch::autograd::variable_list;

// Rows interleaved at a time: 64 pairs; with the next slice prefetched, 128 beat 64, 96 and 256 rows (a prototype).
constexpr int64_t kSliceRows = 128;
constexpr int64_t kRows = bf16_tile::kMaxRows;
constexpr int64_t kOutputBlock = 576;  // output rows per task (a multiple of kRows)
constexpr int64_t kPartRows = 65536;   // K rows per 4 parts: 4 .. 16 parts, so 1, 2 or 4 threads share them evenly
// Weights of up to 512 x 512 elements: there faster than oneDNN (0.62-0.75 TFLOP/s against 0.37-0.59 on two cores,
// 17408-69632 rows, operands out of cache), not at the paper's widths (768 x 3072: 0.74-0.79 against 0.77-0.82).
constexpr int64_t kMaxWeightElements = 512 * 512;

WeightGradientPath path_from_environment() {
  const char* env = std::getenv("UPLVSM_WEIGHT_GRADIENT");
  if (env && std::strcmp(env, "aten") == 0) return WeightGradientPath::Aten;
  if (env && std::strcmp(env, "ours") == 0) return WeightGradientPath::Ours;
  return default_weight_gradient_path(detect_cpu_features());
}

std::atomic<WeightGradientPath>& path_choice() {
  static std::atomic<WeightGradientPath> choice{path_from_environment()};
  return choice;
}

// Words (lo[j] | hi[j] << 16) for j < n into dst; hi null gives zero high halves (a missing odd row).
UPLVSM_ROW_AVX512 void interleave_rows(const uint16_t* lo, const uint16_t* hi, int64_t n, uint32_t* dst) {
  const __m512i first = _mm512_set_epi16(47, 15, 46, 14, 45, 13, 44, 12, 43, 11, 42, 10, 41, 9, 40, 8, 39, 7, 38, 6, 37,
                                         5, 36, 4, 35, 3, 34, 2, 33, 1, 32, 0);
  const __m512i second = _mm512_add_epi16(first, _mm512_set1_epi16(16));
  int64_t j = 0;
  for (; j + 32 <= n; j += 32) {
    const __m512i a = _mm512_loadu_si512(lo + j), b = hi ? _mm512_loadu_si512(hi + j) : _mm512_setzero_si512();
    _mm512_storeu_si512(dst + j, _mm512_permutex2var_epi16(a, first, b));
    _mm512_storeu_si512(dst + j + 16, _mm512_permutex2var_epi16(a, second, b));
  }
  for (; j < n; j += 16) {
    const __mmask16 mask = row_simd::tail_mask(n - j);
    const __m512i a = _mm512_castsi256_si512(_mm256_maskz_loadu_epi16(mask, lo + j));
    const __m512i b = hi ? _mm512_castsi256_si512(_mm256_maskz_loadu_epi16(mask, hi + j)) : _mm512_setzero_si512();
    _mm512_mask_storeu_epi32(dst + j, mask, _mm512_permutex2var_epi16(a, first, b));
  }
}

// Rows [begin, end) of a row-major bf16 matrix, `width` elements each from `first`, rows `stride` apart.
struct RowRange {
  const uint16_t* first;
  int64_t stride, width, begin, end;
};

// Rows [row, row + count) of both operands interleaved into pairs: [ceil(count / 2) x width] words each, a pair
// of a's rows and then b's at a time.
void interleave_slices(const RowRange& a, const RowRange& b, int64_t row, int64_t count, uint32_t* A, uint32_t* B) {
  for (int64_t i = 0; 2 * i < count; ++i) {
    const bool odd = 2 * i + 1 < count;
    const uint16_t* lo = a.first + (row + 2 * i) * a.stride;
    interleave_rows(lo, odd ? lo + a.stride : nullptr, a.width, A + i * a.width);
    lo = b.first + (row + 2 * i) * b.stride;
    interleave_rows(lo, odd ? lo + b.stride : nullptr, b.width, B + i * b.width);
  }
}

// Asks for part `step` of `steps` of rows [row, row + count) ahead of use: the next slice's rows, read while the
// current one is multiplied, so that interleaving them waits less on memory. (Interleaving the next slice itself
// between the micro-kernel calls instead was 15-30 % slower.)
void prefetch_part(const RowRange& x, int64_t row, int64_t count, int64_t step, int64_t steps) {
  const int64_t bytes = x.width * static_cast<int64_t>(sizeof(uint16_t));
  for (int64_t r = row + count * step / steps; r < row + count * (step + 1) / steps; ++r)
    for (int64_t b = 0; b < bytes; b += 64)
      _mm_prefetch(reinterpret_cast<const char*>(x.first + r * x.stride) + b, _MM_HINT_T0);
}

// C[M x N] (+)= A^T B over `pairs` interleaved rows (N a multiple of 16), in 64-column panels; prefetches the next
// slice (rows [next, next + next_count) of a and b) along the way.
void multiply_slice(int64_t M, int64_t N, int64_t pairs, const uint32_t* A, const uint32_t* B, float* C,
                    bool accumulate, const RowRange& a, const RowRange& b, int64_t next, int64_t next_count) {
  const int64_t steps = ((N + 63) / 64) * ((M + kRows - 1) / kRows);
  int64_t step = 0;
  for (int64_t n0 = 0; n0 < N; n0 += 64) {
    const int64_t nv = std::min<int64_t>(4, (N - n0) / 16);
    for (int64_t m0 = 0; m0 < M; m0 += kRows, ++step) {
      bf16_tile::kernel_for<bf16_tile::ALayout::kPairMajor>(std::min(kRows, M - m0), nv)(
          pairs, A + m0, M, B + n0, N, C + m0 * N + n0, N, accumulate);
      prefetch_part(a, next, next_count, step, steps);
      prefetch_part(b, next, next_count, step, steps);
    }
  }
}

// One task: C (the part's sums for rows a.width of the output, N = b.width columns) = a^T b over rows
// [a.begin, a.end) of both operands, a slice at a time.
void multiply_rows(const RowRange& a, const RowRange& b, float* C) {
  std::vector<uint32_t> A((kSliceRows / 2) * a.width), B((kSliceRows / 2) * b.width);
  for (int64_t row = a.begin; row < a.end; row += kSliceRows) {
    const int64_t count = std::min(kSliceRows, a.end - row), next = row + count;
    interleave_slices(a, b, row, count, A.data(), B.data());
    multiply_slice(a.width, b.width, (count + 1) / 2, A.data(), B.data(), C, row > a.begin, a, b, next,
                   std::min(kSliceRows, a.end - next));
  }
}

// The number of K slices summed apart: a function of the shape alone, so the result is too. Their fp32 sums take
// at most 16 x kMaxWeightElements x 4 bytes = 16 MiB for the weights bf16_linear serves.
int64_t parts_for(int64_t K) { return K < 1024 ? 1 : std::min<int64_t>(16, 4 * ((K + kPartRows - 1) / kPartRows)); }

// out[j] = bf16(sum over parts in order of sums[part][j]) for j in [begin, end) (multiples of 16); parts `size` apart.
UPLVSM_ROW_AVX512 void add_parts(const float* sums, int64_t parts, int64_t size, int64_t begin, int64_t end,
                                 c10::BFloat16* out) {
  for (int64_t j = begin; j < end; j += 16) {
    __m512 s = _mm512_loadu_ps(sums + j);
    for (int64_t p = 1; p < parts; ++p) s = _mm512_add_ps(s, _mm512_loadu_ps(sums + p * size + j));
    row_simd::store16(out + j, s);
  }
}

}  // namespace

torch::Tensor weight_gradient_bf16(const torch::Tensor& grad_output, const torch::Tensor& input) {
  RECORD_FUNCTION("uplvsm::weight_gradient_bf16", std::vector<c10::IValue>());
  TORCH_CHECK(grad_output.dim() == 2 && input.dim() == 2 && grad_output.size(0) == input.size(0),
              "weight_gradient_bf16: expected dY [K x O] and X [K x I], got ", grad_output.sizes(), " and ",
              input.sizes());
  TORCH_CHECK(grad_output.scalar_type() == torch::kBFloat16 && input.scalar_type() == torch::kBFloat16 &&
                  grad_output.is_contiguous() && input.is_contiguous() && input.size(1) % 16 == 0,
              "weight_gradient_bf16: expected contiguous bf16 operands and I a multiple of 16");
  const int64_t K = input.size(0), O = grad_output.size(1), I = input.size(1);
  if (K == 0 || O == 0 || I == 0) return torch::zeros({O, I}, input.options());
  TORCH_CHECK(isa_at_least(Isa::Avx512Bf16), "weight_gradient_bf16: needs AVX-512 BF16, and the kernels may use ",
              isa_name(active_isa()), " here (bf16_linear_applies says where it serves)");
  const int64_t parts = parts_for(K), blocks = (O + kOutputBlock - 1) / kOutputBlock;
  auto sums = torch::empty({parts, O, I}, input.options().dtype(torch::kFloat));
  const auto* dy = reinterpret_cast<const uint16_t*>(grad_output.data_ptr<c10::BFloat16>());
  const auto* x = reinterpret_cast<const uint16_t*>(input.data_ptr<c10::BFloat16>());
  float* s = sums.data_ptr<float>();
  at::parallel_for(0, parts * blocks, 1, [&](int64_t begin, int64_t end) {
    for (int64_t task = begin; task < end; ++task) {
      const int64_t part = task / blocks, o0 = (task % blocks) * kOutputBlock;
      const int64_t row0 = K * part / parts / 2 * 2, row1 = part + 1 == parts ? K : K * (part + 1) / parts / 2 * 2;
      const RowRange a{dy + o0, O, std::min(kOutputBlock, O - o0), row0, row1}, b{x, I, I, row0, row1};
      multiply_rows(a, b, s + (part * O + o0) * I);
    }
  });
  auto out = torch::empty({O, I}, input.options());
  c10::BFloat16* o = out.data_ptr<c10::BFloat16>();
  at::parallel_for(0, O, 16, [&](int64_t begin, int64_t end) { add_parts(s, parts, O * I, begin * I, end * I, o); });
  return out;
}

namespace {

// dY's gradients for the saved input and weight (and the bias when there is one), where autograd asks for them.
variable_list linear_backward(AutogradContext* ctx, const torch::Tensor& grad_output, bool with_bias) {
  const auto saved = ctx->get_saved_variables();
  const auto &input = saved[0], &weight = saved[1];
  const int64_t O = weight.size(0), I = weight.size(1);
  const auto dy = grad_output.to(torch::kBFloat16).reshape({-1, O}).contiguous();
  variable_list grads(with_bias ? 3 : 2);
  if (ctx->needs_input_grad(0)) grads[0] = dy.mm(weight).view(input.sizes());
  if (ctx->needs_input_grad(1)) grads[1] = weight_gradient_bf16(dy, input.reshape({-1, I}).contiguous());
  if (with_bias && ctx->needs_input_grad(2)) grads[2] = dy.sum(0);
  return grads;
}

// Two nodes, with and without a bias: a custom autograd function takes no undefined tensor.
struct Bf16LinearFunction : torch::autograd::Function<Bf16LinearFunction> {
  static torch::Tensor forward(AutogradContext* ctx, const torch::Tensor& input, const torch::Tensor& weight) {
    ctx->save_for_backward({input, weight});
    return torch::linear(input, weight);
  }
  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    return linear_backward(ctx, grad_outputs[0], false);
  }
};

struct Bf16LinearWithBiasFunction : torch::autograd::Function<Bf16LinearWithBiasFunction> {
  static torch::Tensor forward(AutogradContext* ctx, const torch::Tensor& input, const torch::Tensor& weight,
                               const torch::Tensor& bias) {
    ctx->save_for_backward({input, weight});
    return torch::linear(input, weight, bias);
  }
  static variable_list backward(AutogradContext* ctx, variable_list grad_outputs) {
    return linear_backward(ctx, grad_outputs[0], true);
  }
};

}  // namespace

WeightGradientPath default_weight_gradient_path(const CpuFeatures& cpu) {
  return cpu.amx_bf16 ? WeightGradientPath::Aten : WeightGradientPath::Ours;
}

void set_weight_gradient_path(WeightGradientPath path) { path_choice().store(path); }

WeightGradientPath weight_gradient_path() { return path_choice().load(); }

bool bf16_linear_applies(const torch::Tensor& input, const torch::Tensor& weight) {
  return path_choice().load() == WeightGradientPath::Ours && isa_at_least(Isa::Avx512Bf16) && input.device().is_cpu() &&
         weight.device().is_cpu() && input.scalar_type() == torch::kBFloat16 &&
         weight.scalar_type() == torch::kBFloat16 && weight.dim() == 2 && weight.size(1) % 16 == 0 &&
         weight.numel() <= kMaxWeightElements && input.dim() >= 1 && input.size(-1) == weight.size(1);
}

torch::Tensor bf16_linear(const torch::Tensor& input, const torch::Tensor& weight, const torch::Tensor& bias) {
  return bias.defined() ? Bf16LinearWithBiasFunction::apply(input, weight, bias)
                        : Bf16LinearFunction::apply(input, weight);
}

}  // namespace uplvsm::kernels
