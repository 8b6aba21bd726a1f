#pragma once
// Streams Hall readings and clock edges into the interchange CSV files
// (interchange-format.md, "Hall CSV files") as they arrive: header
// `mcu_time_us,bx_uT,by_uT,bz_uT` for readings and `mcu_time_us` for the clock file. Numbers use
// the shortest representation that reads back to the same double (lossless). Every Write() ends
// with a flush to the OS, so a crash loses nothing already handed over; Close() also fsyncs.
//
// MCU resets: MCU time restarts, so readings of epoch N > 0 go to their own pair of files,
// `<stem>-reset<N>.csv` and `<stem>-reset<N>_clock.csv` beside the first pair.

#include <cstdio>
#include <filesystem>
#include <map>
#include <string>

#include "drivers/hall_mcu/hall_sensor.h"

namespace msmcal::acquisition {

// Clock file that goes with a readings file: "dir/actual.csv" -> "dir/actual_clock.csv".
std::filesystem::path ClockCsvPathFor(const std::filesystem::path& readings_csv);

class HallCsvWriter {
 public:
  // Creates (truncates) readings_csv and its clock file and writes the headers. Throws
  // std::runtime_error naming the file if it cannot be opened.
  explicit HallCsvWriter(std::filesystem::path readings_csv);
  ~HallCsvWriter();  // Close()
  HallCsvWriter(const HallCsvWriter&) = delete;
  HallCsvWriter& operator=(const HallCsvWriter&) = delete;

  // Appends the batch and flushes. Not thread-safe (call from the recorder's sink thread).
  // Throws std::runtime_error naming the file on a write error.
  void Write(const hall_mcu::HallBatch& batch);
  // Flushes, fsyncs and closes every file; idempotent. Throws on a write/fsync error.
  void Close();

  uint64_t readings_written() const { return readings_written_; }
  uint64_t edges_written() const { return edges_written_; }

 private:
  struct Files {
    std::filesystem::path readings_path, clock_path;
    std::FILE* readings = nullptr;
    std::FILE* clock = nullptr;
  };
  Files& FilesFor(uint32_t epoch);

  std::filesystem::path readings_csv_;
  std::map<uint32_t, Files> files_;
  uint64_t readings_written_ = 0;
  uint64_t edges_written_ = 0;
};

}  // namespace msmcal::acquisition
