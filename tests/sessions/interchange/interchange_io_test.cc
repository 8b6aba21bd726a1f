#include "sessions/interchange/interchange_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <regex>
#include <sstream>

#include "sessions/results/results_files.h"
#include "tests/testing/test_files.h"

namespace msmcal::interchange {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A fresh folder per test, removed afterwards.
// Per-test folders named msmcal_ix_<suite>_<test>_<pid>.
class TempDir : public msmcal::testing::TempDir {
 public:
  TempDir() : msmcal::testing::TempDir("msmcal_ix") {}
};

using msmcal::testing::Slurp;
using msmcal::testing::Spit;

// Replaces the first occurrence of `from` in file `p` (fails the test if absent).
void Edit(const fs::path& p, const std::string& from, const std::string& to) {
  std::string text = Slurp(p);
  const size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from << " not in " << p;
  text.replace(at, from.size(), to);
  Spit(p, text);
}

bool Same(double a, double b) { return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b); }

// Doubles that stress the text form: tiny, huge, subnormal, negative, -0, integers.
class Doubles {
 public:
  explicit Doubles(uint64_t seed) : rng_(seed) {}
  double Next() {
    switch (std::uniform_int_distribution<int>(0, 9)(rng_)) {
      case 0:
        return -0.0;
      case 1:
        return std::numeric_limits<double>::denorm_min() *
               std::uniform_int_distribution<int>(1, 1000)(rng_);
      case 2:
        return std::numeric_limits<double>::max() * Uniform(-1, 1);
      case 3:
        return std::numeric_limits<double>::min() * Uniform(-1, 1);
      case 4:
        return std::round(Uniform(-1e6, 1e6));
      case 5:
        return 0.1 * std::uniform_int_distribution<int>(-100, 100)(rng_);
      default: {
        const double e = Uniform(-300, 300);
        return std::pow(10.0, e) * Uniform(-1, 1);
      }
    }
  }
  double Positive() { return std::abs(Next()) + 1e-3; }
  // A stressing value (as Next(), sign kept or folded) inside the range a session.yaml or
  // camera.yaml field allows (`open_lo`: lo itself excluded).
  double In(double lo, double hi, bool open_lo = false) {
    for (int attempt = 0; attempt < 1000; ++attempt) {
      double v = Next();
      if (lo >= 0) v = std::abs(v);
      if ((open_lo ? v > lo : v >= lo) && v <= hi) return v;
    }
    return 0.5 * (lo + hi);
  }
  int Int(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }
  int64_t Int64() { return std::uniform_int_distribution<int64_t>(INT64_MIN, INT64_MAX)(rng_); }

 private:
  double Uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }
  std::mt19937_64 rng_;
};

dataset::MargRecording RandomMarg(Doubles& d, bool inertial, int n) {
  dataset::MargRecording m;
  m.has_inertial = inertial;
  for (int i = 0; i < n; ++i) {
    dataset::MargSample s;
    s.t_s = d.Next();
    s.mx_uT = d.Next();
    s.my_uT = d.Next();
    s.mz_uT = d.Next();
    if (inertial) {
      s.ax_g = d.Next();
      s.ay_g = d.Next();
      s.az_g = d.Next();
      s.gx_dps = d.Next();
      s.gy_dps = d.Next();
      s.gz_dps = d.Next();
    }
    m.samples.push_back(s);
  }
  return m;
}

dataset::HallRecording RandomHall(Doubles& d, int n) {
  dataset::HallRecording h;
  // Times are strictly increasing decimal microseconds (interchange-format.md), with fractions.
  double t = -5000, tr = d.Int(-100000, 100000) + d.Int(0, 999) / 1000.0;
  for (int i = 0; i < n; ++i) {
    tr += d.Int(1, 2000) + d.Int(0, 999) / 1000.0;
    h.readings.push_back({tr, d.Next(), d.Next(), d.Next()});
    t += d.Int(1, 100000) + d.Int(0, 999) / 1000.0;
    h.clock_edges_us.push_back(t);
  }
  return h;
}

