#pragma once
// Crank decoder part 3 of 4: pattern sync, for wheels whose crank teeth alone cannot identify the position.
//  - Cam-synced (4G63: 2 crank teeth, Nissan CAS: 12, Miata NB2: 4 at 70°/110°): each cam edge is placed at
//    the crank tooth that follows it, as a fraction of that tooth interval (exact, whatever the speed
//    ripple); the position is the one offset k of the 720° cycle at which every observed cam edge lies on a
//    pattern edge of its polarity, and every pattern edge inside the observed span was observed. Sync (with
//    the 720° phase) as soon as exactly one k fits.
//  - Pulse-width-coded (GM 24x): each tooth period carries one bit (opposite edge in the first or second part
//    of the period); the last code_window + 2 bits must match the code at exactly one rotation.
// Synced, every cam edge and width bit is checked against the decoded position: a contradiction is counted
// (cam_phase_errors / width_code_errors) and two in a row lose sync (reason "pattern") and resync.
// Real-time safe: plain members (fixed rings), no allocation.
#include <array>
#include <cstdint>
#include <string>

#include "decoder_wheel.hpp"

namespace torqued {

struct DecoderParams;
struct DecoderStats;

class PatternSync {
 public:
  static constexpr int kNoise = -2;      ///< syncing_step: runt period, reject the edge
  static constexpr int kSearching = -1;  ///< syncing_step: position not identified yet

  /// True when the decoder syncs on the cam pattern or the width code (not on gaps).
  [[nodiscard]] static bool used(const DecoderParams& p) noexcept;
  /// Validates the pattern and finds the width code's identifying window. Error text, empty if ok.
  [[nodiscard]] std::string init(const WheelTables& w, const DecoderParams& p);

  /// Opposite (non-tooth) crank edge: its time gives the width bit of the period it falls in.
  void on_opposite_edge(std::int64_t t_ns) noexcept { last_opp_t_ns_ = t_ns; }
  /// Cam edge of a listed polarity, placed when the next tooth comes. False when the buffer is full.
  bool add_cam_edge(std::int64_t t_ns, bool rising) noexcept;

  /// Syncing: the tooth at t_ns closed a period of period_ns after the last tooth at last_t_ns. Returns the
  /// tooth's index in the 720° cycle once the position is identified (rev: current revolution, used by
  /// width-coded wheels that have no phase), else kSearching or kNoise.
  int syncing_step(std::int64_t t_ns, std::int64_t last_t_ns, std::int64_t period_ns, int rev,
                   const WheelTables& w, const DecoderParams& p) noexcept;
  /// Synced: the width bit of the period ending at tooth idx, and every cam edge since the previous tooth
  /// (prev_idx, advance teeth back), must agree with the decoded position. Counts errors in `stats`; true
  /// when sync must be lost (two contradictions in a row).
  bool check_synced(std::int64_t t_ns, std::int64_t period_ns, int prev_idx, int idx, int advance,
                    const WheelTables& w, const DecoderParams& p, DecoderStats& stats) noexcept;

  /// Sync lost: the search restarts at the next tooth (the previous tooth is counter 0 of the new search).
  void restart() noexcept {
    fresh_ = true;
    misses_ = 0;
  }
  /// Drops the cam edges waiting for the next tooth (the crank signal restarted after a stall).
  void drop_pending_cam() noexcept { cam_pend_n_ = 0; }
  /// Everything back to construction state (keeps the code window, a wheel table).
  void reset() noexcept;

 private:
  struct CamObs {
    double pos;  ///< tooth counter of the interval's first tooth + fraction of the interval
    bool rising;
  };
  struct CamPending {
    std::int64_t t_ns;
    bool rising;
  };
  static constexpr int kCamRing = 16;

  void collect(std::int64_t t_ns, std::int64_t last_t_ns, const WheelTables& w) noexcept;
  [[nodiscard]] int width_bit(std::int64_t t_ns, std::int64_t last_t_ns,
                              const DecoderParams& p) const noexcept;
  [[nodiscard]] bool cam_match(int& k, const WheelTables& w, const DecoderParams& p) const noexcept;
  [[nodiscard]] bool width_match(int& k, const WheelTables& w, const DecoderParams& p) const noexcept;

  int code_window_ = 0;             ///< bits needed to identify the position on a width-coded wheel (table)
  bool fresh_ = true;               ///< next tooth restarts the pattern search (previous tooth = counter 0)
  int count_ = 0;                   ///< teeth since the restart (counter of the current tooth + 1)
  int span_start_ = 0;              ///< first tooth counter covered by the observations
  std::int64_t ref_period_ns_ = 0;  ///< last period (runt check; 0: none since the restart)
  std::array<CamObs, kCamRing> cam_obs_{};
  int cam_obs_n_ = 0;
  std::array<CamPending, 8>
      cam_pend_{};  ///< cam edges since the last tooth (placed when the next tooth comes)
  int cam_pend_n_ = 0;
  std::uint64_t bits_ = 0;  ///< width bits, newest in bit 0
  int nbits_ = 0;
  std::int64_t last_opp_t_ns_ = -1;  ///< time of the last opposite (non-tooth) crank edge
  int misses_ = 0;                   ///< consecutive pattern contradictions while synced
};

}  // namespace torqued
