// Wheel detection from a capture. See wheel_detect.hpp.
#include "wheel_detect.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>

#include "crank_decoder.hpp"
#include "wheel_names.hpp"

namespace torqued {
namespace {

/// Period k over the median of its (up to 8) neighbours: 1 for a tooth, ~M+1 for a gap of M missing.
double ratio_to_neighbours(std::span<const std::int64_t> p, std::size_t k) {
  std::array<std::int64_t, 8> nb{};
  std::size_t n = 0;
  for (std::size_t j = k >= 4 ? k - 4 : 0; j <= k + 4 && j < p.size(); ++j)
    if (j != k && n < nb.size()) nb[n++] = p[j];
  if (n == 0) return 1.0;
  std::nth_element(nb.begin(), nb.begin() + static_cast<std::ptrdiff_t>(n / 2), nb.begin() + n);
  return static_cast<double>(p[k]) / static_cast<double>(nb[n / 2]);
}

/// Whether b equals a rotated by an even number of entries (a run list starts with teeth).
bool same_up_to_rotation(const std::vector<int>& a, const std::vector<int>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t r = 0; r < a.size(); r += 2) {
    bool eq = true;
    for (std::size_t i = 0; i < a.size() && eq; ++i) eq = a[(i + r) % a.size()] == b[i];
    if (eq) return true;
  }
  return false;
}

/// Smallest number of gaps after which the sequence of teeth between gaps repeats, allowing 10 % mismatches
/// (the gap ratios vary too much while cranking to compare: the missing counts come from their medians).
int cycle_length(const std::vector<std::pair<int, double>>& seq) {
  const int n = static_cast<int>(seq.size());
  for (int len = 1; len <= std::min(16, n / 2); ++len) {
    int bad = 0;
    for (int i = 0; i + len < n; ++i)
      bad += seq[static_cast<std::size_t>(i)].first != seq[static_cast<std::size_t>(i + len)].first;
    if (bad * 10 <= n - len) return len;
  }
  return 0;
}

/// Turns per cycle of a catalogue entry whose runs repeat k times per turn (k >= 1), its repeat in `rep`.
int runs_repeat(const NamedWheel& w, std::vector<int>& rep) {
  const int G = w.n_runs / 2;
  for (int p = 1; p <= G; ++p) {
    if (G % p != 0) continue;
    bool eq = true;
    for (int j = 0; j < w.n_runs && eq; ++j) eq = w.runs[j] == w.runs[j % (2 * p)];
    if (!eq) continue;
    rep.assign(w.runs, w.runs + 2 * p);
    return G / p;
  }
  return 1;
}

/// Catalogue entries with the detected cycle. An entry whose runs repeat k >= 2 times per turn shows the same
/// cycle as the wheel turning once per cycle (36-2-2-16-16 and 18-2): the edge times cannot tell them, so
/// all are candidates, unless the cam (720 deg) gives the teeth per turn. Returns the cycles per turn of the
/// matches (1 unless the cam named an entry repeating k times per turn).
int find_matches(WheelDetection& d) {
  int cycle_teeth = 0;
  for (std::size_t i = 0; i < d.runs.size(); i += 2) cycle_teeth += d.runs[i];
  std::vector<std::pair<std::string, int>> hits;  // name, cycles per turn
  for (const NamedWheel& w : wheel_catalogue()) {
    if (w.n_cam > 0 || w.width_coded) continue;
    std::vector<int> rep;
    const int k = runs_repeat(w, rep);
    if (w.positions == d.positions * k && same_up_to_rotation(rep, d.runs)) hits.emplace_back(w.name, k);
  }
  if (d.runs.size() == 2) hits.emplace_back(std::to_string(d.positions) + "-" + std::to_string(d.runs[1]), 1);
  const bool several_k = std::any_of(hits.begin(), hits.end(), [](const auto& h) { return h.second > 1; });
  int turn_k = 1;
  for (const auto& [name, k] : hits) {
    // the cam turns once per 720 deg: 2 k cycles per cam turn
    const bool cam_says = d.cam_cycle_teeth > 0 && d.cam_cycle_teeth == 2 * k * cycle_teeth;
    if (!several_k || cam_says) d.matches.push_back(name);
    if (several_k && cam_says) turn_k = k;
  }
  if (!several_k || !d.matches.empty()) return turn_k;
  for (const auto& [name, k] : hits) {
    d.candidates.push_back(name);
    d.ambiguity +=
        name + (k == 1 ? ": the cycle once per turn; " : ": " + std::to_string(k) + " times per turn; ");
  }
  d.ambiguity += "edge times cannot tell (the speed and every angle differ by the factor); a cam column can";
  return 1;
}

// Pattern wheels (no missing-tooth gap: 4g63, miata-nb2, nissan-cas-24+1, ...): the tooth periods repeat
// every N teeth. Tolerances, with their physical reason:
/// A period against the one N teeth later, the speed change removed (ratio of the time of the N-multiple
/// window around each): at the true N the compression ripple (up to +-20 % speed while cranking) is in phase
/// and cancels; what remains is edge jitter (+-2 % per edge: up to +-8 % on a ratio of two periods) and the
/// curvature of the cranking speed trend. 0.15 still tells a 70/110 deg spacing (ratio 1.57) from equal ones.
constexpr double kPeriodTol = 0.15;
/// Share of the periods that must repeat: noise periods, stalls and the first compressions spoil the
/// comparisons around them (nb2-cranking-good.csv: 72 % repeat at N = 2, the wrong N <= 10 %).
constexpr double kMinPatternFit = 0.6;
/// A tooth spacing read off the periods vs the catalogue's (relative): the compression ripple distorts a
/// spacing read off time by up to the speed ripple it spans (+-20 % cranking), plus jitter.
constexpr double kSpacingTol = 0.3;
/// A repeat is cut to a shorter one when its spacings agree within this (relative). A repeat of 2 teeth: the
/// averaged spacings keep the jitter's mean only, and 70/110 deg (miata-nb2) is +-22 % from equal. From 3
/// teeth on the repeat can be a compression cycle of an equally spaced wheel whose in-phase speed ripple
/// (+-20 % while cranking) stays in the averaged spacings: kSpacingTol.
constexpr double kReduceTol = 0.1;
constexpr int kMaxPatternTeeth = 64;  ///< repeats longer than this are not looked for
constexpr int kMinWindowTeeth = 8;    ///< the speed-trend window spans at least this many teeth

/// Share of the periods i with p[i+N]/p[i] equal (within kPeriodTol) to the local speed change, and the
/// longest run of consecutive repeating periods [best_a, best_a + best_n).
struct PatternFit {
  double fit = 0.0;
  std::size_t a = 0, n = 0;
};

PatternFit pattern_fit(const std::vector<double>& cum, std::size_t np, std::size_t N) {
  const std::size_t w = N * ((kMinWindowTeeth + N - 1) / N), h = w / 2;
  PatternFit f;
  std::size_t total = 0, good = 0, run_a = 0, run_n = 0;
  for (std::size_t i = h; i + N + w - h <= np; ++i) {
    const double s0 = cum[i - h + w] - cum[i - h], s1 = cum[i + N - h + w] - cum[i + N - h];
    const double p0 = cum[i + 1] - cum[i], p1 = cum[i + N + 1] - cum[i + N];
    const bool ok = p0 > 0.0 && s1 > 0.0 && std::abs((p1 / p0) * (s0 / s1) - 1.0) < kPeriodTol;
    ++total;
    good += ok;
    if (!ok) run_n = 0;
    if (ok && run_n++ == 0) run_a = i;
    if (run_n > f.n) f.a = run_a, f.n = run_n;
  }
  f.fit = total > 0 ? static_cast<double>(good) / static_cast<double>(total) : 0.0;
  f.n += N;  // the run's comparisons cover N more periods
  return f;
}

/// Spacings (fractions of the repeat) averaged over the clean stretch, each period over the N around it.
std::vector<double> mean_spacings(const std::vector<double>& cum, std::size_t N, const PatternFit& f) {
  std::vector<double> a(N, 0.0);
  std::vector<int> cnt(N, 0);
  const std::size_t h = N / 2;
  for (std::size_t i = f.a + h; i + N - h <= f.a + f.n; ++i) {
    a[(i - f.a) % N] += (cum[i + 1] - cum[i]) / (cum[i - h + N] - cum[i - h]);
    ++cnt[(i - f.a) % N];
  }
  double sum = 0.0;
  for (std::size_t k = 0; k < N; ++k) sum += a[k] /= std::max(1, cnt[k]);
  for (double& x : a) x /= sum;
  return a;
}

/// The smallest d dividing a.size() such that a repeats every d entries within `tol` (relative); the
/// repeat's spacings, renormalised.
std::vector<double> smallest_repeat(const std::vector<double>& a, double tol) {
  const std::size_t n = a.size();
  for (std::size_t d = 1; d < n; ++d) {
    if (n % d != 0) continue;
    std::vector<double> b(d, 0.0);
    for (std::size_t j = 0; j < n; ++j) b[j % d] += a[j] * static_cast<double>(d) / static_cast<double>(n);
    bool ok = true;
    for (std::size_t j = 0; j < n && ok; ++j) ok = std::abs(a[j] - b[j % d]) <= tol * b[j % d];
    if (!ok) continue;
    double sum = 0.0;
    for (double x : b) sum += x;
    for (double& x : b) x /= sum;
    return b;
  }
  return a;
}

/// A catalogue entry's smallest repeat: its spacings (fractions) and the crank degrees it spans.
std::vector<double> catalogue_repeat(const NamedWheel& w, double& repeat_deg) {
  WheelGeometry g;
  repeat_deg = 0.0;
  if (!wheel_from_runs(w.positions, w.runs, w.n_runs, g, nullptr)) return {};
  const int n = g.teeth();
  std::vector<double> s(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) {
    const double a0 = g.tooth_angles_deg[static_cast<std::size_t>(j)];
    const double a1 = j + 1 < n ? g.tooth_angles_deg[static_cast<std::size_t>(j + 1)] : 360.0;
    s[static_cast<std::size_t>(j)] = (a1 - a0) / 360.0;
  }
  std::vector<double> r = smallest_repeat(s, 1e-9);
  repeat_deg = 360.0 * static_cast<double>(r.size()) / static_cast<double>(n);
  return r;
}

/// Whether b equals a rotated, spacing by spacing within kSpacingTol.
bool spacings_match(const std::vector<double>& a, const std::vector<double>& b) {
  const std::size_t n = a.size();
  if (n != b.size()) return false;
  for (std::size_t r = 0; r < n; ++r) {
    bool ok = true;
    for (std::size_t j = 0; j < n && ok; ++j) ok = std::abs(a[(j + r) % n] - b[j]) <= kSpacingTol * b[j];
    if (ok) return true;
  }
  return false;
}

/// Whether the cam edges (angle in [0, 720), polarity; sorted) are the entry's cam pattern, rotated, each
/// within its cam tolerance.
bool cam_is(const std::vector<std::pair<double, bool>>& e, const NamedWheel& w) {
  const auto n = static_cast<std::size_t>(w.n_cam);
  if (e.size() != n || n == 0) return false;
  for (std::size_t i = 0; i < n; ++i) {
    const double off = w.cam[i].angle_deg - e[0].first;
    bool ok = true;
    for (std::size_t j = 0; j < n && ok; ++j) {
      const CamEdgeSpec& c = w.cam[(i + j) % n];
      const double diff = std::remainder(e[j].first + off - c.angle_deg, 720.0);
      ok = c.rising == e[j].second && std::abs(diff) <= w.cam_tolerance_deg;
    }
    if (ok) return true;
  }
  return false;
}

/// Whether the cam edges of an equally spaced wheel, `pitch_deg` per tooth (the entry's), show the entry's
/// cam pattern in most cam cycles of M teeth (a symmetric cam repeats within 720 deg: its cycle is then half
/// the entry's, the count per turn read off it twice the true one).
bool cam_pattern_fits(std::span<const std::int64_t> t, std::span<const WheelCamEdge> cam, std::size_t M,
                      double pitch_deg, const NamedWheel& w) {
  std::size_t windows = 0, good = 0, c = 0;
  for (std::size_t s = 0; s + M < t.size(); s += M, ++windows) {
    std::vector<std::pair<double, bool>> e;
    while (c < cam.size() && cam[c].t_ns < t[s]) ++c;
    for (std::size_t k = s; k < s + M; ++k)
      for (; c < cam.size() && cam[c].t_ns < t[k + 1]; ++c) {
        const double frac = static_cast<double>(cam[c].t_ns - t[k]) / static_cast<double>(t[k + 1] - t[k]);
        e.emplace_back((static_cast<double>(k - s) + frac) * pitch_deg, cam[c].rising);
      }
    good += cam_is(e, w);
  }
  return windows > 0 && 2 * good > windows;
}

/// Catalogue entries with the detected repeat; entries with the same tooth list (aliases: 36-2-2-17-15 and
/// jeep-evd) count as one. One entry: a match (its degrees per repeat give the angles and rpm), unless it
/// repeats k >= 2 times per turn (miata-nb2: 70/110 deg every 180 deg) and no cam shows the teeth per turn:
/// the crank cannot tell the repeats per turn (a wheel with the repeat once per turn gives the same edge
/// times), so it is a candidate only. Several (equally spaced teeth: any count per revolution fits):
/// candidates only, none printed as a match.
void match_pattern(WheelDetection& d, std::span<const std::int64_t> t, std::span<const WheelCamEdge> cam) {
  std::vector<std::pair<const NamedWheel*, double>> hits;  // one per tooth list (the first name), deg
  std::vector<std::string> names;                          // every hit's names, in catalogue order
  for (const NamedWheel& w : wheel_catalogue()) {
    if (w.width_coded) continue;  // the position is in the pulse widths (both edges), as in find_matches
    double deg = 0.0;
    if (!spacings_match(d.spacing, catalogue_repeat(w, deg))) continue;
    const double teeth_per_rev = 360.0 / deg * static_cast<double>(d.spacing.size());
    if (d.cam_cycle_teeth > 0 && std::abs(2.0 * teeth_per_rev - d.cam_cycle_teeth) > 0.5) continue;
    // equally spaced: the cam names the entry, so its edges must be the entry's cam pattern
    if (d.cam_cycle_teeth > 0 && d.spacing.size() == 1 &&
        !cam_pattern_fits(t, cam, static_cast<std::size_t>(d.cam_cycle_teeth), deg, w)) {
      d.candidates.push_back(w.name);
      d.ambiguity = "the cam's edges per cycle or their angles are not the entry's cam pattern";
      continue;
    }
    names.emplace_back(w.name);
    const bool alias = std::any_of(hits.begin(), hits.end(), [&](const auto& h) {
      return h.first->positions == w.positions &&
             std::equal(w.runs, w.runs + w.n_runs, h.first->runs, h.first->runs + h.first->n_runs);
    });
    if (!alias) hits.emplace_back(&w, deg);
  }
  if (!d.candidates.empty() || hits.size() != 1) {
    d.candidates.insert(d.candidates.end(), names.begin(), names.end());
    return;
  }
  const double per_turn = 360.0 / hits[0].second;
  if (per_turn > 1.5 && d.cam_cycle_teeth == 0) {
    d.candidates = names;
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "%s repeats its %zu teeth every %g deg, %g times per turn; edge times cannot tell how many "
                  "times a turn holds the repeat (the speed and every angle differ by the factor); a cam "
                  "column can",
                  names[0].c_str(), d.spacing.size(), hits[0].second, per_turn);
    d.ambiguity = buf;
    return;
  }
  d.matches = names;
  d.repeat_deg = hits[0].second;
}

