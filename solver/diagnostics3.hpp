// Diagnostics of a 3-D (tetrahedral) run: the general ones -- energies (J, the whole body), the
// element that sets the stable step, the largest aspect ratio (longest edge over smallest
// altitude), the centre's mean stress -- and the rim's, for a body around the z axis (the
// cylinder): the rim is read at the mid-plane z = z_mid (the nodes of the lateral surface there,
// in angle order: A-bar, the mean radial motion and the Fourier modes, as for the 2-D disk) and,
// for the modes, also averaged over the thickness (every lateral-surface node weighted by its
// share of the lateral area). A body with no nodes on that circle (the box) has no rim figures.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "diagnostics.hpp"
#include "model.hpp"
#include "rim_diagnostics.hpp"
#include "simulation.hpp"
#include "tet4_kernels.hpp"

namespace softshock {

// Read-only view of the nodal state, three components.
struct NodalView3 {
  std::array<const double*, 3> x{}, v{}, a{};
  std::array<const double*, 3> p{};  // with a mass blend, its momentum K^-1 v (else null)
  const double* mass = nullptr;
};

// Cauchy stress of one tetrahedron (xx, yy, zz, xy, yz, zx) and its J.
struct ElementStress3 {
  double xx, yy, zz, xy, yz, zx, j;
  double mean() const { return (xx + yy + zz) / 3.0; }
  double von_mises() const;
};

class Diagnostics3 {
 public:
  // modes: the highest Fourier mode asked for (fewer on a rim of few nodes, as in 2-D).
  Diagnostics3(const Problem& problem, const Tet4Geometry& geometry, int modes);

  double reference_radius() const { return reference_radius_; }
  // The mid-plane rim's nodes in angle order, and every lateral-surface node.
  const std::vector<int32_t>& rim_nodes() const { return mid_plane_.nodes(); }
  const std::vector<int32_t>& lateral_nodes() const { return lateral_nodes_; }

  void sample(const NodalView3& nodes, const Tet4State& elements, const KernelView& kernel,
              const KernelTotals& totals, double t, double dt, double dissipated,
              double external_work, History& history) const;
  FieldFrame frame(const NodalView3& nodes, const Tet4State& elements, const KernelView& kernel,
                   double t, FieldFrame reuse = {}) const;

  double kinetic_energy(const NodalView3& nodes) const;
  // The volumetric mean stress the kernel applied to element e (average nodal pressure only).
  double volumetric_mean_stress(const KernelView& kernel, std::size_t e) const;
  ElementStress3 element_stress(const NodalView3& nodes, const Tet4State& elements,
                                const KernelView& kernel, std::size_t e) const;

 private:
  const Problem& problem_;
  const Tet4Geometry& geometry_;
  std::array<double, 2> origin_{};
  double z_mid_ = 0;
  double reference_radius_ = 0;
  bool nodal_pressure_ = false;
  RimRing mid_plane_;  // the lateral nodes at z_mid, in angle order
  RimRing lateral_;    // every lateral node, weighted by its share of the lateral area
  std::vector<int32_t> lateral_nodes_;
  std::vector<int32_t> center_elements_;
  std::vector<int32_t> rim_elements_;  // elements with a corner on the mid-plane rim
  std::vector<uint8_t> on_rim_node_;   // 1 for nodes of the lateral surface
};

}  // namespace softshock
