#pragma once
// The thin seam under the V4L2 driver: exactly the system calls it makes. The real implementation
// forwards to libv4l2 (v4l2_open, v4l2_ioctl, v4l2_mmap, ...; plain poll); tests substitute an
// in-process fake device (drivers/camera/testing/fake_v4l2_device.h). Semantics are those of the
// kernel calls: -1 and errno on failure, MAP_FAILED from Mmap.

#include <poll.h>
#include <sys/types.h>

#include <cstddef>
#include <memory>

namespace msmcal::camera {

class V4l2Syscalls {
 public:
  virtual ~V4l2Syscalls() = default;
  virtual int Open(const char* path, int flags) = 0;
  virtual int Close(int fd) = 0;
  virtual int Ioctl(int fd, unsigned long request, void* arg) = 0;
  virtual void* Mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) = 0;
  virtual int Munmap(void* addr, size_t length) = 0;
  virtual int Poll(struct pollfd* fds, nfds_t nfds, int timeout_ms) = 0;
};

// libv4l2 (format conversion for cameras that only offer compressed or odd formats).
std::shared_ptr<V4l2Syscalls> RealV4l2Syscalls();

}  // namespace msmcal::camera
