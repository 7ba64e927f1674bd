#include <gtest/gtest.h>

#include <cstdlib>
#include <stdexcept>

#include "test_util.h"
#include "uplvsm/core/runtime.h"

using namespace uplvsm;

TEST(Runtime, OpenBlasFallbackCoreIsReplacedByTheCpusBest) {
  CpuFeatures sapphire_rapids{true, true, true};
  CpuFeatures skylake_x{true, true, false};
  CpuFeatures haswell{true, false, false};
  CpuFeatures old_cpu{};
  // OpenBLAS 0.3.21 reports an unknown new CPU as Prescott: ask for the widest kernels the CPU runs.
  EXPECT_EQ(openblas_core_for_cpu("Prescott", sapphire_rapids), "Cooperlake");
  EXPECT_EQ(openblas_core_for_cpu("Prescott", skylake_x), "SkylakeX");
  EXPECT_EQ(openblas_core_for_cpu("Prescott", haswell), "Haswell");
  EXPECT_EQ(openblas_core_for_cpu("Prescott", old_cpu), "");
  // A core OpenBLAS recognised is left alone.
  EXPECT_EQ(openblas_core_for_cpu("Haswell", sapphire_rapids), "");
  EXPECT_EQ(openblas_core_for_cpu("Cooperlake", sapphire_rapids), "");
  EXPECT_EQ(openblas_core_for_cpu("Zen", haswell), "");
}

TEST(Runtime, BlasWarningNamesTheCauseAndTheFix) {
  CpuFeatures sapphire_rapids{true, true, true};
  CpuFeatures haswell{true, false, false};
  auto openblas = [](const std::string& core) {
    RuntimeInfo info;
    info.blas_library = "/usr/lib/x86_64-linux-gnu/openblas-openmp/libblas.so.3";
    info.blas_config = "OpenBLAS 0.3.21 DYNAMIC_ARCH";
    info.blas_core = core;
    return info;
  };
  // OpenBLAS's own good pick, or the best core pinned by hand: nothing to say.
  EXPECT_EQ(blas_warning(openblas("Cooperlake"), sapphire_rapids, nullptr), "");
  EXPECT_EQ(blas_warning(openblas("Cooperlake"), sapphire_rapids, "Cooperlake"), "");
  EXPECT_EQ(blas_warning(openblas("Haswell"), haswell, nullptr), "");
  EXPECT_EQ(blas_warning(openblas("Zen"), haswell, "Zen"), "");
  EXPECT_EQ(blas_warning(openblas("SomeFutureCore"), sapphire_rapids, nullptr), "");  // unknown: no guess
  // The environment holds OpenBLAS to narrower kernels: unset it, or ask for the best.
  auto pinned = blas_warning(openblas("Haswell"), sapphire_rapids, "Haswell");
  EXPECT_NE(pinned.find("OPENBLAS_CORETYPE=Haswell in the environment"), std::string::npos) << pinned;
  EXPECT_NE(pinned.find("unset OPENBLAS_CORETYPE"), std::string::npos) << pinned;
  EXPECT_NE(pinned.find("OPENBLAS_CORETYPE=Cooperlake"), std::string::npos) << pinned;
  // A CPU newer than OpenBLAS: its fallback kernels, fixed by setting the variable.
  auto fallback = blas_warning(openblas("Prescott"), sapphire_rapids, nullptr);
  EXPECT_NE(fallback.find("Prescott fallback kernels"), std::string::npos) << fallback;
  EXPECT_NE(fallback.find("start Python with OPENBLAS_CORETYPE=Cooperlake"), std::string::npos) << fallback;
  // The reference BLAS.
  RuntimeInfo reference;
  reference.blas_library = "/usr/lib/x86_64-linux-gnu/blas/libblas.so.3";
  auto slow = blas_warning(reference, haswell, nullptr);
  EXPECT_NE(slow.find("reference BLAS (/usr/lib/x86_64-linux-gnu/blas/libblas.so.3)"), std::string::npos) << slow;
  EXPECT_EQ(best_openblas_core(CpuFeatures{}), "");
}

TEST(Runtime, LoadedOpenBlasUsesVectorKernelsTheCpuSupports) {
  // The tests run through the same start-up as the binary, so a fallback core must have been fixed by now
  // (unless the environment pins OPENBLAS_CORETYPE, which always wins).
  if (const auto why = test::no_shared_blas()) GTEST_SKIP() << *why;
  auto info = runtime_info();
  ASSERT_FALSE(info.blas_core.empty()) << "OpenBLAS is not the loaded BLAS";
  if (std::getenv("OPENBLAS_CORETYPE") == nullptr)
    EXPECT_EQ(openblas_core_for_cpu(info.blas_core, detect_cpu_features()), "") << info.blas_core;
  EXPECT_NE(format_runtime_info(info).find("BLAS core    " + info.blas_core), std::string::npos);
}

TEST(Runtime, CpuFeaturesAreNamedInInfo) {
  EXPECT_EQ(describe_cpu_features(CpuFeatures{}), "-");
  CpuFeatures amx;
  amx.avx2_fma = amx.avx512 = amx.avx512_bf16 = amx.amx_bf16 = true;
  EXPECT_EQ(describe_cpu_features(amx), "AVX2+FMA AVX-512 AVX-512-BF16 AMX-BF16");
  CpuFeatures avx2;
  avx2.avx2_fma = true;
  EXPECT_EQ(describe_cpu_features(avx2), "AVX2+FMA");
  const auto cpu = detect_cpu_features();
  EXPECT_TRUE(!cpu.amx_bf16 || cpu.avx512) << "AMX-BF16 without AVX-512 on an x86 CPU";
  const auto info = runtime_info();
  EXPECT_NE(format_runtime_info(info).find("CPU          " + describe_cpu_features(cpu)), std::string::npos);
}

TEST(Runtime, DeviceNamesAreParsedOrRejectedClearly) {
  EXPECT_EQ(parse_device("cpu"), torch::Device(torch::kCPU));
  try {
    parse_device("gpu");
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'gpu'"), std::string::npos) << e.what();
  }
}

TEST(Runtime, LargeTensorsAreServedFromTheHeapAfterInit) {
  // test_main calls init_runtime(); unless the environment sets glibc's thresholds itself, large blocks (decoder
  // activations) must come from the heap, not a fresh mmap per op (README, Allocator).
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer replaces malloc: glibc's thresholds do not apply (make sanitize)";
#endif
  const auto info = uplvsm::runtime_info();
  if (std::getenv("MALLOC_MMAP_THRESHOLD_") || std::getenv("MALLOC_TRIM_THRESHOLD_") || std::getenv("GLIBC_TUNABLES"))
    GTEST_SKIP() << "glibc thresholds come from the environment";
  EXPECT_NE(info.allocator.find("1 GiB"), std::string::npos) << info.allocator;
  EXPECT_NE(uplvsm::format_runtime_info(info).find("allocator"), std::string::npos);
}
