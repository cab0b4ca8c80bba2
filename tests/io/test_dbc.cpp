// DBC parser on snippets written in the styles of Vector CANdb++, cantools and Kvaser Database Editor
// exports, plus bit extraction checked against hand-packed payloads.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <random>

#include "dbc.hpp"

namespace torqued {
namespace {

// CANdb++ style: NS_ block, BS_, BU_, attribute definitions, multiplexing, CRLF, comments spanning lines.
constexpr const char* kCandb =
    "VERSION \"\"\r\n\r\n\r\nNS_ : \r\n\tNS_DESC_\r\n\tCM_\r\n\tBA_DEF_\r\n\tBA_\r\n\tVAL_\r\n\tCAT_DEF_\r\n"
    "\tCAT_\r\n\tFILTER\r\n\tBA_DEF_DEF_\r\n\tEV_DATA_\r\n\tENVVAR_DATA_\r\n\tSGTYPE_\r\n\tSGTYPE_VAL_\r\n"
    "\tBA_DEF_SGTYPE_\r\n\tBA_SGTYPE_\r\n\tSIG_TYPE_REF_\r\n\tVAL_TABLE_\r\n\tSIG_GROUP_\r\n\tSIG_VALTYPE_"
    "\r\n"
    "\tSIGTYPE_VALTYPE_\r\n\tBO_TX_BU_\r\n\tBA_DEF_REL_\r\n\tBA_REL_\r\n\tBA_DEF_DEF_REL_\r\n\tBU_SG_REL_\r\n"
    "\tBU_EV_REL_\r\n\tBU_BO_REL_\r\n\tSG_MUL_VAL_\r\n\r\nBS_:\r\n\r\nBU_: ECU DYNO Logger\r\n"
    "VAL_TABLE_ OnOff 1 \"On\" 0 \"Off\" ;\r\n\r\n\r\n"
    "BO_ 256 ENGINE_1: 8 ECU\r\n"
    " SG_ EngineSpeed : 0|16@1+ (0.25,0) [0|16383.75] \"rpm\"  Logger,DYNO\r\n"
    " SG_ MAP : 16|16@1+ (0.01,0) [0|655.35] \"kPa\"  Logger\r\n"
    " SG_ IntakeAirTemp : 32|8@1- (1,0) [-40|125] \"degC\"  Logger\r\n"
    " SG_ Throttle : 40|8@1+ (0.4,0) [0|100] \"%\"  Logger\r\n\r\n"
    "BO_ 2147484160 EXT_MUX: 8 ECU\r\n"
    " SG_ Page M : 0|8@1+ (1,0) [0|255] \"\"  Logger\r\n"
    " SG_ PageA m0 : 8|16@1+ (1,0) [0|65535] \"\"  Logger\r\n"
    " SG_ PageB m1 : 8|16@1- (0.5,-10) [-1000|1000] \"Nm\"  Logger\r\n\r\n"
    "BO_ 3221225472 VECTOR__INDEPENDENT_SIG_MSG: 0 Vector__XXX\r\n"
    " SG_ Orphan : 0|8@1+ (1,0) [0|0] \"\" Vector__XXX\r\n\r\n"
    "CM_ \"Database comment\";\r\n"
    "CM_ BU_ ECU \"Engine control unit\";\r\n"
    "CM_ BO_ 256 \"Engine message one,\r\nspans two lines\";\r\n"
    "CM_ SG_ 256 MAP \"Manifold absolute pressure\";\r\n"
    "BA_DEF_ BO_  \"GenMsgCycleTime\" INT 0 65535;\r\n"
    "BA_DEF_ SG_  \"GenSigStartValue\" INT 0 0;\r\n"
    "BA_DEF_  \"BusType\" STRING ;\r\n"
    "BA_DEF_DEF_  \"GenMsgCycleTime\" 0;\r\n"
    "BA_DEF_DEF_  \"BusType\" \"CAN\";\r\n"
    "BA_ \"BusType\" \"CAN\";\r\n"
    "BA_ \"GenMsgCycleTime\" BO_ 256 10;\r\n"
    "VAL_ 2147484160 Page 0 \"A\" 1 \"B\" ;\r\n";

// cantools style: Motorola signals, VERSION with text, no NS_ entries, minimal BU_.
constexpr const char* kCantools = R"(VERSION "1.0"

NS_ :

BS_:

BU_: ECU

BO_ 257 ENGINE_2: 8 ECU
 SG_ MAF : 7|16@0+ (0.01,0) [0|655.35] "g/s" Vector__XXX
 SG_ FuelMass : 23|16@0+ (0.001,0) [0|65.535] "mg" Vector__XXX
 SG_ SparkAdvance : 39|8@0- (0.5,0) [-64|63.5] "deg" Vector__XXX
 SG_ FuelCutoff : 40|1@0+ (1,0) [0|1] "" Vector__XXX

CM_ SG_ 257 FuelCutoff "1 = fuel cut-off active";
VAL_ 257 FuelCutoff 1 "Active" 0 "Inactive" ;
)";

// Kvaser style: attributes first, signals with receivers list, extended id, SIG_VALTYPE_.
constexpr const char* kKvaser = R"(VERSION "HINBUIBBBBBBBBBBBBBBBBBBBBBBBBBBBBBBBBBB/4/%%%/4/'%**4NNN///"

NS_ :
	NS_DESC_
	CM_
	BA_DEF_
	BA_
	VAL_

BS_:

BU_: Dyno Bench
BO_ 2566848512 DYNO_1: 8 Dyno
 SG_ LoadTorque : 0|16@1- (0.1,0) [-3000|3000] "Nm" Bench
 SG_ DynoSpeed : 16|16@1+ (1,0) [0|10000] "rpm" Bench

BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","J1939PG";
BA_DEF_DEF_ "VFrameFormat" "";
BA_ "VFrameFormat" BO_ 2566848512 1;
SIG_VALTYPE_ 2566848512 DynoSpeed : 0;
)";

