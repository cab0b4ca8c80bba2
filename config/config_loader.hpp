#pragma once
// YAML → validated Config. Every error is collected (not just the first), each formatted
//   FILE:LINE:COL: key 'engine.bore_m': found '-0.08', expected a number > 0 (m, range (0, 1])
// Unknown keys are errors (with "did you mean"); values are rejected, never clamped.
#include <optional>
#include <string>
#include <vector>

#include "config.hpp"

namespace torqued {

struct LoadResult {
  std::optional<Config> config;       ///< set only when errors is empty
  std::vector<std::string> errors;    ///< one formatted message per problem
  std::vector<std::string> warnings;  ///< accepted but suspicious (e.g. no CAN input)
  [[nodiscard]] bool ok() const noexcept { return config.has_value() && errors.empty(); }
};

struct LoadOptions {
  bool check_files =
      true;  ///< require the input files named in the config to exist (off: validate for another machine)
  /// run check_config_physics() (observer stability: eigenvalues over a cycle, milliseconds per new set of
  /// gains); off only where a caller samples it (the config fuzz target runs it on 1 input in 64)
  bool check_physics = true;
};

/// Load and validate a YAML configuration file. Never throws.
[[nodiscard]] LoadResult load_config(const std::string& path, const LoadOptions& options = {});
/// Same, from text; `file_name` is used in messages and its directory resolves relative paths.
[[nodiscard]] LoadResult load_config_from_string(const std::string& yaml, const std::string& file_name,
                                                 const LoadOptions& options = {});

/// Cross-field checks that only need the Config (no YAML marks); each problem is a "key: reason" pair.
struct ConfigProblem {
  std::string key;
  std::string found;
  std::string expected;
};
[[nodiscard]] std::vector<ConfigProblem> check_config_physics(const Config& c);

/// Fourier observer stability (CF-14): L_ke > (Δα/2) Σ_k l_k f_k(n)² for every sample n of the cycle, and
/// 2 n_h + 1 < samples per cycle. Hook for the estimator's own check (FourierObserver::check_stability).
/// Returns the reason when the gains are refused.
[[nodiscard]] std::optional<std::string> check_fourier_stability(const FourierParams& p,
                                                                 const WheelGeometry& w);

}  // namespace torqued
