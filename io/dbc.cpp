// DBC parser (load-time) and bit extraction (real-time safe). Line-oriented with statement joining: CM_ and
// other quoted statements may span lines; the NS_ block's indented keyword list is skipped.
#include "dbc.hpp"

#include <algorithm>
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
  // Motorola: walk from the MSB (start_bit) down the sawtooth to the LSB; the furthest byte is the LSB's.
  int b = start_bit;
  for (int k = 1; k < length; ++k) b = (b % 8 == 0) ? b + 15 : b - 1;
  return static_cast<std::size_t>(std::max(b, static_cast<int>(start_bit)) / 8 + 1);
}

namespace {
std::int64_t sign_extend(std::uint64_t v, int length, bool is_signed) noexcept {
  if (is_signed && length < 64 && ((v >> (length - 1)) & 1u) != 0) v |= ~std::uint64_t{0} << length;
  return static_cast<std::int64_t>(v);
}
}  // namespace

// Word-at-a-time: gather the (at most 8) bytes the signal spans into one integer, shift and mask. Bytes past
// `len` read as 0, as in the bitwise definition. Signals spanning 9 bytes (e.g. 64 bits not byte-aligned)
// take the bitwise path.
std::int64_t DbcSignal::raw(const std::uint8_t* data, std::size_t len) const noexcept {
  const int n = static_cast<int>(length);
  if (n <= 0 || n > 64) return raw_bitwise(data, len);
  const int first = start_bit / 8, shift_in_byte = start_bit % 8;
  std::uint64_t v = 0;
  if (little_endian) {  // Intel: LSB at start_bit, bytes in increasing order
    const int bytes = (shift_in_byte + n + 7) / 8;
    if (bytes > 8) return raw_bitwise(data, len);
    for (int b = bytes - 1; b >= 0; --b) {
      const auto i = static_cast<std::size_t>(first + b);
      v = (v << 8) | (i < len ? data[i] : 0u);
    }
    v >>= shift_in_byte;
  } else {  // Motorola: MSB at start_bit (sawtooth numbering), bytes in increasing order from the MSB's byte
    const int bytes = (7 - shift_in_byte + n + 7) / 8;
    if (bytes > 8) return raw_bitwise(data, len);
    for (int b = 0; b < bytes; ++b) {
      const auto i = static_cast<std::size_t>(first + b);
      v = (v << 8) | (i < len ? data[i] : 0u);
    }
    v >>= 8 * (bytes - 1) + shift_in_byte - n + 1;  // the MSB sits at bit 8·(bytes−1) + shift_in_byte
  }
  if (n < 64) v &= (std::uint64_t{1} << n) - 1u;
  return sign_extend(v, n, is_signed);
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
  if (s.mux != DbcSignal::Mux::kMultiplexed || multiplexor < 0) return true;
  const DbcSignal& m = signals[static_cast<std::size_t>(multiplexor)];
  if (len < m.bytes_needed()) return false;
  return m.raw(data, len) == static_cast<std::int64_t>(s.mux_value);
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
    "BA_DEF_",      "BA_DEF_DEF_",     "BA_",        "BA_DEF_REL_",   "BA_REL_",    "BA_DEF_DEF_REL_",
    "BA_SGTYPE_",   "VAL_TABLE_",      "SIG_GROUP_", "SIG_VALTYPE_",  "EV_",        "ENVVAR_DATA_",
    "SGTYPE_",      "SGTYPE_VAL_",     "BO_TX_BU_",  "SIG_TYPE_REF_", "CAT_DEF_",   "CAT_",
    "FILTER",       "SIG_MUL_VAL_",    "BU_SG_REL_", "BU_EV_REL_",    "BU_BO_REL_", "NS_DESC_",
    "ENVVAR_DATA_", "SIGTYPE_VALTYPE_"};

}  // namespace

class DbcParser {
 public:
  DbcParser(std::string_view name, DbcParseResult& result) : name_(name), r_(result) {}

  void parse(std::string_view text) {
    std::size_t pos = 0;
    std::size_t line_no = 0;
    bool in_ns = false;
    while (pos < text.size()) {
      std::size_t nl = text.find('\n', pos);
      if (nl == std::string_view::npos) nl = text.size();
      std::string_view raw_line = text.substr(pos, nl - pos);
      pos = nl + 1;
      ++line_no;
      const bool indented = !raw_line.empty() && (raw_line.front() == ' ' || raw_line.front() == '\t');
      std::string_view line = trim(raw_line);
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
      const std::size_t stmt_line = line_no;
      std::string stmt(line);
      // CM_ / VAL_ / BA_... may span several lines (multi-line comment strings).
      if (starts_with_kw(line, "CM_") || starts_with_kw(line, "VAL_") || starts_with_kw(line, "BA_") ||
          starts_with_kw(line, "BA_DEF_") || starts_with_kw(line, "VAL_TABLE_")) {
        while (!complete(stmt) && pos < text.size()) {
          nl = text.find('\n', pos);
          if (nl == std::string_view::npos) nl = text.size();
          stmt += '\n';
          stmt += text.substr(pos, nl - pos);
          pos = nl + 1;
          ++line_no;
        }
        if (!complete(stmt)) {
          error(stmt_line, "statement not terminated (missing '\"' or ';')");
          continue;
        }
      }
      statement(stmt, stmt_line);
    }
  }

