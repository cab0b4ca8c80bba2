// DBC parser (load time: multi-line quoted statements, NS_ list skipped) and bit extraction (real-time safe).
#include "dbc.hpp"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace torqued {

// ---------------------------------------------------------------------------------------------- decoding

std::size_t DbcSignal::bytes_needed() const noexcept {
  if (length == 0) return 0;
  if (little_endian) return static_cast<std::size_t>((start_bit + length - 1) / 8 + 1);
  // Motorola (the sawtooth from the MSB, start_bit, to the LSB, whose byte is the furthest): the MSB's byte
  // holds start_bit % 8 + 1 bits, each further one 8 (test Dbc.MotorolaBytesNeededMatchesTheSawtoothWalk).
  const int rest = static_cast<int>(length) - (start_bit % 8 + 1);
  return static_cast<std::size_t>(start_bit / 8 + (rest > 0 ? (rest + 7) / 8 : 0) + 1);
}

namespace {
std::int64_t sign_extend(std::uint64_t v, int length, bool is_signed) noexcept {
  if (is_signed && length > 0 && length < 64 && ((v >> (length - 1)) & 1u) != 0)
    v |= ~std::uint64_t{0} << length;
  return static_cast<std::int64_t>(v);
}
}  // namespace

// Word-at-a-time: gather the (at most 8) bytes the signal spans into one integer, shift and mask. Bytes past
// `len` read as 0, as in the bitwise definition. Signals spanning 9 bytes (e.g. 64 bits not byte-aligned)
// take the bitwise path.
std::uint64_t DbcSignal::raw_bits(const std::uint8_t* data, std::size_t len) const noexcept {
  const int n = static_cast<int>(length);
  const auto bitwise = [&] {
    const std::uint64_t v = static_cast<std::uint64_t>(raw_bitwise(data, len));
    return n > 0 && n < 64 ? v & ((std::uint64_t{1} << n) - 1u) : v;
  };
  if (n <= 0 || n > 64) return bitwise();
  const int first = start_bit / 8, shift_in_byte = start_bit % 8;
  std::uint64_t v = 0;
  if (little_endian) {  // Intel: LSB at start_bit, bytes in increasing order
    const int bytes = (shift_in_byte + n + 7) / 8;
    if (bytes > 8) return bitwise();
    for (int b = bytes - 1; b >= 0; --b) {
      const auto i = static_cast<std::size_t>(first + b);
      v = (v << 8) | (i < len ? data[i] : 0u);
    }
    v >>= shift_in_byte;
  } else {  // Motorola: MSB at start_bit (sawtooth numbering), bytes in increasing order from the MSB's byte
    const int bytes = (7 - shift_in_byte + n + 7) / 8;
    if (bytes > 8) return bitwise();
    for (int b = 0; b < bytes; ++b) {
      const auto i = static_cast<std::size_t>(first + b);
      v = (v << 8) | (i < len ? data[i] : 0u);
    }
    v >>= 8 * (bytes - 1) + shift_in_byte - n + 1;  // the MSB sits at bit 8·(bytes−1) + shift_in_byte
  }
  if (n < 64) v &= (std::uint64_t{1} << n) - 1u;
  return v;
}

std::int64_t DbcSignal::raw(const std::uint8_t* data, std::size_t len) const noexcept {
  return sign_extend(raw_bits(data, len), length, is_signed);
}

double DbcSignal::raw_value(const std::uint8_t* data, std::size_t len) const noexcept {
  switch (value_type) {
    case ValueType::kFloat32:
      return static_cast<double>(std::bit_cast<float>(static_cast<std::uint32_t>(raw_bits(data, len))));
    case ValueType::kFloat64:
      return std::bit_cast<double>(raw_bits(data, len));
    case ValueType::kInteger:
      break;
  }
  return is_signed ? static_cast<double>(raw(data, len)) : static_cast<double>(raw_bits(data, len));
}

std::int64_t DbcSignal::raw_bitwise(const std::uint8_t* data, std::size_t len) const noexcept {
  std::uint64_t v = 0;
  if (little_endian) {
    for (int k = length - 1; k >= 0; --k) {
      const int pos = start_bit + k;
      const auto byte = static_cast<std::size_t>(pos / 8);
      const unsigned bit = byte < len ? (data[byte] >> (pos % 8)) & 1u : 0u;
      v = (v << 1) | bit;
    }
  } else {
    int pos = start_bit;
    for (int k = 0; k < length; ++k) {  // MSB first
      const auto byte = static_cast<std::size_t>(pos / 8);
      const unsigned bit = byte < len ? (data[byte] >> (pos % 8)) & 1u : 0u;
      v = (v << 1) | bit;
      pos = (pos % 8 == 0) ? pos + 15 : pos - 1;
    }
  }
  return sign_extend(v, length, is_signed);
}

const std::string* DbcSignal::value_name(std::int64_t raw_value) const noexcept {
  for (const auto& [v, text] : value_table) {
    if (v == raw_value) return &text;
  }
  return nullptr;
}

const DbcSignal* DbcMessage::find(std::string_view signal_name) const noexcept {
  for (const auto& s : signals) {
    if (s.name == signal_name) return &s;
  }
  return nullptr;
}