/// Crank teeth per cam cycle: the smallest M (<= 2 kMaxPatternTeeth) after which the cam edges inside the
/// crank periods repeat (same polarities in the same order, each at the same fraction of its period within
/// kCamFracTol) for kMinCamFit of the periods that hold a cam edge. The cam turns once per 720 deg.
int cam_cycle_teeth(std::span<const std::int64_t> t, std::span<const WheelCamEdge> cam) {
  constexpr double kCamFracTol =
      0.2;  // cranking ripple moves an edge within its period by a few tenths at most
  constexpr double kMinCamFit = 0.9;  // a few glitch edges (4g63's last edges) may not repeat
  std::vector<std::vector<std::pair<bool, double>>> sig(t.size() > 0 ? t.size() - 1 : 0);
  std::size_t c = 0;
  for (std::size_t k = 0; k < sig.size(); ++k) {
    while (c < cam.size() && cam[c].t_ns < t[k]) ++c;
    for (; c < cam.size() && cam[c].t_ns < t[k + 1]; ++c)
      sig[k].emplace_back(cam[c].rising,
                          static_cast<double>(cam[c].t_ns - t[k]) / static_cast<double>(t[k + 1] - t[k]));
  }
  const auto same = [&](std::size_t a, std::size_t b) {
    if (sig[a].size() != sig[b].size()) return false;
    for (std::size_t j = 0; j < sig[a].size(); ++j)
      if (sig[a][j].first != sig[b][j].first || std::abs(sig[a][j].second - sig[b][j].second) > kCamFracTol)
        return false;
    return true;
  };
  for (std::size_t M = 1; M <= 2 * kMaxPatternTeeth && 3 * M <= sig.size(); ++M) {
    std::size_t with_cam = 0, good = 0;
    for (std::size_t k = 0; k + M < sig.size(); ++k) {
      if (sig[k].empty() && sig[k + M].empty()) continue;
      ++with_cam;
      good += same(k, k + M);
    }
    if (with_cam >= 2 && static_cast<double>(good) >= kMinCamFit * static_cast<double>(with_cam))
      return static_cast<int>(M);
  }
  return 0;
}

