#pragma once
// A GigE Vision camera served on a local address, built on Aravis's GV fake camera (real GVCP
// control channel and GVSP stream, so any GigE Vision client, ours or Aravis's tools, talks to
// it). Its GenICam description is ours (GenicamXml()): a 10 MP sensor by default and the SFNC
// features our driver uses (ExposureTime, Gain, AcquisitionFrameRate, TriggerMode/Source,
// PixelFormat Mono8/Mono16/BayerRG8/RGB8). Frame content comes from a FrameSource.
//
// One server per IP address: the GVCP port 3956 is fixed (run tests in their own network
// namespace). Aravis stays private to the .cc.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace msmcal::sim {

enum class SimPixelFormat { kMono8, kMono16, kBayerRG8, kRGB8 };
int SimBytesPerPixel(SimPixelFormat format);

// Fills one frame: `data` holds width * height * bytes-per-pixel bytes, tightly packed (Mono16
// little-endian, RGB8 as R,G,B); the source must write every byte. Called on the camera's thread,
// one frame at a time; the buffer is not sent until the call returns (frames are never torn).
// timestamp_ns: the frame's device timestamp; frame_index: 0, 1, 2, ... since the server started.
using FrameSource = std::function<void(uint8_t* data, int width, int height, SimPixelFormat fmt,
                                       int64_t timestamp_ns, uint64_t frame_index)>;

struct MockGvCameraOptions {
  std::string address = "127.0.0.1";  // interface address (or name) to serve on
  std::string serial = "MSMCAL-SIM-1";
  int sensor_width = 3840;  // 10.5 MP: 3840 x 2748
  int sensor_height = 2748;
  // Initial region and rate (clients change them through GenICam as on a real camera).
  int width = 0;  // 0 = sensor size
  int height = 0;
  double frame_rate_hz = 10.0;
  // Fault (off when < 0): after this many frames the server stops, as an unplugged camera does
  // (GVCP and the stream go silent when frame N+1 is due; clients see timeouts; exactly N frames
  // are sent). `msmcal mock camera --fault lost@N`.
  int64_t lost_after_frames = -1;

  std::string Validate() const;
};

// The GenICam XML served by the mock (sensor size is a register the server sets).
std::string GenicamXml();

class MockGvCamera {
 public:
  // Starts serving; empty pointer and `error` set if the address cannot be served.
  static std::unique_ptr<MockGvCamera> Start(const MockGvCameraOptions& options, FrameSource source,
                                             std::string* error);
  ~MockGvCamera();  // stops serving
  MockGvCamera(const MockGvCamera&) = delete;
  MockGvCamera& operator=(const MockGvCamera&) = delete;

  // Connects to the server as a GigE Vision client once (reads its GenICam XML) and returns true
  // when it answered: the readiness check behind "camera ready at ADDRESS".
  bool Answers() const;
  uint64_t frames_served() const { return frames_served_.load(); }
  // True once the lost_after_frames fault has silenced the server.
  bool lost() const { return lost_.load(); }
  // The exposure a client set through GenICam (ExposureTime / ExposureTimeAbs, one register),
  // in microseconds; none while the register still holds the value it had when serving began.
  std::optional<double> ClientExposureUs() const;
  const MockGvCameraOptions& options() const { return options_; }

 private:
  struct Impl;
  MockGvCamera() = default;
  static void Fill(void* buffer, void* self, uint32_t exposure_us, uint32_t gain,
                   uint32_t pixel_format);

  MockGvCameraOptions options_;
  FrameSource source_;
  std::unique_ptr<Impl> impl_;
  std::atomic<uint64_t> frames_served_{0};
  std::atomic<bool> lost_{false};
};

// Built-in deterministic test pattern. Byte i of a frame (any format, counted over the whole
// buffer) is PatternByte(frame_index, i); the first 8 bytes hold frame_index (little-endian), so
// a client can check every received frame is whole and untorn.
FrameSource MakeTestPatternSource();
uint8_t PatternByte(uint64_t frame_index, size_t i);

// Replays image files in order (then loops): each is decoded (OpenCV) once, converted to the
// requested format (grey/BGR->RGB, 8->16 bit by << 8) and placed top-left on a black frame
// (cropped if larger). Throws std::runtime_error naming the file if one cannot be read.
FrameSource MakeReplaySource(const std::vector<std::filesystem::path>& files);
// All *.png files in `dir`, sorted by name. Throws if none.
std::vector<std::filesystem::path> ListPngFiles(const std::filesystem::path& dir);

}  // namespace msmcal::sim
