#include "drivers/camera/testing/fake_v4l2_device.h"

#include <linux/videodev2.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace msmcal::camera::testing {
namespace {

constexpr uint32_t kPage = 4096;

void CopyString(uint8_t* dst, size_t size, const char* src) {
  std::strncpy(reinterpret_cast<char*>(dst), src, size - 1);
  dst[size - 1] = 0;
}

}  // namespace

FakeV4l2Device::FakeV4l2Device(Options options) : options_(std::move(options)) {
  if (options_.formats.empty()) {
    options_.formats = {{V4L2_PIX_FMT_GREY, 1, {{640, 480}, {320, 240}}},
                        {V4L2_PIX_FMT_Y16, 2, {{640, 480}, {320, 240}}},
                        {V4L2_PIX_FMT_RGB24, 3, {{640, 480}}}};
  }
  fourcc_ = options_.formats.front().fourcc;
  width_ = options_.formats.front().sizes.front().first;
  height_ = options_.formats.front().sizes.front().second;
}

FakeV4l2Device::~FakeV4l2Device() {
  for (int fd : fds_) ::close(fd);
  if (memfd_ >= 0) ::close(memfd_);
}

uint8_t FakeV4l2Device::PatternByte(uint64_t sequence, size_t i) {
  if (i < 8) return static_cast<uint8_t>(sequence >> (8 * i));
  return static_cast<uint8_t>((i * 7 + sequence * 13) & 0xff);
}

bool FakeV4l2Device::IsOurs(int fd) const {
  return std::find(fds_.begin(), fds_.end(), fd) != fds_.end();
}

const FakeV4l2Device::Format* FakeV4l2Device::FindFormat(uint32_t fourcc) const {
  for (const Format& f : options_.formats) {
    if (f.fourcc == fourcc) return &f;
  }
  return nullptr;
}

uint32_t FakeV4l2Device::BufferStride() const {
  const Format* f = FindFormat(fourcc_);
  return static_cast<uint32_t>(width_ * (f ? f->bytes_per_pixel : 1));
}

uint32_t FakeV4l2Device::BufferLength() const {
  return BufferStride() * static_cast<uint32_t>(height_);
}

// Like a kernel driver's try_fmt: unknown format -> first format; size -> nearest offered size.
void FakeV4l2Device::SnapFormat(void* arg) const {
  auto* fmt = static_cast<v4l2_format*>(arg);
  const Format* f = FindFormat(fmt->fmt.pix.pixelformat);
  if (f == nullptr) f = &options_.formats.front();
  int64_t best = -1;
  std::pair<int, int> chosen = f->sizes.front();
  for (const auto& size : f->sizes) {
    const int64_t dw = size.first - static_cast<int64_t>(fmt->fmt.pix.width);
    const int64_t dh = size.second - static_cast<int64_t>(fmt->fmt.pix.height);
    const int64_t d = dw * dw + dh * dh;
    if (best < 0 || d < best) {
      best = d;
      chosen = size;
    }
  }
  fmt->fmt.pix.pixelformat = f->fourcc;
  fmt->fmt.pix.width = static_cast<uint32_t>(chosen.first);
  fmt->fmt.pix.height = static_cast<uint32_t>(chosen.second);
  fmt->fmt.pix.field = V4L2_FIELD_NONE;
  fmt->fmt.pix.bytesperline = static_cast<uint32_t>(chosen.first * f->bytes_per_pixel);
  fmt->fmt.pix.sizeimage = fmt->fmt.pix.bytesperline * static_cast<uint32_t>(chosen.second);
  fmt->fmt.pix.colorspace = V4L2_COLORSPACE_RAW;
}

int FakeV4l2Device::Open(const char* path, int flags) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (unplugged_ || options_.path != path) {
    errno = ENOENT;
    return -1;
  }
  const int fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (fd < 0) return -1;
  fds_.push_back(fd);
  if (readable_) {
    const uint64_t one = 1;
    [[maybe_unused]] ssize_t n = ::write(fd, &one, sizeof(one));
  }
  return fd;
}

int FakeV4l2Device::Close(int fd) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = std::find(fds_.begin(), fds_.end(), fd);
  if (it == fds_.end()) {
    errno = EBADF;
    return -1;
  }
  fds_.erase(it);
  ::close(fd);
  if (fds_.empty()) {
    // Last close: the kernel stops streaming and frees unmapped buffers.
    streaming_ = false;
    queued_.clear();
    done_.clear();
    if (mapped_ == 0) FreeBuffersLocked();
  }
  return 0;
}

void FakeV4l2Device::FreeBuffersLocked() {
  buffers_.clear();
  queued_.clear();
  done_.clear();
  if (memfd_ >= 0) ::close(memfd_);
  memfd_ = -1;
  UpdateReadableLocked();
}

