// The element types as traits (MFEM's element classes, deal.II's `template <int dim>`): what the
// explicit step (explicit_step.hpp) needs of an element -- its dimension and node count, its
// geometry, state and node rows, and each of its passes -- so that one step and one run loop
// serve both. Tri3 is the plane-strain triangle with its vectorised 2-D loops (element_kernels,
// nodal_pressure, integrator: unchanged, called as before); Tet4 the linear tetrahedron
// (tet4_kernels, tet4_passes).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "diagnostics.hpp"
#include "diagnostics3.hpp"
#include "element_kernels.hpp"
#include "integrator.hpp"
#include "mesh.hpp"
#include "nodal_pressure.hpp"
#include "tet4_kernels.hpp"
#include "tet4_passes.hpp"

namespace softshock {

// A nodal vector field, one array per component (x, y[, z]).
template <int dim>
using NodalVector = std::array<std::vector<double>, dim>;

// The nodal state the node passes read and write.
template <int dim>
struct NodalArrays {
  NodalVector<dim> x, v, a;
  NodalVector<dim> fext;   // the follower load on the nodes (N/m in 2-D, N in 3-D)
  NodalVector<dim> fprev;  // mass blend: the last free forces
  NodalVector<dim> p;      // mass blend: the blended mass's momentum K^-1 v
  std::array<std::vector<uint8_t>, dim> free;
  std::vector<double> mass;  // lumped (row-sum)
  // 3-D with a mass blend: the lumped accelerations again as one row per node (x, y, z, 0), which
  // the corrector writes and the blend's element pass gathers (one load per corner, not three).
  std::vector<NodeForce3> a_rows;
};

struct Tri3 {
  static constexpr int kDim = 2;
  static constexpr int kNodes = 3;
  using Geometry = ElementGeometry;
  using State = ElementState;
  using Row = PackedNode;
  using Force = NodeForce;
  using Facet = std::array<int32_t, 2>;  // a boundary edge, body on the left
  using Diagnostics = softshock::Diagnostics;

  static Geometry build_geometry(const Mesh& mesh) { return build_tri3_geometry(mesh); }
  static const std::vector<int32_t>& corners(const Geometry& g, int k) {
    return k == 0 ? g.node0 : k == 1 ? g.node1 : g.node2;
  }
  static double reference_measure(const Geometry& g, std::size_t e) { return g.area0[e]; }
  static std::vector<double> reference_nodal_measures(const Geometry& g, std::size_t nodes) {
    return reference_nodal_areas(g, nodes);
  }
  static double mass_blend_step_factor(double alpha) {
    return softshock::mass_blend_step_factor(alpha);
  }

  // ---- node passes
  static void predict(double dt, std::size_t n0, std::size_t n1, NodalArrays<2>& s, Row* rows) {
    predict_nodes(dt, n0, n1, s.x[0].data(), s.x[1].data(), s.v[0].data(), s.v[1].data(),
                  s.a[0].data(), s.a[1].data(), rows);
  }
  static void pack_positions(const NodalArrays<2>& s, std::size_t n0, std::size_t n1, Row* rows) {
    softshock::pack_positions(s.x[0].data(), s.x[1].data(), n0, n1, rows);
  }
  static void correct(double dt, std::size_t n0, std::size_t n1, const Force* force,
                      NodalArrays<2>& s) {
    correct_nodes(dt, n0, n1, force, s.fext[0].data(), s.fext[1].data(), s.free[0].data(),
                  s.free[1].data(), s.mass.data(), s.a[0].data(), s.a[1].data(), s.v[0].data(),
                  s.v[1].data());
  }
  static void correct_blended(double dt, std::size_t n0, std::size_t n1, const Force* force,
                              NodalArrays<2>& s) {
    correct_nodes_blended(dt, n0, n1, force, s.fext[0].data(), s.fext[1].data(), s.free[0].data(),
                          s.free[1].data(), s.mass.data(), s.a[0].data(), s.a[1].data(),
                          s.fprev[0].data(), s.fprev[1].data(), s.p[0].data(), s.p[1].data());
  }
  static void correct_mass_blend(double dt, double alpha, std::size_t n0, std::size_t n1,
                                 const Force* difference, NodalArrays<2>& s) {
    softshock::correct_mass_blend(dt, alpha, n0, n1, difference, s.free[0].data(), s.free[1].data(),
                                  s.mass.data(), s.a[0].data(), s.a[1].data(), s.v[0].data(),
                                  s.v[1].data());
  }
  static void pack_nodal_state(const double* sm, const double* k, std::size_t n0, std::size_t n1,
                               Row* rows) {
    softshock::pack_nodal_state(sm, k, n0, n1, rows);
  }
  static void subtract_stabilization(const double* reference, const double* q, const double* k,
                                     std::size_t n0, std::size_t n1, double* sm, Row* rows) {
    softshock::subtract_stabilization(reference, q, k, n0, n1, sm, rows);
  }