bool DbcMessage::signal_present(const DbcSignal& s, const std::uint8_t* data,
                                std::size_t len) const noexcept {
  const DbcSignal* cur = &s;
  // Up the chain of multiplexors (extended multiplexing); bounded, so a cyclic chain reads as absent.
  for (std::size_t depth = 0; depth <= signals.size(); ++depth) {
    if (cur->mux != DbcSignal::Mux::kMultiplexed) return true;
    const int parent = cur->mux_parent >= 0 ? cur->mux_parent : multiplexor;
    if (parent < 0 || static_cast<std::size_t>(parent) >= signals.size()) return true;
    const DbcSignal& m = signals[static_cast<std::size_t>(parent)];
    if (len < m.bytes_needed()) return false;
    if (cur->mux_ranges.empty()) {
      if (m.raw(data, len) != static_cast<std::int64_t>(cur->mux_value)) return false;
    } else {
      const std::uint64_t v = m.raw_bits(data, len);
      bool in = false;
      for (const auto& [lo, hi] : cur->mux_ranges) in = in || (v >= lo && v <= hi);
      if (!in) return false;
    }
    cur = &m;
  }
  return false;
}

const DbcMessage* DbcDatabase::find(std::uint32_t id, bool extended) const noexcept {
  for (const auto& m : messages_) {
    if (m.id == id && m.extended == extended) return &m;
  }
  return nullptr;
}

const DbcMessage* DbcDatabase::find(std::string_view message_name) const noexcept {
  for (const auto& m : messages_) {
    if (m.name == message_name) return &m;
  }
  return nullptr;
}

// ---------------------------------------------------------------------------------------------- parsing

namespace {

enum class Tok : std::uint8_t { kEnd, kIdent, kNumber, kString, kPunct };

struct Token {
  Tok kind = Tok::kEnd;
  std::string_view text;  ///< identifier / number text, string contents without quotes, punctuation char
};

/// Tokenizer over one statement.
class Lexer {
 public:
  explicit Lexer(std::string_view s) : s_(s) {}
  Token next() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
    if (pos_ >= s_.size()) return {};
    const char c = s_[pos_];
    const std::size_t start = pos_;
    if (c == '"') {
      ++pos_;
      while (pos_ < s_.size() && s_[pos_] != '"') {
        if (s_[pos_] == '\\' && pos_ + 1 < s_.size()) ++pos_;
        ++pos_;
      }
      const std::string_view text = s_.substr(start + 1, pos_ - start - 1);
      if (pos_ < s_.size())
        ++pos_;
      else
        unterminated_ = true;
      return {Tok::kString, text};
    }
    const bool sign_num = (c == '-' || c == '+') && pos_ + 1 < s_.size() &&
                          (std::isdigit(static_cast<unsigned char>(s_[pos_ + 1])) || s_[pos_ + 1] == '.');
    if (std::isdigit(static_cast<unsigned char>(c)) || sign_num ||
        (c == '.' && pos_ + 1 < s_.size() && std::isdigit(static_cast<unsigned char>(s_[pos_ + 1])))) {
      ++pos_;
      while (pos_ < s_.size()) {
        const char d = s_[pos_];
        if (std::isdigit(static_cast<unsigned char>(d)) || d == '.' || d == 'x' || d == 'X' ||
            ((d == 'e' || d == 'E')) ||
            ((d == '-' || d == '+') && (s_[pos_ - 1] == 'e' || s_[pos_ - 1] == 'E')) ||
            std::isxdigit(static_cast<unsigned char>(d))) {
          ++pos_;
        } else {
          break;
        }
      }
      return {Tok::kNumber, s_.substr(start, pos_ - start)};
    }
    if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
      while (pos_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[pos_])) || s_[pos_] == '_'))
        ++pos_;
      return {Tok::kIdent, s_.substr(start, pos_ - start)};
    }
    ++pos_;
    return {Tok::kPunct, s_.substr(start, 1)};
  }
  [[nodiscard]] bool unterminated() const noexcept { return unterminated_; }

 private:
  std::string_view s_;
  std::size_t pos_ = 0;
  bool unterminated_ = false;
};

bool to_double(std::string_view t, double& v) {
  std::string s(t);
  char* end = nullptr;
  errno = 0;
  v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && errno == 0;
}

bool to_int64(std::string_view t, std::int64_t& v) {
  int base = 10;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X')) {
    t.remove_prefix(2);
    base = 16;
  }
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v, base);
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

bool to_uint32(std::string_view t, std::uint32_t& v) {
  std::int64_t x = 0;
  if (!to_int64(t, x) || x < 0 || x > 0xFFFFFFFFll) return false;
  v = static_cast<std::uint32_t>(x);
  return true;
}