TEST(Dbc, CandbStyle) {
  const auto r = DbcDatabase::parse_string(kCandb, "candb.dbc");
  ASSERT_TRUE(r.db.has_value()) << (r.errors.empty() ? "" : r.errors.front());
  const auto& db = *r.db;
  EXPECT_EQ(db.nodes().size(), 3u);
  ASSERT_EQ(db.messages().size(), 2u);  // the independent-signal pseudo message is dropped
  const DbcMessage* e1 = db.find(0x100, false);
  ASSERT_NE(e1, nullptr);
  EXPECT_EQ(e1->name, "ENGINE_1");
  EXPECT_EQ(e1->dlc, 8);
  EXPECT_EQ(e1->transmitter, "ECU");
  EXPECT_EQ(e1->comment, "Engine message one,\nspans two lines");
  const DbcSignal* map = e1->find("MAP");
  ASSERT_NE(map, nullptr);
  EXPECT_EQ(map->start_bit, 16);
  EXPECT_EQ(map->length, 16);
  EXPECT_TRUE(map->little_endian);
  EXPECT_FALSE(map->is_signed);
  EXPECT_DOUBLE_EQ(map->factor, 0.01);
  EXPECT_DOUBLE_EQ(map->max, 655.35);
  EXPECT_EQ(map->unit, "kPa");
  EXPECT_EQ(map->comment, "Manifold absolute pressure");
  EXPECT_EQ(e1->find("EngineSpeed")->receivers.size(), 2u);
  // Payload: speed 3000 rpm = 12000 = 0x2EE0; MAP 101.3 kPa = 10130 = 0x2792; IAT -5 = 0xFB; throttle 40 % =
  // 100
  const std::uint8_t d[8] = {0xE0, 0x2E, 0x92, 0x27, 0xFB, 100, 0, 0};
  EXPECT_DOUBLE_EQ(e1->find("EngineSpeed")->decode(d, 8), 3000.0);
  EXPECT_NEAR(map->decode(d, 8), 101.30, 1e-9);
  EXPECT_DOUBLE_EQ(e1->find("IntakeAirTemp")->decode(d, 8), -5.0);
  EXPECT_DOUBLE_EQ(e1->find("Throttle")->decode(d, 8), 40.0);
  // Multiplexed, extended id
  const DbcMessage* mux = db.find(0x200, true);
  ASSERT_NE(mux, nullptr);
  ASSERT_GE(mux->multiplexor, 0);
  const DbcSignal* a = mux->find("PageA");
  const DbcSignal* b = mux->find("PageB");
  EXPECT_EQ(a->mux, DbcSignal::Mux::kMultiplexed);
  EXPECT_EQ(b->mux_value, 1u);
  const std::uint8_t page1[8] = {1, 0x2C, 0x01, 0, 0, 0, 0, 0};  // raw 300 -> 300*0.5-10 = 140
  EXPECT_FALSE(mux->signal_present(*a, page1, 8));
  EXPECT_TRUE(mux->signal_present(*b, page1, 8));
  EXPECT_DOUBLE_EQ(b->decode(page1, 8), 140.0);
  ASSERT_NE(mux->find("Page")->value_name(1), nullptr);
  EXPECT_EQ(*mux->find("Page")->value_name(1), "B");
}

