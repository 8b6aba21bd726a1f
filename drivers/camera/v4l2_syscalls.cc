#include "drivers/camera/v4l2_syscalls.h"

#include <libv4l2.h>
#include <poll.h>

namespace msmcal::camera {
namespace {

class LibV4l2Syscalls : public V4l2Syscalls {
 public:
  int Open(const char* path, int flags) override { return v4l2_open(path, flags); }
  int Close(int fd) override { return v4l2_close(fd); }
  int Ioctl(int fd, unsigned long request, void* arg) override {
    return v4l2_ioctl(fd, request, arg);
  }
  void* Mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) override {
    return v4l2_mmap(addr, length, prot, flags, fd, static_cast<int64_t>(offset));
  }
  int Munmap(void* addr, size_t length) override { return v4l2_munmap(addr, length); }
  int Poll(struct pollfd* fds, nfds_t nfds, int timeout_ms) override {
    return ::poll(fds, nfds, timeout_ms);
  }
};

}  // namespace

std::shared_ptr<V4l2Syscalls> RealV4l2Syscalls() { return std::make_shared<LibV4l2Syscalls>(); }

}  // namespace msmcal::camera