/// Widest spacing last (tooth 0 = the first tooth after it, as for gap wheels).
void rotate_after_widest(std::vector<double>& a) {
  const auto widest = std::max_element(a.begin(), a.end()) - a.begin();
  std::rotate(a.begin(), a.begin() + (widest + 1) % static_cast<std::ptrdiff_t>(a.size()), a.end());
}

/// Periods under 0.6 of the shortest spacing of the repeat (the time of the R periods from each as the
/// repeat).
int pattern_noise(const std::vector<double>& cum, const std::vector<double>& spacing) {
  const double shortest = *std::min_element(spacing.begin(), spacing.end());
  const std::size_t R = spacing.size(), np = cum.size() - 1;
  int n = 0;
  for (std::size_t i = 0; i + R <= np; ++i) n += cum[i + 1] - cum[i] < 0.6 * shortest * (cum[i + R] - cum[i]);
  return n;
}

/// `dropped`: the edges dropped up front (periods <= 0), counted as noise periods.
bool read_pattern_wheel(WheelDetection& d, std::span<const std::int64_t> p, std::span<const std::int64_t> t,
                        std::span<const WheelCamEdge> cam, int dropped) {
  const double t0_s = static_cast<double>(t[0]) * 1e-9;
  std::vector<double> cum(p.size() + 1, 0.0);
  for (std::size_t k = 0; k < p.size(); ++k) cum[k + 1] = cum[k] + static_cast<double>(p[k]) * 1e-9;
  for (std::size_t N = 1; N <= kMaxPatternTeeth && 3 * N + kMinWindowTeeth <= p.size(); ++N) {
    const PatternFit f = pattern_fit(cum, p.size(), N);
    if (f.fit < kMinPatternFit || f.n < 2 * N) continue;
    d.spacing = smallest_repeat(mean_spacings(cum, N, f), N >= 3 ? kSpacingTol : kReduceTol);
    rotate_after_widest(d.spacing);
    d.pattern_teeth = static_cast<int>(d.spacing.size());
    d.noise_periods = dropped + pattern_noise(cum, d.spacing);
    // a cam that does not repeat over the whole capture (start-up, stop) may over the read stretch
    if (d.cam_cycle_teeth == 0 && !cam.empty())
      d.cam_cycle_teeth = cam_cycle_teeth(t.subspan(f.a, f.n + 1), cam);
    match_pattern(d, t, cam);
    const double unit = d.repeat_deg > 0 ? d.repeat_deg / 360.0 : 1.0;  // revolutions per repeat
    const std::size_t R = d.spacing.size();
    d.rpm_min = 1e300;
    for (std::size_t i = f.a; i + R <= f.a + f.n; i += R, ++d.revolutions) {
      const double rpm = 60.0 * unit / (cum[i + R] - cum[i]);
      d.rpm_min = std::min(d.rpm_min, rpm);
      d.rpm_max = std::max(d.rpm_max, rpm);
    }
    char buf[160];
    std::snprintf(buf, sizeof buf, "%zu of %zu periods (%.3f-%.3f s), the longest run that repeats", f.n,
                  p.size(), t0_s + cum[f.a], t0_s + cum[f.a + f.n]);
    d.stretch = buf;
    double deg = 0.0;
    for (std::size_t k = 0; d.repeat_deg > 0 && k < 360.0 / d.repeat_deg * R; ++k) {
      d.tooth_angles_deg.push_back(std::round(deg * 10.0) / 10.0);
      deg += d.spacing[k % R] * d.repeat_deg;
    }
    return true;
  }
  return false;
}

