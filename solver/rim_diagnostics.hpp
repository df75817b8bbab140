// The rim's diagnostics, apart from the general ones (energies, the centre, the element that sets
// the step, aspect ratios: diagnostics.hpp, diagnostics3.hpp): a ring of boundary nodes read as
// r(theta) about an axis -- the 2-D disk's outer loop, the 3-D cylinder's mid-plane circle, or its
// whole lateral surface with area weights (the modes averaged over the thickness) -- giving A-bar
// (raw and rebuilt from the low modes), the ring's mean radial displacement, velocity and
// acceleration, and the Fourier amplitudes of u_r / R0 (docs/model.md, "Diagnostics").
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace softshock {

class RimRing {
 public:
  // nodes with their reference positions x, y about `origin`; r0 normalises A-bar and the modes.
  // weight: per node, summing to 2 pi (the quadrature of the angle); empty = the nodes are a
  // closed loop in angle order and get trapezoidal weights in theta. modes: the highest mode
  // asked for; a ring of N nodes resolves modes up to (N - 1) / 2 (mode N - m takes the same
  // values at the nodes as mode m), so no more are computed.
  RimRing(std::vector<int32_t> nodes, const double* x, const double* y,
          std::array<double, 2> origin, double r0, int modes, std::vector<double> weight = {});
  RimRing() = default;

  int modes() const { return modes_; }
  const std::vector<int32_t>& nodes() const { return nodes_; }

  struct Sample {
    double abar = 0;           // (max r - min r) / R0 over the ring's nodes
    double abar_filtered = 0;  // the same of u_r rebuilt from modes 0..kFilteredAbarModes
    double mean_u = 0, mean_v = 0, mean_a = 0;  // weighted means of the radial components
    std::vector<double> amplitude;              // modes 0..modes(), / R0
  };
  // At the current positions, velocities and accelerations (arrays over all nodes).
  Sample sample(const double* x, const double* y, const double* vx, const double* vy,
                const double* ax, const double* ay) const;

 private:
  std::vector<int32_t> nodes_;
  std::array<double, 2> origin_{};
  double r0_ = 1;
  int modes_ = 0;
  std::vector<double> ref_radius_, weight_;
  std::vector<double> mode_cos_, mode_sin_;  // (M+1) x ring, row-major by mode
  // The same tables ring x (M+1), row-major by node: the amplitude sums run over the modes in
  // the inner loop (vectorised) and keep each mode's sum in ring order.
  std::vector<double> node_cos_, node_sin_;
};

}  // namespace softshock