// A consistent recording with random values; image files named step1/0000.png ...
dataset::Recording RandomRecording(uint64_t seed) {
  Doubles d(seed);
  dataset::Recording r;
  r.camera.width = 4096;
  r.camera.height = 3000;
  // Values inside the allowed ranges (interchange_io.cc), still stressing the text form.
  r.camera.fx = d.In(0, 1e7, /*open_lo=*/true);
  r.camera.fy = d.In(0, 1e7, /*open_lo=*/true);
  r.camera.cx = d.In(-4096, 8192);
  r.camera.cy = d.In(-3000, 6000);
  for (size_t i = 0; i < r.camera.distortion.size(); ++i)
    r.camera.distortion[i] = i == 2 || i == 3 ? d.In(-1, 1) : d.In(-1000, 1000);
  r.world_board = {9, 6, d.In(0, 1000, /*open_lo=*/true)};
  r.sliding_board = {7, 4, d.In(0, 1000, /*open_lo=*/true)};
  r.beams = {{1, dataset::BeamRole::kEstimate},
             {2, dataset::BeamRole::kEstimate},
             {7, dataset::BeamRole::kValidate}};
  for (dataset::DriveAxis* a : {&r.drive.fast, &r.drive.slow})
    *a = {d.In(0, 30e6, /*open_lo=*/true), d.In(0, 20), d.In(-360, 360)};
  r.drive.pattern_period_s = d.In(0, 1e4, /*open_lo=*/true);
  r.clock_frequency_hz = d.In(0, 30e6, /*open_lo=*/true);
  for (int j = 0; j < 12; ++j) r.triggers.push_back({j, d.In(0, r.drive.pattern_period_s)});
  char name[32];
  for (int i = 0; i < 5; ++i) {
    std::snprintf(name, sizeof(name), "step1/%04d.png", i);
    r.step1.push_back(
        {name, i / 2, i < 3 ? std::vector<int>{r.beams[i].id} : std::vector<int>{1, 2, 7}});
  }
  r.step2.push_back({"step2/0000.png", dataset::Step2Kind::kNeutral, {}, {1, 2, 7}});
  r.step2.push_back({"step2/0001.png", dataset::Step2Kind::kFastOnly, {0, 5}, {1, 2}});
  r.step2.push_back({"step2/0002.png", dataset::Step2Kind::kScan, {3}, {1, 2, 7}});
  r.step2.push_back({"step2/0003.png", dataset::Step2Kind::kScan, {}, {7}});
  r.hall_actual = RandomHall(d, 200);
  r.hall_background = RandomHall(d, 50);
  r.marg_plane_rotation = RandomMarg(d, true, 40);
  r.marg_validation = RandomMarg(d, false, 30);
  return r;
}

void WriteImages(const fs::path& dir, const dataset::Recording& r) {
  cv::Mat img(4, 6, CV_8UC1, cv::Scalar(17));
  for (const auto& f : r.step1) WriteImageAtomically(dir / f.file, img);
  for (const auto& f : r.step2) WriteImageAtomically(dir / f.file, img);
}

void ExpectSameHall(const std::optional<dataset::HallRecording>& a,
                    const std::optional<dataset::HallRecording>& b) {
  ASSERT_EQ(a.has_value(), b.has_value());
  if (!a) return;
  ASSERT_EQ(a->readings.size(), b->readings.size());
  for (size_t i = 0; i < a->readings.size(); ++i) {
    EXPECT_EQ(a->readings[i].mcu_time_us, b->readings[i].mcu_time_us);
    EXPECT_TRUE(Same(a->readings[i].bx_uT, b->readings[i].bx_uT));
    EXPECT_TRUE(Same(a->readings[i].by_uT, b->readings[i].by_uT));
    EXPECT_TRUE(Same(a->readings[i].bz_uT, b->readings[i].bz_uT));
  }
  EXPECT_EQ(a->clock_edges_us, b->clock_edges_us);
}

void ExpectSameMarg(const std::optional<dataset::MargRecording>& a,
                    const std::optional<dataset::MargRecording>& b) {
  ASSERT_EQ(a.has_value(), b.has_value());
  if (!a) return;
  EXPECT_EQ(a->has_inertial, b->has_inertial);
  ASSERT_EQ(a->samples.size(), b->samples.size());
  for (size_t i = 0; i < a->samples.size(); ++i) {
    const auto& x = a->samples[i];
    const auto& y = b->samples[i];
    for (auto m :
         {&dataset::MargSample::t_s, &dataset::MargSample::ax_g, &dataset::MargSample::ay_g,
          &dataset::MargSample::az_g, &dataset::MargSample::gx_dps, &dataset::MargSample::gy_dps,
          &dataset::MargSample::gz_dps, &dataset::MargSample::mx_uT, &dataset::MargSample::my_uT,
          &dataset::MargSample::mz_uT}) {
      EXPECT_TRUE(Same(x.*m, y.*m)) << i << ": " << x.*m << " vs " << y.*m;
    }
  }
}