/// Whether most marking periods equal their neighbours' mean: a width-coded wheel's marking edges are
/// equally spaced (GM 24x: every 15 deg); an uneven wheel's (miata-nb2: 70/110 deg) are not, and there a
/// constant tooth width gives two duties with nothing coded. The tolerance passes cranking ripple between
/// neighbouring teeth (a few %) and a gap (one period in a revolution); 70/110 is -36/+57 %.
bool marking_periods_equal(std::span<const std::int64_t> t) {
  constexpr double kEqualTol = 0.25;
  constexpr double kMinEqualShare = 0.8;
  std::size_t n = 0, eq = 0;
  for (std::size_t k = 1; k + 3 < t.size(); ++k, ++n) {
    const double mean = 0.5 * static_cast<double>(t[k] - t[k - 1] + t[k + 2] - t[k + 1]);
    eq += mean > 0 && std::abs(static_cast<double>(t[k + 1] - t[k]) / mean - 1.0) < kEqualTol;
  }
  return n > 0 && static_cast<double>(eq) >= kMinEqualShare * static_cast<double>(n);
}

/// Duty of each marking period (other-polarity edge inside it): two clusters far apart, with equally spaced
/// marking edges = width-coded.
std::string width_code(std::span<const std::int64_t> t, std::span<const std::int64_t> other) {
  constexpr double kDutyGap = 0.25;  // two widths, e.g. GM 24x 3 deg vs 12 deg of 15 (duty 0.2 / 0.8)
  constexpr double kMinShare = 0.2;  // each width on at least a fifth of the teeth (a gap is one tooth)
  if (!marking_periods_equal(t)) return "";
  std::vector<double> duty;
  std::size_t o = 0;
  for (std::size_t k = 0; k + 1 < t.size(); ++k) {
    while (o < other.size() && other[o] <= t[k]) ++o;
    if (o < other.size() && other[o] < t[k + 1])
      duty.push_back(static_cast<double>(other[o] - t[k]) / static_cast<double>(t[k + 1] - t[k]));
  }
  if (duty.size() < 10) return "";
  std::sort(duty.begin(), duty.end());
  const std::size_t lo = static_cast<std::size_t>(static_cast<double>(duty.size()) * kMinShare);
  for (std::size_t i = lo; i + lo < duty.size(); ++i) {
    if (duty[i] - duty[i - 1] < kDutyGap) continue;
    std::string names;
    for (const NamedWheel& w : wheel_catalogue())
      if (w.width_coded) names += std::string(names.empty() ? "" : ", ") + w.name;
    char buf[300];
    std::snprintf(buf, sizeof buf,
                  "pulse-width-coded wheel (duty %.2f-%.2f or %.2f-%.2f of a period): the position is in the "
                  "widths, not the edge times; it needs both edges: --wheel NAME with a width-coded entry "
                  "(%s)",
                  duty.front(), duty[i - 1], duty[i], duty.back(), names.c_str());
    return buf;
  }
  return "";
}

