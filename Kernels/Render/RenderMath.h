#pragma once
// Small vector types and ray/box helpers shared by every per-ray stage. Plain structs with
// INR_HD inline functions only: this header is compiled by nvcc for the CUDA backend as well,
// so nothing here may touch the standard library's host-only parts.
#include <cmath>
#include <cstdint>

#include "Common/HostDevice.h"

namespace inr {

struct Vec3f {
  float x, y, z;
};
struct Vec4f {
  float x, y, z, w;
};
struct Int3 {
  int x, y, z;
};

INR_HD Vec3f makeVec3(float x, float y, float z) { return Vec3f{x, y, z}; }
INR_HD Vec3f operator+(Vec3f a, Vec3f b) { return Vec3f{a.x + b.x, a.y + b.y, a.z + b.z}; }
INR_HD Vec3f operator-(Vec3f a, Vec3f b) { return Vec3f{a.x - b.x, a.y - b.y, a.z - b.z}; }
INR_HD Vec3f operator*(Vec3f a, float s) { return Vec3f{a.x * s, a.y * s, a.z * s}; }
INR_HD Vec3f operator*(float s, Vec3f a) { return Vec3f{a.x * s, a.y * s, a.z * s}; }
INR_HD float dot(Vec3f a, Vec3f b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
INR_HD Vec3f cross(Vec3f a, Vec3f b) {
  return Vec3f{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
INR_HD float length(Vec3f a) { return sqrtf(dot(a, a)); }
INR_HD Vec3f normalize(Vec3f a) {
  const float len = length(a);
  return len > 0.f ? a * (1.f / len) : a;
}
INR_HD float component(Vec3f v, int axis) { return axis == 0 ? v.x : (axis == 1 ? v.y : v.z); }
INR_HD int component(Int3 v, int axis) { return axis == 0 ? v.x : (axis == 1 ? v.y : v.z); }
// Selects rather than indexes, so device code keeps the vector in registers.
INR_HD void setComponent(Vec3f& v, int axis, float value) {
  v.x = axis == 0 ? value : v.x;
  v.y = axis == 1 ? value : v.y;
  v.z = axis == 2 ? value : v.z;
}
INR_HD void setComponent(Int3& v, int axis, int value) {
  v.x = axis == 0 ? value : v.x;
  v.y = axis == 1 ? value : v.y;
  v.z = axis == 2 ? value : v.z;
}
INR_HD float minf(float a, float b) { return a < b ? a : b; }
INR_HD float maxf(float a, float b) { return a > b ? a : b; }
INR_HD float clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }
// True for finite values (NaN - NaN and Inf - Inf are NaN). Works the same in host and device
// code without depending on which isfinite overloads a header set provides.
INR_HD bool isFiniteValue(float v) { return v - v == 0.f; }
INR_HD int clampi(int v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : v); }

// Axis-aligned world box.
struct Box3f {
  Vec3f lo, hi;
};

// Slab test. Returns false when the ray misses; otherwise the parametric interval
// [tEnter, tExit] of the (unit-direction) ray inside the box, clipped to t >= 0.
INR_HD bool intersectBox(const Box3f& box, Vec3f origin, Vec3f dir, float& tEnter, float& tExit) {
  float t0 = 0.f, t1 = INFINITY;
  for (int axis = 0; axis < 3; ++axis) {
    const float o = component(origin, axis), d = component(dir, axis);
    const float lo = component(box.lo, axis), hi = component(box.hi, axis);
    if (d == 0.f) {
      if (o < lo || o > hi) return false;
      continue;
    }
    const float inv = 1.f / d;
    float tNear = (lo - o) * inv, tFar = (hi - o) * inv;
    if (tNear > tFar) {
      const float tmp = tNear;
      tNear = tFar;
      tFar = tmp;
    }
    t0 = maxf(t0, tNear);
    t1 = minf(t1, tFar);
  }
  tEnter = t0;
  tExit = t1;
  return t0 < t1;
}

}  // namespace inr