  // ---- element passes
  static void nodal_measures(const Geometry& g, const Row* rows, std::size_t e0, std::size_t e1,
                             double* measure, double* j_element) {
    accumulate_nodal_areas(g, rows, e0, e1, measure, j_element);
  }
  static void stabilization(const Geometry& g, double beta_kappa, const double* nodal_j,
                            const double* j_element, std::size_t e0, std::size_t e1,
                            double* s_element, double* q_sum, StoredEnergySum energy) {
    accumulate_stabilization(g, beta_kappa, nodal_j, j_element, e0, e1, s_element, q_sum, energy);
  }
  static void element_forces(const Geometry& g, const Row* rows, const KernelParams& p,
                             std::size_t e0, std::size_t e1, State& state, KernelTotals& totals,
                             Force* force) {
    compute_element_forces(g, rows, p, e0, e1, state, totals, force);
  }
  static std::vector<double> consistent_mass_weights(const Geometry& g, double density) {
    return softshock::consistent_mass_weights(g, density);
  }
  static void mass_difference(const Geometry& g, const double* weight, const NodalArrays<2>& s,
                              std::size_t e0, std::size_t e1, Force* difference) {
    accumulate_consistent_mass_difference(g, weight, s.a[0].data(), s.a[1].data(), e0, e1,
                                          difference);
  }
  static void blended_momentum(const Geometry& g, const double* weight, double alpha,
                               NodalArrays<2>& s) {
    softshock::blended_momentum(g, weight, alpha, s.mass.size(), s.mass.data(), s.free[0].data(),
                                s.free[1].data(), s.v[0].data(), s.v[1].data(), s.p[0].data(),
                                s.p[1].data());
  }
  static StepBound volume_change_step(const Geometry& g, std::span<const int32_t> elements,
                                      const NodalArrays<2>& s, double max_volume_change) {
    return softshock::volume_change_step(g, elements, s.v[0].data(), s.v[1].data(), s.a[0].data(),
                                         s.a[1].data(), max_volume_change);
  }
  static std::vector<int32_t> elements_on_nodes(const Geometry& g, std::span<const int32_t> nodes,
                                                std::size_t node_count) {
    return softshock::elements_on_nodes(g, nodes, node_count);
  }
  // The nodal-pressure passes at once for the current positions (a sample's stored energy).
  static NodalPressureState nodal_pressure_state(const Geometry& g,
                                                 const std::vector<double>& reference, double kappa,
                                                 double n, double w, double beta,
                                                 const NodalArrays<2>& s) {
    return softshock::nodal_pressure_state(g, reference, kappa, n, w, beta, s.x[0].data(),
                                           s.x[1].data());
  }

  // ---- the follower pressure: force on each node of a facet = p |e| n_inward / 2; body on the
  // left of (a -> b), so the inward normal times the length is the edge turned by +90 degrees.
  static void add_follower_pressure(const Facet& f, double p, const NodalArrays<2>& s,
                                    NodalVector<2>& fext) {
    const auto [a, b] = f;
    const double hx = -0.5 * p * (s.x[1][b] - s.x[1][a]), hy = 0.5 * p * (s.x[0][b] - s.x[0][a]);
    fext[0][a] += hx, fext[1][a] += hy, fext[0][b] += hx, fext[1][b] += hy;
  }

