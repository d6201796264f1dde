#pragma once
// Running out of GPU memory, as the engine reports it (no CUDA headers: the sessions, the CLI and
// the plugin catch it without knowing the backend).
//
// Every device allocation goes through cuda::DeviceBuffer (Common/Cuda/DeviceBuffer.h). When one
// fails for lack of memory it throws DeviceOutOfMemory, whose message says how many bytes were
// asked, what the device had free, what the memory was for and which setting lowers it. The last
// two come from the innermost DeviceAllocationPurpose alive on the allocating thread: code that
// sizes buffers from a user's request (image size, macrocell grid, points per iteration) opens
// one around those allocations.
#include <cstddef>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

namespace inr {

class DeviceOutOfMemory : public std::runtime_error {
public:
  DeviceOutOfMemory(const std::string& message, std::size_t bytesAsked, std::string purpose)
      : std::runtime_error(message), bytesAsked_(bytesAsked), purpose_(std::move(purpose)) {}
  std::size_t bytesAsked() const { return bytesAsked_; }
  const std::string& purpose() const { return purpose_; }  // "" when none was recorded

private:
  std::size_t bytesAsked_ = 0;
  std::string purpose_;
};

// While alive, device allocations on this thread are for `what` (e.g. "the ray and pixel state of
// a 16384x16384 image"), and `lower` says what reduces them (e.g. "lower the image resolution").
// Scopes nest; the innermost names the allocation.
class DeviceAllocationPurpose {
public:
  DeviceAllocationPurpose(std::string what, std::string lower)
      : what_(std::move(what)), lower_(std::move(lower)), outer_(slot()) {
    slot() = this;
  }
  ~DeviceAllocationPurpose() { slot() = outer_; }
  DeviceAllocationPurpose(const DeviceAllocationPurpose&) = delete;
  DeviceAllocationPurpose& operator=(const DeviceAllocationPurpose&) = delete;

  const std::string& what() const { return what_; }
  const std::string& lower() const { return lower_; }
  static const DeviceAllocationPurpose* current() { return slot(); }

private:
  static const DeviceAllocationPurpose*& slot() {
    thread_local const DeviceAllocationPurpose* innermost = nullptr;
    return innermost;
  }
  std::string what_, lower_;
  const DeviceAllocationPurpose* outer_;
};

inline std::string formatBytes(std::size_t bytes) {
  char text[64];
  const double b = double(bytes);
  if (b >= 1024.0 * 1024.0 * 1024.0)
    std::snprintf(text, sizeof text, "%.2f GiB", b / (1024.0 * 1024.0 * 1024.0));
  else if (b >= 1024.0 * 1024.0)
    std::snprintf(text, sizeof text, "%.1f MiB", b / (1024.0 * 1024.0));
  else
    std::snprintf(text, sizeof text, "%zu bytes", bytes);
  return text;
}

// The message of a failed allocation of `bytes` with `freeBytes` of `totalBytes` free on the
// device (both 0 when unknown) and `injected` when a test's fault hook made it fail.
inline DeviceOutOfMemory deviceOutOfMemory(std::size_t bytes, std::size_t freeBytes, std::size_t totalBytes,
                                           bool injected) {
  const DeviceAllocationPurpose* p = DeviceAllocationPurpose::current();
  std::string m = "out of GPU memory: " + formatBytes(bytes) + " asked for " +
                  (p ? p->what() : std::string("a device buffer"));
  if (totalBytes > 0) m += " (" + formatBytes(freeBytes) + " free of " + formatBytes(totalBytes) + " on the device)";
  if (injected) m += " [injected by the allocation fault hook]";
  m += "; ";
  m += p ? p->lower()
         : std::string("lower the image resolution, the macrocell resolution or the points per iteration");
  m += ", or free GPU memory (other views, models or programs using the GPU)";
  return DeviceOutOfMemory(m, bytes, p ? p->what() : std::string());
}

// A CUDA call other than an allocation that failed for lack of device memory (creating the
// context, a stream, a library handle): the call is named, the bytes are unknown.
inline DeviceOutOfMemory deviceOutOfMemoryIn(const std::string& call) {
  const DeviceAllocationPurpose* p = DeviceAllocationPurpose::current();
  std::string m = "out of GPU memory in " + call + " (CUDA's own memory: context, streams, library handles" +
                  (p ? std::string(", for ") + p->what() : std::string()) +
                  "); free GPU memory (other views, models or programs using the GPU)";
  if (p) m += ", or " + p->lower();
  return DeviceOutOfMemory(m, 0, p ? p->what() : std::string());
}

}  // namespace inr
