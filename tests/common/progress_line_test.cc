// The progress line of long commands: its text, the ETA, redraws in place with a throttle, and
// silence when the stream is not a terminal.
#include "common/progress_line.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace msmcal::common {
namespace {

// What was written to a FILE (a memory stream).
class Captured {
 public:
  Captured() : f_(open_memstream(&buf_, &size_)) {}
  ~Captured() {
    std::fclose(f_);
    std::free(buf_);
  }
  std::FILE* file() { return f_; }
  std::string text() {
    std::fflush(f_);
    return std::string(buf_, size_);
  }

 private:
  char* buf_ = nullptr;
  size_t size_ = 0;
  std::FILE* f_;
};

TEST(FormatProgressLine, FiguresAndEta) {
  EXPECT_EQ(FormatProgressLine("solve", 12, 48, "images", 6.0, ""),
            "solve: 12/48 images (25%), 0:06 elapsed, ETA 0:18");
  EXPECT_EQ(FormatProgressLine("simulate", 0, 10, "frames", 3.0, "x"),
            "simulate: 0/10 frames (0%), 0:03 elapsed, ETA -  x");
  EXPECT_EQ(FormatProgressLine("t", 1, 2, "", 3725.0, ""),
            "t: 1/2 (50%), 1:02:05 elapsed, ETA 1:02:05");
  EXPECT_EQ(FormatProgressLine("t", 5, 2, "rows", 1.0, ""),
            "t: 2/2 rows (100%), 0:01 elapsed, ETA 0:00");
}

TEST(ProgressLine, RedrawsInPlaceAtMostEveryFifthOfASecondAndEndsTheLine) {
  Captured out;
  double now = 100.0;
  {
    ProgressLine p("simulate", 4, "frames", out.file(), /*enabled=*/true, [&] { return now; });
    now += 0.05;
    p.Step();  // within 0.2 s of the first draw: not drawn
    now += 0.2;
    p.Step();  // drawn
    now += 0.25;
    p.Step();
    p.Step();  // the last unit: always drawn
  }
  const std::string t = out.text();
  EXPECT_EQ(t,
            "\rsimulate: 0/4 frames (0%), 0:00 elapsed, ETA -\x1b[K"
            "\rsimulate: 2/4 frames (50%), 0:00 elapsed, ETA 0:00\x1b[K"
            "\rsimulate: 3/4 frames (75%), 0:01 elapsed, ETA 0:00\x1b[K"
            "\rsimulate: 4/4 frames (100%), 0:01 elapsed, ETA 0:00\x1b[K"
            "\rsimulate: 4/4 frames (100%), 0:01 elapsed, ETA 0:00\x1b[K\n");
}

TEST(ProgressLine, SilentWhenNotATerminal) {
  Captured out;
  {
    // A memory stream is not a terminal: the isatty check of the ordinary constructor says so.
    ProgressLine p("solve", 3, "images", out.file());
    EXPECT_FALSE(p.enabled());
    p.Update(1, "reading");
    p.Update(3, "estimating");
  }
  EXPECT_EQ(out.text(), "");
}

}  // namespace
}  // namespace msmcal::common