bool starts_with_kw(std::string_view line, std::string_view kw) {
  if (line.substr(0, kw.size()) != kw) return false;
  return line.size() == kw.size() ||
         !(std::isalnum(static_cast<unsigned char>(line[kw.size()])) || line[kw.size()] == '_');
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

/// Statement complete: quotes balanced and, for statements that need it, ends with ';'.
bool complete(std::string_view stmt) {
  bool in_str = false;
  for (std::size_t i = 0; i < stmt.size(); ++i) {
    if (stmt[i] == '\\' && in_str) {
      ++i;
      continue;
    }
    if (stmt[i] == '"') in_str = !in_str;
  }
  if (in_str) return false;
  return trim(stmt).ends_with(";");
}

constexpr std::string_view kIgnored[] = {
    "BA_DEF_",         "BA_DEF_DEF_",  "BA_",        "BA_DEF_REL_",      "BA_REL_",
    "BA_DEF_DEF_REL_", "BA_SGTYPE_",   "VAL_TABLE_", "SIG_GROUP_",       "EV_",
    "EV_DATA_",        "ENVVAR_DATA_", "SGTYPE_",    "SGTYPE_VAL_",      "BO_TX_BU_",
    "SIG_TYPE_REF_",   "CAT_DEF_",     "CAT_",       "FILTER",           "BU_SG_REL_",
    "BU_EV_REL_",      "BU_BO_REL_",   "NS_DESC_",   "SIGTYPE_VALTYPE_", "BA_DEF_SGTYPE_"};

/// Keywords that start a statement: in a multi-line statement whose ';' is missing, a line starting with one
/// (outside a string) begins the next statement.
constexpr std::string_view kStatementStarts[] = {
    "VERSION",     "NS_",          "BS_",         "BU_",         "BO_",
    "SG_",         "CM_",          "VAL_",        "VAL_TABLE_",  "BA_DEF_",
    "BA_DEF_DEF_", "BA_",          "EV_",         "BO_TX_BU_",   "BA_REL_",
    "SIG_GROUP_",  "SIG_VALTYPE_", "SG_MUL_VAL_", "BA_DEF_REL_", "BA_DEF_DEF_REL_"};

bool starts_statement(std::string_view line) {
  return std::any_of(std::begin(kStatementStarts), std::end(kStatementStarts),
                     [&](std::string_view kw) { return starts_with_kw(line, kw); });
}

/// Whether the text ends inside a "..." string.
bool in_string(std::string_view stmt) {
  bool in_str = false;
  for (std::size_t i = 0; i < stmt.size(); ++i) {
    if (stmt[i] == '\\' && in_str) {
      ++i;
      continue;
    }
    if (stmt[i] == '"') in_str = !in_str;
  }
  return in_str;
}

/// The k-th whitespace-separated word of a statement (0 = the keyword), without a trailing ':' or ';'.
std::string word(std::string_view stmt, int k) {
  std::size_t pos = 0;
  for (int i = 0;; ++i) {
    while (pos < stmt.size() && std::isspace(static_cast<unsigned char>(stmt[pos]))) ++pos;
    std::size_t end = pos;
    while (end < stmt.size() && !std::isspace(static_cast<unsigned char>(stmt[end])) && stmt[end] != ':')
      ++end;
    if (i == k) return std::string(stmt.substr(pos, end - pos));
    if (end == pos) return {};
    pos = end;
    if (pos < stmt.size() && stmt[pos] == ':') ++pos;
  }
}

bool to_uint64(std::string_view t, std::uint64_t& v) {
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v, 10);
  return r.ec == std::errc() && r.ptr == t.data() + t.size();
}

struct LineCursor {
  std::string_view text;
  std::size_t pos = 0, line_no = 0;

  [[nodiscard]] bool at_end() const noexcept { return pos >= text.size(); }
  [[nodiscard]] std::string_view peek() const noexcept {
    std::size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    return text.substr(pos, nl - pos);
  }
  bool next(std::string_view& line) noexcept {
    if (at_end()) return false;
    line = peek();
    pos += line.size() + 1;
    ++line_no;
    return true;
  }
};

/// SG_MUL_VAL_ <id> <signal> <multiplexor> <lo>-<hi>[, <lo>-<hi>]... ; applied once every message is read.
struct MulVal {
  std::size_t line = 0;
  std::uint32_t raw_id = 0;
  std::string signal, multiplexor;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> ranges;
};

std::string hex(std::uint32_t v) {
  char buf[16];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, 16);
  return "0x" + std::string(buf, r.ptr);
}

}  // namespace

class DbcParser {
 public:
  DbcParser(std::string_view name, DbcParseResult& result) : name_(name), r_(result) {}

  void parse(std::string_view text) {
    LineCursor cur{text};
    bool in_ns = false;
    for (std::string_view raw_line; cur.next(raw_line);) {
      const bool indented = !raw_line.empty() && (raw_line.front() == ' ' || raw_line.front() == '\t');
      const std::string_view line = trim(raw_line);
      if (line.empty() || line.starts_with("//")) continue;
      if (in_ns) {
        // NS_ block: indented keyword names, one per line.
        if (indented && line.find(' ') == std::string_view::npos && line.find('"') == std::string_view::npos)
          continue;
        in_ns = false;
      }
      if (starts_with_kw(line, "NS_")) {
        in_ns = true;
        continue;
      }
      const std::size_t stmt_line = cur.line_no;
      std::string stmt(line);
      // CM_ / VAL_ / BA_... may span several lines (multi-line comment strings).
      if (starts_with_kw(line, "CM_") || starts_with_kw(line, "VAL_") || starts_with_kw(line, "BA_") ||
          starts_with_kw(line, "BA_DEF_") || starts_with_kw(line, "VAL_TABLE_")) {
        if (!join_lines(cur, stmt, stmt_line)) continue;
      }
      statement(stmt, stmt_line);
    }
    finish();
  }

