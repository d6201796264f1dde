#pragma once
// The fused kernels' hash-grid encoding (a HashGrid row instruction, runRowInstr): a tile's table
// gathers from the fp16 copy of the tables (FusedParams::hashTables), organised for memory-level
// parallelism, with the arithmetic of hashGridLevelFused (Evaluator/Encodings.h), which the CPU
// emulation runs, bit for bit. The features land in the tile's shared-memory buffer, which the
// next GEMM reads with ldmatrix as it reads any operand.
//
// What bounds it: every query reads 2^D corner entries on each level. On a hashed level an entry
// and its x neighbour share a 32-byte sector unless the lower vertex's x is 7 mod 8 (instant-ngp
// hashes x with the prime 1; a dense level lays x out contiguously), so a level costs about
// 2^(D-1) * 9/8 sectors: levels * 2^(D-1) * 9/8 * 32 bytes from L2 per query when neighbouring
// queries share nothing (random points), fewer where they share coarse-level cells (a render's
// rays). The rate is then L2 bandwidth over that, if the tables stay in L2 (fp16 halves them)
// and enough loads are in flight to cover L2 latency; hence the organisation below.
//
// Work comes in slots of (level, block of rows), level-major, so a warp's level parameters are
// uniform (a dense or a hashed level: no divergence) and a block's warps share a level's table
// in L1. In a slot the lanes are rows (neighbouring queries, which coalesce where they share a
// cell) or, with lane pairs (FusedParams::hashGridPairs), 16 rows by two: the even lane gathers
// the corners at the lower x vertex, the odd one those at the upper, so one load instruction
// reads an entry and its x neighbour together (one sector, one L1 wavefront, mostly) and the
// pair adds its two sums with a shuffle. A lane computes the entries of all its corners of
// several slots and issues every load before it uses any.
#include <cuda_fp16.h>

#include "Common/RtcCompat.h"
#include "Evaluator/Cuda/FusedMlpDevice.cuh"
#include "Evaluator/Cuda/FusedMlpParams.cuh"
#include "Evaluator/Encodings.h"