/// The gaps of a capture: (teeth before the gap, gap ratio), the index of the tooth closing each gap and
/// whether a noise period lies in the run before it.
struct GapScan {
  std::vector<std::pair<int, double>> seq;
  std::vector<std::size_t> gap_end;
  std::vector<bool> noisy;  ///< per seq entry
};

/// Gap k's period over the mean of the nearest tooth periods before and after it (ratio to neighbours in
/// [0.6, 1.5)): the local speed at the gap, interpolated, follows the cranking ripple that the median of 8
/// neighbours spanning 80+ deg does not (+-20 % ripple made a 3-period gap read as 4).
double gap_ratio(std::span<const std::int64_t> p, std::size_t k, double fallback) {
  const auto tooth = [&](std::size_t j) {
    const double r = ratio_to_neighbours(p, j);
    return r >= 0.6 && r < 1.5;
  };
  std::size_t a = k, b = k + 1;
  while (a > 0 && k - a < 8 && !tooth(a - 1)) --a;
  while (b < p.size() && b - k < 8 && !tooth(b)) ++b;
  if (a == 0 || b >= p.size() || !tooth(a - 1) || !tooth(b)) return fallback;
  return 2.0 * static_cast<double>(p[k]) / static_cast<double>(p[a - 1] + p[b]);
}

GapScan scan_gaps(std::span<const std::int64_t> p, int& noise_periods) {
  GapScan g;
  int teeth = -1;  // -1: before the first gap (partial run, dropped)
  bool noisy = false;
  for (std::size_t k = 0; k < p.size(); ++k) {
    const double r = ratio_to_neighbours(p, k);
    if (r < 0.6) {
      ++noise_periods;
      noisy = true;
      continue;
    }
    if (r < 1.5) {
      if (teeth >= 0) ++teeth;
      continue;
    }
    if (teeth >= 0) {
      g.seq.emplace_back(teeth + 1, gap_ratio(p, k, r));
      g.noisy.push_back(noisy);
    }
    g.gap_end.push_back(k + 1);
    teeth = 0;
    noisy = false;
  }
  return g;
}

