// torch.save files without Python: the official UP-LVSM training checkpoint (zip, OrderedDict + optimizer state),
// Meta-style DINOv2 .pth (zip), the LPIPS legacy-format .pth files; corrupt and truncated files; a pickle fuzz.
#include <gtest/gtest.h>

#include <caffe2/serialize/inline_container.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/torch_file.h"
#include "uplvsm/io/zip_directory.h"

using namespace uplvsm;
using Kind = io::PyObject::Kind;

namespace {
std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}
void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}
}  // namespace

TEST(TorchFile, OfficialCheckpointModelEqualsSafetensors) {
  UPLVSM_NEEDS_FIXTURES();
  io::TorchFile file(test::fixture("official_uplvsm/checkpoint.pt"));
  EXPECT_EQ(file.format(), "zip");
  const auto& root = file.root();
  ASSERT_TRUE(root.is(Kind::Dict));
  std::vector<std::string> keys;
  for (const auto& [k, v] : root.dict) keys.push_back(k->text);
  EXPECT_EQ(keys,
            (std::vector<std::string>{"model", "optimizer", "lr_scheduler", "fwdbwd_pass_step", "param_update_step"}));
  EXPECT_EQ(root.get("fwdbwd_pass_step")->integer, 1);

  auto expected = io::read_safetensors(test::fixture("official_uplvsm/model.safetensors")).tensors;
  std::string where;
  auto model = io::read_torch_state_dict(test::fixture("official_uplvsm/checkpoint.pt"), &where);
  EXPECT_EQ(where, "model");
  ASSERT_EQ(model.size(), expected.size());
  for (const auto& [k, v] : expected) {
    ASSERT_TRUE(model.count(k)) << k;
    EXPECT_EQ(model.at(k).dtype(), torch::kFloat32) << k;
    EXPECT_TRUE(torch::equal(model.at(k), v)) << k;  // bit-for-bit
  }

  // The optimiser part parses too: BINFLOAT hyper-parameters, 0-dim step tensors, two param groups.
  const auto* optimizer = root.get("optimizer");
  ASSERT_NE(optimizer, nullptr);
  const auto* groups = optimizer->get("param_groups");
  ASSERT_TRUE(groups && groups->is(Kind::List));
  ASSERT_EQ(groups->items.size(), 2u);
  EXPECT_DOUBLE_EQ(groups->items[0]->get("weight_decay")->real, 0.05);
  EXPECT_DOUBLE_EQ(groups->items[0]->get("betas")->items[1]->real, 0.95);
  const auto* state = optimizer->get("state");
  ASSERT_TRUE(state && state->is(Kind::Dict) && !state->dict.empty());
  auto step = file.tensor(*state->dict.front().second->get("step"));
  EXPECT_EQ(step.dim(), 0);
  EXPECT_EQ(step.item<double>(), 1.0);
}

TEST(TorchFile, Dinov2PthEqualsSafetensors) {
  UPLVSM_NEEDS_FIXTURES();
  auto pth = io::read_torch_state_dict(test::fixture("dinov2/weights.pth"));
  auto st = io::read_safetensors(test::fixture("dinov2/weights.safetensors")).tensors;
  ASSERT_EQ(pth.size(), st.size());
  for (const auto& [k, v] : st) EXPECT_TRUE(torch::equal(pth.at(k), v.to(torch::kFloat32))) << k;
}

TEST(TorchFile, LegacyLpipsWeights) {
  UPLVSM_NEEDS_FIXTURES();
  for (std::string net : {"alex", "vgg"}) {
    io::TorchFile file(test::fixture("lpips/" + net + ".pth"));
    EXPECT_EQ(file.format(), "legacy");
    auto pth = io::read_torch_state_dict(test::fixture("lpips/" + net + ".pth"));
    auto st = io::read_safetensors(test::fixture("lpips/lin_" + net + ".safetensors")).tensors;
    ASSERT_EQ(pth.size(), 5u) << net;
    for (int k = 0; k < 5; ++k) {
      auto key = "lin" + std::to_string(k) + ".model.1.weight";
      ASSERT_TRUE(pth.count(key)) << net << " " << key;
      EXPECT_TRUE(torch::equal(pth.at(key), st.at("lin" + std::to_string(k)))) << net << " " << key;
    }
  }
}

