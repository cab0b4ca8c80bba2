#pragma once
// Seeded random numbers for the simulator: std::mt19937_64 (its output sequence is fixed by the standard)
// with our own uniform mapping and Box-Muller, so results never depend on the standard library's
// distributions.
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace torqued::sim {

class SimRandom {
 public:
  /// Independent stream `stream` of seed `seed` (SplitMix64 mixing), so that adding draws to one sensor
  /// does not change the others.
  SimRandom(std::uint64_t seed, std::uint64_t stream)
      : engine_(mix(seed ^ mix(stream + 0x9E3779B97F4A7C15ull))) {}

  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  /// Uniform in [-a, a).
  double symmetric(double a) { return a * (2.0 * uniform() - 1.0); }
  /// Standard normal by Box-Muller (both values used).
  double gaussian() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = uniform();
    while (u1 <= 0.0) u1 = uniform();
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * std::numbers::pi * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * std::numbers::pi * u2);
  }
  double gaussian(double sd) { return sd * gaussian(); }

 private:
  static std::uint64_t mix(std::uint64_t x) {
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
  }
  std::mt19937_64 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace torqued::sim
