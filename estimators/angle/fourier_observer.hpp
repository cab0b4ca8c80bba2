#pragma once
// Chauvin's adaptive Fourier-basis observer of the mass torque (Chauvin et al., "Periodic input estimation
// for linear periodic systems: automotive engine applications" / Fourier observer paper, eqs. (2)-(14));
// docs/equations.md §2.2.
//   φ = ½ J(α) α̇²,  dφ/dα = T_ind − T*_load ≈ a0 + Σ_{i=1..n_h} a_i cos(iα/2) + b_i sin(iα/2)   (CF-2, CF-3)
//   (+ m(α), a known gas torque ripple from a cylinder-pressure model when set: set_model_torque)
// Discrete observer (CF-8/10) per tooth sample k (step Δ_k between period centres, basis at the edge e_k):
//   e_k = φ̂_k − ½ J(c_k) y_k                              (L_n (ŷ_n − y_n) = Δα [L_ke, l_j f_j]ᵀ e_k)
//   φ̂_{k+1} = φ̂_k + Δ_k m(e_k)·ĉ − Δ_k L_ke e_k
//   ĉ_j ← ĉ_j − Δ_k l_j f_j(e_k) e_k,  l_0 = L_a0, l_{2i−1} = l_{2i} = i L_ref (CF §V.B)
// Basis values are tabulated per tooth at start-up (no trigonometry per tooth).
#include <array>
#include <cstddef>
#include <cstdint>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "lag_ring.hpp"
#include "params.hpp"
#include "samples.hpp"
#include "tooth_preprocessor.hpp"

namespace torqued {

/// Allocator of 16-byte aligned storage (the basis rows' pair loads assume it, whatever the allocator in
/// use).
template <class T>
struct Aligned16Allocator {
  using value_type = T;
  Aligned16Allocator() = default;
  template <class U>
  explicit Aligned16Allocator(const Aligned16Allocator<U>& /*other*/) noexcept {}
  T* allocate(std::size_t n) { return static_cast<T*>(::operator new (n * sizeof(T), std::align_val_t{16})); }
  void deallocate(T* p, std::size_t /*n*/) noexcept { ::operator delete (p, std::align_val_t{16}); }
  template <class U>
  bool operator==(const Aligned16Allocator<U>& /*other*/) const noexcept {
    return true;
  }
};

struct FourierStats {
  std::uint64_t updates = 0;
  std::uint64_t rejected = 0;       ///< not synced / invalid sample
  std::uint64_t skipped_teeth = 0;  ///< tooth index jumps (integrated open loop)
  std::uint64_t resets = 0;         ///< numerical resets
};

class FourierObserver {
 public:
  static constexpr int kMaxHarmonics = 24;
  static constexpr int kMaxCoeffs = 2 * kMaxHarmonics + 1;
  /// Storage per coefficient row, rounded up to a multiple of 4: the per-tooth pass runs four at a time and
  /// the padding (zero coefficient, basis and gain) adds nothing.
  static constexpr int kCoeffStride = (kMaxCoeffs + 3) / 4 * 4;
  static constexpr int kMaxLag = 6;

  /// Gains must have passed check_stability(); the constructor does not re-check (config loader's job).
  FourierObserver(const EngineGeometry& engine, const WheelGeometry& wheel, const FourierParams& params);

  /// Why these gains must be refused, or nullopt when acceptable. Checks, for the configured wheel and
  /// engine: 1 ≤ n_h ≤ kMaxHarmonics, 2n_h + 1 < samples per cycle, strictly positive gains, the paper's
  /// condition (CF-14) L_ke > (Δα/2) Σ_k l_k f_k(n)² at every tooth n, and (beyond the paper, because (CF-14)
  /// alone does not bound the discrete error dynamics) the spectral radius of the closed-loop error
  /// transition over one cycle < 1. Runs at configuration load (allocates, uses an eigen-solver): never call
  /// it on the real-time path.
  [[nodiscard]] static std::optional<std::string> check_stability(const FourierParams& params,
                                                                  const EngineGeometry& engine,
                                                                  const WheelGeometry& wheel);
  /// check_stability() without its memo of the last answer (the memo holds one key: a hash of every input).
  [[nodiscard]] static std::optional<std::string> check_stability_uncached(const FourierParams& params,
                                                                           const EngineGeometry& engine,
                                                                           const WheelGeometry& wheel);
  /// Spectral radius of Π_k (I + Ξ_k) over one 720° cycle (CF-12): < 1 means the observer error decays.
  [[nodiscard]] static double cycle_spectral_radius(const FourierParams& params, const EngineGeometry& engine,
                                                    const WheelGeometry& wheel);
  /// Whether ‖Φ^m‖∞ < ½ for m = 1, 2, 4, …, 1024 (Φ: that cycle transition), which proves ρ(Φ) < 1 without
  /// an eigen-solver; false means not shown this way (check_stability then computes ρ). Start-up only.
  [[nodiscard]] static bool cycle_contracts(const FourierParams& params, const EngineGeometry& engine,
                                            const WheelGeometry& wheel);