TEST(TorchFile, NotATorchFileIsNamed) {
  auto dir = test::temp_dir("torch_file_bad");
  auto path = (dir / "weights.pt").string();
  write_bytes(path, "hello, not a checkpoint");
  EXPECT_FALSE(io::looks_like_torch_file(path));
  auto msg = test::error_of([&] { io::TorchFile f(path); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("not a torch.save file"), std::string::npos) << msg;
  // A dict without tensors anywhere is refused with the keys it has.
  auto nothing = test::error_of([&] { io::read_torch_state_dict(test::fixture("lpips/alex.pth") + ".missing"); });
  EXPECT_NE(nothing.find("cannot open"), std::string::npos) << nothing;
}

TEST(TorchFile, TruncatedFilesGiveClearErrors) {
  UPLVSM_NEEDS_FIXTURES();
  auto dir = test::temp_dir("torch_file_truncated");
  for (std::string name : {"official_uplvsm/checkpoint.pt", "lpips/vgg.pth"}) {
    auto bytes = read_bytes(test::fixture(name));
    for (double fraction : {0.1, 0.5, 0.9, 0.999}) {
      auto path = (dir / "cut.pt").string();
      write_bytes(path, bytes.substr(0, size_t(double(bytes.size()) * fraction)));
      auto msg = test::error_of([&] {
        auto sd = io::read_torch_state_dict(path);
        for (auto& [k, v] : sd) v.sum();  // touch every tensor
      });
      EXPECT_NE(msg.find(path), std::string::npos) << name << " cut at " << fraction << ": " << msg;
    }
  }
}

// Random byte edits of real pickles must end in a runtime_error or a parse, never a crash or a hang.
TEST(TorchFile, Protocol2BytesAreBytes) {
  // pickle.dumps(b"A\xff", protocol=2): _codecs.encode("A\u00ff", "latin1"), the text held as UTF-8.
  const std::string data(
      "\x80\x02"
      "c_codecs\nencode\nq\x00X\x03\x00\x00\x00"
      "A\xc3\xbfq\x01X\x06\x00\x00\x00latin1"
      "q\x02\x86q\x03Rq\x04.",
      50);
  size_t pos = 0;
  auto out = io::unpickle(reinterpret_cast<const uint8_t*>(data.data()), data.size(), &pos, {}, "bytes");
  ASSERT_TRUE(out->is(Kind::Bytes)) << out->describe();
  EXPECT_EQ(out->text, std::string("A\xff"));
  EXPECT_EQ(pos, data.size());
}

TEST(TorchFile, PickleFuzz) {
  UPLVSM_NEEDS_FIXTURES();
  caffe2::serialize::PyTorchStreamReader zip(test::fixture("official_uplvsm/checkpoint.pt"));
  auto [ptr, n] = zip.getRecord("data.pkl");
  const std::string original(static_cast<const char*>(ptr.get()), n);
  io::PersistentLoad storages = [](const io::PyObject& pid) {
    auto s = std::make_shared<io::PyObject>();
    s->kind = Kind::Storage;
    s->tensor.storage_numel = pid.items.size() > 4 && pid.items[4]->is(Kind::Int) ? pid.items[4]->integer : 0;
    return s;
  };
  std::mt19937 rng(7);
  int parsed = 0, rejected = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::string data = original;
    const int edits = 1 + int(rng() % 4);
    for (int e = 0; e < edits; ++e) data[rng() % data.size()] = char(rng() % 256);
    if (trial % 10 == 0) data.resize(rng() % data.size());
    size_t pos = 0;
    try {
      io::unpickle(reinterpret_cast<const uint8_t*>(data.data()), data.size(), &pos, storages, "fuzz");
      ++parsed;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("fuzz"), std::string::npos) << e.what();
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 100);
  EXPECT_EQ(parsed + rejected, 3000);
}