void FakeV4l2Device::UpdateReadableLocked() {
  const bool readable = !done_.empty() || unplugged_;
  if (readable == readable_) return;
  readable_ = readable;
  for (int fd : fds_) {
    if (readable) {
      const uint64_t one = 1;
      [[maybe_unused]] ssize_t n = ::write(fd, &one, sizeof(one));
    } else {
      uint64_t value;
      [[maybe_unused]] ssize_t n = ::read(fd, &value, sizeof(value));
    }
  }
}

int FakeV4l2Device::Ioctl(int fd, unsigned long request, void* arg) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!IsOurs(fd)) {
    errno = EBADF;
    return -1;
  }
  if (unplugged_) {
    errno = ENODEV;
    return -1;
  }
  auto failure = failures_.find(request);
  if (failure != failures_.end()) {
    const int err = failure->second.first;
    if (--failure->second.second <= 0) failures_.erase(failure);
    errno = err;
    return -1;
  }
  return IoctlLocked(request, arg);
}

int FakeV4l2Device::IoctlLocked(unsigned long request, void* arg) {
  auto fail = [](int err) {
    errno = err;
    return -1;
  };
  switch (request) {
    case VIDIOC_QUERYCAP: {
      auto* cap = static_cast<v4l2_capability*>(arg);
      std::memset(cap, 0, sizeof(*cap));
      CopyString(cap->driver, sizeof(cap->driver), "msmcal_fake");
      CopyString(cap->card, sizeof(cap->card), "msmcal fake V4L2 camera");
      CopyString(cap->bus_info, sizeof(cap->bus_info), "platform:fake0");
      cap->version = 0x060100;
      cap->device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
      cap->capabilities = cap->device_caps | V4L2_CAP_DEVICE_CAPS;
      return 0;
    }
    case VIDIOC_ENUM_FMT: {
      auto* desc = static_cast<v4l2_fmtdesc*>(arg);
      if (desc->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || desc->index >= options_.formats.size()) {
        return fail(EINVAL);
      }
      const uint32_t index = desc->index;
      std::memset(desc, 0, sizeof(*desc));
      desc->index = index;
      desc->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      desc->pixelformat = options_.formats[index].fourcc;
      CopyString(desc->description, sizeof(desc->description), "fake format");
      return 0;
    }
    case VIDIOC_ENUM_FRAMESIZES: {
      auto* size = static_cast<v4l2_frmsizeenum*>(arg);
      const Format* f = FindFormat(size->pixel_format);
      if (f == nullptr || size->index >= f->sizes.size()) return fail(EINVAL);
      size->type = V4L2_FRMSIZE_TYPE_DISCRETE;
      size->discrete.width = static_cast<uint32_t>(f->sizes[size->index].first);
      size->discrete.height = static_cast<uint32_t>(f->sizes[size->index].second);
      return 0;
    }
    case VIDIOC_G_FMT: {
      auto* fmt = static_cast<v4l2_format*>(arg);
      if (fmt->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      fmt->fmt.pix.pixelformat = fourcc_;
      fmt->fmt.pix.width = static_cast<uint32_t>(width_);
      fmt->fmt.pix.height = static_cast<uint32_t>(height_);
      SnapFormat(fmt);
      return 0;
    }
    case VIDIOC_TRY_FMT:
    case VIDIOC_S_FMT: {
      auto* fmt = static_cast<v4l2_format*>(arg);
      if (fmt->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (request == VIDIOC_S_FMT && !buffers_.empty()) return fail(EBUSY);
      SnapFormat(fmt);
      if (request == VIDIOC_S_FMT) {
        fourcc_ = fmt->fmt.pix.pixelformat;
        width_ = static_cast<int>(fmt->fmt.pix.width);
        height_ = static_cast<int>(fmt->fmt.pix.height);
      }
      return 0;
    }
    case VIDIOC_G_PARM:
    case VIDIOC_S_PARM: {
      auto* parm = static_cast<v4l2_streamparm*>(arg);
      if (parm->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (request == VIDIOC_S_PARM) {
        const auto& tpf = parm->parm.capture.timeperframe;
        if (tpf.numerator != 0 && tpf.denominator != 0) {
          frame_period_num_ = tpf.numerator;
          frame_period_den_ = tpf.denominator;
        }
      }
      std::memset(&parm->parm, 0, sizeof(parm->parm));
      parm->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
      parm->parm.capture.timeperframe.numerator = frame_period_num_;
      parm->parm.capture.timeperframe.denominator = frame_period_den_;
      return 0;
    }
    case VIDIOC_G_CTRL:
    case VIDIOC_S_CTRL: {
      auto* ctrl = static_cast<v4l2_control*>(arg);
      int32_t* value = nullptr;
      int32_t lo = 0, hi = 0;
      switch (ctrl->id) {
        case V4L2_CID_EXPOSURE_ABSOLUTE:
          value = &exposure_100us_, lo = 1, hi = 10000;
          break;
        case V4L2_CID_EXPOSURE_AUTO:
          value = &exposure_auto_, lo = 0, hi = 3;
          break;
        case V4L2_CID_GAIN:
          value = &gain_, lo = 0, hi = 100;
          break;
        default:
          return fail(EINVAL);
      }
      if (request == VIDIOC_G_CTRL) {
        ctrl->value = *value;
        return 0;
      }
      if (ctrl->value < lo || ctrl->value > hi) return fail(ERANGE);
      *value = ctrl->value;
      return 0;
    }
    case VIDIOC_REQBUFS: {
      auto* req = static_cast<v4l2_requestbuffers*>(arg);
      if (req->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || req->memory != V4L2_MEMORY_MMAP) {
        return fail(EINVAL);
      }
      if (streaming_ || mapped_ > 0) return fail(EBUSY);
      FreeBuffersLocked();
      if (req->count == 0) return 0;
      req->count = std::min(req->count, options_.max_buffers);
      const uint32_t length = BufferLength();
      const uint32_t stride = (length + kPage - 1) / kPage * kPage;
      memfd_ = ::memfd_create("fake_v4l2", MFD_CLOEXEC);
      if (memfd_ < 0) return -1;
      if (::ftruncate(memfd_, static_cast<off_t>(stride) * req->count) < 0) return -1;
      buffers_.assign(req->count, Buffer{});
      return 0;
    }
    case VIDIOC_QUERYBUF: {
      auto* buf = static_cast<v4l2_buffer*>(arg);
      if (buf->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buf->index >= buffers_.size()) {
        return fail(EINVAL);
      }
      const uint32_t length = BufferLength();
      const uint32_t stride = (length + kPage - 1) / kPage * kPage;
      const Buffer& b = buffers_[buf->index];
      buf->memory = V4L2_MEMORY_MMAP;
      buf->length = length;
      buf->m.offset = buf->index * stride;
      buf->bytesused = b.bytesused;
      buf->flags = V4L2_BUF_FLAG_MAPPED |
                   (b.state == BufState::kQueued ? V4L2_BUF_FLAG_QUEUED : 0) |
                   (b.state == BufState::kDone ? V4L2_BUF_FLAG_DONE : 0);
      return 0;
    }
    case VIDIOC_QBUF: {
      auto* buf = static_cast<v4l2_buffer*>(arg);
      if (buf->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buf->memory != V4L2_MEMORY_MMAP ||
          buf->index >= buffers_.size() || buffers_[buf->index].state != BufState::kDequeued) {
        return fail(EINVAL);
      }
      buffers_[buf->index].state = BufState::kQueued;
      queued_.push_back(buf->index);
      buf->flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_QUEUED;
      return 0;
    }
    case VIDIOC_DQBUF: {
      auto* buf = static_cast<v4l2_buffer*>(arg);
      if (buf->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buf->memory != V4L2_MEMORY_MMAP) {
        return fail(EINVAL);
      }
      if (!streaming_) return fail(EINVAL);
      if (done_.empty()) return fail(EAGAIN);
      const uint32_t index = done_.front();
      done_.pop_front();
      Buffer& b = buffers_[index];
      b.state = BufState::kDequeued;
      const uint32_t length = BufferLength();
      const uint32_t stride = (length + kPage - 1) / kPage * kPage;
      buf->index = index;
      buf->bytesused = b.bytesused;
      buf->flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | b.flags;
      buf->field = V4L2_FIELD_NONE;
      buf->sequence = b.sequence;
      buf->timestamp.tv_sec = b.timestamp_us / 1000000;
      buf->timestamp.tv_usec = b.timestamp_us % 1000000;
      buf->length = length;
      buf->m.offset = index * stride;
      UpdateReadableLocked();
      return 0;
    }
    case VIDIOC_STREAMON: {
      if (*static_cast<int*>(arg) != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (buffers_.empty()) return fail(EINVAL);
      streaming_ = true;
      return 0;
    }
    case VIDIOC_STREAMOFF: {
      if (*static_cast<int*>(arg) != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      streaming_ = false;
      for (Buffer& b : buffers_) b.state = BufState::kDequeued;
      queued_.clear();
      done_.clear();
      UpdateReadableLocked();
      return 0;
    }
    default:
      return fail(ENOTTY);
  }
}

void* FakeV4l2Device::Mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!IsOurs(fd)) {
    errno = EBADF;
    return MAP_FAILED;
  }
  if (unplugged_) {
    errno = ENODEV;
    return MAP_FAILED;
  }
  const uint32_t buffer_length = BufferLength();
  const uint32_t stride = (buffer_length + kPage - 1) / kPage * kPage;
  if (memfd_ < 0 || !(flags & MAP_SHARED) || offset % stride != 0 ||
      static_cast<size_t>(offset / stride) >= buffers_.size() || length != buffer_length) {
    errno = EINVAL;
    return MAP_FAILED;
  }
  void* p = ::mmap(addr, length, prot, flags, memfd_, offset);
  if (p != MAP_FAILED) {
    ++mapped_;
    mappings_[reinterpret_cast<uintptr_t>(p)] = length;
  }
  return p;
}

int FakeV4l2Device::Munmap(void* addr, size_t length) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = mappings_.find(reinterpret_cast<uintptr_t>(addr));
  if (it == mappings_.end() || it->second != length) {
    errno = EINVAL;
    return -1;
  }
  mappings_.erase(it);
  --mapped_;
  const int r = ::munmap(addr, length);
  if (mapped_ == 0 && fds_.empty()) FreeBuffersLocked();
  return r;
}

int FakeV4l2Device::Poll(struct pollfd* fds, nfds_t nfds, int timeout_ms) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (auto_produce_ && streaming_ && !unplugged_ && done_.empty() && !queued_.empty()) {
      ProduceLocked(FrameFault{});
    }
  }
  const int n = ::poll(fds, nfds, timeout_ms);
  if (n < 0) return n;
  std::lock_guard<std::mutex> lock(mutex_);
  int ready = 0;
  for (nfds_t i = 0; i < nfds; ++i) {
    if (!IsOurs(fds[i].fd)) {
      if (fds[i].revents) ++ready;
      continue;
    }
    // The kernel reports POLLERR when the device is gone or the queue is not streaming.
    if (unplugged_) {
      fds[i].revents = POLLERR | POLLHUP;
    } else if (!streaming_) {
      fds[i].revents = POLLERR;
    } else {
      fds[i].revents =
          done_.empty() ? 0 : static_cast<short>(fds[i].events & (POLLIN | POLLRDNORM));
    }
    if (fds[i].revents) ++ready;
  }
  return ready;
}

