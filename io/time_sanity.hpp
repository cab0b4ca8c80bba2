#pragma once
// Time sanity of a file source (docs/io.md "Time sanity"): one record far outside the recent time base (a
// flipped digit: one edge at t = 100000 s in a 20 s capture) must not become "now", or every later record
// would be rejected as going backwards and a fast replay would fill the gap with time-triggered output.
//
// Rule, fed the records in file order with their times:
//  - in step (previous accepted time <= t <= previous + max_jump): accepted at once;
//  - behind the previous accepted time: dropped ("backwards");
//  - more than max_jump ahead: held as the start of a candidate run. Each later record in step with the
//    run joins it; when the run holds `rebase_after` records the clock really jumped (a capture resumed after
//    a pause): the run is accepted and becomes the time base (a re-base). A record in step with the old base
//    instead proves the run wrong: its records are dropped as outliers. A run still short at the end of the
//    input is dropped the same way (it cannot be told from a corrupt last line).
//  - before any record was accepted, the first `rebase_after` records must agree the same way; one far out of
//    step with them replaces a lone first record (a corrupt first line is dropped; at most two records are
//    lost) or is judged against two or more agreeing ones as above. An input shorter than that is accepted.
// Every dropped record is reported with its line (drain_drops()) so the source can name file:line.
// Real-time safe: fixed buffers, no allocation, no exceptions.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "source.hpp"

namespace torqued {

struct TimeSanityOptions {
  std::int64_t max_jump_ns = 10'000'000'000;  ///< config inputs.max_time_jump_s; <= 0 = no checks at all
  std::uint32_t rebase_after = 8;             ///< config inputs.time_rebase_records (1..kMaxRebase)
};

/// One dropped record: its input line, its time and the time base it was judged against.
struct TimeDrop {
  std::uint64_t line = 0;
  std::int64_t t_ns = 0;
  std::int64_t base_ns = 0;
  bool backwards = false;  ///< behind the base (else: an outlier ahead of it)
};

/// "<path>:<line>: time goes backwards ..." / "... dropped as an outlier" (not real-time).
[[nodiscard]] std::string describe_time_drop(const TimeDrop& d, const std::string& path);
/// Counts a dropped record in `stats` (bad_lines and time_outliers) and names it file:line in `messages` (the
/// first 20 messages of the source; `error` = the last one). Allocates only for a kept message.
void note_time_drop(const TimeDrop& d, const std::string& path, SourceStats& stats,
                    std::vector<std::string>& messages, std::string& error) noexcept;

template <class Rec>
class TimeSanity {
 public:
  static constexpr std::uint32_t kMaxRebase = 32;

  explicit TimeSanity(TimeSanityOptions o = {}) noexcept : opt_(o) {
    if (opt_.rebase_after < 1) opt_.rebase_after = 1;
    if (opt_.rebase_after > kMaxRebase) opt_.rebase_after = kMaxRebase;
  }

  /// Next record of the input (time t_ns, input line `line`). Inline: the common record (no run held, within
  /// max_jump_ns after the base) is accepted here, per record; the rest in push_held().
  [[gnu::always_inline]] void push(const Rec& r, std::int64_t t_ns, std::uint64_t line) noexcept {
    if (opt_.max_jump_ns <= 0) return ready_push(r);
    if (run_n_ == 0 && have_base_ && ahead_within(base_, t_ns)) [[likely]]
      return accept(r, t_ns);
    push_held(r, t_ns, line);
  }

  /// push() past its common case (the same decisions, in the same order).
  [[gnu::noinline]] void push_held(const Rec& r, std::int64_t t_ns, std::uint64_t line) noexcept {
    if (run_n_ == 0) {
      if (!have_base_) return start_run(r, t_ns, line);  // the first records: a run that must agree
      if (t_ns < base_) return drop(Held{r, t_ns, line}, true, base_);
      if (ahead_within(base_, t_ns)) return accept(r, t_ns);
      return start_run(r, t_ns, line);
    }
    const std::int64_t run_last = run_[run_n_ - 1].t;
    if (ahead_within(run_last, t_ns)) {
      run_[run_n_++] = Held{r, t_ns, line};
      if (run_n_ >= opt_.rebase_after) adopt_run();
      return;
    }
    if (!have_base_) return conflict_at_start(r, t_ns, line, run_last);
    if (ahead_within(base_, t_ns)) {  // the old base holds: the run was wrong
      drop_run();
      return accept(r, t_ns);
    }
    if (t_ns > run_last) {  // a further jump: a new run
      drop_run();
      return start_run(r, t_ns, line);
    }
    drop(Held{r, t_ns, line}, true, base_);
  }

  /// End of input: a run too short to re-base is dropped (before any base: accepted as the whole input).
  void finish() noexcept {
    if (!have_base_ && run_n_ > 0) return adopt_run();
    drop_run();
  }

  /// Next accepted record, in input order.
  [[nodiscard]] bool pop(Rec& out) noexcept {
    if (ready_head_ == ready_tail_) return false;
    out = ready_[ready_head_];
    if (++ready_head_ == ready_.size()) ready_head_ = 0;  // per record: a compare, not a division
    return true;
  }