TEST(Dbc, CantoolsStyleMotorola) {
  const auto r = DbcDatabase::parse_string(kCantools, "cantools.dbc");
  ASSERT_TRUE(r.db.has_value()) << (r.errors.empty() ? "" : r.errors.front());
  EXPECT_EQ(r.db->version(), "1.0");
  const DbcMessage* m = r.db->find("ENGINE_2");
  ASSERT_NE(m, nullptr);
  const DbcSignal* maf = m->find("MAF");
  EXPECT_FALSE(maf->little_endian);
  // Big-endian: MAF 12.34 g/s = 1234 = 0x04D2 in bytes 0..1 (MSB first); FuelMass 20.5 mg = 20500 = 0x5014;
  // SparkAdvance -10 deg = raw -20 = 0xEC in byte 4; FuelCutoff = bit 7 of byte 5 (start 40 = byte 5 bit 0).
  const std::uint8_t d[8] = {0x04, 0xD2, 0x50, 0x14, 0xEC, 0x01, 0, 0};
  EXPECT_NEAR(maf->decode(d, 8), 12.34, 1e-9);
  EXPECT_NEAR(m->find("FuelMass")->decode(d, 8), 20.5, 1e-9);
  EXPECT_DOUBLE_EQ(m->find("SparkAdvance")->decode(d, 8), -10.0);
  EXPECT_DOUBLE_EQ(m->find("FuelCutoff")->decode(d, 8), 1.0);
  EXPECT_EQ(maf->bytes_needed(), 2u);
  EXPECT_EQ(m->find("SparkAdvance")->bytes_needed(), 5u);
  EXPECT_EQ(m->find("FuelCutoff")->value_table.size(), 2u);
  EXPECT_EQ(m->find("FuelCutoff")->comment, "1 = fuel cut-off active");
}

/// The payload bytes a Motorola signal needs, against the bit-by-bit walk down the sawtooth numbering (MSB at
/// start_bit, bit 0 of a byte followed by bit 7 of the next), for every start bit of a 64-byte frame and
/// every length.
TEST(Dbc, MotorolaBytesNeededMatchesTheSawtoothWalk) {
  for (int start = 0; start < 512; ++start)
    for (int length = 1; length <= 64; ++length) {
      int b = start;
      for (int k = 1; k < length; ++k) b = (b % 8 == 0) ? b + 15 : b - 1;
      DbcSignal s;
      s.start_bit = static_cast<std::uint16_t>(start);
      s.length = static_cast<std::uint16_t>(length);
      s.little_endian = false;
      ASSERT_EQ(s.bytes_needed(), static_cast<std::size_t>(std::max(b, start) / 8 + 1))
          << start << " " << length;
    }
}

TEST(Dbc, KvaserStyleExtendedAndWarnings) {
  const auto r = DbcDatabase::parse_string(kKvaser, "kvaser.dbc");
  ASSERT_TRUE(r.db.has_value()) << (r.errors.empty() ? "" : r.errors.front());
  const DbcMessage* m = r.db->find("DYNO_1");
  ASSERT_NE(m, nullptr);
  EXPECT_TRUE(m->extended);
  EXPECT_EQ(m->id, 0x18FF0000u);  // 2566848512 = 0x80000000 | 0x18FF0000 (J1939-like)
  const std::uint8_t d[8] = {0x9C, 0xFF, 0xB8, 0x0B, 0, 0, 0, 0};  // -100 -> -10.0 Nm; 3000 rpm
  EXPECT_DOUBLE_EQ(m->find("LoadTorque")->decode(d, 8), -10.0);
  EXPECT_DOUBLE_EQ(m->find("DynoSpeed")->decode(d, 8), 3000.0);
  EXPECT_TRUE(r.warnings.empty()) << ::testing::PrintToString(r.warnings);  // SIG_VALTYPE_ 0 is understood
  EXPECT_EQ(m->find("DynoSpeed")->value_type, DbcSignal::ValueType::kInteger);
}