TEST(TorchFile, LegacyFuzz) {
  UPLVSM_NEEDS_FIXTURES();
  auto dir = test::temp_dir("torch_file_fuzz");
  const auto original = read_bytes(test::fixture("lpips/alex.pth"));
  std::mt19937 rng(11);
  for (int trial = 0; trial < 300; ++trial) {
    std::string data = original;
    for (int e = 0; e < 3; ++e) data[rng() % data.size()] = char(rng() % 256);
    auto path = (dir / "f.pth").string();
    write_bytes(path, data);
    try {
      auto sd = io::read_torch_state_dict(path);
      for (auto& [k, v] : sd) v.sum();
    } catch (const std::runtime_error&) {
    }
  }
  SUCCEED();  // reaching here without a crash is the check
}

// LibTorch's zip reader allocates the size a record declares before reading it: a central directory entry that
// claims 2 GB for data.pkl in a 2 kB file is refused from the directory, naming the file and the record.
TEST(TorchFile, ZipRecordClaimingMoreThanTheFileHoldsIsRefused) {
  const std::string seed = std::string(UPLVSM_SOURCE_DIR) + "/fuzz/corpus/torch_file/official_like_zip.pt";
  const auto entries = io::read_zip_directory(seed);
  ASSERT_FALSE(entries.empty());
  bool has_pickle = false;
  for (const auto& e : entries) {
    EXPECT_EQ(e.method, 0) << e.name;  // torch.save stores records uncompressed
    EXPECT_EQ(e.compressed_size, e.uncompressed_size) << e.name;
    has_pickle |= e.name.size() >= 8 && e.name.compare(e.name.size() - 8, 8, "data.pkl") == 0;
  }
  EXPECT_TRUE(has_pickle);

  auto bytes = read_bytes(seed);
  const auto entry = bytes.find(std::string("PK\x01\x02", 4));  // the first central directory entry
  ASSERT_NE(entry, std::string::npos);
  for (size_t i = 0; i < 4; ++i) bytes[entry + 24 + i] = char(i == 3 ? 0x7f : 0xff);  // uncompressed: 2^31 - 1
  auto dir = test::temp_dir("torch_file_zip_bomb");
  const auto path = (dir / "bomb.pt").string();
  write_bytes(path, bytes);
  const auto msg = test::error_of([&] { io::TorchFile file(path); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("claims 2147483647 bytes"), std::string::npos) << msg;

  write_bytes(path, bytes.substr(0, bytes.size() - 30));  // cut inside the end-of-directory record
  EXPECT_NE(test::error_of([&] { io::TorchFile file(path); }).find(path), std::string::npos);
}

// A tensor view may repeat stored values (stride 0, or one tensor referenced many times): copies of such views are
// limited to the file's size, so a 1 kB file cannot ask for 256 GiB.
TEST(TorchFile, StridedViewCopiesAreBoundedByTheFileSize) {
  const std::string path = std::string(UPLVSM_SOURCE_DIR) + "/fuzz/corpus/torch_file/regression_stride0_view.pt";
  const auto msg = test::error_of([&] { io::read_torch_state_dict(path); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("strided tensor views would copy more bytes than the file holds"), std::string::npos) << msg;
  // A transposed weight (a legitimate strided view) is copied within the budget.
  auto sd = io::read_torch_state_dict(std::string(UPLVSM_SOURCE_DIR) + "/fuzz/corpus/torch_file/official_like_zip.pt");
  ASSERT_TRUE(sd.count("head.weight"));
  EXPECT_EQ(sd.at("head.weight").sizes(), (std::vector<int64_t>{4, 3}));
  EXPECT_TRUE(sd.at("head.weight").is_contiguous());
}

// A pickle nests one level per opcode byte (TUPLE1): a million levels must parse and be released without
// recursing (the recursive release overflowed the stack; found by reasoning, confirmed under AddressSanitizer).
TEST(TorchFile, DeeplyNestedPickleIsReleasedWithoutRecursion) {
  std::string data = "\x80\x02]" + std::string(1000000, '\x85') + ".";
  size_t pos = 0;
  io::PersistentLoad none = [](const io::PyObject&) -> io::PyPtr { throw std::runtime_error("no storages"); };
  auto root = io::unpickle(reinterpret_cast<const uint8_t*>(data.data()), data.size(), &pos, none, "deep");
  ASSERT_TRUE(root->is(Kind::Tuple));
  EXPECT_EQ(pos, data.size());
  root.reset();  // the check: no stack overflow here
  SUCCEED();
}
