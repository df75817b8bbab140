// Diagnostics of the current state of a 2-D run: history samples (energies, the centre, the
// element that sets the step, aspect ratios, and the rim's figures from rim_diagnostics.hpp) and
// field frames. Called at the history and output intervals, outside the element loop.
#pragma once

#include <array>
#include <utility>
#include <vector>

#include "element_kernels.hpp"
#include "model.hpp"
#include "rim_diagnostics.hpp"
#include "simulation.hpp"

namespace softshock {

// Read-only view of the nodal state.
struct NodalView {
  const double *x, *y, *vx, *vy, *ax, *ay, *mass;
  const double *px = nullptr, *py = nullptr;  // with a mass blend, its momentum K^-1 v
};

// What the last force evaluation computed at the current positions, reused by the diagnostics
// rather than computed again (average nodal pressure; all null for plain P1): each node's J_a and
// its Tait mean stress less the stabilisation's patch mean (the stress the element loop
// averages), and each element's stabilisation stress s_e and J_e = current / reference area.
struct KernelView {
  const double* nodal_j = nullptr;
  const double* nodal_mean_stress = nullptr;  // with damage, the degraded one
  const double* element_stress_shift = nullptr;
  const double* element_j = nullptr;
  // Phase-field damage: each element's degradation g_e of its deviatoric and tensile volumetric
  // stress (damage/damage_pass.hpp); null without damage.
  const double* element_degradation = nullptr;
};

// Cauchy stress of one element (3x3 plane strain: xx, xy, yy, zz) and its J.
struct ElementStress {
  double xx, xy, yy, zz, j;
  double mean() const { return (xx + yy + zz) / 3.0; }
};

class Diagnostics {
 public:
  // modes: the highest Fourier mode asked for; the rim's N nodes resolve modes up to
  // (N - 1) / 2 (mode N - m takes the same values at the nodes as mode m), so no more are computed.
  Diagnostics(const Problem& problem, const ElementGeometry& geometry, int modes);

  double reference_radius() const { return reference_radius_; }
  std::array<double, 2> origin() const { return origin_; }
  const std::vector<int32_t>& rim_nodes() const { return rim_.nodes(); }

  // Appends one sample at time t. Dissipation and external work are accumulated by the
  // integrator and passed in. totals: of the evaluation at these positions, with
  // KernelParams::sample set (the stored energy, the elements' and the nodal passes', the largest
  // aspect ratio, the element that set dt).
  void sample(const NodalView& nodes, const ElementState& elements, const KernelView& kernel,
              const KernelTotals& totals, double t, double dt, double dissipated,
              double external_work, History& history) const;

  // The fields at time t, written into `reuse` (any earlier content is overwritten; its buffers
  // are kept where they have the size).
  FieldFrame frame(const NodalView& nodes, const ElementState& elements, const KernelView& kernel,
                   double t, FieldFrame reuse = {}) const;

  // Whether the elements' volumetric stress comes from the kernel's nodal state (average nodal
  // pressure, with the kernel's arrays at hand) rather than from each element's own J.
  bool nodal_volumetric(const KernelView& kernel) const {
    return nodal_pressure_ && kernel.nodal_mean_stress != nullptr;
  }
  // The volumetric mean stress the kernel applied to element e (average nodal pressure only).
  double volumetric_mean_stress(const KernelView& kernel, std::size_t e) const;
  // The kinetic energy of the mass the integrator moves the nodes with: 1/2 v^T M_L v, or with a
  // mass blend 1/2 v^T K^-1 v of the operator its correction applies (docs/model.md).
  double kinetic_energy(const NodalView& nodes) const;
  // Cauchy stress of element e; its mean stress under the element formulation (kernel: the
  // state the last evaluation left).
  ElementStress element_stress(const NodalView& nodes, const ElementState& elements,
                               const KernelView& kernel, std::size_t e) const;

 private:
  const Problem& problem_;
  const ElementGeometry& geometry_;
  std::array<double, 2> origin_{};
  double reference_radius_ = 0;
  RimRing rim_;  // the outer boundary loop
  std::vector<int32_t> center_elements_;
  std::vector<int32_t> rim_elements_;  // elements with an edge on the outer boundary
  std::vector<uint8_t> on_rim_node_;   // 1 for nodes of the outer boundary loop
  // The average nodal pressure element (the kernel's nodal state carries its volumetric stress).
  bool nodal_pressure_ = false;
};

}  // namespace softshock
