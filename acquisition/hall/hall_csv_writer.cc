#include "acquisition/hall/hall_csv_writer.h"

#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <stdexcept>

#include "processing/dataset/hall_csv.h"

namespace msmcal::acquisition {
namespace {

std::FILE* OpenOrThrow(const std::filesystem::path& path, const char* header) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    throw std::runtime_error("cannot open " + path.string() +
                             " for writing: " + std::strerror(errno));
  }
  std::fputs(header, f);
  std::fputc('\n', f);
  return f;
}

void WriteOrThrow(std::FILE* f, const std::string& text, const std::filesystem::path& path) {
  if (std::fwrite(text.data(), 1, text.size(), f) != text.size() || std::fflush(f) != 0) {
    throw std::runtime_error("write to " + path.string() + " failed: " + std::strerror(errno));
  }
}

}  // namespace

std::filesystem::path ClockCsvPathFor(const std::filesystem::path& readings_csv) {
  std::filesystem::path p = readings_csv;
  p.replace_filename(readings_csv.stem().string() + "_clock" + readings_csv.extension().string());
  return p;
}

HallCsvWriter::HallCsvWriter(std::filesystem::path readings_csv)
    : readings_csv_(std::move(readings_csv)) {
  FilesFor(0);
}

HallCsvWriter::~HallCsvWriter() {
  try {
    Close();
  } catch (const std::exception&) {
    // Destructors do not throw; call Close() to see errors.
  }
}

HallCsvWriter::Files& HallCsvWriter::FilesFor(uint32_t epoch) {
  auto it = files_.find(epoch);
  if (it != files_.end()) return it->second;
  Files f;
  f.readings_path = readings_csv_;
  if (epoch > 0) {
    f.readings_path.replace_filename(readings_csv_.stem().string() + "-reset" +
                                     std::to_string(epoch) + readings_csv_.extension().string());
  }
  f.clock_path = ClockCsvPathFor(f.readings_path);
  f.readings = OpenOrThrow(f.readings_path, dataset::kHallReadingsHeader);
  try {
    f.clock = OpenOrThrow(f.clock_path, dataset::kHallClockHeader);
  } catch (...) {
    std::fclose(f.readings);
    throw;
  }
  std::fflush(f.readings);
  std::fflush(f.clock);
  return files_.emplace(epoch, f).first->second;
}

void HallCsvWriter::Write(const hall_mcu::HallBatch& batch) {
  std::map<uint32_t, std::string> readings, clocks;
  for (const hall_mcu::HallSample& r : batch.readings) {
    dataset::AppendHallReadingRow(&readings[r.epoch], r.mcu_time_us, r.bx_uT, r.by_uT, r.bz_uT);
  }
  for (const hall_mcu::ClockEdge& e : batch.edges) {
    dataset::AppendClockEdgeRow(&clocks[e.epoch], e.mcu_time_us);
  }
  for (const auto& [epoch, text] : readings) {
    Files& f = FilesFor(epoch);
    WriteOrThrow(f.readings, text, f.readings_path);
  }
  for (const auto& [epoch, text] : clocks) {
    Files& f = FilesFor(epoch);
    WriteOrThrow(f.clock, text, f.clock_path);
  }
  readings_written_ += batch.readings.size();
  edges_written_ += batch.edges.size();
}

void HallCsvWriter::Close() {
  std::string error;
  for (auto& [epoch, f] : files_) {
    for (auto [file, path] :
         {std::pair{&f.readings, &f.readings_path}, std::pair{&f.clock, &f.clock_path}}) {
      if (*file == nullptr) continue;
      if (std::fflush(*file) != 0 || fsync(fileno(*file)) != 0) {
        if (error.empty())
          error = "flush of " + path->string() + " failed: " + std::strerror(errno);
      }
      std::fclose(*file);
      *file = nullptr;
    }
  }
  if (!error.empty()) throw std::runtime_error(error);
}

}  // namespace msmcal::acquisition
