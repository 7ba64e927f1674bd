// CPU kernels of fused (flash-style) attention over raw fp32 / bf16 buffers: tiled, online softmax with fp32
// accumulation, no L x L matrix in memory (workspace is O(L) per head). fp32 with AVX2 or AVX-512, bf16 with AVX-512
// BF16; callers check `flash_kernels_available()` and fall back to the unfused LibTorch path elsewhere. Threading is
// the caller's (each entry point handles a range of tasks), so these files need no LibTorch headers.
#pragma once
#include <cstdint>

namespace uplvsm::kernels::flash {

// Element strides of a [B, H, L, D] operand whose last dimension is contiguous.
struct Strides {
  int64_t b = 0, h = 0, l = 0;
};

enum class Precision { Fp32, Bf16 };

// QK-Norm applied to q and k as the kernels read them, with kernels/qk_norm's arithmetic and rounding
// (qk_norm_rows.h): each row of q becomes bf16(bf16(row r) q_weight), r = 1 / sqrt(mean(row^2) + eps), and k
// likewise (fp32: (row r) q_weight, unrounded). Then the bf16 backward's dq and dk are the gradients of the raw q
// and k, and the weights' gradients are added per (batch, head) into q_weight_grad and k_weight_grad ([B*H, D],
// zeroed by the caller); the fp32 kernels apply the norm in the forward only. Null weights: off.
struct QKNormOnRead {
  const float *q_weight = nullptr, *k_weight = nullptr;
  float eps = 0.0f;
  float *q_weight_grad = nullptr, *k_weight_grad = nullptr;
  bool active() const { return q_weight != nullptr; }
};

// One attention problem: o = softmax(scale q k^T) v per (batch, head). Pointers are float* for Fp32 and
// uint16_t* (bf16 bit patterns) for Bf16; lse ([B*H*Lq], fp32, contiguous) is the row log-sum-exp of the scaled
// scores, kept for the backward pass. `norm` normalises q and k first (fp32: forward only).
struct Problem {
  int64_t B = 0, H = 0, Lq = 0, Lk = 0, D = 0;
  float scale = 1.0f;
  Precision precision = Precision::Fp32;
  const void *q = nullptr, *k = nullptr, *v = nullptr;
  Strides sq, sk, sv;
  QKNormOnRead norm;
};

// True when the kernels run at the active ISA level (core/cpu_isa: fp32 needs AVX2, bf16 AVX-512 BF16) and d_head
// suits them.
bool flash_kernels_available(Precision precision, int64_t d_head);
// Whether Problem::norm (QK-Norm applied as q and k are read) is served: the AVX-512 kernels only.
bool qk_norm_on_read_available();

// Forward over (batch*head, query tile) tasks [begin, end) of forward_task_count(p).
int64_t forward_task_count(const Problem& p);
void forward_tasks(const Problem& p, int64_t begin, int64_t end, void* o, Strides so, float* lse);

// Backward over (batch*head) tasks [begin, end) of p.B * p.H. `o`/`dout` have strides so/sdo; delta ([B*H*Lq]) is
// rowsum(dout * o) from `backward_delta`. Gradients are written (not accumulated) in the operand precision.
void backward_delta(const Problem& p, const void* o, Strides so, const void* dout, Strides sdo, int64_t begin,
                    int64_t end, float* delta);
void backward_tasks(const Problem& p, const void* dout, Strides sdo, const float* lse, const float* delta,
                    int64_t begin, int64_t end, void* dq, Strides sdq, void* dk, Strides sdk, void* dv, Strides sdv);

}  // namespace uplvsm::kernels::flash
