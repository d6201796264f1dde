#pragma once
// IEEE binary16 <-> binary32 conversion on the host (round to nearest even), for reading F16
// tensors and for packing fp16 weights for the GPU evaluator without needing CUDA headers.
#include <cstdint>
#include <cstring>

namespace inr {

inline float halfBitsToFloat(std::uint16_t h) {
  const std::uint32_t sign = std::uint32_t(h & 0x8000u) << 16;
  std::uint32_t exponent = (h >> 10) & 0x1fu;
  std::uint32_t mantissa = h & 0x3ffu;
  std::uint32_t bits;
  if (exponent == 0) {
    if (mantissa == 0) {
      bits = sign;
    } else {  // subnormal: renormalise
      exponent = 127 - 15 + 1;
      while ((mantissa & 0x400u) == 0) {
        mantissa <<= 1;
        --exponent;
      }
      mantissa &= 0x3ffu;
      bits = sign | (exponent << 23) | (mantissa << 13);
    }
  } else if (exponent == 0x1f) {
    bits = sign | 0x7f800000u | (mantissa << 13);
  } else {
    bits = sign | ((exponent + 127 - 15) << 23) | (mantissa << 13);
  }
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

inline std::uint16_t floatToHalfBits(float f) {
  std::uint32_t x;
  std::memcpy(&x, &f, 4);
  const std::uint16_t sign = std::uint16_t((x >> 16) & 0x8000u);
  const std::uint32_t absx = x & 0x7fffffffu;
  if (absx >= 0x7f800000u)  // Inf / NaN
    return sign | 0x7c00u | (absx > 0x7f800000u ? 0x200u : 0u);
  if (absx >= 0x477ff000u) return sign | 0x7c00u;  // rounds to >= 65520: overflow to Inf
  if (absx < 0x38800000u) {                         // below the smallest normal half: subnormal or 0
    if (absx < 0x33000000u) return sign;            // < 2^-25 rounds to 0
    const std::uint32_t exponent = absx >> 23;
    const std::uint32_t mantissa = (absx & 0x7fffffu) | 0x800000u;  // with the implicit bit
    const int shift = 126 - int(exponent);  // value / 2^-24 = mantissa >> shift
    std::uint32_t result = mantissa >> shift;
    const std::uint32_t rest = mantissa & ((1u << shift) - 1u);
    const std::uint32_t halfway = 1u << (shift - 1);
    if (rest > halfway || (rest == halfway && (result & 1u))) ++result;
    return sign | std::uint16_t(result);
  }
  // normal
  std::uint32_t result = ((absx - 0x38000000u) >> 13);  // rebias exponent 127 -> 15
  const std::uint32_t r = absx & 0x1fffu;
  if (r > 0x1000u || (r == 0x1000u && (result & 1u))) ++result;
  return sign | std::uint16_t(result);
}

// fp32 value after a round trip through fp16 (what the GPU evaluator stores).
inline float roundToHalf(float f) { return halfBitsToFloat(floatToHalfBits(f)); }

}  // namespace inr
