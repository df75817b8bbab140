// The tetrahedron's passes besides its element loop: the average nodal pressure's nodal half
// (nodal_pressure.hpp for triangles; a node owns a quarter of each tetrahedron's volume), the mass
// blend's element pass (integrator.hpp; the consistent tetrahedron mass rho V / 20 (1 + delta_ij)),
// the node passes of the central-difference integrator in three components, and the load step's
// volume-change bound. Built without FMA contraction, like their 2-D counterparts.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "integrator.hpp"
#include "nodal_pressure.hpp"
#include "tet4_kernels.hpp"

namespace softshock {

// Three components of a nodal vector (x, y, z arrays).
using Components3 = std::array<double*, 3>;
using ConstComponents3 = std::array<const double*, 3>;
using Flags3 = std::array<const uint8_t*, 3>;

// ---- average nodal pressure (nodal_pressure.hpp, passes 1, 3 and 4; pass 2 is shared) --------

// Reference nodal volumes V_a = sum over the tetrahedra around a of V_e / 4.
std::vector<double> reference_nodal_volumes(const Tet4Geometry& geometry, std::size_t nodes);
// Pass 1: adds v_e / 4 (current volume) to each of the element's nodes' volume; J_e = v_e / V_e.
void accumulate_nodal_volumes(const Tet4Geometry& geometry, const PackedNode3* nodes,
                              std::size_t begin, std::size_t end, double* volume,
                              double* j_element);
// Pass 3: s_e = beta_kappa (1 - rho_e^2) / 2 with rho_e = Jbar_e / J_e (Jbar_e the mean of the
// element's four nodal J), and V_e beta_kappa (1 - rho_e) / 4 added to each node's q_sum.
void accumulate_stabilization(const Tet4Geometry& geometry, double beta_kappa,
                              const double* nodal_j, const double* j_element, std::size_t begin,
                              std::size_t end, double* s_element, double* q_sum,
                              StoredEnergySum energy = {});
// Pass 4: mean_stress -= q_sum / reference_volume, written with bulk_modulus into the rows.
void subtract_stabilization(const double* __restrict reference_volume,
                            const double* __restrict q_sum, const double* __restrict bulk_modulus,
                            std::size_t begin, std::size_t end, double* __restrict mean_stress,
                            PackedNode3* __restrict nodes);
// All passes at once, for diagnostics: per element the volumetric mean stress the kernel applies,
// and the stored volumetric + stabilisation energy (J).
NodalPressureState nodal_pressure_state(const Tet4Geometry& geometry,
                                        const std::vector<double>& reference_volume, double kappa,
                                        double tait_n, double element_weight, double beta,
                                        ConstComponents3 x);

// ---- central differences, three components (integrator.hpp) -----------------------------

// x += dt v + dt^2/2 a; v += dt/2 a; the new position to the rows.
void predict_nodes(double dt, std::size_t begin, std::size_t end, Components3 x, Components3 v,
                   ConstComponents3 a, PackedNode3* nodes);
// a = free (f + f_ext) / m; v += dt/2 a.
void correct_nodes(double dt, std::size_t begin, std::size_t end, const NodeForce3* force,
                   ConstComponents3 fext, Flags3 free, const double* mass, Components3 a,
                   Components3 v);
// The mass blend's corrector, first half: a_L = free (f + f_ext) / m, also as rows (x, y, z, 0)
// for the blend's element pass; p += dt/2 (f_prev + f); f_prev = f.
void correct_nodes_blended(double dt, std::size_t begin, std::size_t end, const NodeForce3* force,
                           ConstComponents3 fext, Flags3 free, const double* mass, Components3 a,
                           Components3 fprev, Components3 p, NodeForce3* a_rows);
// a -= alpha free (M_C - M_L) a_L / m; v += dt/2 a.
void correct_mass_blend(double dt, double alpha, std::size_t begin, std::size_t end,
                        const NodeForce3* difference, Flags3 free, const double* mass,
                        Components3 a, Components3 v);
// Each element's rho V_e / 20.
std::vector<double> consistent_mass_weights(const Tet4Geometry& geometry, double density);
// (M_C - M_L) a: node i of element e gets rho V_e / 20 (sum of the other three a - 3 a_i); a as
// rows (x, y, z, 0).
void accumulate_consistent_mass_difference(const Tet4Geometry& geometry, const double* weight,
                                           const NodeForce3* a, std::size_t begin, std::size_t end,
                                           NodeForce3* difference);
// p = K^-1 v for an initial velocity field (integrator.hpp's blended_momentum; ratio 4 alpha / 5).
void blended_momentum(const Tet4Geometry& geometry, const double* weight, double alpha,
                      std::size_t nodes, const double* mass, Flags3 free, ConstComponents3 v,
                      Components3 p);
// S = M_L^-1 (M_L - M_C) per tetrahedron is 4/5 I - 1/5 1 1^T: eigenvalues 0 and 4/5, so the
// blended step shrinks by at most this factor (triangles: 3/4, mass_blend_step_factor).
inline double tet4_mass_blend_step_factor(double alpha) {
  return 1.0 / std::sqrt(1.0 + 0.8 * alpha);
}

// The load step's bound (integrator.hpp's volume_change_step) over the given tetrahedra.
StepBound volume_change_step(const Tet4Geometry& geometry, std::span<const int32_t> elements,
                             ConstComponents3 v, ConstComponents3 a, double max_volume_change);
// The tetrahedra with a corner on any of the given nodes, ascending.
std::vector<int32_t> elements_on_nodes(const Tet4Geometry& geometry, std::span<const int32_t> nodes,
                                       std::size_t node_count);

}  // namespace softshock
