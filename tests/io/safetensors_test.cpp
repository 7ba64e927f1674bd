// safetensors reader/writer: the Python-written fixtures, round trips of every dtype, and strict validation.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include "test_util.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/safetensors.h"

namespace uplvsm::io {
namespace {

using test::fixture;
using test::remove_tree;
using test::temp_dir;

// Builds a raw safetensors file from a header string and a data buffer.
std::vector<uint8_t> raw_file(const std::string& header, const std::vector<uint8_t>& data, uint64_t n_override = 0) {
  uint64_t n = n_override ? n_override : header.size();
  std::vector<uint8_t> out(8);
  for (int i = 0; i < 8; ++i) out[i] = static_cast<uint8_t>(n >> (8 * i));
  out.insert(out.end(), header.begin(), header.end());
  out.insert(out.end(), data.begin(), data.end());
  return out;
}

void write_raw(const std::string& path, const std::vector<uint8_t>& bytes) {
  write_file_atomic(path, bytes.data(), bytes.size());
}

// Expects read_safetensors to throw with a message that names the path and contains `fragment`.
void expect_read_error(const std::string& path, const std::string& fragment) {
  try {
    read_safetensors(path);
    FAIL() << "no error for " << path;
  } catch (const std::runtime_error& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(fragment), std::string::npos) << msg;
  }
}

TEST(AtomicFile, WriteReadAndCreateParents) {
  auto dir = temp_dir("atomic");
  std::string path = (dir / "a" / "b" / "file.bin").string();
  std::string text = "hello atomic";
  write_file_atomic(path, text.data(), text.size());
  auto bytes = read_file(path);
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), text);
  write_file_atomic(path, "xy", 2);  // overwrite
  bytes = read_file(path);
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "xy");
  // No temporary files left behind.
  int n = 0;
  for (auto& e : std::filesystem::directory_iterator(dir / "a" / "b")) n += e.is_regular_file();
  EXPECT_EQ(n, 1);
  EXPECT_THROW(read_file((dir / "missing.bin").string()), std::runtime_error);
  try {
    read_file((dir / "missing.bin").string());
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.bin"), std::string::npos);
  }
  remove_tree(dir);
}

TEST(Safetensors, ReadsTransformerWeightsFixture) {
  UPLVSM_NEEDS_FIXTURES();
  auto st = read_safetensors(fixture("lvsm/transformer_weights.safetensors"));
  ASSERT_EQ(st.tensors.size(), 16u);
  EXPECT_EQ(st.tensors.at("transformer_blocks.0.attn.to_qkv.weight").sizes(), (std::vector<int64_t>{384, 128}));
  EXPECT_EQ(st.tensors.at("transformer_blocks.1.mlp.mlp.0.weight").sizes(), (std::vector<int64_t>{512, 128}));
  EXPECT_EQ(st.tensors.at("transformer_blocks.1.mlp.mlp.2.weight").sizes(), (std::vector<int64_t>{128, 512}));
  EXPECT_EQ(st.tensors.at("transformer_blocks.0.attn.q_norm.weight").sizes(), (std::vector<int64_t>{32}));
  for (const auto& [name, t] : st.tensors) {
    EXPECT_EQ(t.scalar_type(), torch::kFloat32) << name;
    EXPECT_TRUE(torch::isfinite(t).all().item<bool>()) << name;
  }
  // Norm weights ~ N(1, 0.3^2), so their mean is near 1: a byte-order or offset mistake would not be.
  double mean = st.tensors.at("transformer_blocks.0.norm1.weight").mean().item<double>();
  EXPECT_NEAR(mean, 1.0, 0.15);
}

TEST(Safetensors, ReadsHalfPrecisionDinoWeights) {
  UPLVSM_NEEDS_FIXTURES();
  auto st = read_safetensors(fixture("dinov2/weights.safetensors"));
  const auto& pos = st.tensors.at("pos_embed");
  EXPECT_EQ(pos.scalar_type(), torch::kHalf);
  EXPECT_EQ(pos.sizes(), (std::vector<int64_t>{1, 1370, 384}));
  // pos_embed ~ N(0, 0.5^2).
  double std = pos.to(torch::kFloat32).std().item<double>();
  EXPECT_NEAR(std, 0.5, 0.05);
  EXPECT_EQ(st.tensors.at("patch_embed.proj.weight").sizes(), (std::vector<int64_t>{384, 3, 14, 14}));
}

