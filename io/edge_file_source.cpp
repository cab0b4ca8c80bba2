#include "edge_file_source.hpp"

#include <cctype>
#include <cstring>

#include "fast_parse.hpp"

namespace torqued {
namespace {
constexpr std::size_t kMaxMessages = 20;

bool iequals(std::string_view a, std::string_view b) noexcept {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i])))
      return false;
  }
  return true;
}

bool is_comment_or_blank(std::string_view line) noexcept {
  const auto t = parse::trim(line);
  return t.empty() || t.front() == ';' || t.front() == '#';
}

/// Eight ASCII digits at p -> value, or false if any is not a digit (SWAR, little-endian; Lemire's trick).
inline bool eight_digits(const char* p, std::uint64_t& out) noexcept {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  // every byte in '0'..'9': high nibble 3 and (byte + 6) still has high nibble 3
  if (((v & 0xF0F0F0F0F0F0F0F0ull) | (((v + 0x0606060606060606ull) & 0xF0F0F0F0F0F0F0F0ull) >> 4)) !=
      0x3333333333333333ull)
    return false;
  v -= 0x3030303030303030ull;
  v = (v * 10) + (v >> 8);  // pairs
  v = (((v & 0x000000FF000000FFull) * (100 + (1000000ull << 32))) +
       (((v >> 16) & 0x000000FF000000FFull) * (1 + (10000ull << 32)))) >>
      32;
  out = v;
  return true;
}

/// Decimal seconds with an optional exponent ("0.00383033", "8e-05", "1.5E+2", "-2.5e-3") -> integer ns,
/// rounded half away from zero. Up to 18 significant digits are kept exactly. False (p unspecified) on
/// anything else or on an out-of-range value.
bool seconds_exp_to_ns(const char*& p, const char* end, std::int64_t& ns) noexcept {
  bool neg = false;
  if (p < end && (*p == '-' || *p == '+')) neg = *p++ == '-';
  std::uint64_t m = 0;
  int sig = 0, dec_exp = 0, digits = 0;
  bool frac = false;
  for (; p < end; ++p) {
    if (*p == '.' && !frac) {
      frac = true;
      continue;
    }
    const unsigned d = static_cast<unsigned>(*p - '0');
    if (d >= 10u) break;
    ++digits;
    if (sig < 18) {
      if (m != 0 || d != 0) ++sig;
      m = m * 10 + d;
      if (frac) --dec_exp;
    } else if (!frac) {
      ++dec_exp;  // digits beyond 18 significant ones in the integer part only scale
    }
  }
  if (digits == 0) return false;
  if (p < end && (*p == 'e' || *p == 'E')) {
    ++p;
    bool eneg = false;
    if (p < end && (*p == '-' || *p == '+')) eneg = *p++ == '-';
    int e = 0, edigits = 0;
    while (p < end && static_cast<unsigned>(*p - '0') < 10u) {
      if (e < 1000) e = e * 10 + (*p - '0');
      ++p;
      ++edigits;
    }
    if (edigits == 0) return false;
    dec_exp += eneg ? -e : e;
  }
  int scale = dec_exp + 9;  // value in ns = m x 10^scale
  if (m == 0) scale = 0;
  for (; scale > 0; --scale) {
    if (m > static_cast<std::uint64_t>(INT64_MAX) / 10) return false;
    m *= 10;
  }
  if (scale < -19) m = 0;
  for (; scale < 0; ++scale) m = scale == -1 ? (m + 5) / 10 : m / 10;
  if (m > static_cast<std::uint64_t>(INT64_MAX)) return false;
  ns = neg ? -static_cast<std::int64_t>(m) : static_cast<std::int64_t>(m);
  return true;
}

/// A column given by number ("1", "2", ...): its index, else -1.
int column_number(std::string_view s) noexcept {
  const auto t = parse::trim(s);
  if (t.empty() || t.size() > 3) return -1;
  int v = 0;
  for (const char c : t) {
    if (c < '0' || c > '9') return -1;
    v = v * 10 + (c - '0');
  }
  return v >= 1 ? v : -1;
}

