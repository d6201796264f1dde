#pragma once
// Host or device storage of the ray and pixel state (fields from INR_RAY_STATE_FIELDS /
// INR_PIXEL_STATE_FIELDS in Render/RayState.h), one array per field. `Array` is the backend's
// array template: HostArray (std::vector) here, cuda::DeviceBuffer on the GPU. Each backend
// provides, next to its array type, `resizeArray(array, n)` (exactly n elements; contents need
// not survive) and `arrayData(array)` (the element pointer); they are found by argument-dependent
// lookup, so this header knows no backend.
#include <cstddef>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "Render/TrackingPoints.h"
#include "Render/RayState.h"

namespace inr {

template <typename T>
using HostArray = std::vector<T>;

template <typename T>
void resizeArray(HostArray<T>& a, std::size_t n) {
  a.assign(n, T{});
}

// A default-initialising allocator: a resize leaves trivial elements unwritten.
template <typename T>
struct DefaultInitAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() noexcept = default;
  template <typename U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

// Host storage whose resize writes nothing (the stages initialise: resizeArray's contract). Why:
// zero-filling a frame's point slots (rays x points per iteration, tens of MB at 1024^2) was most
// of a first CPU frame's buffer setup; slots a ray never uses are then never touched at all.
template <typename T>
using HostScratchArray = std::vector<T, DefaultInitAllocator<T>>;

template <typename T>
void resizeArray(HostScratchArray<T>& a, std::size_t n) {
  a.clear();  // (nothing to copy when the storage grows)
  a.resize(n);
}
template <typename T>
T* arrayData(HostScratchArray<T>& a) {
  return a.data();
}
template <typename T>
T* arrayData(HostArray<T>& a) {
  return a.data();
}

// Storage struct `Name` for the fields of FIELDS, producing the views of type View.
#define INR_DEFINE_STATE_ARRAYS(Name, View, FIELDS)                  \
  template <template <typename> class Array>                         \
  struct Name {                                                      \
    FIELDS(INR_STATE_DECLARE_ARRAY)                                  \
    std::size_t count = 0;                                           \
    /* Contents are undefined afterwards: the stages initialise. */  \
    void resize(std::size_t n) {                                     \
      FIELDS(INR_STATE_RESIZE_ARRAY)                                 \
      count = n;                                                     \
    }                                                                \
    View view() {                                                    \
      View v;                                                        \
      v.count = int(count);                                          \
      FIELDS(INR_STATE_VIEW_ARRAY)                                   \
      return v;                                                      \
    }                                                                \
  };
#define INR_STATE_DECLARE_ARRAY(type, name) Array<type> name;
#define INR_STATE_RESIZE_ARRAY(type, name) resizeArray(name, n);
#define INR_STATE_VIEW_ARRAY(type, name) v.name = arrayData(name);

INR_DEFINE_STATE_ARRAYS(RayStateArrays, RayStateView, INR_RAY_STATE_FIELDS)
// Reset the accumulation (resetPixel) after a resize.
INR_DEFINE_STATE_ARRAYS(PixelStateArrays, AccumulationView, INR_PIXEL_STATE_FIELDS)
// The pending points of ratio tracking and the marches (TrackingPoints.h): rays x pointsPerIteration slots.
INR_DEFINE_STATE_ARRAYS(PointStateArrays, PointStateView, INR_POINT_STATE_FIELDS)

#undef INR_DEFINE_STATE_ARRAYS
#undef INR_STATE_DECLARE_ARRAY
#undef INR_STATE_RESIZE_ARRAY
#undef INR_STATE_VIEW_ARRAY

}  // namespace inr