  /// Calls f(const TimeDrop&) for each record dropped since the last call.
  template <class F>
  void drain_drops(F&& f) {
    for (std::size_t i = 0; i < drops_n_; ++i) f(drops_[i]);
    drops_n_ = 0;
  }

  [[nodiscard]] std::uint64_t outliers() const noexcept { return outliers_; }
  [[nodiscard]] std::uint64_t backwards() const noexcept { return backwards_; }
  [[nodiscard]] std::uint64_t rebases() const noexcept { return rebases_; }
  [[nodiscard]] const TimeSanityOptions& options() const noexcept { return opt_; }

 private:
  struct Held {
    Rec r;
    std::int64_t t = 0;
    std::uint64_t line = 0;
  };

  /// `to` is at or after `from` by at most max_jump_ns. The distance is taken unsigned: two times of
  /// opposite signs may lie more than INT64_MAX apart (a signed difference would overflow).
  [[nodiscard]] bool ahead_within(std::int64_t from, std::int64_t to) const noexcept {
    return to >= from && static_cast<std::uint64_t>(to) - static_cast<std::uint64_t>(from) <=
                             static_cast<std::uint64_t>(opt_.max_jump_ns);
  }
  void ready_push(const Rec& r) noexcept {
    ready_[ready_tail_] = r;
    if (++ready_tail_ == ready_.size()) ready_tail_ = 0;
  }
  void accept(const Rec& r, std::int64_t t) noexcept {
    base_ = t;
    have_base_ = true;
    ready_push(r);
  }
  void start_run(const Rec& r, std::int64_t t, std::uint64_t line) noexcept {
    run_[0] = Held{r, t, line};
    run_n_ = 1;
    if (run_n_ >= opt_.rebase_after) adopt_run();
  }
  /// Before any base: a record out of step with the first run. Slightly behind: dropped. Far away: a run of
  /// two or more agreeing records becomes the base and judges it; a lone first record is replaced by it
  /// (at most two records are lost to one corrupt time at the very start).
  void conflict_at_start(const Rec& r, std::int64_t t_ns, std::uint64_t line,
                         std::int64_t run_last) noexcept {
    if (t_ns < run_last && ahead_within(t_ns, run_last)) return drop(Held{r, t_ns, line}, true, run_last);
    if (run_n_ >= 2) {
      adopt_run();
      return push(r, t_ns, line);
    }
    drop_run(t_ns);
    start_run(r, t_ns, line);
  }
  void adopt_run() noexcept {
    if (have_base_) ++rebases_;
    for (std::uint32_t i = 0; i < run_n_; ++i) accept(run_[i].r, run_[i].t);
    run_n_ = 0;
  }
  /// Drops the run as outliers, judged against the base (or, before any base, the time that displaced it).
  void drop_run(std::int64_t ref) noexcept {
    for (std::uint32_t i = 0; i < run_n_; ++i) drop(run_[i], false, ref);
    run_n_ = 0;
  }
  void drop_run() noexcept { drop_run(base_); }
  void drop(const Held& h, bool backwards, std::int64_t ref) noexcept {
    ++(backwards ? backwards_ : outliers_);
    if (drops_n_ < drops_.size()) drops_[drops_n_++] = TimeDrop{h.line, h.t, ref, backwards};
  }

  TimeSanityOptions opt_;
  bool have_base_ = false;
  std::int64_t base_ = 0;  ///< time of the last accepted record
  std::array<Held, kMaxRebase> run_{};
  std::uint32_t run_n_ = 0;
  // Between two pop() runs at most one run plus one record become ready.
  std::array<Rec, kMaxRebase + 2> ready_{};
  std::size_t ready_head_ = 0, ready_tail_ = 0;
  std::array<TimeDrop, kMaxRebase + 1> drops_{};
  std::size_t drops_n_ = 0;
  std::uint64_t outliers_ = 0, backwards_ = 0, rebases_ = 0;
};

/// What a line-based file source's next() does after next_line_or_record().
enum class LineStep : std::uint8_t {
  kRecord,  ///< `out` holds a record the time sanity check released (counted in stats.records)
  kEnd,     ///< input finished and every held record handed out: return finish_lines(...)
  kLine,    ///< `line` holds the next input line to parse
};

/// The common head of a line-based file source's next() (candump log, bare edge list): hands out the records
/// the time sanity check released, else reads the next line; at the end of the input it finishes the check
/// first (its drops through note_drop(const TimeDrop&), the re-base count into stats), so the records it
/// still held come out before kEnd. Real-time safe (Reader: LineReader).
template <class Rec, class Reader, class NoteDrop>
[[nodiscard]] LineStep next_line_or_record(TimeSanity<Rec>& sanity, Reader& reader, bool& eof,
                                           SourceStats& stats, Rec& out, std::string_view& line,
                                           NoteDrop&& note_drop) noexcept {
  for (;;) {
    if (sanity.pop(out)) {
      ++stats.records;
      return LineStep::kRecord;
    }
    if (eof) return LineStep::kEnd;
    if (reader.next(line)) return LineStep::kLine;
    eof = true;
    sanity.finish();
    sanity.drain_drops(note_drop);
    stats.time_rebases = sanity.rebases();
  }
}

}  // namespace torqued