TEST(Dbc, ErrorsNameFileAndLineAndParsingContinues) {
  constexpr const char* bad =
      "VERSION \"\"\n"
      "BO_ 256 A: 8 ECU\n"
      " SG_ Good : 0|8@1+ (1,0) [0|255] \"\" X\n"
      " SG_ Broken : 8|8@2+ (1,0) [0|255] \"\" X\n"
      "BO_ 256 B: 8 ECU\n"
      " SG_ Long : 0|65@1+ (1,0) [0|1] \"\" X\n"
      "BO_ 4096 C: 8 ECU\n"
      "CM_ SG_ 256 Good \"never closed;\n"
      "BO_ 513 D: 8 ECU\n";
  const auto r = DbcDatabase::parse_string(bad, "bad.dbc");
  // THEN each bad statement is one error naming file and line; the signals of the skipped message B are not
  // reported again; the rest loads
  ASSERT_TRUE(r.db.has_value());
  ASSERT_EQ(r.errors.size(), 3u) << ::testing::PrintToString(r.errors);
  EXPECT_NE(r.errors[0].find("bad.dbc:4: signal A.Broken: expected 'SG_"), std::string::npos) << r.errors[0];
  EXPECT_NE(r.errors[1].find("bad.dbc:5: message B (id 256 = 0x100): duplicate id"), std::string::npos)
      << r.errors[1];
  EXPECT_NE(r.errors[2].find("bad.dbc:8: statement not terminated"), std::string::npos) << r.errors[2];
  ASSERT_NE(r.db->find("A"), nullptr);
  EXPECT_EQ(r.db->find("A")->signals.size(), 1u);
  EXPECT_EQ(r.db->find("B"), nullptr);
  EXPECT_NE(r.db->find("D"), nullptr);    // parsing resumed after the unclosed string
  const DbcMessage* c = r.db->find("C");  // 4096 without bit 31: a 29-bit id, with a warning
  ASSERT_NE(c, nullptr);
  EXPECT_TRUE(c->extended);
  EXPECT_EQ(c->id, 4096u);
  EXPECT_NE(r.affecting("A", "Broken"), nullptr);
  EXPECT_EQ(r.affecting("A", "Good"), nullptr);
  EXPECT_NE(r.affecting("B", "Long"), nullptr);
}

TEST(Dbc, UnterminatedCommentIsReported) {
  const auto r = DbcDatabase::parse_string("BO_ 1 A: 1 X\nCM_ BO_ 1 \"open\n", "u.dbc");
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].find("u.dbc:2: statement not terminated"), std::string::npos) << r.errors[0];
}

TEST(Dbc, RawExtractionEdgeCases) {
  DbcSignal s;
  s.start_bit = 0;
  s.length = 64;
  s.is_signed = true;
  const std::uint8_t ff[8] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
  EXPECT_EQ(s.raw(ff, 8), -1);
  s.length = 12;
  s.start_bit = 4;
  EXPECT_EQ(s.raw(ff, 8), -1);
  s.is_signed = false;
  EXPECT_EQ(s.raw(ff, 8), 0xFFF);
  // Motorola 12-bit signal starting at bit 3 of byte 0 (MSB) spanning into byte 1 upper bits
  s.little_endian = false;
  s.start_bit = 3;
  s.length = 12;
  const std::uint8_t d[2] = {0x0A, 0xBC};  // bits: byte0 low nibble A, byte1 BC -> 0xABC
  EXPECT_EQ(s.raw(d, 2), 0xABC);
  EXPECT_EQ(s.bytes_needed(), 2u);
}

