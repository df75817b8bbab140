#include "rim_diagnostics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "simulation.hpp"

namespace softshock {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// a[m] += w_k u_k cos(m theta_k), b[m] likewise with sin, over the ring's nodes k in order: each
// mode's sum is the scalar loop's to the bit (built without FMA contraction), the modes side by
// side in the vector lanes (a scalar loop per mode was a chain of dependent adds, most of a
// history sample's time).
__attribute__((target_clones("avx512f", "avx2", "default"))) void fourier_sums(
    std::size_t nodes, std::size_t modes, const double* weight, const double* u,
    const double* node_cos, const double* node_sin, double* __restrict a, double* __restrict b) {
  for (std::size_t k = 0; k < nodes; ++k) {
    const double wu = weight[k] * u[k];
    const double *c = node_cos + k * modes, *s = node_sin + k * modes;
#pragma GCC ivdep
    for (std::size_t m = 0; m < modes; ++m) a[m] += wu * c[m], b[m] += wu * s[m];
  }
}

}  // namespace

RimRing::RimRing(std::vector<int32_t> nodes, const double* x, const double* y,
                 std::array<double, 2> origin, double r0, int modes, std::vector<double> weight)
    : nodes_(std::move(nodes)),
      origin_(origin),
      r0_(r0),
      modes_(modes),
      weight_(std::move(weight)) {
  const std::size_t nr = nodes_.size();
  // Above (N - 1) / 2 a mode is an alias of a lower one: it would report that one's amplitude.
  modes_ = std::min(modes_, nr >= 3 ? static_cast<int>((nr - 1) / 2) : 0);
  std::vector<double> theta(nr);
  ref_radius_.resize(nr);
  for (std::size_t k = 0; k < nr; ++k) {
    const double dx = x[nodes_[k]] - origin_[0], dy = y[nodes_[k]] - origin_[1];
    theta[k] = std::atan2(dy, dx);
    ref_radius_[k] = std::hypot(dx, dy);
  }
  if (weight_.empty()) {  // a closed loop in angle order: trapezoidal in theta
    weight_.resize(nr);
    for (std::size_t k = 0; k < nr; ++k) {
      double span = theta[(k + 1) % nr] - theta[(k + nr - 1) % nr];
      span = std::remainder(span, kTwoPi);  // wrap into (-pi, pi]
      if (span < 0) span += kTwoPi;         // the loop is counter-clockwise
      weight_[k] = 0.5 * span;
    }
  }
  const std::size_t count = static_cast<std::size_t>(modes_) + 1;
  for (auto* v : {&mode_cos_, &mode_sin_, &node_cos_, &node_sin_}) v->resize(count * nr);
  for (std::size_t m = 0; m < count; ++m) {
    for (std::size_t k = 0; k < nr; ++k) {
      const double c = std::cos(static_cast<double>(m) * theta[k]);
      const double sn = std::sin(static_cast<double>(m) * theta[k]);
      mode_cos_[m * nr + k] = node_cos_[k * count + m] = c;
      mode_sin_[m * nr + k] = node_sin_[k * count + m] = sn;
    }
  }
}

RimRing::Sample RimRing::sample(const double* x, const double* y, const double* vx,
                                const double* vy, const double* ax, const double* ay) const {
  Sample s;
  // Radial displacement, velocity and acceleration in the current polar frame.
  const std::size_t nr = nodes_.size();
  std::vector<double> ur(nr);
  double r_min = std::numeric_limits<double>::max(), r_max = 0;
  for (std::size_t k = 0; k < nr; ++k) {
    const int32_t i = nodes_[k];
    const double dx = x[i] - origin_[0], dy = y[i] - origin_[1];
    const double r = std::sqrt(dx * dx + dy * dy);  // no overflow at a disk's size; hypot is slow
    const double ex = r > 0 ? dx / r : 0, ey = r > 0 ? dy / r : 0;
    ur[k] = r - ref_radius_[k];
    r_min = std::min(r_min, r), r_max = std::max(r_max, r);
    const double w = weight_[k] / kTwoPi;
    s.mean_u += w * ur[k];
    s.mean_v += w * (vx[i] * ex + vy[i] * ey);
    s.mean_a += w * (ax[i] * ex + ay[i] * ey);
  }

  // Fourier amplitudes of u_r(theta) (the ring's quadrature), / R0; u_r rebuilt at the nodes from
  // modes 0..kFilteredAbarModes gives the filtered A-bar.
  s.amplitude.resize(modes_ + 1);
  std::vector<double> ur_filtered(nr, 0.0);
  std::vector<double> cos_sum(modes_ + 1, 0.0), sin_sum(modes_ + 1, 0.0);
  fourier_sums(nr, cos_sum.size(), weight_.data(), ur.data(), node_cos_.data(), node_sin_.data(),
               cos_sum.data(), sin_sum.data());
  for (int m = 0; m <= modes_; ++m) {
    const double a = cos_sum[m], b = sin_sum[m];
    const double* cs = &mode_cos_[m * nr];
    const double* sn = &mode_sin_[m * nr];
    const double norm = m == 0 ? 1.0 / kTwoPi : 1.0 / std::numbers::pi;
    s.amplitude[m] = norm * std::hypot(a, b) / r0_;
    if (m <= kFilteredAbarModes)
      for (std::size_t k = 0; k < nr; ++k) ur_filtered[k] += norm * (a * cs[k] + b * sn[k]);
  }
  double uf_min = std::numeric_limits<double>::max(), uf_max = -uf_min;
  for (double u : ur_filtered) uf_min = std::min(uf_min, u), uf_max = std::max(uf_max, u);
  s.abar = nr ? (r_max - r_min) / r0_ : 0;
  s.abar_filtered = nr ? (uf_max - uf_min) / r0_ : 0;
  return s;
}

}  // namespace softshock