 private:
  /// Appends continuation lines until the statement is complete. A missing ';' ends the statement at the next
  /// statement keyword (warning); an unclosed string is an error and parsing resumes on the following line.
  bool join_lines(LineCursor& cur, std::string& stmt, std::size_t stmt_line) {
    const LineCursor start = cur;
    while (!complete(stmt)) {
      if (!in_string(stmt) && (cur.at_end() || starts_statement(trim(cur.peek())))) break;
      std::string_view more;
      if (!cur.next(more)) break;
      stmt += '\n';
      stmt += more;
    }
    if (complete(stmt)) return true;
    if (!in_string(stmt)) {
      warning(stmt_line, "expected ';' at the end of the statement (taken as ending before the next one)");
      return true;
    }
    error(stmt_line, "statement not terminated (expected a closing '\"' and ';'); skipped");
    cur = start;
    return false;
  }

  void error(std::size_t line, const std::string& what) {
    r_.errors.push_back(std::string(name_) + ":" + std::to_string(line) + ": " + what);
  }
  void warning(std::size_t line, const std::string& what) {
    r_.warnings.push_back(std::string(name_) + ":" + std::to_string(line) + ": " + what);
  }
  /// An error that takes out a message (signal empty) or one of its signals.
  void skip(std::size_t line, const std::string& what, std::string message, std::string signal = {}) {
    error(line, what);
    r_.skipped.push_back({r_.errors.size() - 1, std::move(message), std::move(signal)});
  }

  void statement(const std::string& stmt, std::size_t line) {
    Lexer lx(stmt);
    const Token kw = lx.next();
    if (kw.kind != Tok::kIdent) {
      error(line, "expected a DBC keyword, found '" + std::string(kw.text) + "'");
      return;
    }
    if (kw.text != "SG_") skip_signals_ = false;  // a bad BO_'s signals are skipped silently, up to here
    if (kw.text == "VERSION") {
      const Token v = lx.next();
      if (v.kind != Tok::kString)
        error(line, "expected VERSION \"<text>\"");
      else
        db_.version_ = std::string(v.text);
    } else if (kw.text == "BS_") {
      // Bus timing, obsolete: ignored.
    } else if (kw.text == "BU_") {
      const Token c = lx.next();
      if (!(c.kind == Tok::kPunct && c.text == ":")) {
        error(line, "expected 'BU_: <node> ...'");
        return;
      }
      for (Token t = lx.next(); t.kind == Tok::kIdent; t = lx.next()) db_.nodes_.emplace_back(t.text);
    } else if (kw.text == "BO_") {
      message(lx, stmt, line);
    } else if (kw.text == "SG_") {
      signal(lx, stmt, line);
    } else if (kw.text == "CM_") {
      comment(lx, line);
    } else if (kw.text == "VAL_") {
      values(lx, line);
    } else if (kw.text == "SIG_VALTYPE_") {
      value_type(lx, line);
    } else if (kw.text == "SG_MUL_VAL_") {
      mul_val(stmt, line);
    } else if (std::find(std::begin(kIgnored), std::end(kIgnored), kw.text) != std::end(kIgnored)) {
      // Attributes, value tables, signal groups, environment variables: not needed for decoding.
    } else {
      warning(line, "unknown keyword '" + std::string(kw.text) + "' ignored");
    }
  }

  static std::string bad_name(const Token& t, const std::string& raw, const char* what) {
    if (t.kind == Tok::kNumber)
      return std::string(what) + " name '" + raw + "' starts with a digit (expected a letter or '_')";
    return {};
  }

  void message(Lexer& lx, const std::string& stmt, std::size_t line) {
    // BO_ <id> <name>: <dlc> <transmitter>
    current_ = -1;
    skip_signals_ = true;  // until the message is accepted
    const std::string raw_name = word(stmt, 2);
    const Token id = lx.next(), name = lx.next(), colon = lx.next(), dlc = lx.next(), tx = lx.next();
    std::uint32_t raw_id = 0;
    std::int64_t len = 0;
    if (id.kind != Tok::kNumber || !to_uint32(id.text, raw_id) || name.kind != Tok::kIdent ||
        !(colon.kind == Tok::kPunct && colon.text == ":") || dlc.kind != Tok::kNumber ||
        !to_int64(dlc.text, len)) {
      const std::string why = bad_name(name, raw_name, "message");
      note_skipped_id(id);
      return skip(
          line, (why.empty() ? "" : why + "; ") + "expected 'BO_ <id> <name>: <dlc> <transmitter>'; skipped",
          raw_name);
    }
    if (raw_id == 0xC0000000u) return;  // VECTOR__INDEPENDENT_SIG_MSG pseudo-message (id 3221225472)
    const std::string what =
        "message " + std::string(name.text) + " (id " + std::string(id.text) + " = " + hex(raw_id) + "): ";
    skipped_ids_.push_back(raw_id);  // until accepted
    if (len < 0 || len > 64)
      return skip(line, what + "DLC " + std::to_string(len) + " outside 0..64 bytes; skipped", raw_name);
    if ((raw_id & 0x60000000u) != 0)
      return skip(line, what + "bit 29 or 30 set (expected a 29-bit id, plus bit 31 for extended); skipped",
                  raw_name);
    DbcMessage m;
    m.extended = (raw_id & 0x80000000u) != 0;
    m.id = raw_id & 0x1FFFFFFFu;
    m.name = std::string(name.text);
    m.dlc = static_cast<std::uint8_t>(len);
    if (tx.kind == Tok::kIdent) m.transmitter = std::string(tx.text);
    if (!m.extended && m.id > 0x7FF) {
      warning(line, what + "above 0x7FF without the extended flag (bit 31): taken as a 29-bit extended id");
      m.extended = true;
    }
    if (db_.find(m.id, m.extended) != nullptr) return skip(line, what + "duplicate id; skipped", raw_name);
    if (db_.find(m.name) != nullptr) return skip(line, what + "duplicate message name; skipped", raw_name);
    skipped_ids_.pop_back();
    skip_signals_ = false;
    db_.messages_.push_back(std::move(m));
    message_lines_.push_back(line);
    current_ = static_cast<int>(db_.messages_.size()) - 1;
  }

