// Diagnostics of the current state: history samples (energies, rim and centre quantities,
// Fourier modes of the rim) and field frames. Called at the history and output intervals,
// outside the element loop.
#pragma once

#include <array>
#include <vector>

#include "element_kernels.hpp"
#include "model.hpp"
#include "simulation.hpp"

namespace softshock {

// Read-only view of the nodal state.
struct NodalView {
  const double *x, *y, *vx, *vy, *ax, *ay, *mass;
};

// Cauchy stress of one element (3x3 plane strain: xx, xy, yy, zz), its J and stored energy.
struct ElementStress {
  double xx, xy, yy, zz, j, stored_energy_density;
  double mean() const { return (xx + yy + zz) / 3.0; }
};

class Diagnostics {
 public:
  Diagnostics(const Problem& problem, const ElementGeometry& geometry, int modes);

  double reference_radius() const { return reference_radius_; }
  std::array<double, 2> origin() const { return origin_; }
  const std::vector<int32_t>& rim_nodes() const { return rim_nodes_; }

  // Appends one sample at time t. Dissipation and external work are accumulated by the
  // integrator and passed in.
  void sample(const NodalView& nodes, const ElementState& elements, double t, double dt,
              double dissipated, double external_work, History& history) const;

  FieldFrame frame(const NodalView& nodes, const ElementState& elements, double t) const;

  ElementStress element_stress(const NodalView& nodes, const ElementState& elements,
                               std::size_t e) const;

 private:
  const Problem& problem_;
  const ElementGeometry& geometry_;
  int modes_;
  std::array<double, 2> origin_{};
  double reference_radius_ = 0;
  std::vector<int32_t> rim_nodes_;           // outer boundary loop
  std::vector<double> rim_weight_;           // trapezoidal d(theta) weights, sum 2 pi
  std::vector<double> rim_ref_radius_;       // reference distance from the origin
  std::vector<double> mode_cos_, mode_sin_;  // (M+1) x rim, row-major by mode
  std::vector<int32_t> center_elements_;
  std::vector<int32_t> rim_elements_;  // elements with an edge on the outer boundary
};

}  // namespace softshock