/// A data row rather than a header: its first field is a number.
bool looks_like_data(std::string_view line) noexcept {
  const char* p = line.data();
  const char* end = p + line.size();
  parse::skip_ws(p, end);
  std::int64_t t = 0;
  if (!seconds_exp_to_ns(p, end, t)) return false;
  parse::skip_ws(p, end);
  return p == end || *p == ',';
}

}  // namespace

/// Fast path for the common export row "<s>.<9 digits>,<c>,<c>..." (no spaces/sign, exactly 9 decimals, one
/// character per level column, exactly the header's column count) at the start of [p, p + avail): raw time in
/// header units x 1e9 and the crank/cam levels. Returns the row's length (the caller checks what ends it:
/// '\n' in the reader's buffer, or the end of a line), 0 for anything else: the general parser then handles
/// (or reports) the line, so both paths agree on every row the fast one accepts (tests/io:
/// EdgeCsv.FastPathAgreesWithGeneralParser).
/// Inlined into next() (its only caller, twice): per edge row no call and no argument spills through memory.
[[gnu::always_inline]] inline std::size_t EdgeCsvSource::parse_row_fast(const char* p, std::size_t avail,
                                                                        std::int64_t& t, int& crank,
                                                                        int& cam) const noexcept {
  const char* const begin = p;
  const char* const end = p + avail;
  std::int64_t whole = 0;
  // At most 10 digits are accumulated (a 10th makes the row fall back below): no signed overflow, whatever
  // the length of the digit run (tests/io: EdgeCsv.LongIntegerPartIsNotUndefinedBehaviour).
  while (p < end && p - begin < 10 && static_cast<unsigned>(*p - '0') < 10u)
    whole = whole * 10 + (*p++ - '0');
  const auto int_digits = p - begin;
  // integer part 1..9 digits (no overflow), '.', 9 digits, then 2 characters per further column
  const std::ptrdiff_t len = int_digits + 10 + 2 * static_cast<std::ptrdiff_t>(columns_ - 1);
  if (int_digits < 1 || int_digits > 9 || end - begin < len || *p != '.') return 0;
  std::uint64_t frac8 = 0;
  if (!eight_digits(p + 1, frac8) || static_cast<unsigned>(p[9] - '0') >= 10u) return 0;
  const char* c = p + 10;                                   // ",x,y..."
  if (columns_ == 3 && crank_col_ == 1 && cam_col_ == 2) {  // the usual export: ",crank,cam", no loop
    const unsigned dc = static_cast<unsigned>(c[1] - '0'), dm = static_cast<unsigned>(c[3] - '0');
    if (c[0] != ',' || c[2] != ',' || (dc | dm) > 1u) return 0;
    crank = static_cast<int>(dc);
    cam = static_cast<int>(dm);
  } else {
    int lv[2] = {-1, -1};
    for (int col = 1; col < columns_; ++col, c += 2) {
      if (c[0] != ',') return 0;
      const unsigned d = static_cast<unsigned>(c[1] - '0');
      if (col == crank_col_ || col == cam_col_) {
        if (d > 1u) return 0;
        lv[col == crank_col_ ? 0 : 1] = static_cast<int>(d);
      } else if (d >= 10u) {
        return 0;
      }
    }
    crank = lv[0];
    cam = lv[1];
  }
  t = whole * 1'000'000'000 + static_cast<std::int64_t>(frac8 * 10 + static_cast<unsigned>(p[9] - '0'));
  return static_cast<std::size_t>(len);
}

namespace {

void note(std::vector<std::string>& messages, std::string& error, const std::string& path, std::uint64_t line,
          const char* what) {
  if (messages.size() >= kMaxMessages) return;
  messages.push_back(path + ":" + std::to_string(line) + ": " + what);
  error = messages.back();
}
}  // namespace