TEST(Dbc, WordAtATimeExtractionEqualsTheBitwiseDefinition) {
  // GIVEN every start bit of a 64-byte CAN FD payload, every length 1..64, both byte orders, signed and
  // unsigned, random payloads and payloads cut short (bytes past len read as 0)
  std::mt19937_64 rng(7);
  std::uint8_t d[64];
  int checked = 0;
  for (int start = 0; start < 512; ++start)
    for (int length = 1; length <= 64; ++length)
      for (int order = 0; order < 2; ++order) {
        DbcSignal s;
        s.start_bit = static_cast<std::uint16_t>(start);
        s.length = static_cast<std::uint16_t>(length);
        s.little_endian = order == 0;
        s.is_signed = ((start + length) & 1) != 0;
        for (auto& b : d) b = static_cast<std::uint8_t>(rng());
        const std::size_t len = (start % 5 == 0) ? static_cast<std::size_t>(rng() % 65) : 64u;
        // THEN the fast path gives the bitwise definition's value
        ASSERT_EQ(s.raw(d, len), s.raw_bitwise(d, len))
            << "start " << start << " length " << length << (s.little_endian ? " Intel" : " Motorola")
            << " len " << len;
        ++checked;
      }
  EXPECT_EQ(checked, 512 * 64 * 2);
}

TEST(Dbc, MutatedFilesNeverCrash) {
  // Random edits of the three style samples: the parser reports errors or warnings, never crashes or hangs.
  std::mt19937 rng(5);
  for (const char* sample : {kCandb, kCantools, kKvaser}) {
    for (int i = 0; i < 300; ++i) {
      std::string text = sample;
      for (int k = 0; k < 5; ++k) {
        const std::size_t pos = rng() % text.size();
        if (rng() % 2)
          text[pos] = "\"|;:@+-()[], \nM0123456789abcdef_"[rng() % 32];
        else
          text.erase(pos, 1 + rng() % 8);
      }
      const auto r = DbcDatabase::parse_string(text, "mutated.dbc");
      if (r.db) {
        for (const auto& m : r.db->messages()) {
          for (const auto& s : m.signals) EXPECT_LE(s.bytes_needed(), 64u);
        }
      }
    }
  }
}

TEST(Dbc, DemoDbcParsesWhenPresent) {
  const std::string path = std::string(TORQUED_SOURCE_DIR) + "/config/demo.dbc";
  const auto r = DbcDatabase::parse_file(path);
  if (!r.errors.empty() && r.errors[0].find("cannot open") != std::string::npos)
    GTEST_SKIP() << "no " << path << " yet";
  ASSERT_TRUE(r.db.has_value()) << r.errors.front();
  for (const char* name : {"ENGINE_1", "ENGINE_2", "ENGINE_3", "DYNO_1"})
    EXPECT_NE(r.db->find(name), nullptr) << name;
}

// The five defects that made production DBC files (opendbc's) refused whole, one each, with good messages
// around them.
constexpr const char* kVehicle =
    "VERSION \"\"\n"                                        // 1
    "BU_: ECU X\n"                                          // 2
    "BO_ 100 GOOD_1: 8 ECU\n"                               // 3
    " SG_ Speed : 0|16@1+ (0.1,0) [0|6553.5] \"km/h\" X\n"  // 4
    "BO_ 419364350 NO_FLAG_29BIT: 8 ECU\n"                  // 5: 29-bit id, no bit 31
    " SG_ Temp : 0|8@1+ (1,-40) [-40|215] \"degC\" X\n"     // 6
    "BO_ 200 2ND_GEAR: 8 ECU\n"                             // 7: name starts with a digit
    " SG_ A : 0|8@1+ (1,0) [0|255] \"\" X\n"                // 8
    " SG_ B : 8|8@1+ (1,0) [0|255] \"\" X\n"                // 9
    "BO_ 300 MUXED: 8 ECU\n"                                // 10
    " SG_ Page m : 0|8@1+ (1,0) [0|255] \"\" X\n"           // 11: 'm' for 'M'
    " SG_ P0 m0 : 8|8@1+ (1,0) [0|255] \"\" X\n"            // 12
    " SG_ P1 m1 : 8|8@1+ (2,0) [0|510] \"\" X\n"            // 13
    "BO_ 400 NAMES: 8 ECU\n"                                // 14
    " SG_ 12V_Battery : 0|8@1+ (0.1,0) [0|25.5] \"V\" X\n"  // 15: name starts with a digit
    " SG_ Ok : 8|8@1+ (1,0) [0|255] \"\" X\n"               // 16
    "CM_ SG_ 100 \"comment without the signal's name\";\n"  // 17: CM_ without object name
    "VAL_ 100 Speed 0 \"stopped\" 1 \"moving\"\n"           // 18: VAL_ without ';'
    "CM_ BO_ 100 \"read after the VAL_\";\n"                // 19
    "VAL_ 300 Page 0 \"zero\" 1 \"one\" ;\n";               // 20