void ExpectSameRecording(const dataset::Recording& a, const dataset::Recording& b) {
  EXPECT_EQ(a.format, b.format);
  EXPECT_EQ(a.camera.width, b.camera.width);
  EXPECT_EQ(a.camera.height, b.camera.height);
  EXPECT_TRUE(Same(a.camera.fx, b.camera.fx));
  EXPECT_TRUE(Same(a.camera.fy, b.camera.fy));
  EXPECT_TRUE(Same(a.camera.cx, b.camera.cx));
  EXPECT_TRUE(Same(a.camera.cy, b.camera.cy));
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(Same(a.camera.distortion[i], b.camera.distortion[i]));
  for (auto board : {&dataset::Recording::world_board, &dataset::Recording::sliding_board}) {
    EXPECT_EQ((a.*board).cols, (b.*board).cols);
    EXPECT_EQ((a.*board).rows, (b.*board).rows);
    EXPECT_TRUE(Same((a.*board).square_mm, (b.*board).square_mm));
  }
  ASSERT_EQ(a.beams.size(), b.beams.size());
  for (size_t i = 0; i < a.beams.size(); ++i) {
    EXPECT_EQ(a.beams[i].id, b.beams[i].id);
    EXPECT_EQ(a.beams[i].role, b.beams[i].role);
  }
  for (auto axis : {&dataset::Drive::fast, &dataset::Drive::slow}) {
    EXPECT_TRUE(Same((a.drive.*axis).frequency_hz, (b.drive.*axis).frequency_hz));
    EXPECT_TRUE(Same((a.drive.*axis).amplitude_vpp, (b.drive.*axis).amplitude_vpp));
    EXPECT_TRUE(Same((a.drive.*axis).phase_deg, (b.drive.*axis).phase_deg));
  }
  EXPECT_TRUE(Same(a.drive.pattern_period_s, b.drive.pattern_period_s));
  EXPECT_TRUE(Same(a.clock_frequency_hz, b.clock_frequency_hz));
  ASSERT_EQ(a.triggers.size(), b.triggers.size());
  for (size_t i = 0; i < a.triggers.size(); ++i) {
    EXPECT_EQ(a.triggers[i].j, b.triggers[i].j);
    EXPECT_TRUE(Same(a.triggers[i].t_s, b.triggers[i].t_s));
  }
  ASSERT_EQ(a.step1.size(), b.step1.size());
  for (size_t i = 0; i < a.step1.size(); ++i) {
    EXPECT_EQ(a.step1[i].file, b.step1[i].file);
    EXPECT_EQ(a.step1[i].pose, b.step1[i].pose);
    EXPECT_EQ(a.step1[i].beams, b.step1[i].beams);
  }
  ASSERT_EQ(a.step2.size(), b.step2.size());
  for (size_t i = 0; i < a.step2.size(); ++i) {
    EXPECT_EQ(a.step2[i].file, b.step2[i].file);
    EXPECT_EQ(a.step2[i].kind, b.step2[i].kind);
    EXPECT_EQ(a.step2[i].triggers, b.step2[i].triggers);
    EXPECT_EQ(a.step2[i].beams, b.step2[i].beams);
  }
  ExpectSameHall(a.hall_actual, b.hall_actual);
  ExpectSameHall(a.hall_background, b.hall_background);
  ExpectSameMarg(a.marg_plane_rotation, b.marg_plane_rotation);
  ExpectSameMarg(a.marg_free_rotation, b.marg_free_rotation);
  ExpectSameMarg(a.marg_validation, b.marg_validation);
}