  void note_skipped_id(const Token& id) {
    std::uint32_t raw_id = 0;
    if (id.kind == Tok::kNumber && to_uint32(id.text, raw_id)) skipped_ids_.push_back(raw_id);
  }

  /// SG_ multiplexing indicator: M, m (taken as M, with a warning), m<n>, m<n>M. Returns an error text.
  std::string mux_indicator(std::string_view mi, DbcSignal& s, std::size_t line) {
    if (mi == "M") {
      s.mux = DbcSignal::Mux::kMultiplexor;
    } else if (mi == "m") {
      warning(line,
              "signal " + s.name + ": multiplex indicator 'm' without a value taken as the multiplexor 'M'");
      s.mux = DbcSignal::Mux::kMultiplexor;
    } else if (mi.size() >= 2 && mi[0] == 'm') {
      std::string_view digits = mi.substr(1);
      s.also_multiplexor = digits.ends_with("M");
      if (s.also_multiplexor) digits.remove_suffix(1);
      std::int64_t v = 0;
      if (!to_int64(digits, v) || v < 0 || v > 0xFFFFFFFFll)
        return "bad multiplex indicator '" + std::string(mi) + "' (expected M, m<n> or m<n>M)";
      s.mux = DbcSignal::Mux::kMultiplexed;
      s.mux_value = static_cast<std::uint32_t>(v);
    } else {
      return "bad multiplex indicator '" + std::string(mi) + "' (expected M, m<n> or m<n>M)";
    }
    return {};
  }

  /// ": <start>|<length>@<0|1><+|->" into s. Returns an error text.
  static std::string layout(Lexer& lx, DbcSignal& s) {
    static const std::string kExpected =
        "expected 'SG_ <name> [M|m<n>|m<n>M] : <start>|<length>@<0|1><+|-> (<factor>,<offset>) "
        "[<min>|<max>] \"<unit>\" <receivers>'";
    std::int64_t start = 0, length = 0, order = 0;
    const Token a = lx.next(), bar = lx.next(), b = lx.next(), at = lx.next(), o = lx.next();
    if (a.kind != Tok::kNumber || !to_int64(a.text, start) || bar.text != "|" || b.kind != Tok::kNumber ||
        !to_int64(b.text, length) || at.text != "@") {
      return kExpected;
    }
    // "@1+" lexes as '@' '1' '+'; "@1-" likewise (a '-' lexes as a number only when a digit follows).
    Token sign;
    if (o.kind == Tok::kNumber && (o.text == "0" || o.text == "1")) {
      order = o.text == "1" ? 1 : 0;
      sign = lx.next();
    } else if (o.kind == Tok::kNumber &&
               (o.text == "0+" || o.text == "1+" || o.text == "0-" || o.text == "1-")) {
      order = o.text[0] == '1' ? 1 : 0;
      sign = Token{Tok::kPunct, o.text.substr(1)};
    } else {
      return kExpected;
    }
    if (!(sign.kind == Tok::kPunct && (sign.text == "+" || sign.text == "-"))) return kExpected;
    if (length < 1 || length > 64) return "length " + std::to_string(length) + " outside 1..64 bits";
    if (start < 0 || start >= 512) return "start bit " + std::to_string(start) + " outside 0..511";
    s.start_bit = static_cast<std::uint16_t>(start);
    s.length = static_cast<std::uint16_t>(length);
    s.little_endian = order == 1;
    s.is_signed = sign.text == "-";
    return {};
  }

