#pragma once
// A strict reader for the safetensors container: an 8-byte little-endian header length, a JSON
// header, then the raw tensor bytes. Everything is bounds-checked before it is touched; tensors
// come out as fp32 whatever their stored dtype (F32, F16, BF16, F64).
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace inr {

struct SafeTensor {
  std::string dtype;                 // as stored
  std::vector<std::int64_t> shape;
  std::vector<float> values;         // converted to fp32, row-major
};

struct SafeTensorFile {
  std::map<std::string, SafeTensor> tensors;
  std::map<std::string, std::string> metadata;  // __metadata__
};

// Largest header we accept; real headers are a few KB.
constexpr std::uint64_t kMaxSafeTensorsHeaderBytes = 64ull << 20;

// Throws ModelError("<label>: <problem>") on any violation of the container rules.
SafeTensorFile parseSafeTensors(const std::uint8_t* data, std::size_t size, const std::string& label);

std::string shapeToString(const std::vector<std::int64_t>& shape);

}  // namespace inr