std::vector<std::string> FilesUnder(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) out.push_back(fs::relative(e.path(), dir).string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Runs `fn` and returns the InterchangeError message (fails the test if none is thrown).
template <typename Fn>
std::string ErrorOf(Fn fn) {
  try {
    fn();
  } catch (const InterchangeError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InterchangeError thrown";
  return "";
}

TEST(FormatDoubleTest, ShortestFormRoundTrips) {
  EXPECT_EQ(FormatDouble(0.1), "0.1");
  EXPECT_EQ(FormatDouble(1e-7), "1e-07");
  EXPECT_EQ(FormatDouble(-3.0), "-3");
  Doubles d(42);
  for (int i = 0; i < 100000; ++i) {
    const double x = d.Next();
    const std::string s = FormatDouble(x);
    EXPECT_TRUE(Same(x, std::strtod(s.c_str(), nullptr))) << s;
  }
}

TEST(InterchangeRoundTripTest, ReadOfWriteIsBitwiseIdentical) {
  TempDir tmp;
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const dataset::Recording r = RandomRecording(seed);
    const fs::path dir = tmp.path() / std::to_string(seed);
    WriteImages(dir, r);
    WriteRecording(dir, r);
    ExpectSameRecording(r, ReadRecording(dir));
  }
}

TEST(InterchangeRoundTripTest, RewriteIsByteIdentical) {
  TempDir tmp;
  const dataset::Recording r = RandomRecording(7);
  WriteImages(tmp.path() / "a", r);
  WriteRecording(tmp.path() / "a", r);
  WriteImages(tmp.path() / "b", r);
  WriteRecording(tmp.path() / "b", ReadRecording(tmp.path() / "a"));
  const auto files = FilesUnder(tmp.path() / "a");
  EXPECT_EQ(files, FilesUnder(tmp.path() / "b"));
  EXPECT_THAT(files, ::testing::Contains("hall/actual_clock.csv"));
  EXPECT_THAT(files, ::testing::Contains("marg/validation.csv"));
  for (const auto& f : files) {
    EXPECT_EQ(Slurp(tmp.path() / "a" / f), Slurp(tmp.path() / "b" / f)) << f;
  }
  // No temporaries left behind.
  for (const auto& f : files) EXPECT_EQ(f.find(".tmp-"), std::string::npos) << f;
}

TEST(InterchangeRoundTripTest, WrittenFolderPassesTheSharedValidator) {
  const fs::path tool = "/work/shared/tools/validate-interchange";
  if (!fs::exists(tool) || !fs::exists("/usr/bin/python3")) {
    GTEST_SKIP() << "validate-interchange or /usr/bin/python3 not present";
  }
  if (std::system("/usr/bin/python3 -c 'import yaml' >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "python3-yaml is not installed (apt-get install python3-yaml)";
  }
  TempDir tmp;
  const dataset::Recording r = RandomRecording(3);
  WriteImages(tmp.path(), r);
  WriteRecording(tmp.path(), r);
  const std::string cmd = "/usr/bin/python3 " + tool.string() + " " + tmp.path().string() + " > " +
                          (tmp.path() / "validator.txt").string() + " 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << Slurp(tmp.path() / "validator.txt");
}

TEST(InterchangeRoundTripTest, ReadsHandWrittenFolder) {
  TempDir tmp;
  const fs::path dir = tmp.path();
  Spit(dir / "camera.yaml",
       "image_size: [640, 480]\nK: [[500.5, 0, 320], [0, 501, 240.25], [0, 0, 1]]\n"
       "distortion: [0.1, -0.01, 0, 0, 1e-3]\n");
  Spit(dir / "session.yaml", R"(format: msmcal-interchange/1
boards:
  world:   {inner_corners: [9, 6], square_mm: 10.0}
  sliding: {inner_corners: [7, 4], square_mm: 12.5}
beams:
  - {id: 1, role: estimate}
  - {id: 3, role: validate}   # held out
drive:
  fast: {frequency_hz: 1200, amplitude_vpp: 2.5, phase_deg: 0}
  slow: {frequency_hz: 60, amplitude_vpp: 1.0, phase_deg: 90}
  pattern_period_s: 0.05
clock:
  frequency_hz: 20
triggers:
  - {j: 0, t_s: 0.001}
  - {j: 1, t_s: 0.002}
step1:
  frames:
    - {file: step1/0000.png, pose: 0, beams: [1, 3]}
step2:
  frames:
    - {file: step2/0000.png, kind: neutral, beams: [1, 3]}
    - file: step2/0001.png
      kind: scan
      triggers: [0, 1]
      beams: [1]
)");
  Spit(dir / "step1/0000.png", "x");
  Spit(dir / "step2/0000.png", "x");
  Spit(dir / "step2/0001.png", "x");
  Spit(dir / "hall/actual.csv", "mcu_time_us,bx_uT,by_uT,bz_uT\r\n10,1.5,-2,3e2\r\n");
  Spit(dir / "hall/actual_clock.csv", "mcu_time_us\n5\n50005\n");
  const dataset::Recording r = ReadRecording(dir);
  EXPECT_EQ(r.camera.width, 640);
  EXPECT_EQ(r.camera.fx, 500.5);
  EXPECT_EQ(r.camera.cy, 240.25);
  EXPECT_EQ(r.camera.distortion[4], 1e-3);
  EXPECT_EQ(r.sliding_board.square_mm, 12.5);
  EXPECT_EQ(r.beams[1].role, dataset::BeamRole::kValidate);
  EXPECT_EQ(r.drive.slow.phase_deg, 90);
  EXPECT_EQ(r.triggers[1].t_s, 0.002);
  ASSERT_EQ(r.step2.size(), 2u);
  EXPECT_TRUE(r.step2[0].triggers.empty());
  EXPECT_EQ(r.step2[1].triggers, (std::vector<int>{0, 1}));
  ASSERT_TRUE(r.hall_actual);
  EXPECT_EQ(r.hall_actual->readings[0].bz_uT, 300);
  EXPECT_EQ(r.hall_actual->clock_edges_us, (std::vector<double>{5, 50005}));
  EXPECT_FALSE(r.hall_background);
  EXPECT_FALSE(r.marg_free_rotation);
}

// ------------------------------------------------------------------------------------ errors

class InterchangeErrorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = tmp_.path();
    const dataset::Recording r = RandomRecording(11);
    WriteImages(dir_, r);
    WriteRecording(dir_, r);
  }
  std::string ReadError() {
    return ErrorOf([&] { ReadRecording(dir_); });
  }
  // 1-based line of the first line of `file` containing `needle`.
  int LineOf(const std::string& file, const std::string& needle) {
    std::istringstream in(Slurp(dir_ / file));
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      if (line.find(needle) != std::string::npos) return n;
    }
    ADD_FAILURE() << needle << " not in " << file;
    return -1;
  }
  TempDir tmp_;
  fs::path dir_;
};

TEST_F(InterchangeErrorTest, MissingFile) {
  fs::remove(dir_ / "camera.yaml");
  EXPECT_THAT(ReadError(), HasSubstr("camera.yaml: file not found"));
}

TEST_F(InterchangeErrorTest, WrongHeader) {
  Edit(dir_ / "hall/actual.csv", "mcu_time_us,bx_uT,by_uT,bz_uT", "mcu_time_us,bx_uT,by");
  EXPECT_THAT(ReadError(),
              HasSubstr("hall/actual.csv:1: header is 'mcu_time_us,bx_uT,by' but expected "
                        "'mcu_time_us,bx_uT,by_uT,bz_uT'"));
}

TEST_F(InterchangeErrorTest, WrongMargHeaderNamesBothColumnSets) {
  Edit(dir_ / "marg/validation.csv", "t_s,mx_uT", "time,mx_uT");
  const std::string e = ReadError();
  EXPECT_THAT(e, HasSubstr("marg/validation.csv:1: header is 'time,mx_uT,my_uT,mz_uT'"));
  EXPECT_THAT(e, HasSubstr("'t_s,mx_uT,my_uT,mz_uT'"));
  EXPECT_THAT(e, HasSubstr("'t_s,ax_g,ay_g,az_g,gx_dps,gy_dps,gz_dps,mx_uT,my_uT,mz_uT'"));
}