  void reset() noexcept;
  /// Extended load T*_load = T_load + T_fric (N m), added to give T̂_ind (CF eq. (1)). Default 0.
  void set_extended_load(double torque_nm) noexcept { load_star_nm_ = torque_nm; }
  /// Known part of the net torque over the next update()'s step (N m, zero 720° mean): the cylinder-pressure
  /// model's gas torque ripple (LoadRls::gas_ripple_nm; beyond the paper). The Fourier series then
  /// carries only what the model misses. Default 0 (the paper's observer).
  /// `valid` false (no MAP yet): the value is ignored and the paper's gains (l_ref) run; valid: model_l_ref.
  void set_model_torque(double ripple_nm, bool valid = true) noexcept {
    model_next_ = ripple_nm;
    model_next_valid_ = valid;
  }
  /// Whether the last update ran with the gas model's gains (diagnostics, tests).
  [[nodiscard]] bool model_active() const noexcept { return model_active_; }
  /// Whether the tooth widths it is given are corrected by a learned table. While false the
  /// estimate runs but its health is kNotConverged: an unlearned wheel puts the tooth errors into the
  /// in-cycle torque (tens of % of peak-to-peak). Default true (a caller without a learner decides).
  void set_wheel_learned(bool learned) noexcept { wheel_learned_ = learned; }
  /// Real-time safe. Returns false if the sample was rejected.
  bool update(const ToothSample& s) noexcept;
  /// update() for a sample that passed check_tooth_sample for this table (AnglePipeline::on_tooth checks once
  /// per tooth). Real-time safe.
  bool update_checked(const ToothSample& s) noexcept;

  /// T̂_ind at edge k − output_lag (t_ns of that edge): m(e)·ĉ + T*_load (uncertainty not modelled: 0).
  [[nodiscard]] const TorqueEstimate& estimate() const noexcept { return est_; }
  [[nodiscard]] int estimate_tooth() const noexcept { return est_tooth_; }
  /// T̂_mass (= net torque) at any tooth k from the current coefficients (reconstructs the whole cycle).
  [[nodiscard]] double net_torque_at(int k) const noexcept;
  void push_model(double ripple_nm) noexcept;  ///< shift the model ripple history, newest first
  [[nodiscard]] int coefficients() const noexcept { return nc_; }
  [[nodiscard]] double coefficient(int j) const noexcept { return c_[static_cast<std::size_t>(j)]; }
  [[nodiscard]] double kinetic_energy_j() const noexcept { return phi_; }
  [[nodiscard]] const FourierStats& stats() const noexcept { return stats_; }

 private:
  FourierParams params_;
  ToothAngleTable table_;
  int nc_ = 0;   ///< 2 n_h + 1
  int ncp_ = 0;  ///< nc_ rounded up to a multiple of 4: the row stride and the per-tooth pass's length
  std::vector<double, Aligned16Allocator<double>> basis_;  ///< f_j(e_k) at [k * ncp_ + j], 0 for j ≥ nc_
  alignas(16) std::array<double, kCoeffStride> l_{};
  alignas(16) std::array<double, kCoeffStride> lm_{};  ///< the gains with model_l_ref (gas model valid)
  alignas(16) std::array<double, kCoeffStride> c_{};
  double phi_ = 0.0;
  double mean_speed_ = 0.0;  ///< running mean speed over ≈ one cycle (rad/s), for gain_ref_rpm
  double ref_speed_ = 0.0;   ///< gain_ref_rpm in rad/s (0: off)
  bool wheel_learned_ = true;
  double load_star_nm_ = 0.0;
  TorqueEstimate est_;
  int est_tooth_ = 0;
  int expected_tooth_ = -1;
  int teeth_seen_ = 0;
  int lag_ = 0;
  LagRing<std::int64_t, kMaxLag + 1> edge_t_ns_;  ///< edge times of the last teeth, [0] = newest
  double model_next_ = 0.0;                       ///< set_model_torque() for the next tooth
  bool model_next_valid_ = false;
  bool model_active_ = false;
  LagRing<double, kMaxLag + 1> model_;  ///< model ripple of the last steps, [0] = newest
  FourierStats stats_;
};

}  // namespace torqued
