// The central-difference integrator's node passes, vectorised (restrict pointers, one clone per
// ISA) and built without FMA contraction, so they compute exactly what the scalar loops did.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "element_kernels.hpp"
#include "node_layout.hpp"

namespace softshock {

// Predictor over nodes [begin, end): x += dt v + dt^2/2 a; v += dt/2 a; the new x and y also to
// the position lanes of nodes (the element passes' rows).
void predict_nodes(double dt, std::size_t begin, std::size_t end, double* __restrict x,
                   double* __restrict y, double* __restrict vx, double* __restrict vy,
                   const double* __restrict ax, const double* __restrict ay,
                   PackedNode* __restrict nodes);

// Corrector over nodes [begin, end): a = free (f + f_ext) / m; v += dt/2 a.
void correct_nodes(double dt, std::size_t begin, std::size_t end, const NodeForce* __restrict force,
                   const double* __restrict fext_x, const double* __restrict fext_y,
                   const uint8_t* __restrict free_x, const uint8_t* __restrict free_y,
                   const double* __restrict mass, double* __restrict ax, double* __restrict ay,
                   double* __restrict vx, double* __restrict vy);

// The mass blend (Element::mass_blend = alpha; docs/model.md, "Mass blend"). The accelerations
// solve M a = f with M = (1 - alpha) M_L + alpha M_C approximately, by one Jacobi step from the
// lumped ones: a = a_L + alpha M_L^-1 (M_L - M_C) a_L. Per element (M_C - M_L) gives node i rho A_e
// / 12 (a_j + a_k - 2 a_i); its rows sum to zero, so momentum is unchanged. Adds those shares of
// elements [begin, end) to difference (the lumped a_L in ax, ay).
// weight: each element's rho A_e / 12 (consistent_mass_weights, computed once).
std::vector<double> consistent_mass_weights(const ElementGeometry& geometry, double density);
void accumulate_consistent_mass_difference(const ElementGeometry& geometry, const double* weight,
                                           const double* ax, const double* ay, std::size_t begin,
                                           std::size_t end, NodeForce* difference);
// The blend's corrector, first half, over nodes [begin, end): the lumped a_L = free (f + f_ext) /
// m into ax, ay, the velocities left for correct_mass_blend; and the blended mass's momentum p +=
// dt/2 (f_prev + f) with f = free (f + f_ext), f_prev = f (velocity Verlet's v+ = v + dt/2 K
// (f_prev + f), so p = K^-1 v exactly).
void correct_nodes_blended(double dt, std::size_t begin, std::size_t end,
                           const NodeForce* __restrict force, const double* __restrict fext_x,
                           const double* __restrict fext_y, const uint8_t* __restrict free_x,
                           const uint8_t* __restrict free_y, const double* __restrict mass,
                           double* __restrict ax, double* __restrict ay, double* __restrict fprev_x,
                           double* __restrict fprev_y, double* __restrict px,
                           double* __restrict py);
// Over nodes [begin, end): a -= alpha free (M_C - M_L) a_L / m (difference as above); v += dt/2 a.
void correct_mass_blend(double dt, double alpha, std::size_t begin, std::size_t end,
                        const NodeForce* __restrict difference, const uint8_t* __restrict free_x,
                        const uint8_t* __restrict free_y, const double* __restrict mass,
                        double* __restrict ax, double* __restrict ay, double* __restrict vx,
                        double* __restrict vy);
// The blended mass's momentum p = K^-1 v, with K the operator the blend applies to the forces (a =
// K f on the free components: K = (I + alpha M_L^-1 (M_L - M_C)) M_L^-1). The work of the forces
// changes 1/2 v^T K^-1 v, the kinetic energy the diagnostics report. From v by the series
// K^-1 = M_L sum_k (-alpha M_L^-1 (M_L - M_C))^k (ratio at most 3 alpha / 4), summed to round-off:
// once, for an initial velocity field; the integrator then keeps p by correct_nodes_blended.
void blended_momentum(const ElementGeometry& geometry, const double* weight, double alpha,
                      std::size_t nodes, const double* mass, const uint8_t* free_x,
                      const uint8_t* free_y, const double* vx, const double* vy, double* px,
                      double* py);
// The corrected accelerations are (I + alpha S) a_L with S = M_L^-1 (M_L - M_C), whose eigenvalues
// lie in [0, 3/4] (each element's: 0, 3/4, 3/4), so the stable step shrinks by at most this factor.
inline double mass_blend_step_factor(double alpha) {
  return 1.0 / std::sqrt(1.0 + 0.75 * alpha);
}

// The largest step over which no element's area is predicted to change by more than
// max_volume_change (a fraction), from the nodes' velocities and accelerations at the start of the
// step: |dt div v + dt^2/2 div a| <= max_volume_change, bounded by p dt + q dt^2 / 2 with p = |div
// v|, q = |div a| (gradients on the reference configuration). For the steps taken while the load
// acts: the elastic estimate sees the material's stiffness, not a load that starts at full
// strength (docs/model.md, "Time integration").
struct StepBound {
  double dt_s;      // +inf when nothing moves
  int64_t element;  // the element that sets it (-1 when nothing moves)
};
// Over the given elements (ascending), e.g. those the load acts on (elements_on_nodes).
StepBound volume_change_step(const ElementGeometry& geometry, std::span<const int32_t> elements,
                             const double* vx, const double* vy, const double* ax, const double* ay,
                             double max_volume_change);

// The elements with a corner on any of the given nodes, ascending (nodes: indices below
// node_count).
std::vector<int32_t> elements_on_nodes(const ElementGeometry& geometry,
                                       std::span<const int32_t> nodes, std::size_t node_count);

}  // namespace softshock