TEST_F(InterchangeErrorTest, NonNumericCell) {
  std::string text = Slurp(dir_ / "hall/background.csv");
  // Line 4 = third reading: replace its by_uT cell.
  std::istringstream in(text);
  std::string out, line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (n == 4) {
      const size_t c1 = line.find(',');
      const size_t c2 = line.find(',', c1 + 1);
      const size_t c3 = line.find(',', c2 + 1);
      line = line.substr(0, c2 + 1) + "abc" + line.substr(c3);
    }
    out += line + "\n";
  }
  Spit(dir_ / "hall/background.csv", out);
  EXPECT_THAT(ReadError(),
              HasSubstr("hall/background.csv:4: column 'by_uT': 'abc' is not a number"));
}

TEST_F(InterchangeErrorTest, FractionalTimesAreKept) {
  Spit(dir_ / "hall/actual.csv",
       "mcu_time_us,bx_uT,by_uT,bz_uT\n8999999.609,2,3,4\n9000999.6094,2,3,4\n");
  Spit(dir_ / "hall/actual_clock.csv", "mcu_time_us\n8999000.5\n9199000.25\n");
  const auto r = ReadRecording(dir_);
  ASSERT_TRUE(r.hall_actual);
  EXPECT_EQ(r.hall_actual->readings[0].mcu_time_us, 8999999.609);
  EXPECT_EQ(r.hall_actual->readings[1].mcu_time_us, 9000999.6094);
  EXPECT_EQ(r.hall_actual->clock_edges_us, (std::vector<double>{8999000.5, 9199000.25}));
}

TEST_F(InterchangeErrorTest, NonIncreasingReadingTime) {
  Spit(dir_ / "hall/actual.csv", "mcu_time_us,bx_uT,by_uT,bz_uT\n1,2,3,4\n2.5,2,3,4\n2.5,2,3,4\n");
  EXPECT_THAT(ReadError(), HasSubstr("hall/actual.csv:4: column 'mcu_time_us': readings must be "
                                     "in strictly increasing time, got 2.5 after 2.5"));
}

TEST_F(InterchangeErrorTest, NonFiniteNumbersAreRefused) {
  for (const std::string bad : {"nan", "inf", "-inf", "NaN", ".inf", "1e999"}) {
    Spit(dir_ / "hall/actual.csv", "mcu_time_us,bx_uT,by_uT,bz_uT\n1,2,3,4\n2,2," + bad + ",4\n");
    EXPECT_THAT(ReadError(), HasSubstr("hall/actual.csv:3: column 'by_uT': '" + bad +
                                       "' is not a finite number"))
        << bad;
  }
}

TEST_F(InterchangeErrorTest, WrongNumberOfCells) {
  Spit(dir_ / "hall/actual.csv", "mcu_time_us,bx_uT,by_uT,bz_uT\n1,2,3,4\n2,3,4\n");
  EXPECT_THAT(ReadError(), HasSubstr("hall/actual.csv:3: expected 4 cells "
                                     "('mcu_time_us,bx_uT,by_uT,bz_uT') but got 3"));
}

TEST_F(InterchangeErrorTest, UnknownFormatVersion) {
  Edit(dir_ / "session.yaml", "msmcal-interchange/1", "msmcal-interchange/2");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:1: field 'format': unknown format version "
                                     "'msmcal-interchange/2', expected 'msmcal-interchange/1'"));
}

TEST_F(InterchangeErrorTest, MissingKey) {
  Edit(dir_ / "session.yaml", ", pose: 1,", ",");
  const int line = LineOf("session.yaml", "step1/0002.png");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:" + std::to_string(line) +
                                     ": missing key 'step1.frames[2].pose'"));
}

TEST_F(InterchangeErrorTest, MissingTopLevelKey) {
  Edit(dir_ / "session.yaml", "clock:", "clack:");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:1: missing key 'clock'"));
}

TEST_F(InterchangeErrorTest, WrongType) {
  Edit(dir_ / "session.yaml", "pose: 1,", "pose: one,");
  const int line = LineOf("session.yaml", "pose: one");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:" + std::to_string(line) +
                                     ": field 'step1.frames[2].pose': expected an integer, "
                                     "got 'one'"));
}

TEST_F(InterchangeErrorTest, WrongTypeListExpected) {
  Edit(dir_ / "session.yaml", "triggers: [3]", "triggers: 3");
  const int line = LineOf("session.yaml", "triggers: 3");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:" + std::to_string(line) +
                                     ": field 'step2.frames[2].triggers': expected a list"));
}

TEST_F(InterchangeErrorTest, CameraWrongShape) {
  Edit(dir_ / "camera.yaml", "distortion: [", "distortion: [0, ");
  EXPECT_THAT(ReadError(), HasSubstr("camera.yaml:3: field 'distortion': expected a list of 5 "
                                     "elements, got 6"));
}

TEST_F(InterchangeErrorTest, YamlSyntaxError) {
  Edit(dir_ / "session.yaml", "step2:\n", "step2: [\n");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:"));
  EXPECT_THAT(ReadError(), HasSubstr("YAML syntax error"));
}

TEST_F(InterchangeErrorTest, ReferencedImageMissing) {
  fs::remove(dir_ / "step2/0001.png");
  const int line = LineOf("session.yaml", "step2/0001.png");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:" + std::to_string(line) +
                                     ": field 'step2.frames[1].file': referenced image "
                                     "'step2/0001.png' not found"));
}