/// A noisy or stalling capture (one pass per len: O(16 n)): keeps the longest stretch of gaps without a noise
/// period in which the teeth between gaps repeat exactly every `len` gaps (len <= 16), at least
/// kMinCleanCycles cycles long. Returns len (0: none) and cuts `g` to the stretch.
int clean_stretch(GapScan& g) {
  // 3 whole revolutions: the structure seen to repeat twice (once can be chance in noise)
  constexpr int kMinCleanCycles = 3;
  std::size_t best_a = 0, best_n = 0;
  int best_len = 0;
  const std::size_t n = g.seq.size();
  for (int len = 1; len <= 16; ++len) {
    const auto ul = static_cast<std::size_t>(len);
    // one pass: a = the earliest start of a clean stretch [a, b] (no noise, seq[i] == seq[i - len] for
    // i >= a + len); a mismatch at b moves it just past b - len, a noise period past b
    for (std::size_t a = 0, b = 0; b < n; ++b) {
      if (g.noisy[b]) {
        a = b + 1;
        continue;
      }
      if (b >= a + ul && g.seq[b].first != g.seq[b - ul].first) a = b - ul + 1;
      const std::size_t len_ab = b + 1 - a;
      if (len_ab >= ul * kMinCleanCycles && len_ab > best_n) best_a = a, best_n = len_ab, best_len = len;
    }
  }
  if (best_len == 0) return 0;
  g.seq = std::vector<std::pair<int, double>>(g.seq.begin() + static_cast<std::ptrdiff_t>(best_a),
                                              g.seq.begin() + static_cast<std::ptrdiff_t>(best_a + best_n));
  // seq[i] is the run between gap_end[i] and gap_end[i + 1]: keep the gaps bounding the kept runs
  g.gap_end = std::vector<std::size_t>(g.gap_end.begin() + static_cast<std::ptrdiff_t>(best_a),
                                       g.gap_end.begin() + static_cast<std::ptrdiff_t>(best_a + best_n + 1));
  return best_len;
}

// Evidence a gap wheel must show before an entry is named (random periods of a noise capture repeat a short
// cycle by chance: 7 of 30 seeded 300-period captures did for 3 cycles of 7 teeth or fewer):
/// revolutions: the structure seen to repeat at least twice
constexpr int kMinEvidenceRevolutions = 3;
/// teeth: a chance repeat of n gaps over a few teeth is likely; over 60 tooth periods (a 60-2's turn) it is
/// not
constexpr std::size_t kMinEvidenceTeeth = 60;
/// share of the capture's teeth the read stretch spans: a stretch a few percent of a noisy capture is what
/// chance gives (noisy-trigger-2, a real noisy 36-2 capture, reads ~20 %)
constexpr double kMinEvidenceShare = 0.1;
/// a gap's ratio vs the median of the same cycle position: each gap must give the same missing count (the
/// count is the ratio rounded, minus one: +-0.5 changes it); local-speed interpolation keeps a real gap's
/// ratio within a few tenths under +-20 % cranking ripple
constexpr double kGapRatioSpread = 0.5;
/// share of the gaps allowed off that (a stall or the first compressions: arctic-cat.csv has 1 in 30)
constexpr double kMaxGapsOff = 0.2;

/// Why the read gap wheel is too thin to be named ("" = enough evidence). `cyc`: (teeth, missing) per
/// cycle position, in the order of g.seq.
std::string thin_evidence(const WheelDetection& d, std::size_t all_teeth, const GapScan& g,
                          const std::vector<std::pair<int, int>>& cyc) {
  const std::size_t teeth = g.gap_end.back() - g.gap_end.front();
  char buf[160];
  if (d.revolutions < kMinEvidenceRevolutions || teeth < kMinEvidenceTeeth ||
      static_cast<double>(teeth) < kMinEvidenceShare * static_cast<double>(all_teeth)) {
    std::snprintf(
        buf, sizeof buf,
        "%d revolutions, %zu of %zu teeth (a name needs %d revolutions, %zu teeth and %.0f %% of the "
        "capture)",
        d.revolutions, teeth, all_teeth, kMinEvidenceRevolutions, kMinEvidenceTeeth,
        100.0 * kMinEvidenceShare);
    return buf;
  }
  std::size_t off = 0, worst = 0;
  const std::size_t len = cyc.size();
  for (std::size_t i = 0; i < len; ++i) {
    std::vector<double> r;
    for (std::size_t k = i; k < g.seq.size(); k += len) r.push_back(g.seq[k].second);
    std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
    const double median = r[r.size() / 2];
    for (std::size_t k = i; k < g.seq.size(); k += len) {
      const bool bad = std::abs(g.seq[k].second - median) >= kGapRatioSpread;
      if (bad && off++ == 0) worst = k;
    }
  }
  if (static_cast<double>(off) > kMaxGapsOff * static_cast<double>(g.seq.size())) {
    std::snprintf(buf, sizeof buf,
                  "%zu of %zu gaps are 0.5+ periods off their cycle position's median, e.g. gap %zu: %.2f "
                  "periods",
                  off, g.seq.size(), worst, g.seq[worst].second);
    return buf;
  }
  return "";
}