TEST(DbcVehicle, EachDefectIsOneLineNamedAndTheRestLoads) {
  const auto r = DbcDatabase::parse_string(kVehicle, "car.dbc");
  ASSERT_TRUE(r.db.has_value());
  // THEN one error per bad statement, with file:line and what was expected
  ASSERT_EQ(r.errors.size(), 3u) << ::testing::PrintToString(r.errors);
  EXPECT_NE(r.errors[0].find("car.dbc:7: message name '2ND_GEAR' starts with a digit"), std::string::npos)
      << r.errors[0];
  EXPECT_NE(r.errors[1].find("car.dbc:15: signal NAMES.12V_Battery: signal name '12V_Battery' starts with a "
                             "digit"),
            std::string::npos)
      << r.errors[1];
  EXPECT_NE(r.errors[2].find("car.dbc:17: expected 'CM_ SG_ <id> <signal> \"<text>\";'"), std::string::npos)
      << r.errors[2];
  // AND the tolerable ones are warnings with file:line
  std::string w;
  for (const auto& x : r.warnings) w += x + "\n";
  EXPECT_NE(w.find("car.dbc:5: message NO_FLAG_29BIT"), std::string::npos) << w;
  EXPECT_NE(w.find("car.dbc:11: signal Page: multiplex indicator 'm'"), std::string::npos) << w;
  EXPECT_NE(w.find("car.dbc:18: expected ';'"), std::string::npos) << w;
  // AND every other message loads and decodes
  const DbcDatabase& db = *r.db;
  EXPECT_EQ(db.messages().size(), 4u);
  EXPECT_EQ(db.find("2ND_GEAR"), nullptr);
  const DbcMessage* j = db.find(419364350u, true);
  ASSERT_NE(j, nullptr);
  EXPECT_EQ(j->name, "NO_FLAG_29BIT");
  const DbcMessage* g = db.find("GOOD_1");
  ASSERT_NE(g, nullptr);
  EXPECT_EQ(g->comment, "read after the VAL_");
  ASSERT_EQ(g->find("Speed")->value_table.size(), 2u);
  const DbcMessage* mux = db.find("MUXED");
  ASSERT_NE(mux, nullptr);
  ASSERT_GE(mux->multiplexor, 0);
  const std::uint8_t page1[8] = {1, 21, 0, 0, 0, 0, 0, 0};
  EXPECT_FALSE(mux->signal_present(*mux->find("P0"), page1, 8));
  ASSERT_TRUE(mux->signal_present(*mux->find("P1"), page1, 8));
  EXPECT_DOUBLE_EQ(mux->find("P1")->decode(page1, 8), 42.0);
  EXPECT_EQ(mux->find("Page")->value_table.size(), 2u);
  ASSERT_NE(db.find("NAMES"), nullptr);
  EXPECT_EQ(db.find("NAMES")->signals.size(), 1u);
  // AND affecting() names the error behind a skipped signal (the daemon refuses only those it maps)
  ASSERT_NE(r.affecting("2ND_GEAR", "B"), nullptr);
  EXPECT_NE(r.affecting("2ND_GEAR", "B")->find("car.dbc:7:"), std::string::npos);
  ASSERT_NE(r.affecting("NAMES", "12V_Battery"), nullptr);
  EXPECT_EQ(r.affecting("NAMES", "Ok"), nullptr);
  EXPECT_EQ(r.affecting("GOOD_1", "Speed"), nullptr);
}

TEST(DbcVehicle, AnIdWithBit29Or30IsRefusedAndReportedUnmasked) {
  // 1073742000 = 0x400000B0: masking to 29 bits would silently make it the standard id 0xB0
  const auto r = DbcDatabase::parse_string(
      "BO_ 176 REAL_B0: 8 X\nBO_ 1073742000 BIT30: 8 X\n SG_ S : 0|8@1+ "
      "(1,0) [0|0] \"\" X\nCM_ BO_ 1073742000 \"c\";\n",
      "ids.dbc");
  ASSERT_EQ(r.errors.size(), 1u) << ::testing::PrintToString(r.errors);
  EXPECT_NE(r.errors[0].find("ids.dbc:2: message BIT30 (id 1073742000 = 0x400000b0): bit 29 or 30 set"),
            std::string::npos)
      << r.errors[0];
  EXPECT_TRUE(r.warnings.empty()) << ::testing::PrintToString(r.warnings);
  EXPECT_EQ(r.db->find(0xB0, false)->comment, "");  // the CM_ of the bad id did not land on 0xB0
  EXPECT_EQ(r.db->find("BIT30"), nullptr);
}