TEST_F(InterchangeErrorTest, BeamNotInBeams) {
  Edit(dir_ / "session.yaml", "{file: step2/0003.png, kind: scan, triggers: [], beams: [7]}",
       "{file: step2/0003.png, kind: scan, triggers: [], beams: [8]}");
  const int line = LineOf("session.yaml", "step2/0003.png");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:" + std::to_string(line) +
                                     ": field 'step2.frames[3].beams[0]': beam 8 is not listed "
                                     "in 'beams'"));
}

TEST_F(InterchangeErrorTest, TriggerNotInTriggers) {
  Edit(dir_ / "session.yaml", "triggers: [0, 5]", "triggers: [0, 12]");
  const int line = LineOf("session.yaml", "triggers: [0, 12]");
  EXPECT_THAT(ReadError(), HasSubstr("session.yaml:" + std::to_string(line) +
                                     ": field 'step2.frames[1].triggers[1]': trigger index 12 is "
                                     "not listed in 'triggers'"));
}

TEST_F(InterchangeErrorTest, ActualWithoutClock) {
  fs::remove(dir_ / "hall/actual_clock.csv");
  EXPECT_THAT(ReadError(), HasSubstr("hall/actual_clock.csv: file not found: hall/actual.csv "
                                     "needs its clock edges"));
}

TEST_F(InterchangeErrorTest, NonAscendingClockEdges) {
  Spit(dir_ / "hall/background_clock.csv", "mcu_time_us\n10\n20\n20\n");
  EXPECT_THAT(ReadError(), HasSubstr("hall/background_clock.csv:4: column 'mcu_time_us': clock "
                                     "edges must be strictly ascending, got 20 after 20"));
}

TEST_F(InterchangeErrorTest, WriteRefusesInconsistentRecording) {
  dataset::Recording r = RandomRecording(11);
  r.step1[0].beams = {99};
  const std::string e = ErrorOf([&] { WriteRecording(dir_ / "bad", r); });
  EXPECT_THAT(e, HasSubstr("step1.frames[0].beams[0]': beam 99 is not listed"));
  EXPECT_FALSE(fs::exists(dir_ / "bad/session.yaml"));
}

// Every value has a range; an error names the file, the line, the field, the value and the
// allowed range (issue 17: these used to end in std::bad_alloc, a misleading beam error after
// 30 s, or a silently different result).
TEST_F(InterchangeErrorTest, ValuesOutsideTheirRangeAreRefusedAtTheirLine) {
  const std::string session = Slurp(dir_ / "session.yaml");
  const std::string camera = Slurp(dir_ / "camera.yaml");
  struct Case {
    std::string file, pattern, replacement, line_needle, message;
  };
  const std::vector<Case> cases = {
      {"session.yaml", R"(inner_corners: \[9, 6\])", "inner_corners: [2e9, 2e9]", "world:",
       "field 'boards.world.inner_corners[0]': value 2000000000 outside the allowed range "
       "[2, 1000]"},
      {"session.yaml", R"(inner_corners: \[7, 4\])", "inner_corners: [7, 1]", "sliding:",
       "field 'boards.sliding.inner_corners[1]': value 1 outside the allowed range [2, 1000]"},
      {"session.yaml", R"(world: \{inner_corners: \[9, 6\], square_mm: [^}]*\})",
       "world: {inner_corners: [9, 6], square_mm: 0}",
       "world:", "field 'boards.world.square_mm': value 0 outside the allowed range (0, 1000]"},
      {"session.yaml", R"(pose: 1,)", "pose: -5,", "pose: -5",
       "field 'step1.frames[2].pose': value -5 outside the allowed range [0, 1000000]"},
      {"session.yaml", R"(\{id: 7,)", "{id: -7,", "id: -7",
       "field 'beams[2].id': value -7 outside the allowed range [0, 1000000]"},
      {"session.yaml", R"(\{j: 3, t_s: [^}]*\})", "{j: 3, t_s: -1}", "j: 3,",
       "field 'triggers[3].t_s': value -1 outside the allowed range [0, "},
      {"session.yaml", R"(pattern_period_s: .*)", "pattern_period_s: 0", "pattern_period_s",
       "field 'drive.pattern_period_s': value 0 outside the allowed range (0, 10000]"},
      {"session.yaml", R"(fast: \{frequency_hz: [^,]*,)", "fast: {frequency_hz: -1230,", "fast:",
       "field 'drive.fast.frequency_hz': value -1230 outside the allowed range (0, 3.0e+07]"},
      {"session.yaml", R"(amplitude_vpp: [^,]*,)", "amplitude_vpp: 1e6,", "amplitude_vpp: 1e6",
       "field 'drive.fast.amplitude_vpp': value 1.0e+06 outside the allowed range [0, 20]"},
      {"camera.yaml", R"(image_size: .*)", "image_size: [0, 3000]", "image_size",
       "field 'image_size[0]': value 0 outside the allowed range [1, 100000]"},
      {"camera.yaml", R"(K: \[\[[^,]*,)", "K: [[-5,",
       "K:", "field 'K[0][0]': value -5 outside the allowed range (0, 1.0e+07]"},
      {"camera.yaml", R"(distortion: \[([^,]*), ([^,]*), [^,]*,)", "distortion: [$1, $2, 3,",
       "distortion", "field 'distortion[2]': value 3 outside the allowed range [-1, 1]"},
  };
  for (const Case& c : cases) {
    Spit(dir_ / "session.yaml", session);
    Spit(dir_ / "camera.yaml", camera);
    const std::string text = Slurp(dir_ / c.file);
    const std::string edited = std::regex_replace(text, std::regex(c.pattern), c.replacement,
                                                  std::regex_constants::format_first_only);
    ASSERT_NE(edited, text) << c.pattern;
    Spit(dir_ / c.file, edited);
    const int line = LineOf(c.file, c.line_needle);
    EXPECT_THAT(ReadError(), HasSubstr(c.file + ":" + std::to_string(line) + ": " + c.message))
        << c.pattern;
  }
}

