#include "csv_table.hpp"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace torqued::eval {
namespace {

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t\r\"");
  const auto e = s.find_last_not_of(" \t\r\"");
  return b == std::string::npos ? std::string{} : s.substr(b, e - b + 1);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream is(line);
  while (std::getline(is, cell, ',')) out.push_back(trim(cell));
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

bool to_double(const std::string& s, double& v) {
  if (s.empty()) return false;
  if (s == "nan" || s == "NaN" || s == "-nan") {
    v = std::nan("");
    return true;
  }
  char* end = nullptr;
  const double x = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size()) return false;
  v = x;
  return true;
}

}  // namespace

int CsvTable::column(const std::string& name) const noexcept {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return static_cast<int>(i);
  return -1;
}

bool parse_csv(const std::string& text, const std::string& name, CsvTable& out, std::string& error,
               std::vector<std::string>& warnings) {
  out = CsvTable{};
  out.path = name;
  std::istringstream in(text);
  std::string line;
  std::size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!trim(line).empty() && trim(line)[0] != '#') break;
  }
  if (trim(line).empty()) {
    error = name + ": empty file, expected a header row of column names";
    return false;
  }
  out.names = split(line);
  out.cols.assign(out.names.size(), {});
  std::size_t reported = 0;
  auto warn = [&](const std::string& msg) {
    ++out.bad_rows;
    if (reported++ < 10) warnings.push_back(name + ":" + std::to_string(line_no) + ": " + msg);
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (trim(line).empty() || trim(line)[0] == '#') continue;
    const auto cells = split(line);
    if (cells.size() != out.names.size()) {
      warn("expected " + std::to_string(out.names.size()) + " cells, found " + std::to_string(cells.size()) +
           "; row skipped");
      continue;
    }
    bool bad = false;
    for (std::size_t c = 0; c < cells.size(); ++c) {
      double v = std::nan("");
      if (!to_double(cells[c], v)) bad = true;
      out.cols[c].push_back(v);
    }
    if (bad) warn("a cell is not a number (kept as NaN)");
  }
  if (reported > 10) warnings.push_back(name + ": " + std::to_string(reported - 10) + " more bad rows");
  return true;
}

bool read_csv(const std::string& path, CsvTable& out, std::string& error,
              std::vector<std::string>& warnings) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = path + ": cannot open";
    return false;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_csv(ss.str(), path, out, error, warnings);
}

}  // namespace torqued::eval