  /// "(<factor>,<offset>) [<min>|<max>] "<unit>" <receivers>" into s. Returns an error text.
  static std::string scaling(Lexer& lx, DbcSignal& s) {
    const Token lp = lx.next(), f = lx.next(), comma = lx.next(), off = lx.next(), rp = lx.next();
    if (lp.text != "(" || f.kind != Tok::kNumber || !to_double(f.text, s.factor) || comma.text != "," ||
        off.kind != Tok::kNumber || !to_double(off.text, s.offset) || rp.text != ")") {
      return "expected '(<factor>,<offset>)'";
    }
    const Token lb = lx.next(), mn = lx.next(), bar2 = lx.next(), mx = lx.next(), rb = lx.next();
    if (lb.text != "[" || mn.kind != Tok::kNumber || !to_double(mn.text, s.min) || bar2.text != "|" ||
        mx.kind != Tok::kNumber || !to_double(mx.text, s.max) || rb.text != "]") {
      return "expected '[<min>|<max>]'";
    }
    const Token unit = lx.next();
    if (unit.kind != Tok::kString) return "expected \"<unit>\"";
    s.unit = std::string(unit.text);
    for (Token r = lx.next(); r.kind == Tok::kIdent || (r.kind == Tok::kPunct && r.text == ",");
         r = lx.next()) {
      if (r.kind == Tok::kIdent) s.receivers.emplace_back(r.text);
    }
    return {};
  }

  void signal(Lexer& lx, const std::string& stmt, std::size_t line) {
    if (skip_signals_) return;  // its BO_ line was reported (or is the independent-signals pseudo message)
    if (current_ < 0) return error(line, "SG_ before any BO_ message; skipped");
    DbcMessage& m = db_.messages_[static_cast<std::size_t>(current_)];
    DbcSignal s;
    s.name = word(stmt, 1);
    const auto fail = [&](const std::string& why) {
      skip(line, "signal " + m.name + "." + s.name + ": " + why + "; skipped", m.name, s.name);
    };
    Token t = lx.next();
    if (t.kind != Tok::kIdent) {
      const std::string why = bad_name(t, s.name, "signal");
      return fail(why.empty() ? "expected 'SG_ <name> ...'" : why);
    }
    t = lx.next();
    if (t.kind == Tok::kIdent) {
      if (std::string why = mux_indicator(t.text, s, line); !why.empty()) return fail(why);
      t = lx.next();
    }
    if (!(t.kind == Tok::kPunct && t.text == ":")) return fail("expected ':' after the name");
    if (std::string why = layout(lx, s); !why.empty()) return fail(why);
    if (std::string why = scaling(lx, s); !why.empty()) return fail(why);
    if (s.factor == 0.0) warning(line, "signal " + s.name + ": factor 0");
    const std::size_t need = s.bytes_needed();
    if (need > 64) return fail("does not fit in 64 bytes");
    if (need > m.dlc) {
      warning(line, "signal " + s.name + ": needs " + std::to_string(need) + " bytes, message " + m.name +
                        " has DLC " + std::to_string(m.dlc));
    }
    if (m.find(s.name) != nullptr) return fail("duplicate signal name");
    if (s.mux == DbcSignal::Mux::kMultiplexor) {
      if (m.multiplexor >= 0) return fail("second multiplexor 'M' in the message");
      m.multiplexor = static_cast<int>(m.signals.size());
    }
    m.signals.push_back(std::move(s));
  }

  DbcMessage* by_raw_id(std::uint32_t raw_id) {
    if ((raw_id & 0x60000000u) != 0) return nullptr;
    const std::uint32_t id = raw_id & 0x1FFFFFFFu;
    return const_cast<DbcMessage*>(db_.find(id, (raw_id & 0x80000000u) != 0 || id > 0x7FF));
  }

  /// The message and signal a CM_/VAL_/SIG_VALTYPE_/SG_MUL_VAL_ names; references into skipped messages are
  /// silent (their BO_ line was reported).
  std::pair<DbcMessage*, DbcSignal*> find_signal(std::string_view id_text, std::string_view sig,
                                                 std::size_t line) {
    std::uint32_t raw_id = 0;
    if (!to_uint32(id_text, raw_id)) {
      error(line, "expected a message id, found '" + std::string(id_text) + "'");
      return {nullptr, nullptr};
    }
    DbcMessage* m = by_raw_id(raw_id);
    if (m == nullptr) {
      const bool known = raw_id == 0xC0000000u ||
                         std::find(skipped_ids_.begin(), skipped_ids_.end(), raw_id) != skipped_ids_.end();
      if (!known) warning(line, "reference to unknown message id " + std::to_string(raw_id));
      return {nullptr, nullptr};
    }
    for (auto& s : m->signals) {
      if (s.name == sig) return {m, &s};
    }
    if (r_.affecting(m->name, sig) == nullptr)
      warning(line, "reference to unknown signal " + m->name + "." + std::string(sig));
    return {m, nullptr};
  }

  void comment(Lexer& lx, std::size_t line) {
    const Token t = lx.next();
    if (t.kind == Tok::kString) return;  // database comment
    if (t.kind != Tok::kIdent)
      return error(line, "expected 'CM_ [BU_|BO_|SG_|EV_] ... \"<text>\";'; skipped");
    if (t.text == "BO_") {
      const Token id = lx.next(), text = lx.next();
      std::uint32_t raw_id = 0;
      if (id.kind != Tok::kNumber || !to_uint32(id.text, raw_id) || text.kind != Tok::kString) {
        return error(line, "expected 'CM_ BO_ <id> \"<text>\";'; skipped");
      }
      if (DbcMessage* m = by_raw_id(raw_id)) m->comment = std::string(text.text);
    } else if (t.text == "SG_") {
      const Token id = lx.next(), sig = lx.next(), text = lx.next();
      if (id.kind != Tok::kNumber || sig.kind != Tok::kIdent || text.kind != Tok::kString) {
        return error(line, "expected 'CM_ SG_ <id> <signal> \"<text>\";'; skipped");
      }
      if (DbcSignal* s = find_signal(id.text, sig.text, line).second) s->comment = std::string(text.text);
    } else if (t.text == "BU_" || t.text == "EV_") {
      // node / environment variable comments: not needed
    } else {
      error(line, "expected 'CM_ [BU_|BO_|SG_|EV_] ... \"<text>\";'; skipped");
    }
  }