EdgeCsvSource::EdgeCsvSource(std::string path, EdgeCsvOptions options)
    : path_(std::move(path)), opt_(std::move(options)), sanity_(opt_.time) {
  messages_.reserve(kMaxMessages + 2);
  if (!reader_.open(path_)) {
    error_ = reader_.error();
    return;
  }
  std::string_view line;
  while (reader_.next(line) && is_comment_or_blank(line)) {
  }
  if (reader_.line_number() == 0 || is_comment_or_blank(line)) {
    error_ = path_ + ": empty file, expected a header row 'Time [s]," + opt_.crank_column +
             ",...' or data rows '<time s>,<level 0|1>,...'";
    return;
  }
  ok_ = resolve_columns(line);
}

/// Header row (names) or, in a headerless file, the first data row (column count; kept to be read first).
bool EdgeCsvSource::resolve_columns(std::string_view line) {
  has_header_ = !looks_like_data(line);
  int col = 0;
  std::size_t start = 0;
  std::string names;
  while (start <= line.size()) {
    std::size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) comma = line.size();
    const auto name = parse::trim(line.substr(start, comma - start));
    if (col == 0 && has_header_) {
      if (name.find("[ms]") != std::string_view::npos)
        time_scale_div_ = 1000;
      else if (name.find("[us]") != std::string_view::npos || name.find("[µs]") != std::string_view::npos)
        time_scale_div_ = 1'000'000;
      else if (name.find("[ns]") != std::string_view::npos)
        time_scale_div_ = 1'000'000'000;
    } else if (col > 0 && has_header_) {
      if (iequals(name, opt_.crank_column)) crank_col_ = col;
      if (!opt_.cam_column.empty() && iequals(name, opt_.cam_column)) cam_col_ = col;
      names += (names.empty() ? "" : ", ") + std::string(name);
    }
    ++col;
    start = comma + 1;
  }
  columns_ = col;
  // Columns given by number (also with a header); without a header the default names mean columns 1 and 2.
  if (crank_col_ < 0) crank_col_ = column_number(opt_.crank_column);
  if (cam_col_ < 0 && !opt_.cam_column.empty()) cam_col_ = column_number(opt_.cam_column);
  if (!has_header_) {
    if (crank_col_ < 0 && opt_.crank_column == "crank") crank_col_ = 1;
    if (cam_col_ < 0 && opt_.cam_column == "cam") cam_col_ = columns_ > 2 ? 2 : -2;  // -2: no cam column
    names = std::to_string(columns_ - 1) + " level columns, no header";
  }
  const std::string where = path_ + ":" + std::to_string(reader_.line_number()) + ": ";
  if (crank_col_ < 0 || crank_col_ >= columns_) {
    error_ = where + "no crank column named '" + opt_.crank_column + "' (found: " + names +
             "); give its header name or its number (1 = first column after the time)";
    return false;
  }
  if (cam_col_ == -2)
    cam_col_ = -1;
  else if (!opt_.cam_column.empty() && (cam_col_ < 0 || cam_col_ >= columns_)) {
    error_ = where + "no cam column named '" + opt_.cam_column + "' (found: " + names +
             "); give its name or number, or set the cam channel name to empty if there is none";
    return false;
  }
  if (!has_header_) {
    first_row_text_.assign(line);
    first_row_pending_ = true;
  }
  return true;
}

