#include "common/text_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace msmcal::common {

void AppendShortestDouble(std::string* out, double value) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), value);
  out->append(buf, r.ptr);
}

std::string ShortestDouble(double value) {
  std::string out;
  AppendShortestDouble(&out, value);
  return out;
}

std::string YamlDouble(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  std::string s = ShortestDouble(value);
  const size_t e = s.find('e');
  if (e != std::string::npos && s.find('.') == std::string::npos) s.insert(e, ".0");
  return s;
}

namespace {

struct FdCloser {
  int fd;
  ~FdCloser() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

void WriteFileAtomically(const std::filesystem::path& file, const std::string& contents) {
  namespace fs = std::filesystem;
  static std::atomic<uint64_t> counter{0};
  const fs::path parent = file.has_parent_path() ? file.parent_path() : fs::path(".");
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) throw std::runtime_error(file.string() + ": cannot create folder " + parent.string() + ": " + ec.message());
  const fs::path tmp = parent / ("." + file.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                                 std::to_string(counter.fetch_add(1)));
  auto fail_errno = [&](const char* what) {
    const int err = errno;
    ::unlink(tmp.c_str());
    throw std::runtime_error(file.string() + ": " + what + ": " + std::strerror(err));
  };
  {
    FdCloser f{::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644)};
    if (f.fd < 0) fail_errno("cannot create temporary file");
    size_t done = 0;
    while (done < contents.size()) {
      const ssize_t n = ::write(f.fd, contents.data() + done, contents.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        fail_errno("write failed");
      }
      done += static_cast<size_t>(n);
    }
    if (::fsync(f.fd) != 0) fail_errno("fsync failed");
    const int fd = f.fd;
    f.fd = -1;
    if (::close(fd) != 0) fail_errno("close failed");
  }
  if (::rename(tmp.c_str(), file.c_str()) != 0) fail_errno("rename failed");
  FdCloser d{::open(parent.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (d.fd < 0 || ::fsync(d.fd) != 0)
    throw std::runtime_error(file.string() + ": fsync of folder failed: " + std::strerror(errno));
}

}  // namespace msmcal::common
