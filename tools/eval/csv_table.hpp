#pragma once
// A numeric CSV file held column-wise: a header row of names, then rows of numbers. Used by torque-eval for
// estimate CSVs (first column t_ns) and simulator truth CSVs (t_s or cycle,t_start_s,t_end_s). Not real-time.
#include <cstddef>
#include <string>
#include <vector>

namespace torqued::eval {

struct CsvTable {
  std::string path;
  std::vector<std::string> names;
  std::vector<std::vector<double>> cols;  ///< cols[c][row]; unparsable cells are NaN
  std::size_t bad_rows = 0;               ///< rows with the wrong cell count (skipped) or unparsable cells

  [[nodiscard]] std::size_t rows() const noexcept { return cols.empty() ? 0 : cols.front().size(); }
  /// Index of a column, or -1.
  [[nodiscard]] int column(const std::string& name) const noexcept;
  [[nodiscard]] const std::vector<double>& col(int index) const {
    return cols.at(static_cast<std::size_t>(index));
  }
};

/// Reads `path`. Returns false (with a message naming the file) if it cannot be read or has no header.
/// Bad rows are reported in `warnings` as "FILE:LINE: ..." (at most 10, then a count) and skipped.
bool read_csv(const std::string& path, CsvTable& out, std::string& error, std::vector<std::string>& warnings);
/// Same from text (tests).
bool parse_csv(const std::string& text, const std::string& name, CsvTable& out, std::string& error,
               std::vector<std::string>& warnings);

}  // namespace torqued::eval