  /// A VAL_ value: integer (unsigned 64-bit values keep their bit pattern) or an integral float.
  bool table_value(std::string_view text, std::int64_t& x, std::size_t line) {
    std::uint64_t u = 0;
    if (to_int64(text, x)) return true;
    if (to_uint64(text, u)) {
      x = static_cast<std::int64_t>(u);
      return true;
    }
    double d = 0;
    if (!to_double(text, d)) {
      error(line, "VAL_: bad value '" + std::string(text) + "' (expected an integer); skipped");
      return false;
    }
    // Raw values are integers of at most 64 bits: anything outside [-2^63, 2^64) cannot be a raw value (and
    // casting it is undefined behaviour).
    if (!(d >= -9223372036854775808.0 && d < 18446744073709551616.0)) {
      error(line, "VAL_: value " + std::string(text) + " is outside the 64-bit raw range; skipped");
      return false;
    }
    x = d < 9223372036854775808.0 ? static_cast<std::int64_t>(d)
                                  : static_cast<std::int64_t>(static_cast<std::uint64_t>(d));
    return true;
  }

  void values(Lexer& lx, std::size_t line) {
    const Token id = lx.next();
    const Token sig = lx.next();
    if (id.kind != Tok::kNumber || sig.kind != Tok::kIdent) {
      if (id.kind == Tok::kIdent) return;  // VAL_ for an environment variable
      return error(line, "expected 'VAL_ <id> <signal> <value> \"<text>\" ... ;'; skipped");
    }
    DbcSignal* s = find_signal(id.text, sig.text, line).second;
    std::vector<std::pair<std::int64_t, std::string>> table;
    for (Token v = lx.next(); v.kind == Tok::kNumber; v = lx.next()) {
      const Token text = lx.next();
      std::int64_t x = 0;
      if (!table_value(v.text, x, line)) return;
      if (text.kind != Tok::kString)
        return error(line, "VAL_: expected \"<text>\" after value " + std::string(v.text) + "; skipped");
      table.emplace_back(x, std::string(text.text));
    }
    if (s != nullptr) s->value_table = std::move(table);
  }

  /// SIG_VALTYPE_ <id> <signal> : <0|1|2> ;  (1 = IEEE float32, 2 = IEEE float64)
  void value_type(Lexer& lx, std::size_t line) {
    const Token id = lx.next(), sig = lx.next(), colon = lx.next(), type = lx.next();
    std::int64_t t = -1;
    if (id.kind != Tok::kNumber || sig.kind != Tok::kIdent ||
        !(colon.kind == Tok::kPunct && colon.text == ":") || type.kind != Tok::kNumber ||
        !to_int64(type.text, t) || t < 0 || t > 2) {
      return error(line, "expected 'SIG_VALTYPE_ <id> <signal> : <0|1|2>;'; skipped");
    }
    const auto [m, s] = find_signal(id.text, sig.text, line);
    if (s == nullptr) return;
    const int bits = t == 1 ? 32 : 64;
    if (t != 0 && s->length != bits) {
      skip(line,
           "signal " + m->name + "." + s->name + ": SIG_VALTYPE_ " + std::to_string(t) + " needs length " +
               std::to_string(bits) + ", the signal has " + std::to_string(s->length) + "; signal skipped",
           m->name, s->name);
      drop_.emplace_back(m->name, s->name);
      return;
    }
    s->value_type = static_cast<DbcSignal::ValueType>(t);
  }

  /// SG_MUL_VAL_ <id> <signal> <multiplexor> <lo>-<hi>[, <lo>-<hi>]... ;  (read by words: "1-1" is no token)
  void mul_val(std::string_view stmt, std::size_t line) {
    static const char* kExpected =
        "expected 'SG_MUL_VAL_ <id> <signal> <multiplexor> <lo>-<hi>, ...;'; skipped";
    MulVal mv;
    mv.line = line;
    mv.signal = word(stmt, 2);
    mv.multiplexor = word(stmt, 3);
    std::string_view rest = stmt;
    std::size_t at = 0;
    for (int k = 0; k < 4 && at != std::string_view::npos; ++k) {
      at = rest.find_first_not_of(" \t\r\n", at);
      at = at == std::string_view::npos ? at : rest.find_first_of(" \t\r\n", at);
    }
    if (!to_uint32(word(stmt, 1), mv.raw_id) || mv.multiplexor.empty() || at == std::string_view::npos)
      return error(line, kExpected);
    rest = trim(rest.substr(at));
    if (rest.ends_with(";")) rest.remove_suffix(1);
    while (!trim(rest).empty()) {
      const std::size_t comma = rest.find(',');
      const std::string_view range = trim(rest.substr(0, comma));
      rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
      const std::size_t dash = range.find('-');
      std::uint64_t lo = 0, hi = 0;
      if (dash == std::string_view::npos || !to_uint64(trim(range.substr(0, dash)), lo) ||
          !to_uint64(trim(range.substr(dash + 1)), hi) || hi < lo)
        return error(line, kExpected);
      mv.ranges.emplace_back(lo, hi);
    }
    if (mv.ranges.empty()) return error(line, kExpected);
    mul_vals_.push_back(std::move(mv));
  }