namespace inr::cuda {

// One table entry's F fp16 features as one load (the fp16 table is 16-byte aligned and entries
// are F halves, so each is naturally aligned).
template <int F>
struct HashEntryBits;
template <>
struct HashEntryBits<1> {
  using T = unsigned short;
};
template <>
struct HashEntryBits<2> {
  using T = unsigned int;
};
template <>
struct HashEntryBits<4> {
  using T = uint2;
};
template <>
struct HashEntryBits<8> {
  using T = uint4;
};

// The features of a DIMS-input hash grid with F features per level for the M rows of a tile, by
// THREADS threads (tid: this thread's index), into dst (row stride ldDst, features from column
// featureAt); input(r, d): network input d of row r. Rows past the queries hold coordinates too
// (zeros), so every read stays in the tables.
template <int M, int THREADS, int DIMS, int F, bool PAIRS, class Input>
__device__ inline void hashGridGather(const HashGridView& g, const __half* table, const Input& input, __half* dst,
                                      int ldDst, int featureAt, int tid) {
  using Bits = typename HashEntryBits<F>::T;
  constexpr int kWarps = THREADS / 32;
  constexpr int kLaneCorners = PAIRS ? (1 << DIMS) / 2 : 1 << DIMS;
  constexpr int kRowsPerSlot = PAIRS ? 16 : 32;
  constexpr int kSlotsPerLevel = M / kRowsPerSlot;
  static_assert(M % kRowsPerSlot == 0, "a tile holds whole slots");
  // Slots per round: as many as keep a lane's loads in flight within about 32 registers.
  constexpr int kWordsPerSlot = kLaneCorners * int((sizeof(Bits) + 3) / 4);
  constexpr int U = kWordsPerSlot >= 32 ? 1 : (32 / kWordsPerSlot > 4 ? 4 : 32 / kWordsPerSlot);
  const int warp = tid >> 5, lane = tid & 31;
  const int xb = PAIRS ? lane & 1 : 0;  // with pairs: which x vertex this lane's corners have
  const int rowInSlot = PAIRS ? lane >> 1 : lane;
  const int slots = g.levels() * kSlotsPerLevel;
  for (int s0 = warp * U; s0 < slots; s0 += kWarps * U) {  // warp-uniform
    Bits bits[U][kLaneCorners];
    HashGridCell cell[U];
#pragma unroll
    for (int u = 0; u < U; ++u) {
      // A slot past the end repeats the last one: its loads stay in bounds, its sums unused.
      const int s = min(s0 + u, slots - 1);
      const int level = s / kSlotsPerLevel, r = (s % kSlotsPerLevel) * kRowsPerSlot + rowInSlot;
      float x[DIMS];
#pragma unroll
      for (int d = 0; d < DIMS; ++d) x[d] = input(r, d);
      cell[u] = hashGridCell(g, level, DIMS, [&x](int d) { return x[d]; });
      const HashGridCorners<DIMS> corners(cell[u].lower, g.resolution(level), g.entries(level));
      const Bits* levelTable = reinterpret_cast<const Bits*>(table + std::size_t(g.firstEntry(level)) * F);
#pragma unroll
      for (int k = 0; k < kLaneCorners; ++k) bits[u][k] = __ldg(levelTable + corners.entry(PAIRS ? 2 * k + xb : k));
    }
#pragma unroll
    for (int u = 0; u < U; ++u) {
      const int s = s0 + u;
      if (s >= slots) break;  // warp-uniform, so the shuffle below has every lane
      const int level = s / kSlotsPerLevel, r = (s % kSlotsPerLevel) * kRowsPerSlot + rowInSlot;
      float acc[2][F];  // the sums over the corners at the lower and at the upper x vertex
#pragma unroll
      for (int j = 0; j < F; ++j) acc[0][j] = acc[1][j] = 0.f;
#pragma unroll
      for (int k = 0; k < kLaneCorners; ++k) {
        const int corner = PAIRS ? 2 * k + xb : k;
        const float weight = hashGridCornerWeight(cell[u], DIMS, corner);
        __half h[F];
        memcpy(h, &bits[u][k], sizeof h);
#pragma unroll
        for (int j = 0; j < F; ++j) acc[corner & 1][j] = fmaf(weight, __half2float(h[j]), acc[corner & 1][j]);
      }
      __half* out = dst + r * ldDst + featureAt + level * F;
#pragma unroll
      for (int j = 0; j < F; ++j) {
        // lower + upper in that order on both lanes of a pair (fp32 addition commutes exactly)
        const float v = PAIRS ? acc[xb][j] + __shfl_xor_sync(0xffffffffu, acc[xb][j], 1) : acc[0][j] + acc[1][j];
        if (!PAIRS || (j & 1) == xb) out[j] = __float2half(v);
      }
    }
  }
}

// A HashGrid instruction's features on a tile's M rows (runRowInstr adds any included inputs and
// the zero padding): the gather above for the grid's dimensions, features per level and lane
// arrangement; the inputs are the tile's coordinates (src null) or an fp16 buffer. Not inlined:
// the gather's loads in flight want registers that the GEMM code around it holds, and a call
// saves those once per tile instead of spilling inside either loop.
template <int M, int THREADS>
__device__ __noinline__ void hashGridRows(HashGridView g, const __half* table, int dims, bool pairs, const float* coords,
                                          const __half* src, int ldSrc, __half* dst, int ldDst, int featureAt, int tid) {
  auto input = [&](int r, int k) { return src ? __half2float(src[r * ldSrc + k]) : coords[r * 4 + k]; };
  auto run = [&](auto dimsTag, auto pairsTag) {
    constexpr int D = decltype(dimsTag)::value;
    constexpr bool kPairs = decltype(pairsTag)::value;
    switch (g.features()) {
      case 1: hashGridGather<M, THREADS, D, 1, kPairs>(g, table, input, dst, ldDst, featureAt, tid); break;
      case 2: hashGridGather<M, THREADS, D, 2, kPairs>(g, table, input, dst, ldDst, featureAt, tid); break;
      case 4: hashGridGather<M, THREADS, D, 4, kPairs>(g, table, input, dst, ldDst, featureAt, tid); break;
      default: hashGridGather<M, THREADS, D, 8, kPairs>(g, table, input, dst, ldDst, featureAt, tid); break;
    }
  };
  auto withPairs = [&](auto dimsTag) {
    if (pairs)
      run(dimsTag, BoolTag<true>{});
    else
      run(dimsTag, BoolTag<false>{});
  };
  if (dims == 3)
    withPairs(IntTag<3>{});
  else
    withPairs(IntTag<4>{});
}

}  // namespace inr::cuda
