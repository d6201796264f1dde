#include "Model/SafeTensors.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "Common/Half.h"
#include "Model/InrModel.h"

namespace inr {
namespace {

using nlohmann::json;

[[noreturn]] void fail(const std::string& label, const std::string& what) {
  throw ModelError(label + ": " + what);
}

std::size_t dtypeSize(const std::string& dtype) {
  if (dtype == "F32") return 4;
  if (dtype == "F16" || dtype == "BF16") return 2;
  if (dtype == "F64") return 8;
  return 0;
}

// Returns the flat index of the first F64 value outside the fp32 range, or `count` if none.
std::size_t convert(const std::string& dtype, const std::uint8_t* src, std::size_t count, float* dst) {
  // The file is little-endian; so is every machine we build for (x86-64, aarch64).
  if (count == 0) return 0;  // nothing to copy; `dst` may be null for an empty vector
  if (dtype == "F32") {
    std::memcpy(dst, src, count * 4);
  } else if (dtype == "F64") {
    for (std::size_t i = 0; i < count; ++i) {
      double d;
      std::memcpy(&d, src + 8 * i, 8);
      if (std::isfinite(d) && std::fabs(d) > std::numeric_limits<float>::max()) return i;
      dst[i] = static_cast<float>(d);
    }
  } else if (dtype == "F16") {
    for (std::size_t i = 0; i < count; ++i) {
      std::uint16_t h;
      std::memcpy(&h, src + 2 * i, 2);
      dst[i] = halfBitsToFloat(h);
    }
  } else {  // BF16: the top half of an fp32
    for (std::size_t i = 0; i < count; ++i) {
      std::uint16_t h;
      std::memcpy(&h, src + 2 * i, 2);
      const std::uint32_t bits = std::uint32_t(h) << 16;
      std::memcpy(dst + i, &bits, 4);
    }
  }
  return count;
}

}  // namespace

std::string shapeToString(const std::vector<std::int64_t>& shape) {
  std::ostringstream s;
  s << '[';
  for (std::size_t i = 0; i < shape.size(); ++i) s << (i ? ", " : "") << shape[i];
  s << ']';
  return s.str();
}

SafeTensorFile parseSafeTensors(const std::uint8_t* data, std::size_t size, const std::string& label) {
  if (size < 8)
    fail(label, "file is " + std::to_string(size) +
                    " bytes, too short for a safetensors header (8-byte length + JSON)");
  std::uint64_t headerLen = 0;
  for (int i = 7; i >= 0; --i) headerLen = (headerLen << 8) | data[i];
  if (headerLen > kMaxSafeTensorsHeaderBytes)
    fail(label, "safetensors header length " + std::to_string(headerLen) +
                    " bytes is absurdly large (limit " + std::to_string(kMaxSafeTensorsHeaderBytes) +
                    "); the file is not safetensors or is corrupt");
  if (headerLen > size - 8)
    fail(label, "safetensors header length " + std::to_string(headerLen) + " bytes runs past the end of the " +
                    std::to_string(size) + "-byte file (truncated or not safetensors)");
  if (headerLen == 0) fail(label, "safetensors header is empty");

  const char* headerBegin = reinterpret_cast<const char*>(data + 8);
  json header;
  try {
    header = json::parse(headerBegin, headerBegin + headerLen);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for numbers like 1e999
    fail(label, std::string("safetensors header is not valid JSON: ") + e.what());
  }
  if (!header.is_object()) fail(label, "safetensors header must be a JSON object");

  const std::uint8_t* payload = data + 8 + headerLen;
  const std::uint64_t payloadSize = size - 8 - headerLen;

  SafeTensorFile out;
  struct Span {
    std::uint64_t begin, end;
    std::string name;
  };
  std::vector<Span> spans;

  for (auto it = header.begin(); it != header.end(); ++it) {
    const std::string& name = it.key();
    const json& entry = it.value();
    if (name == "__metadata__") {
      if (!entry.is_object()) fail(label, "__metadata__ must be a JSON object of strings");
      for (auto m = entry.begin(); m != entry.end(); ++m) {
        if (!m.value().is_string())
          fail(label, "__metadata__ entry '" + m.key() + "' must be a string (safetensors stores metadata as strings; "
                      "serialise JSON values with json.dumps)");
        out.metadata[m.key()] = m.value().get<std::string>();
      }
      continue;
    }
    const std::string where = "tensor '" + name + "'";
    if (!entry.is_object()) fail(label, where + ": header entry must be an object");
    for (auto f = entry.begin(); f != entry.end(); ++f)
      if (f.key() != "dtype" && f.key() != "shape" && f.key() != "data_offsets")
        fail(label, where + ": unknown header field '" + f.key() + "'");
    if (!entry.contains("dtype") || !entry["dtype"].is_string())
      fail(label, where + ": missing string field 'dtype'");
    if (!entry.contains("shape") || !entry["shape"].is_array())
      fail(label, where + ": missing array field 'shape'");
    if (!entry.contains("data_offsets") || !entry["data_offsets"].is_array() || entry["data_offsets"].size() != 2)
      fail(label, where + ": 'data_offsets' must be an array [begin, end]");

    SafeTensor t;
    t.dtype = entry["dtype"].get<std::string>();
    const std::size_t elem = dtypeSize(t.dtype);
    if (elem == 0)
      fail(label, where + ": unsupported dtype '" + t.dtype + "' (supported: F32, F16, BF16, F64; "
                  "convert integer or quantised tensors to float before export)");

    std::uint64_t count = 1;
    for (const json& d : entry["shape"]) {
      if (!d.is_number_integer() || d.get<std::int64_t>() < 0)
        fail(label, where + ": shape entries must be non-negative integers");
      const auto dim = d.get<std::uint64_t>();
      if (dim != 0 && count > std::numeric_limits<std::uint64_t>::max() / 8 / dim)
        fail(label, where + ": shape " + entry["shape"].dump() + " is absurdly large");
      count *= dim;
      t.shape.push_back(static_cast<std::int64_t>(dim));
    }
    for (const json& o : entry["data_offsets"])
      if (!o.is_number_unsigned() && !(o.is_number_integer() && o.get<std::int64_t>() >= 0))
        fail(label, where + ": data_offsets must be non-negative integers");
    const auto begin = entry["data_offsets"][0].get<std::uint64_t>();
    const auto end = entry["data_offsets"][1].get<std::uint64_t>();
    if (begin > end) fail(label, where + ": data_offsets begin " + std::to_string(begin) + " > end " + std::to_string(end));
    if (end > payloadSize)
      fail(label, where + ": data_offsets [" + std::to_string(begin) + ", " + std::to_string(end) +
                      "] run past the end of the data section (" + std::to_string(payloadSize) + " bytes)");
    if (end - begin != count * elem)
      fail(label, where + ": data_offsets span " + std::to_string(end - begin) + " bytes but shape " +
                      shapeToString(t.shape) + " of " + t.dtype + " needs " + std::to_string(count * elem));
    if (count == 0)
      fail(label, where + " has no elements (shape " + shapeToString(t.shape) +
                      "); an INR model has no empty tensors (remove it from the file)");
    t.values.resize(count);
    const std::size_t tooLarge = convert(t.dtype, payload + begin, count, t.values.data());
    if (tooLarge < count)
      fail(label, where + " holds a value outside the fp32 range at flat index " + std::to_string(tooLarge) +
                      " (F64 weights are converted to fp32); the network weights are corrupt");
    for (std::size_t i = 0; i < count; ++i)
      if (!std::isfinite(t.values[i]))
        fail(label, where + " contains a non-finite value (" + std::to_string(t.values[i]) + ") at flat index " +
                        std::to_string(i) + "; the network weights are corrupt");
    spans.push_back({begin, end, name});
    out.tensors.emplace(name, std::move(t));
  }

  // The tensors must tile the data section exactly: no overlap (aliasing), no gaps, no trailing
  // bytes. Anything else means a damaged or hand-edited file.
  std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) {
    return a.begin != b.begin ? a.begin < b.begin : a.end < b.end;
  });
  std::uint64_t cursor = 0;
  for (const Span& s : spans) {
    if (s.begin < cursor)
      fail(label, "tensor '" + s.name + "' overlaps the previous tensor (data_offsets begin " +
                      std::to_string(s.begin) + " < " + std::to_string(cursor) + ")");
    if (s.begin > cursor)
      fail(label, "data section has " + std::to_string(s.begin - cursor) + " unaccounted bytes before tensor '" +
                      s.name + "' (offsets must cover the data exactly)");
    cursor = s.end;
  }
  if (cursor != payloadSize)
    fail(label, "data section has " + std::to_string(payloadSize - cursor) +
                    " trailing bytes not covered by any tensor (offsets must cover the data exactly)");
  return out;
}

}  // namespace inr