bool FakeV4l2Device::ProduceFrame() { return ProduceFrame(FrameFault{}); }

bool FakeV4l2Device::ProduceFrame(const FrameFault& fault) {
  std::lock_guard<std::mutex> lock(mutex_);
  return ProduceLocked(fault);
}

bool FakeV4l2Device::ProduceLocked(const FrameFault& fault) {
  sequence_ += fault.skip_sequence;
  if (!streaming_ || queued_.empty()) {
    ++underruns_;
    ++sequence_;  // the device still counted the frame it could not store
    return false;
  }
  const uint32_t index = queued_.front();
  queued_.pop_front();
  const uint32_t length = BufferLength();
  const uint32_t stride = (length + kPage - 1) / kPage * kPage;
  void* p = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, memfd_,
                   static_cast<off_t>(index) * stride);
  if (p != MAP_FAILED) {
    auto* bytes = static_cast<uint8_t*>(p);
    for (size_t i = 0; i < length; ++i) bytes[i] = PatternByte(sequence_, i);
    ::munmap(p, length);
  }
  Buffer& b = buffers_[index];
  b.state = BufState::kDone;
  b.sequence = sequence_;
  b.bytesused = length - std::min(length, fault.short_bytes);
  b.flags = fault.error_flag ? V4L2_BUF_FLAG_ERROR : 0;
  b.timestamp_us = static_cast<int64_t>(sequence_) * 1000000 * frame_period_num_ /
                   std::max<uint32_t>(1, frame_period_den_);
  ++sequence_;
  done_.push_back(index);
  UpdateReadableLocked();
  return true;
}

void FakeV4l2Device::SetAutoProduce(bool on) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto_produce_ = on;
}

void FakeV4l2Device::FailIoctl(unsigned long request, int err, int count) {
  std::lock_guard<std::mutex> lock(mutex_);
  failures_[request] = {err, count};
}

void FakeV4l2Device::Unplug() {
  std::lock_guard<std::mutex> lock(mutex_);
  unplugged_ = true;
  streaming_ = false;
  UpdateReadableLocked();
}

bool FakeV4l2Device::streaming() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return streaming_;
}
int FakeV4l2Device::open_fds() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(fds_.size());
}
int FakeV4l2Device::mapped_buffers() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return mapped_;
}
int FakeV4l2Device::queued_buffers() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(queued_.size());
}
uint64_t FakeV4l2Device::underruns() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return underruns_;
}
uint32_t FakeV4l2Device::current_fourcc() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return fourcc_;
}

}  // namespace msmcal::camera::testing