  /// After the last statement: SG_MUL_VAL_ ranges, each multiplexed signal's multiplexor, dropped signals.
  void finish() {
    std::vector<std::pair<std::string, std::string>> parents;  // (message.signal, multiplexor name)
    for (const MulVal& mv : mul_vals_) {
      const auto [m, s] = find_signal(std::to_string(mv.raw_id), mv.signal, mv.line);
      if (s == nullptr) continue;
      const DbcSignal* p = m->find(mv.multiplexor);
      if (s->mux != DbcSignal::Mux::kMultiplexed || p == nullptr ||
          !(p->mux == DbcSignal::Mux::kMultiplexor || p->also_multiplexor) || p == s) {
        skip(mv.line,
             "signal " + m->name + "." + s->name + ": SG_MUL_VAL_ needs a multiplexed signal (m<n>) and a " +
                 "multiplexor (M or m<n>M) of the same message, found '" + mv.multiplexor +
                 "'; signal skipped",
             m->name, s->name);
        drop_.emplace_back(m->name, s->name);
        continue;
      }
      s->mux_ranges = mv.ranges;
      parents.emplace_back(m->name + "." + s->name, mv.multiplexor);
    }
    for (std::size_t i = 0; i < db_.messages_.size(); ++i)
      resolve(db_.messages_[i], message_lines_[i], parents);
  }

  void resolve(DbcMessage& m, std::size_t line,
               const std::vector<std::pair<std::string, std::string>>& parents) {
    const auto parent_of = [&](const DbcSignal& s) -> std::string {
      for (const auto& [key, p] : parents)
        if (key.size() == m.name.size() + 1 + s.name.size() && key.starts_with(m.name) &&
            key.ends_with(s.name) && key[m.name.size()] == '.')
          return p;
      return m.multiplexor >= 0 ? m.signals[static_cast<std::size_t>(m.multiplexor)].name : std::string{};
    };
    std::string orphans;
    for (const auto& s : m.signals) {
      if (s.mux == DbcSignal::Mux::kMultiplexed && parent_of(s).empty()) {
        orphans += (orphans.empty() ? "" : ", ") + s.name;
        r_.skipped.push_back({r_.errors.size(), m.name, s.name});
        drop_.emplace_back(m.name, s.name);
      }
    }
    if (!orphans.empty())
      error(line, "message " + m.name + ": multiplexed signals " + orphans +
                      " but no multiplexor (expected one signal marked 'M'); those signals skipped");
    std::erase_if(m.signals, [&](const DbcSignal& s) {
      return std::find(drop_.begin(), drop_.end(), std::pair{m.name, s.name}) != drop_.end();
    });
    m.multiplexor = -1;
    for (std::size_t i = 0; i < m.signals.size(); ++i)
      if (m.signals[i].mux == DbcSignal::Mux::kMultiplexor) m.multiplexor = static_cast<int>(i);
    for (auto& s : m.signals) {
      if (s.mux != DbcSignal::Mux::kMultiplexed) continue;
      const DbcSignal* p = m.find(parent_of(s));
      s.mux_parent = p == nullptr ? -1 : static_cast<int>(p - m.signals.data());
    }
  }

 public:
  DbcDatabase db_;

 private:
  std::string_view name_;
  DbcParseResult& r_;
  int current_ = -1;
  bool skip_signals_ = false;
  std::vector<std::size_t> message_lines_;  ///< BO_ line of each accepted message
  std::vector<std::uint32_t> skipped_ids_;  ///< ids of skipped BO_ lines (references stay silent)
  std::vector<MulVal> mul_vals_;
  std::vector<std::pair<std::string, std::string>> drop_;  ///< (message, signal) taken out after parsing
};

const std::string* DbcParseResult::affecting(std::string_view message,
                                             std::string_view signal) const noexcept {
  for (const auto& s : skipped) {
    if (s.message == message && (s.signal.empty() || s.signal == signal) && s.error < errors.size())
      return &errors[s.error];
  }
  return nullptr;
}

DbcParseResult DbcDatabase::parse_string(std::string_view text, std::string_view name) {
  DbcParseResult result;
  DbcParser parser(name, result);
  parser.parse(text);
  result.db = std::move(parser.db_);
  return result;
}

DbcParseResult DbcDatabase::parse_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    DbcParseResult r;
    r.errors.push_back(path + ": cannot open: " + std::strerror(errno));
    return r;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  // DBC files are often CP1252/Latin-1 with CRLF; bytes are kept as they are, '\r' is whitespace.
  return parse_string(text, path);
}

}  // namespace torqued