TEST(Safetensors, ReadsOfficialModelWithMetadata) {
  UPLVSM_NEEDS_FIXTURES();
  std::map<std::string, std::string> md;
  auto header = read_safetensors_header(fixture("official_uplvsm/model.safetensors"), &md);
  EXPECT_EQ(header.size(), 93u);
  auto st = read_safetensors(fixture("official_uplvsm/model.safetensors"));
  EXPECT_EQ(st.tensors.size(), 93u);
  EXPECT_EQ(st.metadata.at("format"), "pt");
  EXPECT_EQ(md.at("format"), "pt");
  int64_t params = 0;
  for (const auto& [name, t] : st.tensors) params += t.numel();
  EXPECT_EQ(params, 667047);  // per the fixture README
}

TEST(Safetensors, RoundTripsEveryDtype) {
  auto dir = temp_dir("st_roundtrip");
  std::string path = (dir / "all.safetensors").string();
  torch::manual_seed(0);
  TensorMap in;
  in["f64"] = torch::randn({3, 2}, torch::kFloat64);
  in["f32"] = torch::randn({4, 5});
  in["f16"] = torch::randn({7}).to(torch::kHalf);
  in["bf16"] = torch::randn({2, 3, 2}).to(torch::kBFloat16);
  in["i64"] = torch::randint(-1000000000000LL, 1000000000000LL, {5}, torch::kInt64);
  in["i32"] = torch::randint(-100000, 100000, {3, 3}, torch::kInt32);
  in["i16"] = torch::randint(-30000, 30000, {6}, torch::kInt16);
  in["i8"] = torch::randint(-128, 127, {9}, torch::kInt8);
  in["u8"] = torch::randint(0, 255, {11}, torch::kUInt8);  // odd size: later tensors start unaligned
  in["bool"] = torch::randn({13}) > 0;
  in["scalar"] = torch::tensor(3.25);
  in["empty"] = torch::zeros({0, 4});
  in["strided"] = torch::arange(24, torch::kFloat32).view({4, 6}).t();  // non-contiguous input
  std::map<std::string, std::string> md{{"format", "pt"}, {"note", "quote \" and unicode é"}};
  write_safetensors(path, in, md);

  auto out = read_safetensors(path);
  EXPECT_EQ(out.metadata, md);
  ASSERT_EQ(out.tensors.size(), in.size());
  for (const auto& [name, t] : in) {
    const auto& r = out.tensors.at(name);
    EXPECT_EQ(r.scalar_type(), t.scalar_type()) << name;
    EXPECT_EQ(r.sizes(), t.sizes()) << name;
    EXPECT_TRUE(torch::equal(r, t)) << name;
  }
  EXPECT_EQ(out.tensors.at("scalar").dim(), 0);

  // Header: length multiple of 8, space padded, tensors in name order with contiguous offsets.
  auto bytes = read_file(path);
  uint64_t n = 0;
  for (int i = 7; i >= 0; --i) n = (n << 8) | bytes[i];
  EXPECT_EQ(n % 8, 0u);
  auto header = read_safetensors_header(path);
  int64_t offset = 0;
  for (const auto& [name, e] : header) {  // std::map iterates in name order, as the writer stores
    EXPECT_EQ(e.begin, offset) << name;
    offset = e.end;
  }
  EXPECT_EQ(bytes.size(), 8 + n + static_cast<uint64_t>(offset));
  remove_tree(dir);
}

TEST(Safetensors, EmptyMapAndNoMetadata) {
  auto dir = temp_dir("st_empty");
  std::string path = (dir / "empty.safetensors").string();
  write_safetensors(path, {});
  auto st = read_safetensors(path);
  EXPECT_TRUE(st.tensors.empty());
  EXPECT_TRUE(st.metadata.empty());
  remove_tree(dir);
}