 private:
  void error(std::size_t line, const std::string& what) {
    r_.errors.push_back(std::string(name_) + ":" + std::to_string(line) + ": " + what);
  }
  void warning(std::size_t line, const std::string& what) {
    r_.warnings.push_back(std::string(name_) + ":" + std::to_string(line) + ": " + what);
  }

  void statement(const std::string& stmt, std::size_t line) {
    Lexer lx(stmt);
    const Token kw = lx.next();
    if (kw.kind != Tok::kIdent) {
      error(line, "expected a DBC keyword, found '" + std::string(kw.text) + "'");
      return;
    }
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
      message(lx, line);
    } else if (kw.text == "SG_") {
      signal(lx, line);
    } else if (kw.text == "CM_") {
      comment(lx, line);
    } else if (kw.text == "VAL_") {
      values(lx, line);
    } else if (kw.text == "SIG_VALTYPE_") {
      warning(line, "SIG_VALTYPE_ (IEEE float signals) not supported; such signals decode as integers");
    } else if (std::find(std::begin(kIgnored), std::end(kIgnored), kw.text) != std::end(kIgnored)) {
      // Attributes, value tables, signal groups, environment variables: not needed for decoding.
    } else {
      warning(line, "unknown keyword '" + std::string(kw.text) + "' ignored");
    }
  }

  void message(Lexer& lx, std::size_t line) {
    // BO_ <id> <name>: <dlc> <transmitter>
    const Token id = lx.next();
    const Token name = lx.next();
    const Token colon = lx.next();
    const Token dlc = lx.next();
    const Token tx = lx.next();
    std::uint32_t raw_id = 0;
    std::int64_t len = 0;
    if (id.kind != Tok::kNumber || !to_uint32(id.text, raw_id) || name.kind != Tok::kIdent ||
        !(colon.kind == Tok::kPunct && colon.text == ":") || dlc.kind != Tok::kNumber ||
        !to_int64(dlc.text, len)) {
      error(line, "expected 'BO_ <id> <name>: <dlc> <transmitter>'");
      current_ = -1;
      return;
    }
    if (len < 0 || len > 64) {
      error(line,
            "message " + std::string(name.text) + ": DLC " + std::to_string(len) + " outside 0..64 bytes");
      current_ = -1;
      return;
    }
    DbcMessage m;
    m.extended = (raw_id & 0x80000000u) != 0;
    m.id = raw_id & 0x1FFFFFFFu;
    m.name = std::string(name.text);
    m.dlc = static_cast<std::uint8_t>(len);
    if (tx.kind == Tok::kIdent) m.transmitter = std::string(tx.text);
    if (raw_id == 0xC0000000u) {  // VECTOR__INDEPENDENT_SIG_MSG pseudo-message (id 3221225472)
      current_ = -1;
      skip_signals_ = true;
      return;
    }
    skip_signals_ = false;
    if (!m.extended && m.id > 0x7FF) {
      error(line, "message " + m.name + ": standard id 0x" + hex(m.id) +
                      " above 0x7FF (extended ids have bit 31 set)");
      current_ = -1;
      return;
    }
    if (db_.find(m.id, m.extended) != nullptr) {
      error(line, "message " + m.name + ": duplicate id 0x" + hex(m.id));
      current_ = -1;
      return;
    }
    if (db_.find(m.name) != nullptr) {
      error(line, "duplicate message name " + m.name);
      current_ = -1;
      return;
    }
    db_.messages_.push_back(std::move(m));
    current_ = static_cast<int>(db_.messages_.size()) - 1;
  }

  void signal(Lexer& lx, std::size_t line) {
    if (skip_signals_) return;
    if (current_ < 0) {
      error(line, "SG_ outside a valid BO_ message");
      return;
    }
    DbcMessage& m = db_.messages_[static_cast<std::size_t>(current_)];
    static const char* kExpected =
        "expected 'SG_ <name> [M|m<n>] : <start>|<length>@<0|1><+|-> (<factor>,<offset>) [<min>|<max>] "
        "\"<unit>\" "
        "<receivers>'";
    DbcSignal s;
    Token t = lx.next();
    if (t.kind != Tok::kIdent) return error(line, kExpected);
    s.name = std::string(t.text);
    t = lx.next();
    if (t.kind == Tok::kIdent) {  // multiplexing indicator: M, m<n>, m<n>M
      const std::string_view mi = t.text;
      if (mi == "M") {
        s.mux = DbcSignal::Mux::kMultiplexor;
      } else if (mi.size() >= 2 && mi[0] == 'm') {
        std::string_view digits = mi.substr(1);
        const bool also_mux = digits.ends_with("M");
        if (also_mux) {
          digits.remove_suffix(1);
          warning(line,
                  "signal " + s.name + ": extended multiplexing (m<n>M) treated as simple multiplexing");
        }
        std::int64_t v = 0;
        if (!to_int64(digits, v) || v < 0)
          return error(line, "signal " + s.name + ": bad multiplex indicator '" + std::string(mi) + "'");
        s.mux = DbcSignal::Mux::kMultiplexed;
        s.mux_value = static_cast<std::uint32_t>(v);
      } else {
        return error(line, "signal " + s.name + ": bad multiplex indicator '" + std::string(mi) + "'");
      }
      t = lx.next();
    }
    if (!(t.kind == Tok::kPunct && t.text == ":")) return error(line, kExpected);
    std::int64_t start = 0, length = 0, order = 0;
    Token a = lx.next(), bar = lx.next(), b = lx.next(), at = lx.next(), o = lx.next();
    if (a.kind != Tok::kNumber || !to_int64(a.text, start) || bar.text != "|" || b.kind != Tok::kNumber ||
        !to_int64(b.text, length) || at.text != "@") {
      return error(line, kExpected);
    }
    // "@1+" lexes as '@' '1' '+'; "@1-" likewise; but "@1" followed by "-" could lex as a number "-..." only
    // if a digit follows, which the grammar never has.
    Token sign;
    if (o.kind == Tok::kNumber && (o.text == "0" || o.text == "1")) {
      order = o.text == "1" ? 1 : 0;
      sign = lx.next();
    } else if (o.kind == Tok::kNumber &&
               (o.text == "0+" || o.text == "1+" || o.text == "0-" || o.text == "1-")) {
      order = o.text[0] == '1' ? 1 : 0;
      sign = Token{Tok::kPunct, o.text.substr(1)};
    } else {
      return error(line, kExpected);
    }
    if (!(sign.kind == Tok::kPunct && (sign.text == "+" || sign.text == "-"))) return error(line, kExpected);
    if (length < 1 || length > 64)
      return error(line, "signal " + s.name + ": length " + std::to_string(length) + " outside 1..64 bits");
    if (start < 0 || start >= 512)
      return error(line, "signal " + s.name + ": start bit " + std::to_string(start) + " outside 0..511");
    s.start_bit = static_cast<std::uint16_t>(start);
    s.length = static_cast<std::uint16_t>(length);
    s.little_endian = order == 1;
    s.is_signed = sign.text == "-";
    Token lp = lx.next(), f = lx.next(), comma = lx.next(), off = lx.next(), rp = lx.next();
    if (lp.text != "(" || f.kind != Tok::kNumber || !to_double(f.text, s.factor) || comma.text != "," ||
        off.kind != Tok::kNumber || !to_double(off.text, s.offset) || rp.text != ")") {
      return error(line, "signal " + s.name + ": expected '(<factor>,<offset>)'");
    }
    Token lb = lx.next(), mn = lx.next(), bar2 = lx.next(), mx = lx.next(), rb = lx.next();
    if (lb.text != "[" || mn.kind != Tok::kNumber || !to_double(mn.text, s.min) || bar2.text != "|" ||
        mx.kind != Tok::kNumber || !to_double(mx.text, s.max) || rb.text != "]") {
      return error(line, "signal " + s.name + ": expected '[<min>|<max>]'");
    }
    const Token unit = lx.next();
    if (unit.kind != Tok::kString) return error(line, "signal " + s.name + ": expected \"<unit>\"");
    s.unit = std::string(unit.text);
    for (Token r = lx.next(); r.kind == Tok::kIdent || (r.kind == Tok::kPunct && r.text == ",");
         r = lx.next()) {
      if (r.kind == Tok::kIdent) s.receivers.emplace_back(r.text);
    }
    if (s.factor == 0.0) warning(line, "signal " + s.name + ": factor 0");
    const std::size_t need = s.bytes_needed();
    if (need > 64) return error(line, "signal " + s.name + ": does not fit in 64 bytes");
    if (need > m.dlc) {
      warning(line, "signal " + s.name + ": needs " + std::to_string(need) + " bytes, message " + m.name +
                        " has DLC " + std::to_string(m.dlc));
    }
    if (m.find(s.name) != nullptr) return error(line, "message " + m.name + ": duplicate signal " + s.name);
    if (s.mux == DbcSignal::Mux::kMultiplexor) {
      if (m.multiplexor >= 0) return error(line, "message " + m.name + ": second multiplexor " + s.name);
      m.multiplexor = static_cast<int>(m.signals.size());
    }
    m.signals.push_back(std::move(s));
  }

  DbcSignal* find_signal(std::string_view id_text, std::string_view sig, std::size_t line) {
    std::uint32_t raw_id = 0;
    if (!to_uint32(id_text, raw_id)) {
      error(line, "expected a message id, found '" + std::string(id_text) + "'");
      return nullptr;
    }
    auto* m = const_cast<DbcMessage*>(db_.find(raw_id & 0x1FFFFFFFu, (raw_id & 0x80000000u) != 0));
    if (m == nullptr) {
      if (raw_id != 0xC0000000u) warning(line, "reference to unknown message id " + std::to_string(raw_id));
      return nullptr;
    }
    for (auto& s : m->signals) {
      if (s.name == sig) return &s;
    }
    warning(line, "reference to unknown signal " + m->name + "." + std::string(sig));
    return nullptr;
  }

  void comment(Lexer& lx, std::size_t line) {
    const Token t = lx.next();
    if (t.kind == Tok::kString) return;  // database comment
    if (t.kind != Tok::kIdent) return error(line, "expected 'CM_ [BU_|BO_|SG_|EV_] ... \"<text>\";'");
    if (t.text == "BO_") {
      const Token id = lx.next(), text = lx.next();
      std::uint32_t raw_id = 0;
      if (id.kind != Tok::kNumber || !to_uint32(id.text, raw_id) || text.kind != Tok::kString) {
        return error(line, "expected 'CM_ BO_ <id> \"<text>\";'");
      }
      auto* m = const_cast<DbcMessage*>(db_.find(raw_id & 0x1FFFFFFFu, (raw_id & 0x80000000u) != 0));
      if (m != nullptr) m->comment = std::string(text.text);
    } else if (t.text == "SG_") {
      const Token id = lx.next(), sig = lx.next(), text = lx.next();
      if (id.kind != Tok::kNumber || sig.kind != Tok::kIdent || text.kind != Tok::kString) {
        return error(line, "expected 'CM_ SG_ <id> <signal> \"<text>\";'");
      }
      if (DbcSignal* s = find_signal(id.text, sig.text, line)) s->comment = std::string(text.text);
    } else if (t.text == "BU_" || t.text == "EV_") {
      // node / environment variable comments: not needed
    } else {
      error(line, "expected 'CM_ [BU_|BO_|SG_|EV_] ... \"<text>\";'");
    }
  }

  void values(Lexer& lx, std::size_t line) {
    const Token id = lx.next();
    const Token sig = lx.next();
    if (id.kind != Tok::kNumber || sig.kind != Tok::kIdent) {
      if (id.kind == Tok::kIdent) return;  // VAL_ for an environment variable
      return error(line, "expected 'VAL_ <id> <signal> <value> \"<text>\" ... ;'");
    }
    DbcSignal* s = find_signal(id.text, sig.text, line);
    std::vector<std::pair<std::int64_t, std::string>> table;
    for (Token v = lx.next(); v.kind == Tok::kNumber; v = lx.next()) {
      const Token text = lx.next();
      std::int64_t x = 0;
      double d = 0;
      if (!to_int64(v.text, x)) {
        if (!to_double(v.text, d)) return error(line, "VAL_: bad value '" + std::string(v.text) + "'");
        // Raw values are integers of at most 64 bits: anything outside [-2^63, 2^63) cannot be a raw value
        // (and casting it to int64 is undefined behaviour).
        if (!(d >= -9223372036854775808.0 && d < 9223372036854775808.0))
          return error(line, "VAL_: value " + std::string(v.text) + " is outside the 64-bit raw range");
        x = static_cast<std::int64_t>(d);
      }
      if (text.kind != Tok::kString)
        return error(line, "VAL_: expected \"<text>\" after value " + std::string(v.text));
      table.emplace_back(x, std::string(text.text));
    }
    if (s != nullptr) s->value_table = std::move(table);
  }

  static std::string hex(std::uint32_t v) {
    char buf[16];
    const auto r = std::to_chars(buf, buf + sizeof buf, v, 16);
    return std::string(buf, r.ptr);
  }

 public:
  DbcDatabase db_;

 private:
  std::string_view name_;
  DbcParseResult& r_;
  int current_ = -1;
  bool skip_signals_ = false;
};

DbcParseResult DbcDatabase::parse_string(std::string_view text, std::string_view name) {
  DbcParseResult result;
  DbcParser parser(name, result);
  parser.parse(text);
  if (result.errors.empty()) result.db = std::move(parser.db_);
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