/// The gap wheel of `len` gaps per cycle read off `g`: runs, speed, tooth angles, decoder check, matches.
WheelDetection& read_gap_wheel(WheelDetection& d, std::span<const std::int64_t> t, const GapScan& g,
                               int len) {
  const auto& seq = g.seq;
  const auto& gap_end = g.gap_end;
  // Missing teeth of each gap of the cycle: its median ratio, rounded, minus one.
  std::vector<std::pair<int, int>> cyc(static_cast<std::size_t>(len));
  for (int i = 0; i < len; ++i) {
    std::vector<double> r;
    for (std::size_t k = static_cast<std::size_t>(i); k < seq.size(); k += static_cast<std::size_t>(len))
      r.push_back(seq[k].second);
    std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
    cyc[static_cast<std::size_t>(i)] = {seq[static_cast<std::size_t>(i)].first,
                                        std::max(1, static_cast<int>(std::lround(r[r.size() / 2])) - 1)};
  }
  // Start after the widest gap, then the longest run after it.
  const auto ulen = static_cast<std::size_t>(len);
  std::size_t best = 0;
  for (std::size_t i = 1; i < ulen; ++i) {
    const auto& a = cyc[(i + ulen - 1) % ulen];
    const auto& b = cyc[(best + ulen - 1) % ulen];
    if (a.second > b.second || (a.second == b.second && cyc[i].first > cyc[best].first)) best = i;
  }
  for (std::size_t i = 0; i < ulen; ++i) {
    const auto& [n_teeth, missing] = cyc[(best + i) % ulen];
    d.runs.push_back(n_teeth);
    d.runs.push_back(missing);
    d.positions += n_teeth + missing;
  }
  // The cam can show the cycle to be 1/k of a turn (36-2-2-16-16): the wheel is then k cycles.
  const int turn_k = find_matches(d);
  const std::vector<int> cycle_runs = d.runs;
  for (int j = 1; j < turn_k; ++j) d.runs.insert(d.runs.end(), cycle_runs.begin(), cycle_runs.end());
  d.positions *= turn_k;
  const std::size_t turn = ulen * static_cast<std::size_t>(turn_k);
  // Per revolution: the time between closings of the same gap, one turn (len gaps per cycle) apart (every
  // one-turn window, sliding gap by gap); the whole turns between the first and the last gap read.
  d.rpm_min = 1e300;
  for (std::size_t k = 0; k + turn < gap_end.size(); ++k) {
    const double rev_s = static_cast<double>(t[gap_end[k + turn]] - t[gap_end[k]]) * 1e-9;
    d.rpm_min = std::min(d.rpm_min, 60.0 / rev_s);
    d.rpm_max = std::max(d.rpm_max, 60.0 / rev_s);
  }
  d.revolutions = gap_end.empty() ? 0 : static_cast<int>((gap_end.size() - 1) / turn);
  if (d.revolutions == 0) d.rpm_min = 0.0;
  WheelGeometry w;
  std::string err;
  if (!wheel_from_runs(d.positions, d.runs.data(), static_cast<int>(d.runs.size()), w, &err)) {
    d.error = err;
    return d;
  }
  for (int i = 0; i < w.teeth(); ++i)
    d.tooth_angles_deg.push_back(w.tooth_angles_deg[static_cast<std::size_t>(i)]);
  const CrankDecoder dec(w, DecoderParams{});
  if (!dec.valid()) d.decoder_error = dec.error();
  d.thin = thin_evidence(d, t.size(), g, cyc);
  if (!d.thin.empty()) d.candidates.insert(d.candidates.end(), d.matches.begin(), d.matches.end());
  if (!d.thin.empty()) d.matches.clear();
  return d;
}

}  // namespace

WheelDetection detect_wheel(std::span<const std::int64_t> t, std::span<const std::int64_t> other,
                            std::span<const WheelCamEdge> cam) {
  WheelDetection d;
  // A period <= 0 (a duplicated time stamp; through this API also an out-of-order one) is noise: its closing
  // edge is dropped up front, so every ratio below divides by a positive time.
  std::vector<std::int64_t> kept;
  const std::size_t all_edges = t.size();
  if (std::adjacent_find(t.begin(), t.end(), std::greater_equal<>{}) != t.end()) {
    for (const std::int64_t x : t)
      if (kept.empty() || x > kept.back()) kept.push_back(x);
    t = kept;
  }
  const int dropped = d.noise_periods = static_cast<int>(all_edges - t.size());
  if (t.size() < 3) return d.error = "fewer than 3 teeth", d;
  std::vector<std::int64_t> p(t.size() - 1);
  for (std::size_t k = 0; k + 1 < t.size(); ++k) p[k] = t[k + 1] - t[k];
  d.width_code = width_code(t, other);
  if (d.width_code.empty()) d.width_code = width_code(other, t);  // the widths seen from the other edge
  GapScan g = scan_gaps(p, d.noise_periods);
  const std::size_t all_gaps = g.gap_end.size();
  int len = g.seq.size() >= 2 ? cycle_length(g.seq) : 0;
  if (len == 0) {
    len = clean_stretch(g);
    if (len > 0) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "%zu of %zu gaps (%.3f-%.3f s): the longest stretch without noise periods or stalls "
                    "in which the gaps repeat",
                    g.gap_end.size(), all_gaps, static_cast<double>(t[g.gap_end.front()]) * 1e-9,
                    static_cast<double>(t[g.gap_end.back()]) * 1e-9);
      d.stretch = buf;
    }
  }
  if (!d.width_code.empty()) return d.error = d.width_code, d;
  d.cam_cycle_teeth = cam_cycle_teeth(t, cam);
  if (len > 0) return read_gap_wheel(d, t, g, len);
  if (read_pattern_wheel(d, p, t, cam, dropped)) return d;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "no repeating gap structure (%zu gaps in %zu teeth, %d noise periods; no stretch without "
                "noise periods repeats its gaps for 3 revolutions) and no tooth pattern repeating in %.0f %% "
                "of the periods: too noisy or irregular to read",
                all_gaps, t.size(), d.noise_periods, 100.0 * kMinPatternFit);
  return d.error = buf, d;
}