TEST(Safetensors, WriterRejectsUnsupportedDtype) {
  auto dir = temp_dir("st_bad_dtype");
  std::string path = (dir / "c.safetensors").string();
  TensorMap m{{"c", torch::zeros({2}, torch::kComplexFloat)}};
  EXPECT_THROW(write_safetensors(path, m), std::runtime_error);
  EXPECT_FALSE(std::filesystem::exists(path));
  remove_tree(dir);
}

TEST(Safetensors, TrailingBytesAreIgnored) {
  auto dir = temp_dir("st_trailing");
  std::string path = (dir / "t.safetensors").string();
  std::vector<uint8_t> data(8 + 5, 0xAB);
  float v[2] = {1.5f, -2.0f};
  std::memcpy(data.data(), v, 8);
  write_raw(path, raw_file(R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})", data));
  auto st = read_safetensors(path);
  EXPECT_FLOAT_EQ(st.tensors.at("a")[1].item<float>(), -2.0f);
  remove_tree(dir);
}

TEST(Safetensors, CorruptedFilesRaiseErrorsNamingThePath) {
  auto dir = temp_dir("st_corrupt");
  auto p = [&](const std::string& name) { return (dir / name).string(); };
  std::vector<uint8_t> eight(8, 0);
  const std::string ok_entry = R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})";

  write_raw(p("short.st"), {1, 2, 3});
  expect_read_error(p("short.st"), "shorter than");

  // A valid file cut in the middle of its data.
  TensorMap m{{"w", torch::randn({64})}};
  write_safetensors(p("full.st"), m);
  auto full = read_file(p("full.st"));
  full.resize(full.size() - 10);
  write_raw(p("truncated.st"), full);
  expect_read_error(p("truncated.st"), "beyond the data buffer");

  write_raw(p("hugeheader.st"), raw_file(ok_entry, eight, 1ull << 40));
  expect_read_error(p("hugeheader.st"), "header length");

  write_raw(p("badjson.st"), raw_file(R"({"a":{"dtype":"F32",)", eight));
  expect_read_error(p("badjson.st"), "invalid JSON");

  write_raw(p("dtype.st"), raw_file(R"({"a":{"dtype":"F12","shape":[2],"data_offsets":[0,8]}})", eight));
  expect_read_error(p("dtype.st"), "unknown dtype 'F12'");

  write_raw(p("beyond.st"), raw_file(R"({"a":{"dtype":"F32","shape":[4],"data_offsets":[0,16]}})", eight));
  expect_read_error(p("beyond.st"), "beyond the data buffer");

  write_raw(p("size.st"), raw_file(R"({"a":{"dtype":"F32","shape":[3],"data_offsets":[0,8]}})", eight));
  expect_read_error(p("size.st"), "need 12");

  write_raw(p("neg.st"), raw_file(R"({"a":{"dtype":"F32","shape":[-2],"data_offsets":[0,8]}})", eight));
  expect_read_error(p("neg.st"), "negative dimension");

  std::vector<uint8_t> twelve(12, 0);
  write_raw(p("overlap.st"), raw_file(R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]},)"
                                      R"("b":{"dtype":"F32","shape":[2],"data_offsets":[4,12]}})",
                                      twelve));
  expect_read_error(p("overlap.st"), "overlapping");

  write_raw(p("reversed.st"), raw_file(R"({"a":{"dtype":"F32","shape":[0],"data_offsets":[8,0]}})", eight));
  expect_read_error(p("reversed.st"), "invalid data_offsets");

  write_raw(p("missing.st"), raw_file(R"({"a":{"dtype":"F32","shape":[2]}})", eight));
  expect_read_error(p("missing.st"), "missing field 'data_offsets'");

  write_raw(p("meta.st"), raw_file(R"({"__metadata__":{"k":1}})", {}));
  expect_read_error(p("meta.st"), "__metadata__");

  expect_read_error(p("does_not_exist.st"), "cannot open");
  remove_tree(dir);
}

}  // namespace
}  // namespace uplvsm::io