// `msmcal solve` reads images through interchange::ImageProblem, the check `interchange check`
// makes: a wrong size or pixel type is named, not measured.
TEST(InterchangeImagesTest, ImageProblemChecksSizeAndType) {
  geometry::CameraModel cam;
  cam.width = 6;
  cam.height = 4;
  EXPECT_EQ(ImageProblem(cv::Mat(4, 6, CV_8UC1, cv::Scalar(0)), cam), "");
  EXPECT_EQ(ImageProblem(cv::Mat(4, 6, CV_16UC3, cv::Scalar(0)), cam), "");
  EXPECT_EQ(ImageProblem(cv::Mat(4, 5, CV_8UC1, cv::Scalar(0)), cam),
            "image is 5x4 but camera.yaml image_size is [6, 4]");
  EXPECT_THAT(ImageProblem(cv::Mat(4, 6, CV_32FC1, cv::Scalar(0)), cam),
              HasSubstr("expected 8- or 16-bit mono or BGR"));
}

TEST(InterchangeImagesTest, CheckImageFilesDecodesEveryImage) {
  TempDir tmp;
  dataset::Recording r = RandomRecording(2);
  r.camera.width = 6;
  r.camera.height = 4;
  r.camera.cx = 3;  // inside the allowed range for a 6x4 image
  r.camera.cy = 2;
  WriteImages(tmp.path(), r);
  WriteRecording(tmp.path(), r);
  CheckImageFiles(tmp.path(), ReadRecording(tmp.path()));
  WriteImageAtomically(tmp.path() / "step2/0002.png", cv::Mat(4, 5, CV_16UC3, cv::Scalar(1)));
  EXPECT_THAT(ErrorOf([&] { CheckImageFiles(tmp.path(), r); }),
              HasSubstr("step2/0002.png (step2.frames[2].file): image is 5x4 but camera.yaml "
                        "image_size is [6, 4]"));
  Spit(tmp.path() / "step1/0001.png", "not an image");
  EXPECT_THAT(ErrorOf([&] { CheckImageFiles(tmp.path(), r); }),
              HasSubstr("step1/0001.png (step1.frames[1].file): not a PNG file"));
}

// ---------------------------------------------------------------------------- single files

TEST(InterchangeFilesTest, MargBothColumnSetsRoundTrip) {
  TempDir tmp;
  Doubles d(5);
  for (bool inertial : {true, false}) {
    const auto m = RandomMarg(d, inertial, 100);
    const fs::path f = tmp.path() / (inertial ? "full.csv" : "mag.csv");
    WriteMargCsv(f, m);
    ExpectSameMarg(m, ReadMargCsv(f));
    EXPECT_EQ(Slurp(f).substr(0, 5), inertial ? "t_s,a" : "t_s,m");
  }
}

