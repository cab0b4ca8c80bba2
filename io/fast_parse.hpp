#pragma once
// Hand-written, allocation-free parsers for the text backends (no std::stod, no locale): exact decimal
// seconds -> integer ns, hex digits, small integers. Each returns false on malformed input; `p` advances.
#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <string_view>

namespace torqued::parse {

/// 10^n for n = 0..9.
inline constexpr std::array<std::int64_t, 10> kPow10 = {
    1, 10, 100, 1'000, 10'000, 100'000, 1'000'000, 10'000'000, 100'000'000, 1'000'000'000};

/// The leading ASCII digits (at most 8) of the 8 bytes at p: their count, and their value in `value` (SWAR;
/// Lemire's 8-digit conversion with the digits right-aligned). The bytes after the first non-digit do not
/// matter: a carry or borrow between bytes only runs towards later bytes. Reads 8 bytes: p + 8 <= end.
inline int leading_digits8(const char* p, std::uint64_t& value) noexcept {
  std::uint64_t v = 0;
  std::memcpy(&v, p, sizeof v);
  if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap64(v);
  // A digit byte has high nibble 3, and still has after adding 6.
  const std::uint64_t bad = ((v & 0xF0F0F0F0F0F0F0F0ull) ^ 0x3030303030303030ull) |
                            (((v + 0x0606060606060606ull) & 0xF0F0F0F0F0F0F0F0ull) ^ 0x3030303030303030ull);
  const int n = bad == 0 ? 8 : std::countr_zero(bad) / 8;
  if (n == 0) {
    value = 0;
    return 0;
  }
  std::uint64_t d = (v - 0x3030303030303030ull) << (8 * (8 - n));  // zero digits in front of the n
  d = (d * 10) + (d >> 8);                                         // pairs
  d = (((d & 0x000000FF000000FFull) * (100 + (1000000ull << 32))) +
       (((d >> 16) & 0x000000FF000000FFull) * (1 + (10000ull << 32)))) >>
      32;
  value = d;
  return n;
}

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
  // Eight digits at a time while 8 bytes remain. The bound below holds after a block iff it held after each
  // of its digits (the value only grows), and whole ≤ 9.2e9 before a block keeps whole·10^8 in range.
  for (int n = 8; n == 8 && end - p >= 8;) {
    std::uint64_t v = 0;
    n = leading_digits8(p, v);
    whole = whole * kPow10[static_cast<std::size_t>(n)] + static_cast<std::int64_t>(v);
    if (whole > 9'200'000'000) return false;
    p += n;
    digits += n;
  }
  while (p < end && static_cast<unsigned>(*p - '0') < 10u) {
    whole = whole * 10 + (*p++ - '0');
    if (whole > 9'200'000'000) return false;  // whole * 1e9 + frac must fit in int64 (~292 years)
    ++digits;
  }
  std::int64_t frac = 0;
  if (p < end && *p == '.') {
    ++p;
    int f = 0;
    if (end - p >= 8) {  // the first (up to) 8 fractional digits at once; all kept (f < 9)
      std::uint64_t v = 0;
      f = leading_digits8(p, v);
      frac = static_cast<std::int64_t>(v);
      p += f;
      digits += f;
    }
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
    if (f < 9) frac *= kPow10[static_cast<std::size_t>(9 - f)];
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

/// Value of one hex digit ('0'-'9', 'a'-'f', 'A'-'F'), or -1: one table load, no branches.
inline int hex_digit(char c) noexcept {
  static constexpr std::array<std::int8_t, 256> kHex = [] {
    std::array<std::int8_t, 256> t{};
    t.fill(-1);
    for (int i = 0; i < 10; ++i) t[static_cast<std::size_t>('0' + i)] = static_cast<std::int8_t>(i);
    for (int i = 0; i < 6; ++i) {
      t[static_cast<std::size_t>('a' + i)] = static_cast<std::int8_t>(10 + i);
      t[static_cast<std::size_t>('A' + i)] = static_cast<std::int8_t>(10 + i);
    }
    return t;
  }();
  return kHex[static_cast<unsigned char>(c)];
}

/// Trim spaces, tabs, quotes.
inline std::string_view trim(std::string_view s) noexcept {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '"')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '"')) s.remove_suffix(1);
  return s;
}

}  // namespace torqued::parse
