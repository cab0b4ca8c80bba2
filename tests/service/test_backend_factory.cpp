// Backend factory: config names -> sources; DBC + signal mapping from the config; and the demo recording
// end to end through factory, merger, decoder and signal store (no sync loss, signals fresh while synced).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "backend_factory.hpp"
#include "cam_check.hpp"
#include "config_loader.hpp"
#include "crank_decoder.hpp"
#include "io_test_util.hpp"
#include "replay_merger.hpp"

namespace torqued {
namespace {

const std::string kRoot = TORQUED_SOURCE_DIR;

Config default_config() {
  Config c;
  c.wheel.geometry = WheelGeometry{};
  return c;
}

TEST(BackendFactory, FileEdgeBackendsByFormat) {
  test::TempFile csv("Time [s],crk,cm\n0,0,0\n0.001,1,0\n0.002,1,1\n", ".csv");
  Config c = default_config();
  c.inputs.edges.path = csv.path();
  c.wheel.crank_channel = "crk";
  c.wheel.cam_channel = "cm";
  std::string err;
  auto src = make_edge_source(c, &err);
  ASSERT_NE(src, nullptr) << err;
  EdgeEvent e;
  ASSERT_EQ(src->next(e), SourceStatus::kOk);
  EXPECT_EQ(e.channel, kCrankChannel);
  ASSERT_EQ(src->next(e), SourceStatus::kOk);
  EXPECT_EQ(e.channel, kCamChannel);

  test::TempFile list("0.001\n0.002\n");
  c.inputs.edges.path = list.path();
  c.inputs.edges.format = EdgeFormat::kList;
  c.wheel.geometry.rising_edge = false;
  src = make_edge_source(c, &err);
  ASSERT_NE(src, nullptr) << err;
  ASSERT_EQ(src->next(e), SourceStatus::kOk);
  EXPECT_EQ(e.level, 0);  // falling-edge wheel: list edges are falling edges

  c.inputs.edges.path = "/nonexistent/edges.csv";
  c.inputs.edges.format = EdgeFormat::kCsv;
  EXPECT_EQ(make_edge_source(c, &err), nullptr);
  EXPECT_NE(err.find("inputs.edges: /nonexistent/edges.csv"), std::string::npos) << err;
}

TEST(BackendFactory, CanFileAndNoCan) {
  Config c = default_config();
  std::string err;
  EXPECT_EQ(make_can_source(c, &err), nullptr);
  EXPECT_TRUE(err.empty());
  test::TempFile log("(1700000000.5) can0 100#01\n");
  c.inputs.can.path = log.path();
  c.inputs.can.time_offset_s = -1700000000.0;
  auto src = make_can_source(c, &err);
  ASSERT_NE(src, nullptr) << err;
  CanFrame f;
  ASSERT_EQ(src->next(f), SourceStatus::kOk);
  EXPECT_EQ(f.t_ns, 1'700'000'000'500'000'000);  // raw: the offset is applied once, by the consumer
  EXPECT_EQ(can_time_offset_ns(c), -1'700'000'000'000'000'000);
}

TEST(BackendFactory, DecoderParamsFollowTheWheelConfig) {
  Config c = default_config();
  c.wheel.cam_channel = "";
  c.wheel.cam_rising_edge = false;
  const DecoderParams p = decoder_params(c);
  EXPECT_FALSE(p.use_cam);
  EXPECT_FALSE(p.cam_rising);
  EXPECT_EQ(p.crank_channel, kCrankChannel);
  EXPECT_EQ(p.cam_channel, kCamChannel);
}

TEST(BackendFactory, EncoderAlignsToReceiveTimeOnlyLive) {
  // GIVEN the can_encoder edge backend WHEN CAN is a candump replay THEN the encoder's own clock is kept
  // (deterministic replay); WHEN CAN is SocketCAN (live) THEN edges are aligned to the frames' receive clock.
  Config c = default_config();
  c.inputs.edges.backend = EdgeBackend::kCanEncoder;
  c.inputs.edges.encoder_can_id = 0x18FF0001u;
  c.inputs.can.backend = CanBackend::kFile;
  CanEncoderConfig e = can_encoder_config(c);
  EXPECT_FALSE(e.align_to_receive_time);
  EXPECT_EQ(e.id, 0x18FF0001u);
  EXPECT_TRUE(e.extended);
  EXPECT_EQ(e.crank_channel, kCrankChannel);
  EXPECT_EQ(e.cam_channel, kCamChannel);
  EXPECT_EQ(validate(e), nullptr);
  c.inputs.can.backend = CanBackend::kSocketCan;
  e = can_encoder_config(c);
  EXPECT_TRUE(e.align_to_receive_time);
  EXPECT_EQ(validate(e), nullptr);
}

TEST(BackendFactory, DbcAndSignalBindingErrors) {
  test::TempFile dbc("BO_ 256 E1: 8 ECU\n SG_ MAP : 0|16@1+ (0.01,0) [0|655.35] \"kPa\" X\n", ".dbc");
  Config c = default_config();
  c.can.dbc = dbc.path();
  std::string err;
  auto db = load_dbc(c, &err);
  ASSERT_TRUE(db.has_value()) << err;
  SignalStore store(*db);
  c.can.signals[static_cast<std::size_t>(Quantity::kMap)] = {"E1", "MAP", 100};
  EXPECT_TRUE(bind_signals(c, store, &err)) << err;
  c.can.signals[static_cast<std::size_t>(Quantity::kMaf)] = {"E1", "MAF", 100};
  c.can.signals[static_cast<std::size_t>(Quantity::kOilTemp)] = {"E9", "Oil", 100};
  EXPECT_FALSE(bind_signals(c, store, &err));
  EXPECT_NE(err.find("can.signals.maf"), std::string::npos) << err;
  EXPECT_NE(err.find("can.signals.oil_temp"), std::string::npos) << err;
  test::TempFile bad("BO_ 256 E1: 8 ECU\n SG_ MAP : 0|16@7+ (0.01,0) [0|655.35] \"kPa\" X\n", ".dbc");
  c.can.dbc = bad.path();
  EXPECT_FALSE(load_dbc(c, &err).has_value());
  EXPECT_NE(err.find(bad.path() + ":2:"), std::string::npos) << err;
}

TEST(BackendFactory, ADbcDefectRefusesOnlyWhenItTakesOutAMappedSignal) {
  // GIVEN a DBC with a message whose name starts with a digit (its 3 signals go with it) and a good message
  test::TempFile dbc(
      "BO_ 256 E1: 8 ECU\n SG_ MAP : 0|16@1+ (0.01,0) [0|655.35] \"kPa\" X\nBO_ 300 3RD: 8 ECU\n"
      " SG_ A : 0|8@1+ (1,0) [0|0] \"\" X\n SG_ B : 8|8@1+ (1,0) [0|0] \"\" X\n SG_ C : 16|8@1+ (1,0) [0|0] "
      "\"\" X\n",
      ".dbc");
  Config c = default_config();
  c.can.dbc = dbc.path();
  c.can.signals[static_cast<std::size_t>(Quantity::kMap)] = {"E1", "MAP", 100};
  std::string err;
  std::vector<std::string> warnings;
  // THEN mapping the good message loads, the defect is one warning with its file:line
  auto db = load_dbc(c, &err, &warnings);
  ASSERT_TRUE(db.has_value()) << err;
  ASSERT_EQ(warnings.size(), 1u) << ::testing::PrintToString(warnings);
  EXPECT_NE(warnings[0].find(dbc.path() + ":3: message name '3RD' starts with a digit"), std::string::npos)
      << warnings[0];
  // AND mapping a signal of the bad message refuses, naming the quantity and the DBC line once
  c.can.signals[static_cast<std::size_t>(Quantity::kMaf)] = {"3RD", "B", 100};
  err.clear();
  EXPECT_FALSE(load_dbc(c, &err).has_value());
  EXPECT_NE(err.find("can.signals.maf: 3RD.B is unusable: " + dbc.path() + ":3:"), std::string::npos) << err;
  EXPECT_EQ(err.find('\n'), std::string::npos) << err;
}

TEST(BackendFactory, DemoRecordingEndToEnd) {
  if (!std::ifstream(kRoot + "/data/demo/edges.csv")) GTEST_SKIP() << "no data/demo recording";
  LoadResult lr = load_config(kRoot + "/config/demo.yaml");
  ASSERT_TRUE(lr.ok()) << (lr.errors.empty() ? "" : lr.errors.front());
  const Config& c = *lr.config;
  std::string err;
  auto edges = make_edge_source(c, &err);
  ASSERT_NE(edges, nullptr) << err;
  auto can = make_can_source(c, &err);
  ASSERT_NE(can, nullptr) << err;
  auto db = load_dbc(c, &err);
  ASSERT_TRUE(db.has_value()) << err;
  SignalStore store(*db);
  ASSERT_TRUE(bind_signals(c, store, &err)) << err;
  CrankDecoder dec(c.wheel.geometry, decoder_params(c));
  ASSERT_TRUE(dec.valid()) << dec.error();

  ReplayMerger merger(edges.get(), can.get(), can_time_offset_ns(c));
  ReplayMerger::Item it;
  ToothEvent ev;
  std::uint64_t synced = 0, fresh_map = 0, fresh_all = 0;
  while (merger.next(it) == SourceStatus::kOk) {
    if (it.kind == ReplayMerger::Kind::kCan) {
      store.on_frame(it.frame);
      continue;
    }
    if (!dec.on_edge(it.edge, ev) || ev.sync != SyncState::kSynced) continue;
    ++synced;
    const EngineSignals s = store.signals_at(ev.t_ns);
    fresh_map += s.map_valid ? 1 : 0;
    fresh_all +=
        (s.map_valid && s.maf_valid && s.oil_temp_valid && s.load_torque_valid && s.lambda_valid) ? 1 : 0;
  }
  EXPECT_EQ(dec.stats().sync_losses, 0u);
  EXPECT_EQ(dec.stats().noise_edges, 0u);
  EXPECT_EQ(merger.out_of_order(), 0u);
  EXPECT_GT(synced, 10'000u);
  EXPECT_EQ(store.stats().bad_frames, 0u);
  EXPECT_EQ(store.stats().rejected_values, 0u);
  // CAN at 100 Hz with 0.1 % drops and 100 ms time-outs: signals are fresh at (nearly) every synced tooth.
  EXPECT_GT(static_cast<double>(fresh_map), 0.99 * static_cast<double>(synced));
  EXPECT_GT(static_cast<double>(fresh_all), 0.99 * static_cast<double>(synced));
  EXPECT_EQ(edges->stats().bad_lines + can->stats().bad_lines, 0u);
}

}  // namespace
}  // namespace torqued

namespace torqued {
namespace {
// --check-config with a recording: the demo's cam edge lies inside its configured window with a
// margin; a window that misses it, or one whose edge sits on it, is warned about with the measured angle.
TEST(BackendFactory, CamWindowCheckAgainstTheRecording) {
  LoadResult lr = load_config(std::string(TORQUED_SOURCE_DIR) + "/config/demo.yaml");
  ASSERT_TRUE(lr.ok());
  Config c = *lr.config;
  EXPECT_TRUE(cam_window_warnings(c).empty());
  // Measure the angle with auto, then build windows around it.
  DecoderParams p = decoder_params(c);
  p.cam_window_auto = true;
  std::string err;
  auto src = make_edge_source(c, &err);
  ASSERT_TRUE(src) << err;
  CrankDecoder dec(c.wheel.geometry, p);
  EdgeEvent e;
  ToothEvent t;
  while (dec.stats().cam_angle_deg < 0.0 && src->next(e) == SourceStatus::kOk) dec.on_edge(e, t);
  const double a = dec.stats().cam_angle_deg;
  ASSERT_GE(a, 0.0);
  c.wheel.decoder.cam_window_start_deg = std::fmod(a + 100.0, 360.0);  // misses a and a + 360
  c.wheel.decoder.cam_window_end_deg = c.wheel.decoder.cam_window_start_deg + 60.0;
  auto w = cam_window_warnings(c);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("outside"), std::string::npos) << w[0];
  c.wheel.decoder.cam_window_start_deg = a + 5.0 < 360.0 ? a + 5.0 : a - 355.0;  // edge 5° from the cam
  c.wheel.decoder.cam_window_end_deg = c.wheel.decoder.cam_window_start_deg + 360.0;
  w = cam_window_warnings(c);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("flip"), std::string::npos) << w[0];
}
}  // namespace
}  // namespace torqued