/// End of file: the read error if any; else, once, a count of the bad lines beyond the reported ones and a
/// warning when the file held no data row at all.
SourceStatus EdgeCsvSource::finish() noexcept {
  const SourceStatus st = finish_lines(reader_, path_, stats_, error_);
  if (finished_ || st != SourceStatus::kEnd) return st;
  finished_ = true;
  try {
    if (stats_.bad_lines > kMaxMessages) {
      messages_.push_back(path_ + ": " + std::to_string(stats_.bad_lines - kMaxMessages) +
                          " more bad lines not listed (" + std::to_string(stats_.bad_lines) + " in all)");
    }
    if (data_rows_ == 0) {
      messages_.push_back(path_ + ":" + std::to_string(reader_.line_number()) + ": warning: no data rows" +
                          (has_header_ ? " after the header" : "") +
                          " (expected '<time s>,<level 0|1>,...')");
    }
  } catch (...) {  // out of memory while formatting: the counts are in stats()
  }
  return st;
}

std::string EdgeCsvSource::describe() const {
  return "edge-csv " + path_ + " (crank=" + opt_.crank_column +
         ", cam=" + (opt_.cam_column.empty() ? "-" : opt_.cam_column) + ")";
}

void EdgeCsvSource::bad_line(const char* what) noexcept {
  ++stats_.bad_lines;
  try {
    note(messages_, error_, path_, reader_.line_number(), what);
  } catch (...) {  // out of memory while formatting a message: the count is what matters
  }
}

/// General row parser (spaces, signs, any number of decimals, longer level fields): raw time (header units
/// x 1e9) and the crank/cam levels; reports and counts a bad line and returns false.
bool EdgeCsvSource::parse_row(std::string_view line, std::int64_t& t, int& crank, int& cam) noexcept {
  if (line.empty() || line.front() == ';' || line.front() == '#') return false;
  const char* p = line.data();
  const char* end = p + line.size();
  parse::skip_ws(p, end);
  if (!seconds_exp_to_ns(p, end, t)) {
    bad_line("expected a time in seconds in the first column (e.g. 0.0125 or 1.25e-2)");
    return false;
  }
  // Levels: only the configured columns are looked at.
  int col = 1;
  crank = cam = -1;
  bool bad = false;
  while (p < end) {
    parse::skip_ws(p, end);
    if (p == end || *p != ',') {
      bad = true;
      break;
    }
    ++p;
    parse::skip_ws(p, end);
    if (col == crank_col_ || col == cam_col_) {
      if (p == end || (*p != '0' && *p != '1')) {
        bad = true;
        break;
      }
      (col == crank_col_ ? crank : cam) = *p - '0';
      ++p;
    } else {
      while (p < end && *p != ',') ++p;
    }
    parse::skip_ws(p, end);
    ++col;
  }
  if (bad || crank < 0 || (cam_col_ >= 0 && cam < 0)) {
    bad_line(has_header_ ? "expected '<time>,<level 0|1>,...' with the header's columns"
                         : "expected '<time>,<level 0|1>,...' with as many columns as the first row");
    return false;
  }
  return true;
}

/// One edge into the time sanity check; records dropped for their time are counted and named.
void EdgeCsvSource::push_event(const EdgeEvent& e) noexcept {
  sanity_.push(e, e.t_ns, reader_.line_number());
  sanity_.drain_drops([&](const TimeDrop& d) { note_time_drop(d, path_, stats_, messages_, error_); });
}

