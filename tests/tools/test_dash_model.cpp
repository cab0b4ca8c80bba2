// torque-dash's model and the method registry (idl/methods.hpp): the page's method labels and its in-cycle
// methods come from the server's snapshot (no ids in dash.js), and the model places only the registry's
// in-cycle methods on the crank angle.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <set>

#include "dash/dash_model.hpp"

namespace {
using namespace torqued;

torque_EstimatorTorque estimate(std::uint8_t method, std::int64_t t_ns) {
  torque_EstimatorTorque s{};
  s.engine_id = 1;
  s.method = method;
  s.source_t_ns = t_ns;
  s.value_nm = 100.0 + method;
  return s;
}

TEST(DashModel, SnapshotCarriesTheMethodRegistry) {
  dash::Model m;
  dash::Cursor c;
  const auto j = nlohmann::json::parse(m.delta(c));
  ASSERT_TRUE(j.contains("methods"));
  ASSERT_EQ(j["methods"].size(), static_cast<std::size_t>(dds::kMethodCount));
  for (const auto& e : j["methods"]) {
    const dds::MethodInfo* info = dds::method_info(e["id"].get<std::uint8_t>());
    ASSERT_NE(info, nullptr);
    EXPECT_EQ(e["name"].get<std::string>(), info->name);
    EXPECT_EQ(e["label"].get<std::string>(), info->label);
    EXPECT_EQ(e["in_cycle"].get<bool>(), info->in_cycle);
  }
  EXPECT_EQ(j["methods"][torque_METHOD_KALMAN]["label"], "Kalman");
  EXPECT_EQ(j["methods"][torque_METHOD_FOURIER]["label"], "Fourier");
  EXPECT_EQ(j["methods"][torque_METHOD_UIO]["domain"], "time");
  EXPECT_EQ(nlohmann::json::parse(dash::methods_json()), j["methods"]);  // GET /api/methods: the same
  dash::Cursor again = c;
  EXPECT_EQ(m.delta(again), "");  // nothing new: no message (the registry is static data of the snapshot)
}

TEST(DashModel, PlacesOnlyInCycleMethodsOfTheRegistry) {
  dash::Model m;
  for (int id = 0; id < dds::kMethodCount; ++id) m.add(estimate(static_cast<std::uint8_t>(id), 1'500'000));
  torque_CrankState a{}, b{};
  a.engine_id = b.engine_id = 1;
  a.sync = b.sync = 2;
  a.phase_known = b.phase_known = true;
  a.tooth = 10, b.tooth = 12;
  a.source_t_ns = 1'000'000, b.source_t_ns = 2'000'000;
  a.angle_rad = 1.0, b.angle_rad = 1.2;
  m.add(a);
  m.add(b);
  const dash::EngineView& v = m.engines().at(1);
  std::set<int> placed;
  for (std::uint64_t i = v.incycle.first(); i < v.incycle.total(); ++i) placed.insert(v.incycle.at(i).method);
  std::set<int> expected;
  for (const auto& e : dds::kMethods)
    if (e.in_cycle) expected.insert(e.id);
  EXPECT_EQ(placed, expected);
  EXPECT_EQ(expected, (std::set<int>{torque_METHOD_KALMAN, torque_METHOD_FOURIER}));
  EXPECT_EQ(v.unplaced, 0u);
  // Halfway in time between the anchors: halfway in angle (1.1 rad = 63.03°), within the 0.01° print step.
  EXPECT_NEAR(v.incycle.at(v.incycle.first()).angle_deg, 1.1 * 180.0 / 3.141592653589793, 1e-9);
}

TEST(DashModel, StatusCarriesTheFuelModelsLearnedCells) {
  // GIVEN a status whose fuel model rests on 42 references, learned in two speed x MAP cells
  dash::Model m;
  torque_DaemonStatus s{};
  s.engine_id = 1;
  s.fuel_references = 42;
  s.fuel_cells = (1u << (4 * 1 + 2)) | (1u << (4 * 2 + 3));  // 1500-2500 rpm x 60-80 kPa, 2500-3500 x >= 80
  m.add(s);
  dash::Cursor c;
  const auto j = nlohmann::json::parse(m.delta(c));
  // THEN the page gets both (it draws the cells grid from the bit mask)
  ASSERT_TRUE(j.contains("engines")) << j.dump();
  const auto& st = j["engines"]["1"]["status"];
  EXPECT_EQ(st["fuel_references"].get<int>(), 42);
  EXPECT_EQ(st["fuel_cells"].get<int>(), (1 << 6) | (1 << 11));
}

TEST(DashModel, TorqueOutsideTheEnginesPhysicalRangeIsCountedNotPlotted) {
  // The demo engine (4 x 82.5 mm x 86 mm, 1.84 l): mean |T| <= 50 bar x Vd / 4 pi = 732 N m, instantaneous
  // <= 4 x 300 bar x piston area x half the stroke = 27.6 kN m (idl/physical_range.hpp).
  dash::Geometry g;
  g.range = dds::torque_range(4, 0.0825, 0.086);
  EXPECT_NEAR(g.range.mean_nm,
              50e5 * 4 * 3.141592653589793 / 4 * 0.0825 * 0.0825 * 0.086 / (4 * 3.141592653589793), 1e-9);
  dash::Model m({}, g);
  torque_EngineTorque e{};
  e.engine_id = 1;
  e.kind = torque_KIND_CYCLE;
  e.fused_nm = e.brake_nm = 1e9;  // a foreign plain-DDS writer's value, quality 0
  m.add(e);
  e.fused_nm = e.brake_nm = 80.0;
  m.add(e);
  m.add(estimate(torque_METHOD_KALMAN, 1'000'000));  // in-cycle 104 N m: plausible (waits for its anchor)
  torque_EstimatorTorque k = estimate(torque_METHOD_KALMAN, 1'100'000);
  k.value_nm = -1e7;  // beyond any instantaneous torque of this engine
  m.add(k);
  const dash::EngineView& v = m.engines().at(1);
  EXPECT_EQ(v.out_of_range, 2u);
  EXPECT_EQ(v.torque.total(), 1u) << "only the plausible EngineTorque is plotted";
  EXPECT_EQ(v.pending.size(), 1u);
  dash::Cursor c;
  const auto j = nlohmann::json::parse(m.delta(c));
  EXPECT_EQ(j["engines"]["1"]["out_of_range"], 2);
}

}  // namespace