  // ---- views for the diagnostics
  static NodalView view(const NodalArrays<2>& s, bool blended) {
    return {s.x[0].data(),
            s.x[1].data(),
            s.v[0].data(),
            s.v[1].data(),
            s.a[0].data(),
            s.a[1].data(),
            s.mass.data(),
            blended ? s.p[0].data() : nullptr,
            blended ? s.p[1].data() : nullptr};
  }
};

struct Tet4 {
  static constexpr int kDim = 3;
  static constexpr int kNodes = 4;
  using Geometry = Tet4Geometry;
  using State = Tet4State;
  using Row = PackedNode3;
  using Force = NodeForce3;
  using Facet = std::array<int32_t, 3>;  // a boundary face, (b - a) x (c - a) outward
  using Diagnostics = Diagnostics3;

  static Geometry build_geometry(const Mesh& mesh) { return build_tet4_geometry(mesh); }
  static const std::vector<int32_t>& corners(const Geometry& g, int k) {
    return k == 0 ? g.node0 : k == 1 ? g.node1 : k == 2 ? g.node2 : g.node3;
  }
  static double reference_measure(const Geometry& g, std::size_t e) { return g.volume0[e]; }
  static std::vector<double> reference_nodal_measures(const Geometry& g, std::size_t nodes) {
    return reference_nodal_volumes(g, nodes);
  }
  static double mass_blend_step_factor(double alpha) { return tet4_mass_blend_step_factor(alpha); }

  static Components3 components(NodalVector<3>& v) {
    return {v[0].data(), v[1].data(), v[2].data()};
  }
  static ConstComponents3 components(const NodalVector<3>& v) {
    return {v[0].data(), v[1].data(), v[2].data()};
  }
  static Flags3 flags(const NodalArrays<3>& s) {
    return {s.free[0].data(), s.free[1].data(), s.free[2].data()};
  }

  static void predict(double dt, std::size_t n0, std::size_t n1, NodalArrays<3>& s, Row* rows) {
    predict_nodes(dt, n0, n1, components(s.x), components(s.v), components(std::as_const(s.a)),
                  rows);
  }
  static void pack_positions(const NodalArrays<3>& s, std::size_t n0, std::size_t n1, Row* rows) {
    softshock::pack_positions(s.x[0].data(), s.x[1].data(), s.x[2].data(), n0, n1, rows);
  }
  static void correct(double dt, std::size_t n0, std::size_t n1, const Force* force,
                      NodalArrays<3>& s) {
    correct_nodes(dt, n0, n1, force, components(std::as_const(s.fext)), flags(s), s.mass.data(),
                  components(s.a), components(s.v));
  }
  static void correct_blended(double dt, std::size_t n0, std::size_t n1, const Force* force,
                              NodalArrays<3>& s) {
    correct_nodes_blended(dt, n0, n1, force, components(std::as_const(s.fext)), flags(s),
                          s.mass.data(), components(s.a), components(s.fprev), components(s.p),
                          s.a_rows.data());
  }
  static void correct_mass_blend(double dt, double alpha, std::size_t n0, std::size_t n1,
                                 const Force* difference, NodalArrays<3>& s) {
    softshock::correct_mass_blend(dt, alpha, n0, n1, difference, flags(s), s.mass.data(),
                                  components(s.a), components(s.v));
  }
  static void pack_nodal_state(const double* sm, const double* k, std::size_t n0, std::size_t n1,
                               Row* rows) {
    softshock::pack_nodal_state(sm, k, n0, n1, rows);
  }
  static void subtract_stabilization(const double* reference, const double* q, const double* k,
                                     std::size_t n0, std::size_t n1, double* sm, Row* rows) {
    softshock::subtract_stabilization(reference, q, k, n0, n1, sm, rows);
  }

