#pragma once
// Crank decoder part 2 of 4: sync on the wheel's gaps (missing teeth), before the position is known. Each
// period is compared with the predicted tooth period (the last normal one times the trend of the last two);
// a gap candidate's tooth count since the previous one goes into a history, and sync is declared when the
// recent history matches exactly one gap of the wheel (crank_decoder.hpp has the model). Real-time safe:
// plain members, no allocation.
#include <array>
#include <cstdint>
#include <string>

#include "decoder_wheel.hpp"

namespace torqued {

struct DecoderParams;
struct DecoderStats;

class GapSync {
 public:
  static constexpr int kMaxGaps = 16;
  /// After a sync loss: clean tooth periods a single-gap wheel's gap needs before it to resync.
  static constexpr int kResyncRunBeforeGap = 4;

  enum class Step : std::uint8_t {
    kNoise,       ///< runt period: reject the edge
    kNormal,      ///< a normal tooth period (syncing)
    kOther,       ///< a period that is no tooth period (gap candidate, first period, restart)
    kIdentified,  ///< this period closed the gap identified_tooth(): the position is known
  };

  /// Finds the gaps (periods > 1.5 pitch). Error if the wheel has more than kMaxGaps.
  [[nodiscard]] std::string find_gaps(const WheelTables& w);
  /// Gap-synced wheels: tooth counts between gaps, gap threshold, identifying history. Error text if the
  /// wheel has no gap or cannot be identified by them.
  [[nodiscard]] std::string init_identification(const WheelTables& w, const DecoderParams& p);
  [[nodiscard]] int num_gaps() const noexcept { return num_gaps_; }

  /// One period (ns) while syncing. Counts gaps in `stats`.
  Step on_period(std::int64_t period_ns, const WheelTables& w, const DecoderParams& p,
                 DecoderStats& stats) noexcept;
  /// After kIdentified: the tooth (within a revolution) of this period: the one that closed the identified
  /// gap, or (confirmed after the gap, identified_at_gap() false) the kResyncRunBeforeGap-th tooth after it.
  [[nodiscard]] int identified_tooth() const noexcept {
    return (gap_tooth_[static_cast<std::size_t>(match_)] + identified_after_) % teeth_;
  }
  [[nodiscard]] bool identified_at_gap() const noexcept { return identified_after_ == 0; }
  /// After kIdentified: true if the revolution changed since the last tooth before the identified gap.
  [[nodiscard]] bool identified_new_rev() const noexcept {
    const int g = gap_tooth_[static_cast<std::size_t>(match_)];
    return g == 0 || g + identified_after_ >= teeth_;
  }

  /// Forgets the reference period and the gap history: the next period starts a new search. after_loss: the
  /// search follows a sync loss (the position was known before), not the first start.
  void reset(bool after_loss = false) noexcept;

 private:
  Step classify(std::int64_t period_ns, const WheelTables& w, const DecoderParams& p,
                DecoderStats& stats) noexcept;
  Step on_gap_candidate(std::int64_t period_ns, double r, const WheelTables& w, const DecoderParams& p,
                        DecoderStats& stats) noexcept;
  [[nodiscard]] int match_gap(int need, double r, const WheelTables& w,
                              const DecoderParams& p) const noexcept;
  void restart_reference(std::int64_t period_ns) noexcept;
  [[nodiscard]] bool run_fits_gap(double gap_over_pitch, const DecoderParams& p) const noexcept;
  [[nodiscard]] static bool steady_run_fits(std::array<std::int64_t, kResyncRunBeforeGap> v,
                                            double gap_over_pitch, const DecoderParams& p) noexcept;
  Step on_post_gap_period(std::int64_t period_ns, Step step, const WheelTables& w,
                          const DecoderParams& p) noexcept;

  // Wheel tables (built once).
  int num_gaps_ = 0;
  std::array<int, kMaxGaps> gap_tooth_{};  ///< tooth index closing gap j
  std::array<int, kMaxGaps> gap_count_{};  ///< teeth from the previous gap's tooth to this one
  int max_count_ = 0;                      ///< largest gap_count_
  double min_gap_ratio_ = 0.0;             ///< smallest gap width / pitch
  double gap_threshold_ = 0.0;             ///< P/P_pred at or above this is a gap candidate
  int history_needed_ = 1;                 ///< gap counts needed to identify the position
  int max_gap_run_ = 1;                    ///< most consecutive gap periods on the wheel
  // Run state.
  std::int64_t ref_period_ns_ = 0;    ///< last period classified normal (0: none yet)
  std::int64_t ref_prev_ns_ = 0;      ///< normal period before ref (0: not consecutive)
  bool ref_provisional_ = false;      ///< ref is the first period after a (re)start (may be a gap)
  int since_gap_ = -1;                ///< teeth since the last gap candidate (-1: no gap seen yet)
  std::array<int, kMaxGaps> hist_{};  ///< teeth counts between recent gap candidates (newest last)
  int hist_len_ = 0;
  int normal_run_ = 0;                                   ///< consecutive normal periods
  std::array<std::int64_t, kResyncRunBeforeGap> run_{};  ///< the last normal periods (ring)
  int normal_run_after_gap_check_ = 0;  ///< normal_run_ before the gap candidate being judged
  int gap_run_ = 0;                     ///< consecutive gap candidates
  int match_ = 0;                       ///< gap identified by the last kIdentified
  bool after_loss_ = false;             ///< searching again after a sync loss
  int teeth_ = 1;                       ///< teeth per revolution (wheel)
  int identified_after_ = 0;            ///< kIdentified: teeth after the gap (0: at the gap)
  // After a sync loss, single-gap wheel: the last gap candidate, confirmed by the clean run after it when the
  // run before it was too short or not steady (a burst that ended just before the gap).
  std::int64_t post_gap_ns_ = 0;                          ///< the candidate's period (0: none pending)
  int post_len_ = 0;                                      ///< periods after it so far
  bool post_started_ = false;                             ///< this period is a new candidate
  std::array<std::int64_t, kResyncRunBeforeGap> post_{};  ///< those periods
};

}  // namespace torqued
