#pragma once
// Reading and writing the recorded-session interchange folder, format version 1
// (../shared/docs/interchange-format.md). This is a contract with other tools and labs: file
// names, keys and CSV columns are exactly those of the document.
//
// Errors: every function throws InterchangeError whose message names the file (path relative to
// the folder where there is one), the line (1-based, CSV and YAML) and the field, and what was
// expected, e.g. "hall/actual.csv:1: header is 'mcu_time_us,bx_uT,by' but expected
// 'mcu_time_us,bx_uT,by_uT,bz_uT'".
//
// Lossless: numbers are written with the shortest representation that reads back to the same
// double (std::to_chars), so Read(Write(x)) == x field for field.

#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "processing/dataset/recording.h"

namespace cv {
class Mat;
}

namespace msmcal::interchange {

class InterchangeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads session.yaml, camera.yaml, the hall/ CSVs and the marg/ CSVs that exist. Checks that
// every referenced image exists (does not decode it). Hall files are optional as a pair
// (actual.csv needs actual_clock.csv); marg files are optional each.
// What of a folder a tool needs (a problem in a file a command does not use is not its error).
struct ReadParts {
  bool hall = true;  // hall/*.csv
  bool marg = true;  // marg/*.csv
};
dataset::Recording ReadRecording(const std::filesystem::path& dir, ReadParts parts = {});
// What `msmcal solve` needs: session.yaml, camera.yaml and the images, never hall/ or marg/.
inline dataset::Recording ReadRecordingForSolve(const std::filesystem::path& dir) {
  return ReadRecording(dir, ReadParts{/*hall=*/false, /*marg=*/false});
}

// Writes session.yaml, camera.yaml and the hall/ and marg/ CSVs present in `recording`.
// Images are not written here (see WriteImage); existing files are replaced atomically
// (write to a temporary, fsync, rename).
void WriteRecording(const std::filesystem::path& dir, const dataset::Recording& recording);

// Single files (used by the above and by tools that work on one file).
geometry::CameraModel ReadCameraYaml(const std::filesystem::path& file);
void WriteCameraYaml(const std::filesystem::path& file, const geometry::CameraModel& camera);
dataset::HallRecording ReadHallCsv(const std::filesystem::path& readings_csv,
                                   const std::filesystem::path& clock_csv);
void WriteHallCsv(const std::filesystem::path& readings_csv, const std::filesystem::path& clock_csv,
                  const dataset::HallRecording& hall);
std::vector<dataset::HallReading> ReadHallReadingsCsv(const std::filesystem::path& file);
void WriteHallReadingsCsv(const std::filesystem::path& file,
                          const std::vector<dataset::HallReading>& readings);
dataset::MargRecording ReadMargCsv(const std::filesystem::path& file);
void WriteMargCsv(const std::filesystem::path& file, const dataset::MargRecording& recording);

// The CSV readers and writers above on text (`display_name` stands for the file in messages):
// ParseX(FormatX(x), name) == x.
std::vector<dataset::HallReading> ParseHallReadingsCsv(const std::string& text,
                                                       const std::string& display_name);
std::vector<double> ParseClockEdgesCsv(const std::string& text, const std::string& display_name);
dataset::MargRecording ParseMargCsv(const std::string& text, const std::string& display_name);
std::string FormatHallReadingsCsv(const std::vector<dataset::HallReading>& readings);
std::string FormatClockEdgesCsv(const std::vector<double>& edges);
std::string FormatMargCsv(const dataset::MargRecording& recording);

// results/ files: sessions/results/results_files.h.

// Writes `contents` to `file` atomically: temporary in the same folder, fsync, rename, fsync of
// the folder. Creates parent folders.
void WriteFileAtomically(const std::filesystem::path& file, const std::string& contents);

// Encodes `image` as PNG (CV_8U or CV_16U, 1 channel = mono or 3 channels = BGR) and writes it
// atomically as above. Throws InterchangeError naming the file for any other type or on failure.
void WriteImageAtomically(const std::filesystem::path& file, const cv::Mat& image);

// The text WriteRecording puts in session.yaml / camera.yaml (deterministic: the same recording
// gives the same bytes). Used by the session store to re-create a folder.
std::string FormatSessionYaml(const dataset::Recording& recording);
std::string FormatCameraYaml(const geometry::CameraModel& camera);

// Parses session.yaml text into the session fields of `recording` (format, boards, beams, drive,
// clock, triggers, step1, step2) and checks its internal references (beam ids, trigger indices).
// `display_name` is the name used in error messages. Image files are not checked here.
void ParseSessionYaml(const std::string& text, const std::string& display_name,
                      dataset::Recording* recording);
geometry::CameraModel ParseCameraYaml(const std::string& text, const std::string& display_name);

// Checks that `recording`'s references are consistent (frame beam ids in `beams`, trigger indices
// in `triggers`, unique ids, clock edges strictly ascending). Empty if fine, else the first
// problem, naming the field.
std::string CheckRecording(const dataset::Recording& recording);

// Decodes every image `recording` references under `dir` and checks it is a PNG of 8 or 16 bits
// with 1 or 3 channels and the size of camera.yaml's image_size. Throws InterchangeError naming
// the image and the session.yaml field ("step2/0001.png (step2.frames[1].file): ...").
// Empty when a decoded image is what the format allows (8- or 16-bit, mono or BGR) and has
// camera.yaml's image_size; else what is wrong. CheckImageFiles and `msmcal solve` (as it reads
// each image) apply it.
std::string ImageProblem(const cv::Mat& image, const geometry::CameraModel& camera);
// Slow for big images: ReadRecording does not do it; `msmcal interchange check` does.
void CheckImageFiles(const std::filesystem::path& dir, const dataset::Recording& recording);

// Shortest round-trip text for a double ("0.1", "1e-07", "-3").
std::string FormatDouble(double value);

}  // namespace msmcal::interchange