// The results/ CSVs (sessions/results) with the interchange format's number round trip.
TEST(InterchangeFilesTest, ResultsCsvsRoundTrip) {
  TempDir tmp;
  Doubles d(9);
  std::vector<dataset::MirrorPlaneRow> planes(20);
  for (auto& p : planes) {
    p.j = d.Int(-5, 500);
    p.t_s = d.Next();
    p.plane_in_world.n = Eigen::Vector3d(d.Next(), d.Next(), d.Next());
    p.plane_in_world.d = d.Next();
    p.alpha_deg = d.Next();
    p.beta_deg = d.Next();
    p.trans_mm = d.Next();
    p.sigma_alpha_deg = d.Next();
    p.sigma_beta_deg = d.Next();
    p.sigma_trans_mm = d.Next();
  }
  results::WriteMirrorPlanesCsv(tmp.path() / "results/mirror_planes.csv", planes);
  const auto planes2 = results::ReadMirrorPlanesCsv(tmp.path() / "results/mirror_planes.csv");
  ASSERT_EQ(planes.size(), planes2.size());
  for (size_t i = 0; i < planes.size(); ++i) {
    EXPECT_EQ(planes[i].j, planes2[i].j);
    EXPECT_TRUE(Same(planes[i].t_s, planes2[i].t_s));
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(Same(planes[i].plane_in_world.n[k], planes2[i].plane_in_world.n[k]));
    }
    EXPECT_TRUE(Same(planes[i].plane_in_world.d, planes2[i].plane_in_world.d));
    EXPECT_TRUE(Same(planes[i].alpha_deg, planes2[i].alpha_deg));
    EXPECT_TRUE(Same(planes[i].beta_deg, planes2[i].beta_deg));
    EXPECT_TRUE(Same(planes[i].trans_mm, planes2[i].trans_mm));
    EXPECT_TRUE(Same(planes[i].sigma_alpha_deg, planes2[i].sigma_alpha_deg));
    EXPECT_TRUE(Same(planes[i].sigma_beta_deg, planes2[i].sigma_beta_deg));
    EXPECT_TRUE(Same(planes[i].sigma_trans_mm, planes2[i].sigma_trans_mm));
  }
  EXPECT_EQ(Slurp(tmp.path() / "results/mirror_planes.csv").substr(0, 94),
            "j,t_s,nx,ny,nz,d_mm,alpha_deg,beta_deg,trans_mm,sigma_alpha_deg,sigma_beta_deg,"
            "sigma_trans_mm\n");

  std::vector<dataset::BeamRow> beams(4);
  for (auto& b : beams) {
    b.beam = d.Int(1, 9);
    b.p = Eigen::Vector3d(d.Next(), d.Next(), d.Next());
    b.v = Eigen::Vector3d(d.Next(), d.Next(), d.Next());
  }
  results::WriteBeamsCsv(tmp.path() / "beams.csv", beams);
  const auto beams2 = results::ReadBeamsCsv(tmp.path() / "beams.csv");
  ASSERT_EQ(beams2.size(), beams.size());
  for (size_t i = 0; i < beams.size(); ++i) {
    EXPECT_EQ(beams[i].beam, beams2[i].beam);
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(Same(beams[i].p[k], beams2[i].p[k]));
      EXPECT_TRUE(Same(beams[i].v[k], beams2[i].v[k]));
    }
  }

  std::vector<dataset::ValidationRow> val = {{3, 0, 0.25, 1e-3}, {3, 7, -0.0, 12.5}};
  results::WriteValidationCsv(tmp.path() / "validation.csv", val);
  EXPECT_EQ(Slurp(tmp.path() / "validation.csv"),
            "beam,j,err_px,err_deg\n3,0,0.25,0.001\n3,7,-0,12.5\n");
  const auto val2 = results::ReadValidationCsv(tmp.path() / "validation.csv");
  ASSERT_EQ(val2.size(), 2u);
  EXPECT_TRUE(Same(val2[1].err_px, -0.0));
  EXPECT_EQ(val2[1].j, 7);
}

TEST(InterchangeFilesTest, CameraYamlRoundTripAndText) {
  TempDir tmp;
  geometry::CameraModel c;
  c.width = 4096;
  c.height = 3000;
  c.fx = 8123.25;
  c.fy = 8120.5;
  c.cx = 2048.1;
  c.cy = 1499.9;
  c.distortion = {-0.1, 0.02, 1e-7, -2e-5, 0};
  WriteCameraYaml(tmp.path() / "camera.yaml", c);
  EXPECT_EQ(Slurp(tmp.path() / "camera.yaml"),
            "image_size: [4096, 3000]\n"
            "K: [[8123.25, 0, 2048.1], [0, 8120.5, 1499.9], [0, 0, 1]]\n"
            "distortion: [-0.1, 0.02, 1.0e-07, -2.0e-05, 0]\n");
  const auto c2 = ReadCameraYaml(tmp.path() / "camera.yaml");
  EXPECT_EQ(c2.fx, c.fx);
  EXPECT_EQ(c2.distortion, c.distortion);
}

TEST(InterchangeFilesTest, AtomicWriteReportsFailureAndLeavesNoTemporary) {
  TempDir tmp;
  Spit(tmp.path() / "blocker", "a file, not a folder");
  EXPECT_THAT(ErrorOf([&] { WriteFileAtomically(tmp.path() / "blocker/x.csv", "x"); }),
              HasSubstr("blocker/x.csv: cannot create folder"));
  fs::create_directories(tmp.path() / "dir");
  WriteFileAtomically(tmp.path() / "dir/x.csv", "old");
  WriteFileAtomically(tmp.path() / "dir/x.csv", "new");
  EXPECT_EQ(Slurp(tmp.path() / "dir/x.csv"), "new");
  EXPECT_EQ(FilesUnder(tmp.path() / "dir"), std::vector<std::string>{"x.csv"});
}

TEST(InterchangeFilesTest, ImagesAreWrittenLosslessly) {
  TempDir tmp;
  std::mt19937 rng(1);
  for (int type : {CV_8UC1, CV_8UC3, CV_16UC1, CV_16UC3}) {
    cv::Mat img(31, 47, type);
    cv::randu(img, 0, CV_MAT_DEPTH(type) == CV_8U ? 256 : 65536);
    const fs::path f = tmp.path() / "img" / (std::to_string(type) + ".png");
    WriteImageAtomically(f, img);
    const cv::Mat back = cv::imread(f.string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(back.type(), type);
    EXPECT_EQ(cv::norm(img, back, cv::NORM_INF), 0);
  }
  cv::Mat floats(4, 4, CV_32FC1, cv::Scalar(1));
  EXPECT_THAT(ErrorOf([&] { WriteImageAtomically(tmp.path() / "f.png", floats); }),
              HasSubstr("f.png: image must be a non-empty 8- or 16-bit mono or BGR image"));
  EXPECT_FALSE(fs::exists(tmp.path() / "f.png"));
}

}  // namespace
}  // namespace msmcal::interchange
