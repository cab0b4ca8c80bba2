#pragma once
// Hand-written, allocation-free parsers for the text backends (no std::stod, no locale): exact decimal
// seconds -> integer ns, hex digits, small integers. Each returns false on malformed input; `p` advances.
#include <cstdint>
#include <string_view>

namespace torqued::parse {

/// Skip spaces and tabs.
inline void skip_ws(const char*& p, const char* end) noexcept {
  while (p < end && (*p == ' ' || *p == '\t')) ++p;
}

/// Decimal seconds ("-12.345678901", "1700000000.123456", "1e-3" not accepted) -> ns, exact for up to 9
/// fractional digits (more are rounded half-up). Requires at least one digit. Overflow-checked.
inline bool seconds_to_ns(const char*& p, const char* end, std::int64_t& ns) noexcept {
  bool neg = false;
  if (p < end && (*p == '-' || *p == '+')) neg = *p++ == '-';
  std::int64_t whole = 0;
  int digits = 0;
  while (p < end && static_cast<unsigned>(*p - '0') < 10u) {
    whole = whole * 10 + (*p++ - '0');
    if (whole > 9'200'000'000) return false;  // whole * 1e9 + frac must fit in int64 (~292 years)
    ++digits;
  }
  std::int64_t frac = 0;
  if (p < end && *p == '.') {
    ++p;
    int f = 0;
    while (p < end && static_cast<unsigned>(*p - '0') < 10u) {
      if (f < 9) {
        frac = frac * 10 + (*p - '0');
      } else if (f == 9 && *p >= '5') {
        ++frac;  // round on the 10th digit
      }
      ++f;
      ++p;
      ++digits;
    }
    for (int k = f; k < 9; ++k) frac *= 10;
  }
  if (digits == 0) return false;
  ns = whole * 1'000'000'000 + frac;
  if (neg) ns = -ns;
  return true;
}

/// Unsigned decimal integer.
inline bool uint_dec(const char*& p, const char* end, std::uint64_t& v) noexcept {
  const char* s = p;
  v = 0;
  while (p < end && static_cast<unsigned>(*p - '0') < 10u) v = v * 10 + static_cast<unsigned>(*p++ - '0');
  return p != s;
}

/// Value of one hex digit, or -1.
inline int hex_digit(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  c = static_cast<char>(c | 0x20);
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

/// Trim spaces, tabs, quotes.
inline std::string_view trim(std::string_view s) noexcept {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '"')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '"')) s.remove_suffix(1);
  return s;
}

}  // namespace torqued::parse
