// The committed config/demo.dbc, parsed by io/'s DBC parser, decodes the simulator's frames to the same
// values the simulator packed (both byte orders), and its signal ranges match the codec table.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "can_codec.hpp"
#include "dbc.hpp"
#include "sim_fixture.hpp"

namespace torqued::sim {
namespace {

TEST(SimDbcIo, DemoDbcParsesAndDecodesSimulatorFrames) {
  const auto res = DbcDatabase::parse_file(std::string(TORQUED_SOURCE_DIR) + "/config/demo.dbc");
  for (const auto& e : res.errors) ADD_FAILURE() << e;
  for (const auto& w : res.warnings) ADD_FAILURE() << "warning: " << w;
  ASSERT_TRUE(res.db.has_value());
  const DbcDatabase& db = *res.db;
  for (const auto& m : demo_messages()) {
    const DbcMessage* dm = db.find(m.id, false);
    ASSERT_NE(dm, nullptr) << m.name;
    EXPECT_EQ(dm->name, m.name);
    EXPECT_EQ(dm->dlc, m.dlc);
    ASSERT_EQ(dm->signals.size(), m.signals.size()) << m.name;
    for (const auto& s : m.signals) {
      const DbcSignal* ds = dm->find(s.name);
      ASSERT_NE(ds, nullptr) << s.name;
      EXPECT_EQ(ds->little_endian, s.little_endian) << s.name;
      EXPECT_EQ(ds->is_signed, s.is_signed) << s.name;
      EXPECT_DOUBLE_EQ(ds->factor, s.factor) << s.name;
      EXPECT_DOUBLE_EQ(ds->min, s.min) << s.name;
      EXPECT_DOUBLE_EQ(ds->max, s.max) << s.name;
      EXPECT_EQ(ds->unit, s.unit) << s.name;
    }
  }
  const auto& r = test::run("fuel_cut", 1.5);
  int decoded = 0;
  for (const CanFrame& f : r.out.can) {
    const MessageDef* m = find_message(f.id);
    const DbcMessage* dm = db.find(f.id, false);
    ASSERT_TRUE(m && dm);
    for (const auto& s : m->signals) {
      const double mine = unpack_signal(s, f.data.data());
      const double theirs = dm->find(s.name)->decode(f.data.data(), f.len);
      ASSERT_NEAR(theirs, mine, 1e-9 * std::max(1.0, std::abs(mine))) << m->name << "." << s.name;
      ++decoded;
    }
  }
  EXPECT_GT(decoded, 1000);
  // The FuelCutoff value table made it through.
  const DbcSignal* cut = db.find(kEngine2Id, false)->find("FuelCutoff");
  ASSERT_NE(cut->value_name(1), nullptr);
  EXPECT_EQ(*cut->value_name(1), "Active");
}

}  // namespace
}  // namespace torqued::sim
