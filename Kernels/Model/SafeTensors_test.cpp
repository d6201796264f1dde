#include "Model/SafeTensors.h"

#include <gtest/gtest.h>

#include <cstring>

#include "Model/InrModel.h"
#include "TestSupport/TestModelBuilder.h"

namespace inr {
namespace {

std::vector<std::uint8_t> rawFile(const std::string& header, const std::vector<std::uint8_t>& payload) {
  std::vector<std::uint8_t> out(8 + header.size() + payload.size());
  const std::uint64_t len = header.size();
  for (int i = 0; i < 8; ++i) out[i] = std::uint8_t(len >> (8 * i));
  std::memcpy(out.data() + 8, header.data(), header.size());
  if (!payload.empty()) std::memcpy(out.data() + 8 + header.size(), payload.data(), payload.size());
  return out;
}

std::string errorOf(const std::vector<std::uint8_t>& bytes) {
  try {
    parseSafeTensors(bytes.data(), bytes.size(), "x.inr");
  } catch (const ModelError& e) {
    return e.what();
  }
  return "";
}

TEST(SafeTensors, ConvertsEveryFloatDtypeToFp32) {
  // 1.5 and -2 in each dtype, little-endian.
  std::vector<std::uint8_t> payload;
  auto put = [&](const void* p, std::size_t n) {
    payload.insert(payload.end(), (const std::uint8_t*)p, (const std::uint8_t*)p + n);
  };
  const float f32[2] = {1.5f, -2.f};
  put(f32, 8);
  const double f64[2] = {1.5, -2.0};
  put(f64, 16);
  const std::uint16_t f16[2] = {0x3e00, 0xc000};
  put(f16, 4);
  const std::uint16_t bf16[2] = {0x3fc0, 0xc000};
  put(bf16, 4);
  const std::uint16_t f16sub[1] = {0x0001};  // smallest subnormal half: 2^-24
  put(f16sub, 2);
  const std::string header =
      R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]},)"
      R"("b":{"dtype":"F64","shape":[2],"data_offsets":[8,24]},)"
      R"("c":{"dtype":"F16","shape":[2],"data_offsets":[24,28]},)"
      R"("d":{"dtype":"BF16","shape":[1,2],"data_offsets":[28,32]},)"
      R"("e":{"dtype":"F16","shape":[],"data_offsets":[32,34]},)"
      R"("__metadata__":{"k":"v"}})";
  const auto bytes = rawFile(header, payload);
  const SafeTensorFile f = parseSafeTensors(bytes.data(), bytes.size(), "x");
  for (const char* name : {"a", "b", "c", "d"}) {
    ASSERT_EQ(f.tensors.at(name).values.size(), 2u) << name;
    EXPECT_EQ(f.tensors.at(name).values[0], 1.5f) << name;
    EXPECT_EQ(f.tensors.at(name).values[1], -2.f) << name;
  }
  EXPECT_EQ(f.tensors.at("e").values.at(0), std::ldexp(1.f, -24));
  EXPECT_EQ(f.tensors.at("d").shape, (std::vector<std::int64_t>{1, 2}));
  EXPECT_EQ(f.metadata.at("k"), "v");
}

TEST(SafeTensors, RejectsShortFile) {
  EXPECT_NE(errorOf({1, 2, 3}).find("too short"), std::string::npos);
}

TEST(SafeTensors, RejectsHeaderPastEnd) {
  auto bytes = rawFile("{}", {});
  bytes[0] = 200;
  EXPECT_NE(errorOf(bytes).find("runs past the end"), std::string::npos);
}

TEST(SafeTensors, RejectsAbsurdHeaderLength) {
  auto bytes = rawFile("{}", {});
  bytes[7] = 0x7f;
  EXPECT_NE(errorOf(bytes).find("absurdly large"), std::string::npos);
}

TEST(SafeTensors, RejectsShapeThatOverflows) {
  const std::string h =
      R"({"a":{"dtype":"F32","shape":[4294967296,4294967296,16],"data_offsets":[0,4]}})";
  EXPECT_NE(errorOf(rawFile(h, {0, 0, 0, 0})).find("absurdly large"), std::string::npos);
}

TEST(SafeTensors, RejectsOverlapAndGapsAndTrailingBytes) {
  const std::vector<std::uint8_t> eight(8, 0);
  EXPECT_NE(errorOf(rawFile(R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},"b":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})", eight))
                .find("overlaps"),
            std::string::npos);
  EXPECT_NE(errorOf(rawFile(R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[4,8]}})", eight)).find("unaccounted"),
            std::string::npos);
  EXPECT_NE(errorOf(rawFile(R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]}})", eight)).find("trailing"),
            std::string::npos);
  EXPECT_NE(errorOf(rawFile(R"({"a":{"dtype":"F32","shape":[3],"data_offsets":[0,12]}})", eight)).find("run past"),
            std::string::npos);
  EXPECT_NE(errorOf(rawFile(R"({"a":{"dtype":"F32","shape":[3],"data_offsets":[0,8]}})", eight)).find("needs 12"),
            std::string::npos);
}

TEST(SafeTensors, ErrorNamesTheFile) {
  EXPECT_EQ(errorOf(rawFile("{nope", {})).rfind("x.inr: ", 0), 0u);
}

}  // namespace
}  // namespace inr
