// tests/learned/test_state_format.cpp: the state file's text is pinned. A state with every line present gives
// exactly the text the serializer gave before the line table (learned/state_store.cpp kLines) replaced the
// hand-written one (version 2, %.17g, CRC-32), and what parses serializes back to the same text.
#include <gtest/gtest.h>

#include <string>

#include "state_store.hpp"

namespace torqued {
namespace {

const std::string kIdentity = "engine_id=1 cylinders=4 bore_m=0.0825 stroke_m=0.086 wheel=60-2 teeth=58";

/// Every line present, with values at the edges of their kinds (near-subnormal, -1e-300, 2^32-1, int64).
LearnedState full_state() {
  LearnedState s;
  s.friction = std::array<double, 4>{-23.86, 2.45e-3, -5.2e-6, -4.67e-3};
  s.friction_idle = std::array<double, 2>{1.4999999999999998, 812.25};
  s.friction_residual = std::array<double, 2>{0.31234567890123456, 87.0};
  s.tooth_corrections_rad.assign(6, 0.0);
  s.tooth_corrections_rad[3] = 7.123456789012345e-4;
  s.tooth_corrections_rad[5] = -1e-300;
  FuelTorqueState f;  // an older file's model: the two-parameter view only (no physics part)
  f.physics = false;
  f.eta_ref = 0.38123456789012345;
  f.p_exh_nm = -12.5;
  f.p2 = {1e-4, -2.5e-7, -2.5e-7, 0.75};
  f.resid_var = 4.0000000000000009;
  f.references = 4294967295u;
  f.cover.sd = 0.73456789012345678;
  f.cover.n = 321;
  s.fuel = f;
  s.crank_error_var = 2.2250738585072014e-308;
  s.inertia = std::array<double, 3>{1.0873456789012345, 4321.5, 0.146722};
  s.saved_at_t_ns = -9223372036854775807LL;
  return s;
}

TEST(StateFormat, TextOfAFullStateIsThatOfTheFormerSerializer) {
  // Printed for full_state() by the serializer before the line table (commit 873c273).
  const std::string want =
      "torqued-state 2\n"
      "identity engine_id=1 cylinders=4 bore_m=0.0825 stroke_m=0.086 wheel=60-2 teeth=58\n"
      "friction -23.859999999999999 0.0024499999999999999 -5.2000000000000002e-06 -0.0046699999999999997\n"
      "friction_idle 1.4999999999999998 812.25\n"
      "friction_residual 0.31234567890123455 87\n"
      "tooth_corrections 6 0 0 0 0.00071234567890123446 0 -1e-300\n"
      "fuel_model 0.38123456789012344 -12.5 0.0001 -2.4999999999999999e-07 -2.4999999999999999e-07 0.75 "
      "4.0000000000000009 4294967295 0.7345678901234568 321\n"
      "crank_error_var 2.2250738585072014e-308\n"
      "inertia 1.0873456789012346 4321.5 0.14672199999999999\n"
      "saved_at_t_ns -9223372036854775807\n"
      "checksum crc32 1e12591c\n";
  const std::string text = serialize_state(full_state(), kIdentity);
  EXPECT_EQ(text, want);
  std::string err;
  const auto back = parse_state(text, "full", &err);
  ASSERT_TRUE(back) << err;
  EXPECT_EQ(serialize_state(*back, kIdentity), want) << "parse + serialize gives the same text";
}

TEST(StateFormat, APhysicsFuelModelLineRoundTripsExactly) {
  // GIVEN a state whose fuel model carries the physics part (parameters, covariance, cell counts) WHEN it is
  // written and read back THEN every number is the same, the line carries "physics", and a count beyond a
  // cell's 16 bits is refused.
  LearnedState s = full_state();
  FuelTorqueState f = *s.fuel;
  f.physics = true;
  f.theta = {0.93123456789012345, 0.081, 5123.25, 31000.5};
  for (std::size_t i = 0; i < f.p.size(); ++i)
    f.p[i] = (i % 5 == 0) ? 1e-3 * static_cast<double>(i + 1) : 0.0;
  for (std::size_t i = 0; i < f.cells.size(); ++i) f.cells[i] = static_cast<std::uint16_t>(i * 4000);
  f.pxb = {1.5e-3, -2.25e-4, 12.5, -40.25};
  s.fuel = f;
  const std::string text = serialize_state(s, kIdentity);
  EXPECT_NE(text.find(" 321 physics 0.93123456789012"), std::string::npos) << text;
  std::string err;
  const auto back = parse_state(text, "physics", &err);
  ASSERT_TRUE(back) << err;
  ASSERT_TRUE(back->fuel);
  EXPECT_TRUE(back->fuel->physics);
  EXPECT_EQ(back->fuel->theta, f.theta);
  EXPECT_EQ(back->fuel->p, f.p);
  EXPECT_EQ(back->fuel->cells, f.cells);
  EXPECT_EQ(back->fuel->pxb, f.pxb);
  EXPECT_EQ(serialize_state(*back, kIdentity), text);
  // A physics line written before the shared-bias cross-covariance was added (the line ends after the cell
  // counts) loads with it 0.
  const auto fl = text.find("\nfuel_model");
  std::string line = text.substr(fl + 1, text.find('\n', fl + 1) - fl - 1);
  for (int k = 0; k < 4; ++k) line.erase(line.rfind(' '));
  const auto o = parse_state("torqued-state 1\n" + line + "\n", "older", &err);  // version 1: no checksum
  ASSERT_TRUE(o) << err;
  ASSERT_TRUE(o->fuel);
  EXPECT_EQ(o->fuel->cells, f.cells);
  EXPECT_EQ(o->fuel->pxb, (std::array<double, 4>{}));
  std::string big = text.substr(0, text.find("\nchecksum"));
  big.replace(big.rfind(" 60000"), 6, " 65536");
  EXPECT_FALSE(parse_state(big + "\n", "big", &err)) << "a cell count beyond 16 bits";
}

TEST(StateFormat, OlderFilesLoadAndAreRewrittenInTheCurrentForm) {
  // Version 1 (no identity, no checksum), and a fuel_model line without its two trailing values (read as 0).
  std::string err;
  const auto v1 = parse_state(
      "torqued-state 1\nfriction 1 0 0 0\nfuel_model 0.4 10 1e-4 0 0 1 4 100\nsaved_at_t_ns 5\n", "v1", &err);
  ASSERT_TRUE(v1) << err;
  EXPECT_EQ(v1->version, 1);
  ASSERT_TRUE(v1->fuel);
  EXPECT_EQ(v1->fuel->cover.sd, 0.0);
  EXPECT_EQ(v1->fuel->cover.n, 0u);
  const std::string text = serialize_state(*v1, kIdentity);
  EXPECT_NE(text.find("\nfuel_model 0.40000000000000002 10 0.0001 0 0 1 4 100 0 0\n"), std::string::npos)
      << text;
  // A version 2 file with only the first lines (before fuel_model and the others were added) loads as such.
  LearnedState early;
  early.friction = std::array<double, 4>{1.0, 0.0, 0.0, 0.0};
  early.tooth_corrections_rad.assign(58, 0.0);
  const auto p = parse_state(serialize_state(early, kIdentity), "early", &err);
  ASSERT_TRUE(p) << err;
  EXPECT_EQ(p->identity, kIdentity);
  EXPECT_EQ(p->tooth_corrections_rad.size(), 58u);
  EXPECT_FALSE(p->fuel || p->crank_error_var || p->inertia || p->friction_idle || p->friction_residual);
}

TEST(StateFormat, ATableOrIdentityLongerThanTheRecordIsRefused) {
  std::string err;
  EXPECT_FALSE(parse_state("torqued-state 1\ntooth_corrections 721 0\n", "long", &err));
  EXPECT_NE(err.find("(a count <= 720)"), std::string::npos) << err;
  EXPECT_FALSE(parse_state("torqued-state 2\nidentity " + std::string(300, 'x') + "\n", "id", &err));
  EXPECT_NE(err.find("identity longer than 255"), std::string::npos) << err;
}

}  // namespace
}  // namespace torqued
