// The bf16 autocast scope: matmuls run in bf16 inside it, fp32 outside, nesting restores the previous state, and a
// small model's bf16 forward stays close to its fp32 one.
#include "uplvsm/core/autocast.h"

#include <gtest/gtest.h>

#include "test_util.h"

using namespace uplvsm;

TEST(Autocast, Bf16MatmulsOnlyInsideTheScope) {
  auto a = torch::randn({8, 16}), b = torch::randn({16, 4});
  {
    AutocastGuard amp(torch::kCPU, true);
    EXPECT_EQ(torch::matmul(a, b).scalar_type(), torch::kBFloat16);
    EXPECT_EQ(torch::softmax(a, -1).scalar_type(), torch::kFloat32);  // elementwise / fp32-policy ops keep fp32
    {
      AutocastGuard off(torch::kCPU, false);  // disabled guard: a no-op
      EXPECT_EQ(torch::matmul(a, b).scalar_type(), torch::kBFloat16);
    }
    {
      AutocastGuard nested(torch::kCPU, true);
      EXPECT_EQ(torch::matmul(a, b).scalar_type(), torch::kBFloat16);
    }
    EXPECT_EQ(torch::matmul(a, b).scalar_type(), torch::kBFloat16);  // still on after the nested scope
  }
  EXPECT_EQ(torch::matmul(a, b).scalar_type(), torch::kFloat32);
}

TEST(Autocast, LinearLayerCloseToFp32AndGradientsFp32) {
  torch::manual_seed(0);
  torch::nn::Linear lin(64, 32);
  auto x = torch::randn({4, 64});
  auto ref = lin(x);
  torch::Tensor y;
  {
    AutocastGuard amp(torch::kCPU, true);
    y = lin(x);
  }
  EXPECT_EQ(y.scalar_type(), torch::kBFloat16);
  EXPECT_LE(test::max_abs_diff(y.to(torch::kFloat32), ref), 0.05);
  y.to(torch::kFloat32).sum().backward();
  EXPECT_EQ(lin->weight.grad().scalar_type(), torch::kFloat32);  // fp32 master weights get fp32 gradients
}

// training.tf32 (the official use_tf32): both CUDA switches follow it on a CUDA device; on the CPU nothing moves.
TEST(Autocast, Tf32SwitchActsOnCudaDevicesOnly) {
  auto& context = at::globalContext();
  const bool cublas = context.allowTF32CuBLAS(), cudnn = context.allowTF32CuDNN();
  EXPECT_FALSE(set_cuda_tf32(torch::kCPU, !cublas));
  EXPECT_EQ(context.allowTF32CuBLAS(), cublas);
  EXPECT_EQ(context.allowTF32CuDNN(), cudnn);
  for (bool on : {true, false}) {
    EXPECT_TRUE(set_cuda_tf32(torch::Device(torch::kCUDA, 0), on));  // the flags exist without a GPU
    EXPECT_EQ(context.allowTF32CuBLAS(), on);
    EXPECT_EQ(context.allowTF32CuDNN(), on);
  }
  context.setAllowTF32CuBLAS(cublas);
  context.setAllowTF32CuDNN(cudnn);
}
