// The linear tetrahedron (Tet4): its reference geometry, its state, and the per-element hot loop
// (deformation gradient, full 3-D Tait + neo-Hookean stress, artificial and Kelvin-Voigt
// viscosity, nodal forces, stable-step candidate, dissipation increment), the 3-D counterpart of
// element_kernels.hpp's triangle loop, over the same KernelParams and KernelTotals.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "element_kernels.hpp"
#include "mesh.hpp"
#include "node_layout.hpp"

namespace softshock {

// Per-element 3x3 quantities are stored in blocks of kTet4Block elements, component by component
// ([block][component][lane]): the element loop then reaches all nine components of a block from
// one pointer (separate arrays per component needed 27 pointers live and spilled them), and, with
// 8 lanes, one block's component fills one cache line of doubles, so that each array is read as
// one sequential stream (64 lanes made 9 interleaved streams of each array, 27 in all, more than
// the hardware prefetchers follow: the loop waited on memory at 100k elements).
inline constexpr std::size_t kTet4Block = 8;
inline std::size_t tet4_blocked_index(int component, std::size_t e) {
  return (e / kTet4Block) * 9 * kTet4Block + static_cast<std::size_t>(component) * kTet4Block +
         e % kTet4Block;
}
inline std::size_t tet4_blocked_size(std::size_t elements) {
  return (elements + kTet4Block - 1) / kTet4Block * 9 * kTet4Block;
}

// Reference geometry of the tetrahedra (constant during a run).
struct Tet4Geometry {
  std::vector<int32_t> node0, node1, node2, node3;
  // Dm^-1 with Dm = [X1 - X0, X2 - X0, X3 - X0], row-major, blocked: component 3 (a - 1) + j is
  // the j-th entry of the reference gradient of N_a (a = 1, 2, 3; grad N_0 = -their sum).
  std::vector<double> dm_inv;
  std::vector<double> volume0;  // m^3
  // The regular tetrahedron's altitude at volume0 (continuum::regular_tetrahedron_altitude): the
  // continuous artificial viscosity's length is this times J^(1/3).
  std::vector<double> regular_altitude0;
  std::size_t size() const { return volume0.size(); }
  double dm_inv_at(int component, std::size_t e) const {
    return dm_inv[tet4_blocked_index(component, e)];
  }
};
// From a finalized 3-D mesh. Throws std::invalid_argument for a mesh without tetrahedra.
Tet4Geometry build_tet4_geometry(const Mesh& mesh);

// Element state carried from one force evaluation to the next (as ElementState for triangles),
// the 3x3 ones blocked as the geometry's Dm^-1.
struct Tet4State {
  std::vector<double> f;  // F at the last evaluation (lags the viscosity)
  std::vector<float> pv;  // viscous P at the last evaluation (dissipation, diagnostics only)
  void resize(std::size_t elements);
  void reset_to_reference();  // F = I, P_v = 0
  double f_at(int component, std::size_t e) const { return f[tet4_blocked_index(component, e)]; }
  double pv_at(int component, std::size_t e) const { return pv[tet4_blocked_index(component, e)]; }
};

// nodes[i]'s position lanes = (x[i], y[i], z[i]), for i in [begin, end).
void pack_positions(const double* x, const double* y, const double* z, std::size_t begin,
                    std::size_t end, PackedNode3* nodes);
// nodes[i]'s state lanes = (mean_stress[i], bulk_modulus[i]), for i in [begin, end).
void pack_nodal_state(const double* mean_stress, const double* bulk_modulus, std::size_t begin,
                      std::size_t end, PackedNode3* nodes);

// Evaluates elements [begin, end): updates their state and adds their nodal forces (acting on the
// nodes, = -f_int, N) to node_force, element by element in index order. KernelParams as for
// triangles, with lengths: altitude_length > 0.5 the smallest altitude (3 V / largest face),
// else the altitude of the regular tetrahedron of the current volume. KernelTotals in 3-D: the
// stored energy in J, the aspect ratio the longest edge over the smallest altitude.
void compute_tet4_forces(const Tet4Geometry& geometry, const PackedNode3* nodes,
                         const KernelParams& params, std::size_t begin, std::size_t end,
                         Tet4State& state, KernelTotals& totals, NodeForce3* node_force);

}  // namespace softshock
