// CSV number formatting of the recordings (idl/csv_number.hpp): integers exact, doubles rounded to the
// column's resolution (or shortest round-trip when too small/large), every text parses back within it.
#include <gtest/gtest.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <random>
#include <string>

#include "csv_number.hpp"
#include "topic_format.hpp"

namespace torqued::dds {
namespace {

template <int D>
std::string fixed(double v) {
  char buf[64];
  return std::string(buf, csv::write_fixed<D>(buf, v));
}
std::string uint_text(std::uint64_t v) {
  char buf[32];
  return std::string(buf, csv::write_uint(buf, v));
}
std::string int_text(std::int64_t v) {
  char buf[32];
  return std::string(buf, csv::write_int(buf, v));
}
double parse(const std::string& s) {
  double v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  EXPECT_EQ(r.ptr, s.data() + s.size()) << s;
  return v;
}

TEST(CsvNumber, IntegersMatchToString) {
  std::mt19937_64 rng(7);
  for (std::uint64_t v : std::initializer_list<std::uint64_t>{0, 1, 9, 10, 99, 100, 12345, 1000000000,
                                                              std::numeric_limits<std::uint64_t>::max()})
    EXPECT_EQ(uint_text(v), std::to_string(v));
  for (std::int64_t v : std::initializer_list<std::int64_t>{
           0, -1, -10, std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::max()})
    EXPECT_EQ(int_text(v), std::to_string(v));
  for (int i = 0; i < 100000; ++i) {
    const std::uint64_t v = rng() >> (rng() % 64);
    ASSERT_EQ(uint_text(v), std::to_string(v));
    const auto s = static_cast<std::int64_t>(rng()) >> (rng() % 64);
    ASSERT_EQ(int_text(s), std::to_string(s));
  }
}

TEST(CsvNumber, FixedDecimalsTrimmedAndSigned) {
  EXPECT_EQ(fixed<6>(0.0), "0");
  EXPECT_EQ(fixed<6>(-0.0), "0");
  EXPECT_EQ(fixed<6>(60.172303254731204), "60.172303");
  EXPECT_EQ(fixed<6>(-20670.286274046175), "-20670.286274");
  EXPECT_EQ(fixed<6>(314.5), "314.5");
  EXPECT_EQ(fixed<6>(60.75), "60.75");
  EXPECT_EQ(fixed<6>(1.0000004), "1");
  EXPECT_EQ(fixed<6>(1.0000005), "1.000001");  // half away from zero
  EXPECT_EQ(fixed<6>(0.0123456789), "0.012346");
  EXPECT_EQ(fixed<3>(7727.8508179025985), "7727.851");
  EXPECT_EQ(fixed<9>(12.345678901234), "12.345678901");
  EXPECT_EQ(fixed<9>(0.000123), "0.000123");
  // too small for >= 4 significant digits, too large, not finite: shortest round-trip / nan / inf
  EXPECT_EQ(fixed<6>(1.2755074774162267e-13), "1.2755074774162267e-13");
  EXPECT_EQ(fixed<6>(-0.0099), "-0.0099");
  EXPECT_EQ(fixed<6>(1e10), "1e+10");
  EXPECT_EQ(fixed<6>(1.5e300), "1.5e+300");
  EXPECT_EQ(fixed<6>(std::nan("")), "nan");
  EXPECT_EQ(fixed<6>(std::numeric_limits<double>::infinity()), "inf");
  EXPECT_EQ(fixed<6>(-std::numeric_limits<double>::infinity()), "-inf");
}

TEST(CsvNumber, RandomValuesParseBackWithinResolution) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> mant(-1.0, 1.0);
  for (int i = 0; i < 200000; ++i) {
    const double v = mant(rng) * std::pow(10.0, static_cast<int>(rng() % 40) - 20);
    const std::string s6 = fixed<6>(v), s3 = fixed<3>(v), s9 = fixed<9>(v);
    const double a = std::fabs(v);
    constexpr double k53 = 9007199254740992.0;
    // within half a unit of the last decimal (+ the rounding of v * 10^D), or exact (shortest form)
    ASSERT_LE(std::fabs(parse(s6) - v), a >= 1e-2 && a < k53 / 1e6 ? 0.5e-6 + a * 1e-15 : 0.0)
        << v << " " << s6;
    ASSERT_LE(std::fabs(parse(s3) - v), a >= 10 && a < k53 / 1e3 ? 0.5e-3 + a * 1e-15 : 0.0)
        << v << " " << s3;
    ASSERT_LE(std::fabs(parse(s9) - v), a >= 1e-5 && a < k53 / 1e9 ? 0.5e-9 + a * 1e-15 : 0.0)
        << v << " " << s9;
    ASSERT_EQ(s6, fixed<6>(v));  // deterministic
  }
}

TEST(CsvNumber, ColumnResolutionFromUnit) {
  static_assert(csv::csv_decimals("angle_rad") == 9);
  static_assert(csv::csv_decimals("accel_rad_s2") == 3);
  static_assert(csv::csv_decimals("speed_rad_s") == 6);
  static_assert(csv::csv_decimals("brake_nm") == 6);
  torque_CrankState c{};
  c.source_t_ns = 123456789;
  c.engine_id = 1;
  c.seq = 42;
  c.tooth = -1;
  c.phase_known = true;
  c.angle_rad = 1.2345678901234;
  c.speed_rad_s = 314.15926535;
  c.accel_rad_s2 = -20670.286274046175;
  c.events = 5;
  std::string row;
  append_csv_row(row, c);
  EXPECT_EQ(row, "123456789,1,42,0,0,0,-1,0,1,1.23456789,314.159265,-20670.286,5\n");
  EXPECT_EQ(
      csv_header<torque_CrankState>(),
      "t_ns,engine_id,seq,ingest_t_ns,publish_t_ns,validity,tooth,sync,phase_known,angle_rad,speed_rad_s,"
      "accel_rad_s2,events\n");
}

/// The trailing-zero trim as it was (reading the written digits back), the reference of the integer form; the
/// whole part by std::to_string and the fraction by printf's zero padding (independent of the writer's
/// digits).
template <int D>
std::string ref_fixed(double v) {
  const double a = std::fabs(v);
  constexpr double kScale = static_cast<double>(csv::kPow10[D]);
  if (a == 0.0 || !(a >= 1e4 / kScale && a < 9007199254740992.0 / kScale)) return fixed<D>(v);
  // the writer's rounding (half away from zero on |v| x 10^D in IEEE double), on purpose
  const auto n = static_cast<std::uint64_t>(a * kScale + 0.5);  // NOLINT(bugprone-incorrect-roundings)
  const std::uint64_t whole = n / csv::kPow10[D];
  char frac[32];
  std::snprintf(frac, sizeof frac, "%0*llu", D, static_cast<unsigned long long>(n - whole * csv::kPow10[D]));
  std::string s = v < 0 ? "-" : "";
  s += std::to_string(whole);
  s += '.';
  s += frac;
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s;
}

/// The SWAR digits (csv::digits8) against printf on every value below 10^5, a stride through [0, 10^8) and
/// around each power of ten; and integers of every length at each offset.
TEST(CsvNumber, EightDigitsMatchPrintf) {
  auto check = [](std::uint32_t v) {
    char want[16], got[9] = {};
    std::snprintf(want, sizeof want, "%08u", v);
    const std::uint64_t d = csv::digits8(v) | csv::kAsciiZeros;
    for (int i = 0; i < 8; ++i) got[i] = static_cast<char>((d >> (8 * i)) & 0xFF);
    ASSERT_STREQ(got, want) << v;
  };
  for (std::uint32_t v = 0; v < 100000; ++v) check(v);
  for (std::uint32_t v = 100000; v < 100000000; v += 97) check(v);
  for (std::uint64_t p = 10; p <= 100000000; p *= 10)
    for (std::uint64_t v = p - 3; v < p + 3 && v < 100000000; ++v) check(static_cast<std::uint32_t>(v));
  for (std::uint64_t p = 1; p != 0 && p <= 10000000000000000000ull; p *= 10)
    for (const std::uint64_t v : {p - 1, p, p + 1, 2 * p - 1, 9 * p + (p - 1)})
      EXPECT_EQ(uint_text(v), std::to_string(v));
}

TEST(CsvNumber, TrailingZerosTrimmedLikeTheCharacterScan) {
  // around the single-SWAR form's bounds (n = v * 10^D below 10^8; a whole part of 0) and the fall-backs
  for (const double x : {99.9999994, 99.9999996, 100.0, 99.999999, 0.01, 0.0099999, 0.1, 0.999999, 1.0, 1.5,
                         -0.5, -99.9999996, 9.99999999, 10.0, 12345.678, 99999.9999, 100000.0, 0.0001})
    for (const double y : {x, x / 1000.0, x * 1000.0}) {
      ASSERT_EQ(fixed<3>(y), ref_fixed<3>(y)) << y;
      ASSERT_EQ(fixed<6>(y), ref_fixed<6>(y)) << y;
      ASSERT_EQ(fixed<9>(y), ref_fixed<9>(y)) << y;
    }
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> mant(-1.0, 1.0);
  for (int i = 0; i < 300000; ++i) {
    const double v = mant(rng) * std::pow(10.0, static_cast<int>(rng() % 24) - 8);
    // and values with few significant decimals (k / 10^j): many trailing zeros, whole numbers
    const double q = static_cast<double>(static_cast<std::int64_t>(rng() % 2000001) - 1000000) /
                     std::pow(10.0, static_cast<int>(rng() % 10));
    for (const double x : {v, q}) {
      ASSERT_EQ(fixed<3>(x), ref_fixed<3>(x)) << x;
      ASSERT_EQ(fixed<6>(x), ref_fixed<6>(x)) << x;
      ASSERT_EQ(fixed<9>(x), ref_fixed<9>(x)) << x;
    }
  }
}

}  // namespace
}  // namespace torqued::dds
