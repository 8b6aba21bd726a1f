#pragma once
// The strict CSV reader of the interchange format (../shared/docs/interchange-format.md), shared
// by every reader of a CSV file msmcal writes (the recording's hall/ and marg/ files, results/).
//
// The first line must be one of the expected headers (cells trimmed, a UTF-8 byte-order mark
// tolerated); every row must have the header's number of cells; empty lines are skipped and '\r'
// before '\n' is accepted. Numbers are strict: the whole cell, finite (no nan/inf).
// Errors throw InterchangeError naming the file, the line and the column:
// "results/hall_poses.csv:12: column 't_s': 'abc' is not a number".

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace msmcal::interchange {

class CsvReader {
 public:
  // Reads `path` whole; `display` is its name in messages. Throws when the file is missing,
  // empty, or its header is none of `headers`.
  CsvReader(const std::filesystem::path& path, std::string display,
            const std::vector<const char*>& headers);
  // The same on a file's contents already in memory (parsers of text, e.g. the fuzz targets).
  struct Text {
    std::string contents;
  };
  CsvReader(Text text, std::string display, const std::vector<const char*>& headers);

  // Which of the constructor's `headers` the file has.
  int header_index() const { return header_index_; }
  // 1-based line of the current row.
  int line() const { return line_; }
  const std::string& display() const { return display_; }

  // Advances to the next non-empty row; false at the end of the file. Throws on a row whose
  // number of cells is not the header's.
  bool Next();

  // Cell `i` of the current row as a finite number / an integer (also "3.0", "3e0"); throws
  // naming the file, line and column otherwise.
  double Double(size_t i) const;
  int Int(size_t i) const;
  long long Int64(size_t i) const;

 private:
  void ReadHeader(const std::vector<const char*>& headers);
  std::string HeaderText() const;
  bool NextLine();

  std::string display_;
  std::string text_;
  size_t pos_ = 0;
  int line_ = 0;
  std::string_view line_text_;
  int header_index_ = -1;
  std::vector<std::string> columns_;
  std::vector<std::string_view> cells_;
};

}  // namespace msmcal::interchange