SourceStatus EdgeCsvSource::next(EdgeEvent& out) noexcept {
  if (!ok_) return SourceStatus::kError;
  for (;;) {
    if (sanity_.pop(out)) {
      ++stats_.records;
      return SourceStatus::kOk;
    }
    if (eof_) return finish();
    std::int64_t t = 0;
    int crank = -1, cam = -1;
    // Fast path straight from the reader's buffer (no line search); anything else through next(line).
    const std::string_view buf = reader_.buffered();
    const std::size_t len = first_row_pending_ ? 0 : parse_row_fast(buf.data(), buf.size(), t, crank, cam);
    if (first_row_pending_) [[unlikely]] {  // headerless file: the row read while opening comes first
      first_row_pending_ = false;
      if (!parse_row(first_row_text_, t, crank, cam)) continue;
    } else if (len != 0 && len < buf.size() && buf[len] == '\n') {
      reader_.consume_line(len + 1);
    } else {
      std::string_view line;
      if (!reader_.next(line)) {
        eof_ = true;
        sanity_.finish();
        sanity_.drain_drops([&](const TimeDrop& d) { note_time_drop(d, path_, stats_, messages_, error_); });
        stats_.time_rebases = sanity_.rebases();
        continue;
      }
      const std::size_t n = parse_row_fast(line.data(), line.size(), t, crank, cam);
      if ((n == 0 || n != line.size()) && !parse_row(line, t, crank, cam)) continue;
    }
    stats_.bytes = reader_.bytes();
    stats_.lines = reader_.line_number();
    // Branch kept on purpose: `div == 1 ? t : t / div` was folded into an unconditional 64-bit idiv per row
    // (t / 1 == t), a quarter of this function's time.
    if (time_scale_div_ != 1) [[unlikely]]
      t /= time_scale_div_;
    t += opt_.time_offset_ns;
    ++data_rows_;
    if (initial_) {
      initial_ = false;
      if (opt_.first_row == EdgeCsvFirstRow::kInitialLevels) {  // levels at capture start, not edges
        level_[0] = static_cast<std::uint8_t>(crank);
        level_[1] = static_cast<std::uint8_t>(cam < 0 ? 0 : cam);
        continue;
      }
      level_ = {0, 0};  // kEdgesFromLow: compared with all-low below
    }
    // The levels follow every row, also one whose time is then dropped (a corrupt time costs that row's edge
    // only: the next row's edge is still seen). Crank first when both channels change.
    const bool crank_edge = crank != level_[0];
    const bool cam_edge = cam >= 0 && cam != level_[1];
    if (crank_edge) level_[0] = static_cast<std::uint8_t>(crank);
    if (cam_edge) level_[1] = static_cast<std::uint8_t>(cam);
    if (crank_edge) push_event(EdgeEvent{t, opt_.crank_channel, level_[0]});
    if (cam_edge) push_event(EdgeEvent{t, opt_.cam_channel, level_[1]});
  }
}

EdgeListSource::EdgeListSource(std::string path, EdgeListOptions options)
    : path_(std::move(path)), opt_(options), sanity_(opt_.time) {
  messages_.reserve(kMaxMessages);
  ok_ = reader_.open(path_);
  if (!ok_) error_ = reader_.error();
}

std::string EdgeListSource::describe() const { return "edge-list " + path_; }

SourceStatus EdgeListSource::next(EdgeEvent& out) noexcept {
  if (!ok_) return SourceStatus::kError;
  auto note_drop = [&](const TimeDrop& d) { note_time_drop(d, path_, stats_, messages_, error_); };
  std::string_view line;
  for (;;) {
    const LineStep step = next_line_or_record(sanity_, reader_, eof_, stats_, out, line, note_drop);
    if (step == LineStep::kRecord) return SourceStatus::kOk;
    if (step == LineStep::kEnd) return finish_lines(reader_, path_, stats_, error_);
    stats_.bytes = reader_.bytes();
    stats_.lines = reader_.line_number();
    const char* p = line.data();
    const char* end = p + line.size();
    parse::skip_ws(p, end);
    if (p == end || *p == '#' || *p == ';') continue;
    std::int64_t t = 0;
    const bool ok = parse::seconds_to_ns(p, end, t);
    parse::skip_ws(p, end);
    if (!ok || (p != end && *p != ',')) {
      // A header line ("time") at the top is allowed.
      if (reader_.line_number() == 1 && !ok) continue;
      ++stats_.bad_lines;
      try {
        note(messages_, error_, path_, reader_.line_number(), "expected one edge time in seconds per line");
      } catch (...) {
      }
      continue;
    }
    t += opt_.time_offset_ns;
    sanity_.push(EdgeEvent{t, opt_.channel, opt_.level}, t, reader_.line_number());
    sanity_.drain_drops(note_drop);
  }
}

}  // namespace torqued
