// Encoder-over-CAN frames (io/can_encoder.hpp): wire layout, batching, unwrap, lost-frame detection, and the
// crank decoder staying in sync on edges carried through the frames.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "alloc_counter.hpp"
#include "can_encoder.hpp"
#include "crank_decoder.hpp"
#include "synthetic_wheel.hpp"

namespace torqued {
namespace {

namespace ce = can_encoder;

/// CanSource over a vector of frames (what a candump log or SocketCAN would deliver).
class VectorCanSource final : public CanSource {
 public:
  explicit VectorCanSource(std::vector<CanFrame> frames) : frames_(std::move(frames)) {}
  SourceStatus next(CanFrame& out) noexcept override {
    if (i_ == frames_.size()) return SourceStatus::kEnd;
    out = frames_[i_++];
    ++stats_.records;
    return SourceStatus::kOk;
  }
  const SourceStats& stats() const noexcept override { return stats_; }
  std::string describe() const override { return "vector"; }

 private:
  std::vector<CanFrame> frames_;
  std::size_t i_ = 0;
  SourceStats stats_;
};

std::vector<CanFrame> encode_all(const std::vector<EdgeEvent>& edges, const CanEncoderConfig& cfg,
                                 std::int64_t latency_ns = 1'000'000) {
  std::vector<CanFrame> frames;
  ce::Batcher b(cfg, latency_ns);
  CanFrame f;
  for (const EdgeEvent& e : edges) {
    if (b.push(e, f)) frames.push_back(f);
  }
  while (b.flush(f)) frames.push_back(f);
  return frames;
}

std::vector<EdgeEvent> drain(EdgeSource& s) {
  std::vector<EdgeEvent> out;
  EdgeEvent e;
  while (s.next(e) == SourceStatus::kOk) out.push_back(e);
  return out;
}

TEST(CanEncoderFrame, FdLengthsAreValidCanFdLengths) {
  EXPECT_EQ(ce::fd_length(6), 6);
  EXPECT_EQ(ce::fd_length(9), 12);
  EXPECT_EQ(ce::fd_length(30), 32);
  EXPECT_EQ(ce::fd_length(33), 48);
  EXPECT_EQ(ce::fd_length(62), 64);
}

TEST(CanEncoderFrame, RoundTripFullFdFrame) {
  // GIVEN 15 edges with both channels and levels, times beyond one 30-bit wrap
  CanEncoderConfig cfg;
  cfg.tick_ns = 1;
  std::vector<EdgeEvent> edges;
  for (int k = 0; k < 15; ++k) {
    edges.push_back({(std::int64_t{1} << 31) + 12345 * k, static_cast<std::uint8_t>(k % 3 == 0),
                     static_cast<std::uint8_t>(k & 1)});
  }
  // WHEN encoded and decoded
  CanFrame f;
  ASSERT_EQ(ce::encode_frame(edges.data(), edges.size(), 200, ce::kFlagOverflow, cfg, f), 15u);
  EXPECT_TRUE(f.fd);
  EXPECT_EQ(f.len, 64);
  EXPECT_EQ(f.id, 0x300u);
  EXPECT_EQ(f.data[0], 200);
  ce::FrameView v;
  ASSERT_EQ(ce::decode_frame(f, cfg, v), nullptr);
  // THEN every field survives (times mod 2^30 ticks)
  EXPECT_EQ(v.seq, 200);
  EXPECT_EQ(v.flags, ce::kFlagOverflow);
  ASSERT_EQ(v.n, 15);
  for (int k = 0; k < 15; ++k) {
    EXPECT_EQ(v.entries[k].ticks, static_cast<std::uint32_t>(edges[k].t_ns) & ce::kTickMask);
    EXPECT_EQ(v.entries[k].cam, edges[k].channel == 1);
    EXPECT_EQ(v.entries[k].level, edges[k].level);
  }
}

TEST(CanEncoderFrame, ClassicFrameCarriesOneEntryInSixBytes) {
  CanEncoderConfig cfg;
  cfg.fd = false;
  std::vector<EdgeEvent> edges = {{1000, 0, 1}, {2000, 0, 0}};
  CanFrame f;
  EXPECT_EQ(ce::encode_frame(edges.data(), edges.size(), 7, 0, cfg, f), 1u);
  EXPECT_FALSE(f.fd);
  EXPECT_EQ(f.len, 6);
  // 1000 ns / 10 ns = 100 ticks, level bit 30 set, crank channel.
  EXPECT_EQ(f.data[1], 1);
  EXPECT_EQ(f.data[2], 100);
  EXPECT_EQ(f.data[5], 0x40);
}

TEST(CanEncoderFrame, MalformedFramesAreRejectedWithReason) {
  CanEncoderConfig cfg;
  ce::FrameView v;
  CanFrame f;
  f.len = 1;
  EXPECT_NE(ce::decode_frame(f, cfg, v), nullptr);
  f.len = 8;
  f.data[1] = 2;  // two entries need 10 bytes
  EXPECT_NE(ce::decode_frame(f, cfg, v), nullptr);
  f.fd = false;
  f.len = 8;
  f.data[1] = 2;  // classic: at most one entry
  EXPECT_NE(ce::decode_frame(f, cfg, v), nullptr);
  f.data[1] = 0x11;  // reserved bit 4
  EXPECT_NE(ce::decode_frame(f, cfg, v), nullptr);
  f.data[1] = 0x01;
  EXPECT_EQ(ce::decode_frame(f, cfg, v), nullptr);
}

TEST(CanEncoderFrame, ConfigValidation) {
  CanEncoderConfig cfg;
  EXPECT_EQ(validate(cfg), nullptr);
  cfg.id = 0x800;
  EXPECT_NE(validate(cfg), nullptr);
  cfg.extended = true;
  EXPECT_EQ(validate(cfg), nullptr);
  cfg.tick_ns = 0;
  EXPECT_NE(validate(cfg), nullptr);
}

TEST(CanEncoderBatcher, ClosesFramesWhenFullOrTooOld) {
  CanEncoderConfig cfg;
  ce::Batcher b(cfg, 1'000'000);  // 1 ms
  CanFrame f;
  int frames = 0;
  // 20 edges 10 µs apart: the first 15 fill one frame.
  for (int k = 0; k < 20; ++k) frames += b.push({10'000 * k, 0, 1}, f);
  EXPECT_EQ(frames, 1);
  // An edge 5 ms later closes the pending 5 edges by latency.
  ASSERT_TRUE(b.push({5'000'000, 0, 0}, f));
  EXPECT_EQ(f.data[1] & 0x0F, 5);
  EXPECT_EQ(f.data[0], 1);  // second frame: sequence 1
  ASSERT_TRUE(b.flush(f));
  EXPECT_EQ(f.data[1] & 0x0F, 1);
  EXPECT_FALSE(b.flush(f));
}

TEST(CanEncoderEdgeSource, ReproducesEdgesAcrossManyWrapsWithoutAllocating) {
  // GIVEN 3.5 s of edges at 1 ns ticks (30-bit wrap = 1.07 s), frames stamped by their last edge
  test::SynthOptions o;
  o.rpm0 = 800;
  o.rpm1 = 4000;
  o.duration_s = 3.5;
  o.step_s = 1e-5;
  const auto synth = test::synthesize(o);
  CanEncoderConfig cfg;
  cfg.tick_ns = 1;
  VectorCanSource can(encode_all(synth.edges, cfg));
  CanEncoderEdgeSource src(can, cfg);
  ASSERT_TRUE(src.ok());
  // WHEN decoded
  std::vector<EdgeEvent> got;
  got.reserve(synth.edges.size());
  EdgeEvent e;
  test::AllocationScope scope;
  while (src.next(e) == SourceStatus::kOk) got.push_back(e);
  EXPECT_EQ(scope.count(), 0u);
  // THEN the same edges come out, bit for bit
  ASSERT_EQ(got.size(), synth.edges.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_EQ(got[k].t_ns, synth.edges[k].t_ns) << k;
    ASSERT_EQ(got[k].channel, synth.edges[k].channel) << k;
    ASSERT_EQ(got[k].level, synth.edges[k].level) << k;
  }
  EXPECT_EQ(src.encoder_stats().lost_frames, 0u);
  EXPECT_EQ(src.stats().dropped, 0u);
}

TEST(CanEncoderEdgeSource, CountsLostAndDuplicateFramesAndIgnoresOtherIds) {
  CanEncoderConfig cfg;
  std::vector<EdgeEvent> edges;
  for (int k = 0; k < 15 * 300; ++k)
    edges.push_back({100'000 + 50'000 * k, 0, static_cast<std::uint8_t>(k & 1)});
  auto frames = encode_all(edges, cfg);
  ASSERT_EQ(frames.size(), 300u);
  // Lose frames 10, 11, 12 and 100; the sequence also wraps past 255 on the way.
  std::vector<CanFrame> wire;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (i == 10 || i == 11 || i == 12 || i == 100) continue;
    wire.push_back(frames[i]);
    if (i == 50) wire.push_back(frames[i]);  // duplicate
    if (i == 60) {
      CanFrame other = frames[i];
      other.id = 0x100;
      wire.push_back(other);
    }
  }
  VectorCanSource can(wire);
  CanEncoderEdgeSource src(can, cfg);
  const auto got = drain(src);
  EXPECT_EQ(got.size(), edges.size() - 4 * 15);
  EXPECT_EQ(src.encoder_stats().lost_frames, 4u);
  EXPECT_EQ(src.encoder_stats().sequence_errors, 2u);
  EXPECT_EQ(src.stats().dropped, 4u);
  EXPECT_EQ(src.encoder_stats().duplicate_frames, 1u);
  EXPECT_EQ(src.encoder_stats().other_frames, 1u);
  for (std::size_t k = 1; k < got.size(); ++k) ASSERT_GT(got[k].t_ns, got[k - 1].t_ns);
}

TEST(CanEncoderEdgeSource, LongPauseIsUnwrappedFromReceiveTimes) {
  // GIVEN a 5.3 s pause (about 5 wraps at 1 ns ticks) between two edges, receive times on the same clock
  CanEncoderConfig cfg;
  cfg.tick_ns = 1;
  cfg.fd = false;
  std::vector<EdgeEvent> edges = {{1'000, 0, 1}, {2'000, 0, 0}, {5'300'002'000, 0, 1}, {5'300'003'000, 0, 0}};
  auto frames = encode_all(edges, cfg, 0);
  ASSERT_EQ(frames.size(), 4u);
  for (auto& f : frames) f.t_ns += 700'000;  // transmission delay; the encoder clock is what counts
  VectorCanSource can(frames);
  CanEncoderEdgeSource src(can, cfg);
  const auto got = drain(src);
  ASSERT_EQ(got.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(got[k].t_ns, edges[k].t_ns) << k;
  EXPECT_EQ(src.encoder_stats().long_pauses, 1u);
}

TEST(CanEncoderEdgeSource, MalformedFrameIsCountedAndNamed) {
  CanEncoderConfig cfg;
  std::vector<EdgeEvent> edges = {{1'000, 0, 1}};
  auto frames = encode_all(edges, cfg);
  CanFrame bad = frames[0];
  bad.len = 1;
  frames.insert(frames.begin(), bad);
  VectorCanSource can(frames);
  CanEncoderEdgeSource src(can, cfg);
  EXPECT_EQ(drain(src).size(), 1u);
  EXPECT_EQ(src.encoder_stats().bad_frames, 1u);
  EXPECT_NE(src.last_error().find("expected"), std::string::npos) << src.last_error();
}

TEST(CanEncoderEdgeSource, AlignsToReceiveClockAndFollowsOscillatorDrift) {
  // GIVEN an encoder whose oscillator runs 80 ppm fast with its own origin, edges every 1 ms for 120 s,
  // frames received 200 µs + 0..300 µs (pseudo-random) after their last edge, on a host clock near 1.7e18 ns
  const std::int64_t host0 = 1'700'000'000'000'000'000;
  const double drift = 80e-6;
  const std::int64_t delay = 200'000;
  CanEncoderConfig cfg;
  cfg.tick_ns = 10;
  cfg.align_to_receive_time = true;
  std::vector<EdgeEvent> enc_edges;
  std::vector<std::int64_t> host_t;
  for (int k = 0; k < 120'000; ++k) {
    const std::int64_t h = 1'000'000LL * k + 123;
    host_t.push_back(host0 + h);
    enc_edges.push_back({987'654'321 + static_cast<std::int64_t>(static_cast<double>(h) * (1.0 + drift)), 0,
                         static_cast<std::uint8_t>(k & 1)});
  }
  auto frames = encode_all(enc_edges, cfg, 3'000'000);
  std::uint32_t lcg = 12345;
  std::size_t edge_i = 0;
  for (auto& f : frames) {
    edge_i += static_cast<std::size_t>(f.data[1] & 0x0F);
    lcg = lcg * 1664525u + 1013904223u;
    f.t_ns = host_t[edge_i - 1] + delay + static_cast<std::int64_t>(lcg >> 8) % 300'000;
  }
  VectorCanSource can(frames);
  CanEncoderEdgeSource src(can, cfg);
  // WHEN decoded
  const auto got = drain(src);
  ASSERT_EQ(got.size(), host_t.size());
  // THEN after 20 s the edges sit on the host clock, late by the transport floor (200 µs) within 20 µs
  // (jitter 300 µs), the error does not grow (without alignment: 9.6 ms after 120 s), and no period is
  // changed by more than the slew limit
  double worst = 0.0, worst_period = 0.0;
  for (std::size_t k = 20'000; k < got.size(); ++k) {
    const double err = static_cast<double>(got[k].t_ns - (host_t[k] + delay));
    worst = std::max(worst, std::abs(err));
  }
  for (std::size_t k = 1; k < got.size(); ++k) {
    const double p_out = static_cast<double>(got[k].t_ns - got[k - 1].t_ns);
    const double p_enc = static_cast<double>(enc_edges[k].t_ns - enc_edges[k - 1].t_ns);
    worst_period = std::max(worst_period, std::abs(p_out / p_enc - 1.0));
  }
  EXPECT_LT(worst, 20'000.0);
  EXPECT_LT(worst_period, cfg.max_slew_ppm * 1e-6 + 2e-5);  // + quantisation of 10 ns ticks / 1 ms
  EXPECT_NEAR(src.encoder_stats().align_rate_ppm, -80.0, 10.0);
}

class EncoderDecoderSync : public ::testing::TestWithParam<bool> {};

TEST_P(EncoderDecoderSync, CrankDecoderStaysInSyncThroughEncoderFrames) {
  // GIVEN a 60-2 wheel accelerating 1000 -> 6000 rpm with cam, sent as FD (15/frame) or classic (1/frame)
  test::SynthOptions o;
  o.rpm0 = 1000;
  o.rpm1 = 6000;
  o.duration_s = 1.0;
  o.ripple = 0.05;
  o.step_s = 5e-6;
  const auto synth = test::synthesize(o);
  CanEncoderConfig cfg;
  cfg.fd = GetParam();
  cfg.tick_ns = 10;
  VectorCanSource can(encode_all(synth.edges, cfg));
  CanEncoderEdgeSource src(can, cfg);
  CrankDecoder dec(WheelGeometry{}, DecoderParams{});
  ASSERT_TRUE(dec.valid()) << dec.error();
  // WHEN the decoded edges drive the crank decoder
  EdgeEvent e;
  ToothEvent t;
  std::size_t synced = 0;
  while (src.next(e) == SourceStatus::kOk) {
    if (dec.on_edge(e, t) && t.sync == SyncState::kSynced) ++synced;
  }
  // THEN it syncs within the first two revolutions and never loses sync
  EXPECT_EQ(dec.stats().sync_losses, 0u);
  EXPECT_EQ(dec.stats().syncs, 1u);
  EXPECT_GT(synced, synth.teeth.size() - 2 * 58);
  EXPECT_EQ(src.encoder_stats().lost_frames, 0u);
}

INSTANTIATE_TEST_SUITE_P(FdAndClassic, EncoderDecoderSync, ::testing::Values(true, false));

}  // namespace
}  // namespace torqued