TEST(DbcVehicle, Unsigned64BitValuesAreExact) {
  const auto r = DbcDatabase::parse_string(
      "BO_ 1 U64: 8 X\n SG_ Intel : 0|64@1+ (1,0) [0|0] \"\" X\nBO_ 2 M64: 8 X\n SG_ Moto : 7|64@0+ (1,0) "
      "[0|0] \"\" X\n SG_ Moto56 : 7|56@0+ (1,0) [0|0] \"\" X\nVAL_ 1 Intel 18446744073709551615 \"all "
      "ones\" "
      "9223372036854775808 \"bit 63\" ;\n",
      "u64.dbc");
  ASSERT_TRUE(r.errors.empty()) << ::testing::PrintToString(r.errors);
  const DbcSignal& in = r.db->find("U64")->signals[0];
  const std::uint8_t hi[8] = {0x01, 0, 0, 0, 0, 0, 0, 0x80};  // 2^63 + 1
  EXPECT_EQ(in.raw_bits(hi, 8), 0x8000000000000001ull);
  EXPECT_DOUBLE_EQ(in.decode(hi, 8), 9223372036854775808.0);  // not -2^63
  const std::uint8_t ones[8] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
  EXPECT_EQ(in.raw_bits(ones, 8), ~std::uint64_t{0});
  EXPECT_DOUBLE_EQ(in.decode(ones, 8), 18446744073709551615.0);
  ASSERT_NE(in.value_name(in.raw(ones, 8)), nullptr);
  EXPECT_EQ(*in.value_name(in.raw(ones, 8)), "all ones");
  const std::uint8_t bit63[8] = {0, 0, 0, 0, 0, 0, 0, 0x80};
  ASSERT_NE(in.value_name(in.raw(bit63, 8)), nullptr);
  EXPECT_EQ(*in.value_name(in.raw(bit63, 8)), "bit 63");
  const DbcMessage* m = r.db->find("M64");
  const std::uint8_t be[8] = {0xFE, 0xDC, 0xBA, 0x98, 0x76, 0x54, 0x32, 0x10};
  EXPECT_EQ(m->find("Moto")->raw_bits(be, 8), 0xFEDCBA9876543210ull);
  EXPECT_GT(m->find("Moto")->decode(be, 8), 0.0);
  EXPECT_EQ(m->find("Moto56")->raw_bits(be, 8), 0xFEDCBA98765432ull);
}

TEST(DbcVehicle, IeeeFloatSignals) {
  const auto r = DbcDatabase::parse_string(
      "BO_ 10 F: 8 X\n SG_ F32 : 0|32@1- (1,0) [0|0] \"\" X\n SG_ F32M : 39|32@0- (2,1) [0|0] \"\" X\n"
      "BO_ 11 D: 8 X\n SG_ F64 : 0|64@1- (1,0) [0|0] \"\" X\n SG_ Wrong : 0|16@1+ (1,0) [0|0] \"\" X\n"
      "SIG_VALTYPE_ 10 F32 : 1;\nSIG_VALTYPE_ 10 F32M : 1;\nSIG_VALTYPE_ 11 F64 : 2;\n"
      "SIG_VALTYPE_ 11 Wrong : 1;\n",
      "f.dbc");
  ASSERT_EQ(r.errors.size(), 1u) << ::testing::PrintToString(r.errors);
  EXPECT_NE(r.errors[0].find("f.dbc:10: signal D.Wrong: SIG_VALTYPE_ 1 needs length 32"), std::string::npos)
      << r.errors[0];
  EXPECT_EQ(r.db->find("D")->find("Wrong"), nullptr);  // not decoded as an integer by mistake
  EXPECT_NE(r.affecting("D", "Wrong"), nullptr);
  const float a = -3.25f, b = 1234.5f;
  const double c = -1.5e300;
  std::uint8_t f[8]{}, d[8]{};
  std::memcpy(f, &a, 4);  // little-endian host (x86-64, aarch64): Intel byte order
  std::uint32_t bb = 0;
  std::memcpy(&bb, &b, 4);
  for (int i = 0; i < 4; ++i) f[4 + i] = static_cast<std::uint8_t>(bb >> (24 - 8 * i));  // Motorola
  std::memcpy(d, &c, 8);
  const DbcMessage* fm = r.db->find("F");
  EXPECT_EQ(fm->find("F32")->decode(f, 8), -3.25);
  EXPECT_EQ(fm->find("F32M")->decode(f, 8), 2.0 * 1234.5 + 1.0);
  EXPECT_EQ(r.db->find("D")->find("F64")->decode(d, 8), -1.5e300);
}

