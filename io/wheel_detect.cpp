// Wheel detection from a capture. See wheel_detect.hpp.
#include "wheel_detect.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

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

void find_matches(WheelDetection& d) {
  for (const NamedWheel& w : wheel_catalogue()) {
    if (w.n_cam > 0 || w.width_coded || w.positions != d.positions) continue;
    if (same_up_to_rotation(std::vector<int>(w.runs, w.runs + w.n_runs), d.runs))
      d.matches.emplace_back(w.name);
  }
  if (d.runs.size() == 2) d.matches.push_back(std::to_string(d.positions) + "-" + std::to_string(d.runs[1]));
}

}  // namespace

WheelDetection detect_wheel(std::span<const std::int64_t> t) {
  WheelDetection d;
  if (t.size() < 3) return d.error = "fewer than 3 teeth", d;
  std::vector<std::int64_t> p(t.size() - 1);
  for (std::size_t k = 0; k + 1 < t.size(); ++k) p[k] = t[k + 1] - t[k];
  // (teeth, missing) per gap, and the index of the tooth closing each gap.
  std::vector<std::pair<int, double>> seq;  ///< teeth before the gap, gap period / neighbours' median
  std::vector<std::size_t> gap_end;
  int teeth = -1;  // -1: before the first gap (partial run, dropped)
  for (std::size_t k = 0; k < p.size(); ++k) {
    const double r = ratio_to_neighbours(p, k);
    if (r < 0.6) {
      ++d.noise_periods;
      continue;
    }
    if (r < 1.5) {
      if (teeth >= 0) ++teeth;
      continue;
    }
    if (teeth >= 0) seq.emplace_back(teeth + 1, r);
    gap_end.push_back(k + 1);
    teeth = 0;
  }
  const int len = cycle_length(seq);
  if (seq.size() < 2 || len == 0) {
    char buf[120];
    std::snprintf(buf, sizeof buf, "no repeating gap structure (%zu gaps in %zu teeth, %d noise periods)",
                  gap_end.size(), t.size(), d.noise_periods);
    return d.error = buf, d;
  }
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
  // Per revolution: the time between closings of the same gap, len gaps apart.
  d.rpm_min = 1e300;
  for (std::size_t g = 0; g + static_cast<std::size_t>(len) < gap_end.size(); ++g) {
    const double rev_s = static_cast<double>(t[gap_end[g + len]] - t[gap_end[g]]) * 1e-9;
    d.rpm_min = std::min(d.rpm_min, 60.0 / rev_s);
    d.rpm_max = std::max(d.rpm_max, 60.0 / rev_s);
    ++d.revolutions;
  }
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
  find_matches(d);
  return d;
}

std::string describe(const WheelDetection& d) {
  if (!d.error.empty()) return "detect-wheel: " + d.error + "\n";
  std::string s = "wheel: " + std::to_string(d.positions) + " positions, " +
                  std::to_string(d.tooth_angles_deg.size()) + " teeth; runs (teeth, missing):";
  for (std::size_t i = 0; i < d.runs.size(); ++i) s += (i == 0 ? " " : ", ") + std::to_string(d.runs[i]);
  char buf[160];
  std::snprintf(buf, sizeof buf, "\nseen: %d revolutions, %.0f-%.0f rpm (per revolution), %d noise periods\n",
                d.revolutions, d.rpm_min, d.rpm_max, d.noise_periods);
  s += buf;
  s += "catalogue: ";
  for (std::size_t i = 0; i < d.matches.size(); ++i) s += (i == 0 ? "" : ", ") + d.matches[i];
  s += d.matches.empty() ? "no entry (paste the angles below)\n" : "\n";
  if (!d.decoder_error.empty()) s += "decoder: refuses this wheel by itself: " + d.decoder_error + "\n";
  s += "wheel:\n  tooth_angles_deg: [";
  for (std::size_t i = 0; i < d.tooth_angles_deg.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%.10g", i == 0 ? "" : ", ", d.tooth_angles_deg[i]);
    s += buf;
  }
  return s + "]\n";
}

}  // namespace torqued
