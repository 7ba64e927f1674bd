// Tests of model/bf16_linear: the weight-gradient product against an fp64 computation rounded once to bf16, over
// shapes that exercise the odd row, the output-row and column tails and the split into parts; its independence of
// the thread count; the linear's forward and gradients against autocast's ATen linear; Linear taking it in
// autocast training only; ATen's weight gradient where the CPU has AMX-BF16 or where chosen.
#include "uplvsm/kernels/bf16_linear.h"

#include <ATen/Parallel.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "uplvsm/core/autocast.h"
#include "uplvsm/kernels/bf16_simd.h"
#include "uplvsm/model/linear.h"

using namespace uplvsm;

namespace {

bool has_bf16_dot_products() { return isa_at_least(Isa::Avx512Bf16); }

// Our weight gradient for a scope, whatever the start-up chose (ATen's on a CPU with AMX-BF16).
struct OurWeightGradient {
  kernels::WeightGradientPath before = kernels::weight_gradient_path();
  OurWeightGradient() { kernels::set_weight_gradient_path(kernels::WeightGradientPath::Ours); }
  ~OurWeightGradient() { kernels::set_weight_gradient_path(before); }
};

torch::Tensor bf16_randn(std::vector<int64_t> shape, uint64_t seed) {
  torch::manual_seed(seed);
  return torch::randn(shape).to(torch::kBFloat16);
}

// The number of values of `got` (bf16) further than `steps` bf16 steps of 2^-8 relative from `truth` (fp64), with
// `floor` absolute for sums that cancel.
int64_t off_by_more_than(const torch::Tensor& got, const torch::Tensor& truth, double steps, double floor) {
  auto g = got.to(torch::kFloat64), t = truth.to(torch::kFloat64);
  return ((g - t).abs() > t.abs() * steps * std::ldexp(1.0, -8) + floor).sum().item<int64_t>();
}

TEST(Bf16Linear, WeightGradientIsTheExactProductRoundedOnce) {
  if (!has_bf16_dot_products()) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  // K: one row, an odd count below the split into parts, above it with an odd tail; O: below a micro-kernel's rows,
  // past one 576-row task with a 24-row tail, a 5-row tail; I: one vector, a 64-column panel plus 16 and 32, a wide
  // one.
  const std::vector<std::array<int64_t, 3>> shapes = {
      {1, 7, 16}, {999, 3, 48}, {4099, 600, 80}, {20001, 197, 96}, {2500, 16, 512}};
  for (const auto& [K, O, I] : shapes) {
    SCOPED_TRACE(testing::Message() << "K " << K << " O " << O << " I " << I);
    auto dy = bf16_randn({K, O}, 11 + K), x = bf16_randn({K, I}, 13 + O);
    auto got = kernels::weight_gradient_bf16(dy, x);
    ASSERT_EQ(got.sizes(), (std::vector<int64_t>{O, I}));
    ASSERT_EQ(got.scalar_type(), torch::kBFloat16);
    auto exact = dy.to(torch::kFloat64).t().mm(x.to(torch::kFloat64));
    // fp32 sums of K products of bf16 values (exact in fp32) err by ~K 2^-24 of the sum of |terms|, then one
    // rounding; the floor covers sums that cancel far below their terms' size.
    const double floor = 1e-5 * std::sqrt(static_cast<double>(K)) + 1e-6 * K;
    EXPECT_EQ(off_by_more_than(got, exact, 1.0, floor), 0);
    // And most values are exactly the fp64 sum's own rounding.
    const double same = (got.to(torch::kFloat32) == exact.to(torch::kBFloat16).to(torch::kFloat32))
                            .to(torch::kFloat64)
                            .mean()
                            .item<double>();
    EXPECT_GT(same, 0.95);
  }
}

TEST(Bf16Linear, WeightGradientDoesNotDependOnTheThreadCount) {
  if (!has_bf16_dot_products()) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  auto dy = bf16_randn({40000, 200}, 3), x = bf16_randn({40000, 64}, 4);
  const int threads = at::get_num_threads();
  at::set_num_threads(1);
  auto one = kernels::weight_gradient_bf16(dy, x);
  at::set_num_threads(3);
  auto three = kernels::weight_gradient_bf16(dy, x);
  at::set_num_threads(threads);
  auto all = kernels::weight_gradient_bf16(dy, x);
  EXPECT_TRUE(torch::equal(one, three));
  EXPECT_TRUE(torch::equal(one, all));
}

TEST(Bf16Linear, WeightGradientRejectsOperandsItCannotServeByName) {
  auto dy = bf16_randn({10, 8}, 1);
  EXPECT_THROW(kernels::weight_gradient_bf16(dy, bf16_randn({11, 16}, 2)), c10::Error);      // rows differ
  EXPECT_THROW(kernels::weight_gradient_bf16(dy, bf16_randn({10, 24}, 2)), c10::Error);      // I not 16k
  EXPECT_THROW(kernels::weight_gradient_bf16(dy, torch::randn({10, 16})), c10::Error);       // fp32
  EXPECT_THROW(kernels::weight_gradient_bf16(dy, bf16_randn({16, 10}, 2).t()), c10::Error);  // strided
  try {
    kernels::weight_gradient_bf16(dy, bf16_randn({11, 16}, 2));
  } catch (const c10::Error& e) {
    EXPECT_NE(std::string(e.what()).find("weight_gradient_bf16"), std::string::npos) << e.what();
  }
  auto zero = kernels::weight_gradient_bf16(bf16_randn({0, 8}, 1), bf16_randn({0, 16}, 2));
  EXPECT_TRUE(torch::equal(zero, torch::zeros({8, 16}, torch::kBFloat16)));
}

// The linear's output, input and bias gradients against autocast's ATen linear on the same fp32 parameters
// (the same ATen calls: equal bits), the weight gradient within a bf16 step of it (two fp32 sums in different
// orders, each rounded once).
void expect_linear_matches_autocast(bool with_bias) {
  torch::manual_seed(5);
  model::Linear ours(torch::nn::LinearOptions(96, 200).bias(with_bias));
  model::Linear reference(torch::nn::LinearOptions(96, 200).bias(with_bias));
  {
    torch::NoGradGuard no_grad;
    for (size_t i = 0; i < ours->parameters().size(); ++i) reference->parameters()[i].copy_(ours->parameters()[i]);
  }
  auto x = torch::randn({6, 700, 96}).requires_grad_(true);
  auto x_ref = x.detach().clone().requires_grad_(true);
  auto upstream = torch::randn({6, 700, 200});
  torch::Tensor y, y_ref;
  {
    AutocastGuard autocast(torch::kCPU, true);
    y = ours(x);
    y_ref = torch::linear(x_ref, reference->weight, reference->bias);
  }
  ASSERT_NE(y.grad_fn()->name().find("Bf16Linear"), std::string::npos) << y.grad_fn()->name();
  (y.to(torch::kFloat32) * upstream).sum().backward();
  (y_ref.to(torch::kFloat32) * upstream).sum().backward();
  EXPECT_TRUE(torch::equal(y, y_ref));
  EXPECT_TRUE(torch::equal(x.grad(), x_ref.grad()));
  if (with_bias) EXPECT_TRUE(torch::allclose(ours->bias.grad(), reference->bias.grad(), 1e-2, 1e-2));
  const auto& g = ours->weight.grad();
  ASSERT_EQ(g.scalar_type(), torch::kFloat32);
  EXPECT_EQ(off_by_more_than(g, reference->weight.grad(), 2.0, 1e-3), 0);
  EXPECT_GT((g == reference->weight.grad()).to(torch::kFloat64).mean().item<double>(), 0.5);
}

TEST(Bf16Linear, TrainsAsAutocastsLinearWithAndWithoutBias) {
  if (!has_bf16_dot_products()) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  OurWeightGradient ours;
  expect_linear_matches_autocast(true);
  expect_linear_matches_autocast(false);
}

TEST(Bf16Linear, CastOnceLinearTakesItOnlyInAutocastTraining) {
  if (!has_bf16_dot_products()) GTEST_SKIP() << "no AVX-512 BF16 at this ISA level";
  OurWeightGradient ours;
  model::Linear linear(torch::nn::LinearOptions(32, 16).bias(false));
  auto x = torch::randn({5, 32});
  const auto node = [&] {
    auto y = linear(x);
    return y.grad_fn() ? y.grad_fn()->name() : std::string("none");
  };
  EXPECT_EQ(node().find("Bf16Linear"), std::string::npos) << "fp32 training stays ATen's";
  {
    AutocastGuard autocast(torch::kCPU, true);
    EXPECT_NE(node().find("Bf16Linear"), std::string::npos);
    torch::NoGradGuard no_grad;
    EXPECT_EQ(node(), "none") << "inference keeps the cast-once path";
  }
  model::Linear odd(torch::nn::LinearOptions(24, 16).bias(false));  // input width not a multiple of 16
  AutocastGuard autocast(torch::kCPU, true);
  auto y = odd(torch::randn({5, 24}));
  EXPECT_EQ(y.grad_fn()->name().find("Bf16Linear"), std::string::npos) << y.grad_fn()->name();
}

TEST(Bf16Linear, AtensWeightGradientWhereTheCpuHasAmxOrWhenChosen) {
  CpuFeatures bf16_only, amx;
  bf16_only.avx512 = bf16_only.avx512_bf16 = true;
  amx = bf16_only;
  amx.amx_bf16 = true;
  EXPECT_EQ(kernels::default_weight_gradient_path(bf16_only), kernels::WeightGradientPath::Ours);
  EXPECT_EQ(kernels::default_weight_gradient_path(amx), kernels::WeightGradientPath::Aten);
  if (std::getenv("UPLVSM_WEIGHT_GRADIENT") == nullptr)
    EXPECT_EQ(kernels::weight_gradient_path(), kernels::default_weight_gradient_path(detect_cpu_features()));
  // Chosen at run time, Linear follows: autocast training takes ATen's linear with ATen's chosen.
  const auto before = kernels::weight_gradient_path();
  kernels::set_weight_gradient_path(kernels::WeightGradientPath::Aten);
  model::Linear linear(torch::nn::LinearOptions(32, 16).bias(false));
  {
    AutocastGuard autocast(torch::kCPU, true);
    auto y = linear(torch::randn({5, 32}));
    EXPECT_EQ(y.grad_fn()->name().find("Bf16Linear"), std::string::npos) << y.grad_fn()->name();
  }
  kernels::set_weight_gradient_path(before);
}

}  // namespace