  static void nodal_measures(const Geometry& g, const Row* rows, std::size_t e0, std::size_t e1,
                             double* measure, double* j_element) {
    accumulate_nodal_volumes(g, rows, e0, e1, measure, j_element);
  }
  static void stabilization(const Geometry& g, double beta_kappa, const double* nodal_j,
                            const double* j_element, std::size_t e0, std::size_t e1,
                            double* s_element, double* q_sum, StoredEnergySum energy) {
    accumulate_stabilization(g, beta_kappa, nodal_j, j_element, e0, e1, s_element, q_sum, energy);
  }
  static void element_forces(const Geometry& g, const Row* rows, const KernelParams& p,
                             std::size_t e0, std::size_t e1, State& state, KernelTotals& totals,
                             Force* force) {
    compute_tet4_forces(g, rows, p, e0, e1, state, totals, force);
  }
  static std::vector<double> consistent_mass_weights(const Geometry& g, double density) {
    return softshock::consistent_mass_weights(g, density);
  }
  static void mass_difference(const Geometry& g, const double* weight, const NodalArrays<3>& s,
                              std::size_t e0, std::size_t e1, Force* difference) {
    accumulate_consistent_mass_difference(g, weight, s.a_rows.data(), e0, e1, difference);
  }
  // Called once, before the first step: also sizes the acceleration rows.
  static void blended_momentum(const Geometry& g, const double* weight, double alpha,
                               NodalArrays<3>& s) {
    s.a_rows.assign(s.mass.size(), NodeForce3{});
    softshock::blended_momentum(g, weight, alpha, s.mass.size(), s.mass.data(), flags(s),
                                components(std::as_const(s.v)), components(s.p));
  }
  static StepBound volume_change_step(const Geometry& g, std::span<const int32_t> elements,
                                      const NodalArrays<3>& s, double max_volume_change) {
    return softshock::volume_change_step(g, elements, components(s.v), components(s.a),
                                         max_volume_change);
  }
  static std::vector<int32_t> elements_on_nodes(const Geometry& g, std::span<const int32_t> nodes,
                                                std::size_t node_count) {
    return softshock::elements_on_nodes(g, nodes, node_count);
  }
  static NodalPressureState nodal_pressure_state(const Geometry& g,
                                                 const std::vector<double>& reference, double kappa,
                                                 double n, double w, double beta,
                                                 const NodalArrays<3>& s) {
    return softshock::nodal_pressure_state(g, reference, kappa, n, w, beta, components(s.x));
  }

  // The follower pressure on a boundary face (Nanson: p J F^-T N dA = p n da): the inward
  // normal times the current area, -(b - a) x (c - a) / 2, a third to each node.
  static void add_follower_pressure(const Facet& f, double p, const NodalArrays<3>& s,
                                    NodalVector<3>& fext) {
    const auto [a, b, c] = f;
    const double abx = s.x[0][b] - s.x[0][a], aby = s.x[1][b] - s.x[1][a],
                 abz = s.x[2][b] - s.x[2][a];
    const double acx = s.x[0][c] - s.x[0][a], acy = s.x[1][c] - s.x[1][a],
                 acz = s.x[2][c] - s.x[2][a];
    const double sixth = -p / 6.0;
    const double hx = sixth * (aby * acz - abz * acy), hy = sixth * (abz * acx - abx * acz),
                 hz = sixth * (abx * acy - aby * acx);
    for (int32_t i : {a, b, c}) fext[0][i] += hx, fext[1][i] += hy, fext[2][i] += hz;
  }

  static NodalView3 view(const NodalArrays<3>& s, bool blended) {
    NodalView3 v;
    for (int c = 0; c < 3; ++c) {
      v.x[c] = s.x[c].data(), v.v[c] = s.v[c].data(), v.a[c] = s.a[c].data();
      v.p[c] = blended ? s.p[c].data() : nullptr;
    }
    v.mass = s.mass.data();
    return v;
  }
};

}  // namespace softshock
