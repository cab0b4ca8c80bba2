#pragma once
// Fast, exact and deterministic number formatting for the CSV recordings (recorder + torque-echo).
//  - integers: plain decimal, 8 digits per step by SWAR (digits8(); no locale, no division per digit);
//  - doubles: fixed point with D decimals chosen per column from its unit (csv_decimals()), i.e. the value
//    rounded to that resolution (half away from zero, applied to v * 10^D computed in IEEE double, so the
//    same value always gives the same text), trailing zeros dropped ("60.172303", "314.5", "0"). Values too
//    small to keep >= 4 significant digits at that resolution (0 < |v| < 10^(4-D), e.g. an excitation level
//    of 1e-13) and values too large for an exact integer (|v| * 10^D >= 2^53) are written in the shortest
//    round-trip form of std::to_chars instead; NaN/Inf as nan/inf/-inf. Every form parses with strtod /
//    std::from_chars. Several times fewer instructions than shortest round-trip for typical values.
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string_view>

namespace torqued::dds::csv {

#define TORQUED_CSV_INLINE [[gnu::always_inline]] inline

inline constexpr std::uint64_t kPow10[20] = {1ull,
                                             10ull,
                                             100ull,
                                             1000ull,
                                             10000ull,
                                             100000ull,
                                             1000000ull,
                                             10000000ull,
                                             100000000ull,
                                             1000000000ull,
                                             10000000000ull,
                                             100000000000ull,
                                             1000000000000ull,
                                             10000000000000ull,
                                             100000000000000ull,
                                             1000000000000000ull,
                                             10000000000000000ull,
                                             100000000000000000ull,
                                             1000000000000000000ull,
                                             10000000000000000000ull};

/// The 8 decimal digits of v < 10^8 as byte values 0-9, the most significant in the lowest byte (the first in
/// memory on a little-endian machine), by SWAR: two halves of 4 digits in the 32-bit lanes, each split into
/// pairs by a multiply-shift division by 100, the pairs into digits by one by 10 (P. Khuong's and
/// D. Lemire's "encode ten thousands"; exact for every v < 10^8, tests/idl: CsvNumber.*). Add 0x30 to each
/// byte for the ASCII text.
TORQUED_CSV_INLINE std::uint64_t digits8(std::uint32_t v) noexcept {
  const std::uint32_t hi = static_cast<std::uint32_t>((static_cast<std::uint64_t>(v) * 109951163ull) >> 40);
  const std::uint64_t merged = hi | (static_cast<std::uint64_t>(v - hi * 10000u) << 32);  // v / 10^4 exact
  const std::uint64_t top = ((merged * 10486ull) >> 20) & ((0x7Full << 32) | 0x7Full);    // / 100 per lane
  const std::uint64_t bot = merged - 100ull * top;
  const std::uint64_t hundreds = (bot << 16) + top;
  std::uint64_t tens = (hundreds * 103ull) >> 10;  // / 10 per 16-bit lane
  tens &= (0xFull << 48) | (0xFull << 32) | (0xFull << 16) | 0xFull;
  tens += (hundreds - 10ull * tens) << 8;
  return tens;
}
inline constexpr std::uint64_t kAsciiZeros = 0x3030303030303030ull;

/// Stores the 8 bytes of w at p (little-endian: its lowest byte first).
TORQUED_CSV_INLINE void store8(char* p, std::uint64_t w) noexcept {
  if constexpr (std::endian::native == std::endian::big) w = __builtin_bswap64(w);
  std::memcpy(p, &w, 8);
}

/// 1-8 digits of 0 < v < 10^8 without leading zeros; returns the end. Writes 8 bytes at p.
TORQUED_CSV_INLINE char* write_upto8(char* p, std::uint32_t v) noexcept {
  const std::uint64_t d = digits8(v);
  const int lead = __builtin_ctzll(d) >> 3;  // leading zero digits (v != 0: d != 0)
  store8(p, (d | kAsciiZeros) >> (8 * lead));
  return p + 8 - lead;
}

/// Unsigned decimal; returns the end. Needs 20 bytes of room (may write up to 20 bytes past p).
TORQUED_CSV_INLINE char* write_uint(char* p, std::uint64_t v) noexcept {
  if (v < 10) {
    *p = static_cast<char>('0' + v);
    return p + 1;
  }
  if (v < 100000000ull) return write_upto8(p, static_cast<std::uint32_t>(v));
  std::uint64_t hi = v / 100000000ull;
  const auto lo = static_cast<std::uint32_t>(v - hi * 100000000ull);
  if (hi >= 100000000ull) {  // >= 10^16: at most 4 more digits
    const std::uint64_t top = hi / 100000000ull;
    p = write_upto8(p, static_cast<std::uint32_t>(top));
    hi -= top * 100000000ull;
    store8(p, digits8(static_cast<std::uint32_t>(hi)) | kAsciiZeros);
    p += 8;
  } else {
    p = write_upto8(p, static_cast<std::uint32_t>(hi));
  }
  store8(p, digits8(lo) | kAsciiZeros);
  return p + 8;
}

/// Signed decimal; returns the end. Needs 21 bytes of room.
TORQUED_CSV_INLINE char* write_int(char* p, std::int64_t v) noexcept {
  if (v < 0) {
    *p++ = '-';
    return write_uint(p, 0u - static_cast<std::uint64_t>(v));
  }
  return write_uint(p, static_cast<std::uint64_t>(v));
}

/// Shortest round-trip form (std::to_chars), nan/inf/-inf. Needs 32 bytes of room.
inline char* write_shortest(char* p, double v) noexcept {
  if (std::isnan(v)) return static_cast<char*>(std::memcpy(p, "nan", 3)) + 3;
  if (std::isinf(v))
    return v > 0 ? static_cast<char*>(std::memcpy(p, "inf", 3)) + 3
                 : static_cast<char*>(std::memcpy(p, "-inf", 4)) + 4;
  return std::to_chars(p, p + 32, v).ptr;
}

/// n < 10^8 in fixed point with D < 8 decimals from its 8 SWAR digit bytes d: the whole part from the first
/// 8 - D (its leading zeros dropped, "0" when all are), '.', the last D without trailing zeros (nothing when
/// all are). One SWAR pass and no division for the values of most columns. Writes up to 17 bytes at p.
TORQUED_CSV_INLINE char* write_fixed_upto8(char* p, std::uint64_t d, int D) noexcept {
  const std::uint64_t whole_mask = ~0ull >> (8 * D);  // bytes 0 .. 7 - D
  const std::uint64_t w = d & whole_mask;
  if (w == 0) {
    *p++ = '0';
  } else {
    const int lead = __builtin_ctzll(w) >> 3;
    store8(p, (w | (kAsciiZeros & whole_mask)) >> (8 * lead));
    p += 8 - D - lead;
  }
  *p = '.';
  const std::uint64_t f = d >> (8 * (8 - D));  // the last D digits, first at byte 0
  if (f == 0) return p;
  store8(p + 1, f | kAsciiZeros);
  return p + 9 - (__builtin_clzll(f) >> 3);
}

/// Fixed point with D decimals (see the file comment for the fall-backs). Needs 40 bytes of room.
template <int D>
TORQUED_CSV_INLINE char* write_fixed(char* p, double v) noexcept {
  static_assert(D >= 1 && D <= 9);
  constexpr double kScale = static_cast<double>(kPow10[D]);
  constexpr double kMin = 1e4 / kScale;                 // >= 4 significant digits
  constexpr double kMax = 9007199254740992.0 / kScale;  // 2^53
  const double a = std::fabs(v);
  if (a == 0.0) {  // also -0.0
    *p = '0';
    return p + 1;
  }
  if (!(a >= kMin && a < kMax)) [[unlikely]]
    return write_shortest(p, v);                                // also NaN/Inf
  const auto n = static_cast<std::uint64_t>(a * kScale + 0.5);  // 10^4 <= n < 2^53 + 1
  *p = '-';
  p += v < 0;
  if constexpr (D < 8) {
    if (n < 100000000ull) return write_fixed_upto8(p, digits8(static_cast<std::uint32_t>(n)), D);
  }
  // Whole part (at least "0"), '.', exactly D fraction digits, then trailing zeros dropped. Written in place
  // (a digit buffer copied with wide loads stalled on store forwarding).
  const std::uint64_t whole = n / kPow10[D];
  p = write_uint(p, whole);
  *p = '.';
  const std::uint64_t frac = n - whole * kPow10[D];
  if (frac == 0) return p;
  // Exactly D fraction digits from their SWAR bytes (the last D of 8, or a first digit and 8 for D = 9), the
  // trailing zeros dropped by counting the zero bytes at the end (the last digit is the highest byte): no
  // division per digit, no loop.
  std::uint64_t d;
  char* q = p + 1;
  if constexpr (D > 8) {
    static_assert(D == 9);
    const std::uint64_t first = frac / 100000000ull;
    *q++ = static_cast<char>('0' + first);
    d = digits8(static_cast<std::uint32_t>(frac - first * 100000000ull));
    if (d == 0) return q;
    store8(q, d | kAsciiZeros);
    return q + 8 - (__builtin_clzll(d) >> 3);
  } else {
    d = digits8(static_cast<std::uint32_t>(frac)) >> (8 * (8 - D));  // the last D digits, first at byte 0
    store8(q, d | kAsciiZeros);
    return q + 8 - (__builtin_clzll(d) >> 3);  // d != 0: frac != 0
  }
}

/// Decimals of a CSV column of doubles, from its unit suffix: angles in rad 9 (1 nrad), angular
/// accelerations in rad/s^2 3, everything else (N m, rad/s, %, uncertainties) 6.
constexpr int csv_decimals(std::string_view name) noexcept {
  if (name.ends_with("_rad")) return 9;
  if (name.ends_with("_rad_s2")) return 3;
  return 6;
}

/// Formats a double for column `name`'s resolution.
TORQUED_CSV_INLINE char* write_column_double(char* p, double v, int decimals) noexcept {
  switch (decimals) {
    case 3:
      return write_fixed<3>(p, v);
    case 9:
      return write_fixed<9>(p, v);
    default:
      return write_fixed<6>(p, v);
  }
}

}  // namespace torqued::dds::csv

#undef TORQUED_CSV_INLINE