namespace {

/// Report lines of a pattern wheel (no missing-tooth gap).
std::string describe_pattern(const WheelDetection& d) {
  char buf[200];
  std::string s = "wheel: no missing-tooth gap; the tooth periods repeat every " +
                  std::to_string(d.pattern_teeth) + (d.pattern_teeth == 1 ? " tooth" : " teeth") +
                  ", spacings (fractions of the repeat):";
  for (std::size_t i = 0; i < d.spacing.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%.3f", i == 0 ? " " : ", ", d.spacing[i]);
    s += buf;
  }
  if (d.repeat_deg > 0)
    std::snprintf(buf, sizeof buf,
                  "\nseen: %d repeats of %.0f deg, %.0f-%.0f rpm (per repeat), %d noise periods\n",
                  d.revolutions, d.repeat_deg, d.rpm_min, d.rpm_max, d.noise_periods);
  else
    std::snprintf(buf, sizeof buf,
                  "\nseen: %d repeats, %.0f-%.0f per minute (degrees per repeat unknown), %d "
                  "noise periods\n",
                  d.revolutions, d.rpm_min, d.rpm_max, d.noise_periods);
  s += buf + ("read: " + d.stretch + "\n");
  if (d.cam_cycle_teeth > 0) {
    std::snprintf(buf, sizeof buf,
                  "cam: its edges repeat every %d crank teeth (one cam turn = 720 deg: %g teeth per "
                  "revolution)\n",
                  d.cam_cycle_teeth, d.cam_cycle_teeth / 2.0);
    s += buf;
  }
  if (!d.matches.empty()) {
    s += "catalogue: " + d.matches[0];
    for (std::size_t i = 1; i < d.matches.size(); ++i) s += ", " + d.matches[i];
    std::snprintf(buf, sizeof buf,
                  " (its teeth repeat every %g deg: the crank alone gives the position only within that; its "
                  "cam or code resolves it)",
                  d.repeat_deg);
    if (d.repeat_deg < 360.0) s += buf;
    s += "\n";
  } else if (!d.ambiguity.empty()) {
    s += "catalogue: not identified: candidates";
    for (std::size_t i = 0; i < d.candidates.size(); ++i) s += (i == 0 ? " " : ", ") + d.candidates[i];
    s += " (" + d.ambiguity + ")\n";
  } else if (!d.candidates.empty()) {
    s += "catalogue: not identified by the crank alone: equally good for";
    for (std::size_t i = 0; i < d.candidates.size(); ++i) s += (i == 0 ? " " : ", ") + d.candidates[i];
    s += " (equally spaced teeth: the count per revolution is not in the periods; the cam or the "
         "pulse widths tell them apart)\n";
  } else {
    s += "catalogue: no entry has this repeat\n";
  }
  if (d.tooth_angles_deg.empty())
    return s + "wheel: tooth_angles_deg not determined (degrees per repeat unknown)\n";
  s += "wheel:\n  tooth_angles_deg: [";
  for (std::size_t i = 0; i < d.tooth_angles_deg.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%.10g", i == 0 ? "" : ", ", d.tooth_angles_deg[i]);
    s += buf;
  }
  return s + "]\n";
}

}  // namespace

std::string describe(const WheelDetection& d) {
  if (!d.error.empty()) return "detect-wheel: " + d.error + "\n";
  if (d.positions == 0) return describe_pattern(d);
  std::string s = "wheel: " + std::to_string(d.positions) + " positions, " +
                  std::to_string(d.tooth_angles_deg.size()) + " teeth; runs (teeth, missing):";
  for (std::size_t i = 0; i < d.runs.size(); ++i) s += (i == 0 ? " " : ", ") + std::to_string(d.runs[i]);
  char buf[160];
  std::snprintf(buf, sizeof buf, "\nseen: %d revolutions, %.0f-%.0f rpm (per revolution), %d noise periods\n",
                d.revolutions, d.rpm_min, d.rpm_max, d.noise_periods);
  s += buf;
  if (!d.stretch.empty()) s += "read: " + d.stretch + "\n";
  s += "catalogue: ";
  for (std::size_t i = 0; i < d.matches.size(); ++i) s += (i == 0 ? "" : ", ") + d.matches[i];
  if (!d.thin.empty()) {
    s += "not identified: too little evidence (" + d.thin + "); candidates:";
    for (std::size_t i = 0; i < d.candidates.size(); ++i) s += (i == 0 ? " " : ", ") + d.candidates[i];
    s += d.candidates.empty() ? " none\n" : "\n";
  } else if (!d.candidates.empty()) {
    s += "not identified by the edge times: candidates";
    for (std::size_t i = 0; i < d.candidates.size(); ++i) s += (i == 0 ? " " : ", ") + d.candidates[i];
    s += " (" + d.ambiguity + ")\n";
  } else {
    s += d.matches.empty() ? "no entry (paste the angles below)\n" : "\n";
  }
  if (!d.decoder_error.empty()) s += "decoder: refuses this wheel by itself: " + d.decoder_error + "\n";
  s += "wheel:\n  tooth_angles_deg: [";
  for (std::size_t i = 0; i < d.tooth_angles_deg.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%.10g", i == 0 ? "" : ", ", d.tooth_angles_deg[i]);
    s += buf;
  }
  return s + "]\n";
}

}  // namespace torqued