TEST(DbcVehicle, ExtendedMultiplexing) {
  // S0 selects S1 (0); S1 (itself a multiplexor, m0M) selects S2 at 1 and S3 at 2..3 or 5.
  const auto r = DbcDatabase::parse_string(
      "BO_ 100 EXT: 8 X\n SG_ S0 M : 0|4@1+ (1,0) [0|0] \"\" X\n SG_ S1 m0M : 4|4@1+ (1,0) [0|0] \"\" X\n"
      " SG_ S2 m1 : 8|8@1+ (1,0) [0|0] \"\" X\n SG_ S3 m2 : 8|8@1+ (1,0) [0|0] \"\" X\n"
      "SG_MUL_VAL_ 100 S1 S0 0-0;\nSG_MUL_VAL_ 100 S2 S1 1-1;\nSG_MUL_VAL_ 100 S3 S1 2-3, 5-5;\n",
      "x.dbc");
  ASSERT_TRUE(r.errors.empty()) << ::testing::PrintToString(r.errors);
  EXPECT_TRUE(r.warnings.empty()) << ::testing::PrintToString(r.warnings);  // SG_MUL_VAL_ understood
  const DbcMessage& m = *r.db->find("EXT");
  const DbcSignal &s1 = *m.find("S1"), &s2 = *m.find("S2"), &s3 = *m.find("S3");
  EXPECT_TRUE(s1.also_multiplexor);
  const auto payload = [](unsigned s0, unsigned s1) {
    return std::array<std::uint8_t, 8>{static_cast<std::uint8_t>(s0 | (s1 << 4)), 7, 0, 0, 0, 0, 0, 0};
  };
  auto p = payload(0, 1);
  EXPECT_TRUE(m.signal_present(s1, p.data(), 8));
  EXPECT_TRUE(m.signal_present(s2, p.data(), 8));
  EXPECT_FALSE(m.signal_present(s3, p.data(), 8));
  for (unsigned v : {2u, 3u, 5u}) {
    p = payload(0, v);
    EXPECT_FALSE(m.signal_present(s2, p.data(), 8)) << v;
    EXPECT_TRUE(m.signal_present(s3, p.data(), 8)) << v;
  }
  p = payload(0, 4);
  EXPECT_FALSE(m.signal_present(s3, p.data(), 8));
  p = payload(1, 1);  // S0 does not select S1: nothing below it is present
  EXPECT_FALSE(m.signal_present(s1, p.data(), 8));
  EXPECT_FALSE(m.signal_present(s2, p.data(), 8));
}

TEST(DbcVehicle, MultiplexedSignalsWithoutAMultiplexorAreOneError) {
  const auto r = DbcDatabase::parse_string(
      "BO_ 1 NOMUX: 8 X\n SG_ A m0 : 0|8@1+ (1,0) [0|0] \"\" X\n SG_ B m1 : 0|8@1+ (1,0) [0|0] \"\" X\n"
      " SG_ C : 8|8@1+ (1,0) [0|0] \"\" X\n",
      "n.dbc");
  ASSERT_EQ(r.errors.size(), 1u) << ::testing::PrintToString(r.errors);
  EXPECT_NE(r.errors[0].find("n.dbc:1: message NOMUX: multiplexed signals A, B but no multiplexor"),
            std::string::npos)
      << r.errors[0];
  EXPECT_EQ(r.db->find("NOMUX")->signals.size(), 1u);
  EXPECT_NE(r.affecting("NOMUX", "B"), nullptr);
  EXPECT_EQ(r.affecting("NOMUX", "C"), nullptr);
}

}  // namespace
}  // namespace torqued
