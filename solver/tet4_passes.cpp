#include "tet4_passes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "continuum.hpp"
#include "vector_math.hpp"

namespace softshock {

namespace {
constexpr std::size_t kBlock = 256;
}  // namespace

// ---- average nodal pressure -----------------------------------------------------------------

std::vector<double> reference_nodal_volumes(const Tet4Geometry& g, std::size_t nodes) {
  std::vector<double> v(nodes, 0.0);
  for (std::size_t e = 0; e < g.size(); ++e) {
    const double quarter = g.volume0[e] / 4.0;
    v[g.node0[e]] += quarter, v[g.node1[e]] += quarter, v[g.node2[e]] += quarter,
        v[g.node3[e]] += quarter;
  }
  return v;
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void accumulate_nodal_volumes(
    const Tet4Geometry& g, const PackedNode3* nodes, std::size_t begin, std::size_t end,
    double* volume, double* j_element) {
  const int32_t *n0 = g.node0.data(), *n1 = g.node1.data(), *n2 = g.node2.data(),
                *n3 = g.node3.data();
  const double* volume0 = g.volume0.data();
  alignas(64) double edge[9][kBlock], quarter[kBlock];
  for (std::size_t block = begin; block < end; block += kBlock) {
    const std::size_t count = std::min(kBlock, end - block);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const NodeLanes3 a = nodes[n0[e]].lanes;
      const NodeLanes3 e1 = nodes[n1[e]].lanes - a, e2 = nodes[n2[e]].lanes - a,
                       e3 = nodes[n3[e]].lanes - a;
      for (int c = 0; c < 3; ++c)
        edge[c][k] = e1[c], edge[3 + c][k] = e2[c], edge[6 + c][k] = e3[c];
    }
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      // det [e1 e2 e3] = e1 . (e2 x e3)
      const double cx = edge[4][k] * edge[8][k] - edge[5][k] * edge[7][k];
      const double cy = edge[5][k] * edge[6][k] - edge[3][k] * edge[8][k];
      const double cz = edge[3][k] * edge[7][k] - edge[4][k] * edge[6][k];
      const double current = (edge[0][k] * cx + edge[1][k] * cy + edge[2][k] * cz) / 6.0;
      j_element[block + k] = current / volume0[block + k];
      quarter[k] = current / 4.0;
    }
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      volume[n0[e]] += quarter[k], volume[n1[e]] += quarter[k], volume[n2[e]] += quarter[k],
          volume[n3[e]] += quarter[k];
    }
  }
}

namespace {
template <bool kEnergy>
inline __attribute__((always_inline)) void stabilization_blocks(
    const Tet4Geometry& g, double beta_kappa, const double* nodal_j, const double* j_element,
    std::size_t begin, std::size_t end, double* s_element, double* q_sum, StoredEnergySum energy) {
  const int32_t *n0 = g.node0.data(), *n1 = g.node1.data(), *n2 = g.node2.data(),
                *n3 = g.node3.data();
  const double* volume0 = g.volume0.data();
  alignas(64) double j_sum[kBlock], share[kBlock], out[kBlock];
  for (std::size_t block = begin; block < end; block += kBlock) {
    const std::size_t count = std::min(kBlock, end - block);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      j_sum[k] = nodal_j[n0[e]] + nodal_j[n1[e]] + nodal_j[n2[e]] + nodal_j[n3[e]];
    }
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const double rho = j_sum[k] / (4.0 * j_element[e]);  // Jbar_e / J_e
      s_element[e] = continuum::stabilization_element_stress(beta_kappa, rho);
      share[k] = volume0[e] * continuum::stabilization_nodal_share(beta_kappa, rho) / 4.0;
      if constexpr (kEnergy)
        out[k] = energy.weight * volume0[e] *
                 continuum::stabilization_energy(beta_kappa, j_element[e], j_sum[k] / 4.0);
    }
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      q_sum[n0[e]] += share[k], q_sum[n1[e]] += share[k], q_sum[n2[e]] += share[k],
          q_sum[n3[e]] += share[k];
    }
    if constexpr (kEnergy)
      for (std::size_t k = 0; k < count; ++k) *energy.sum += out[k];
  }
}
}  // namespace

__attribute__((target_clones("avx512f", "avx2", "default"))) void accumulate_stabilization(
    const Tet4Geometry& g, double beta_kappa, const double* nodal_j, const double* j_element,
    std::size_t begin, std::size_t end, double* s_element, double* q_sum, StoredEnergySum energy) {
  if (energy.sum)
    stabilization_blocks<true>(g, beta_kappa, nodal_j, j_element, begin, end, s_element, q_sum,
                               energy);
  else
    stabilization_blocks<false>(g, beta_kappa, nodal_j, j_element, begin, end, s_element, q_sum,
                                energy);
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void subtract_stabilization(
    const double* __restrict reference_volume, const double* __restrict q_sum,
    const double* __restrict bulk_modulus, std::size_t begin, std::size_t end,
    double* __restrict mean_stress, PackedNode3* __restrict nodes) {
  for (std::size_t i = begin; i < end; ++i) {
    mean_stress[i] -= q_sum[i] / reference_volume[i];
    nodes[i].lanes[3] = mean_stress[i], nodes[i].lanes[4] = bulk_modulus[i];
  }
}

NodalPressureState nodal_pressure_state(const Tet4Geometry& g,
                                        const std::vector<double>& reference_volume, double kappa,
                                        double n, double element_weight, double beta,
                                        ConstComponents3 x) {
  const std::size_t nn = reference_volume.size(), ne = g.size();
  std::vector<double> volume(nn, 0.0), nodal_j(nn), sm(nn), k(nn), j_element(ne), s(ne, 0.0),
      q(nn, 0.0);
  std::vector<PackedNode3> nodes(nn);
  pack_positions(x[0], x[1], x[2], 0, nn, nodes.data());
  accumulate_nodal_volumes(g, nodes.data(), 0, ne, volume.data(), j_element.data());
  NodalPressureState out;
  const double w_nodal = 1.0 - element_weight;
  const StoredEnergySum energy{w_nodal, &out.stored_energy};
  nodal_tait_state(kappa, n, reference_volume.data(), volume.data(), 0, nn, nodal_j.data(),
                   sm.data(), k.data(), energy);
  accumulate_stabilization(g, beta * kappa, nodal_j.data(), j_element.data(), 0, ne, s.data(),
                           q.data(), beta > 0 ? energy : StoredEnergySum{});
  subtract_stabilization(reference_volume.data(), q.data(), k.data(), 0, nn, sm.data(),
                         nodes.data());
  out.element_mean_stress.resize(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const double nodal_mean =
        (sm[g.node0[e]] + sm[g.node1[e]] + sm[g.node2[e]] + sm[g.node3[e]]) / 4.0 + s[e];
    out.element_mean_stress[e] =
        w_nodal * nodal_mean +
        element_weight * continuum::tait_mean_stress(kappa, n, std::pow(j_element[e], -n));
  }
  return out;
}

// ---- central differences -------------------------------------------------------------------

// The node passes below run once over the nodes with the three components in the same iteration
// (not one loop per component): each array, and each node's force row, is read once. A 3-D step
// reads ~330 B of node data per node, beyond L2 at 100k tetrahedra (per component, the force rows
// were streamed three times). The arithmetic per entry is the same.
__attribute__((target_clones("avx512f", "avx2", "default"))) void predict_nodes(
    double dt, std::size_t begin, std::size_t end, Components3 x, Components3 v, ConstComponents3 a,
    PackedNode3* nodes) {
  double* __restrict x0 = x[0], * __restrict x1 = x[1], * __restrict x2 = x[2];
  double* __restrict v0 = v[0], * __restrict v1 = v[1], * __restrict v2 = v[2];
  const double* __restrict a0 = a[0], * __restrict a1 = a[1], * __restrict a2 = a[2];
  for (std::size_t i = begin; i < end; ++i) {
    x0[i] += dt * v0[i] + 0.5 * dt * dt * a0[i];
    x1[i] += dt * v1[i] + 0.5 * dt * dt * a1[i];
    x2[i] += dt * v2[i] + 0.5 * dt * dt * a2[i];
    v0[i] += 0.5 * dt * a0[i];
    v1[i] += 0.5 * dt * a1[i];
    v2[i] += 0.5 * dt * a2[i];
    nodes[i].lanes[0] = x0[i], nodes[i].lanes[1] = x1[i], nodes[i].lanes[2] = x2[i];
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void correct_nodes(
    double dt, std::size_t begin, std::size_t end, const NodeForce3* force, ConstComponents3 fext,
    Flags3 free, const double* mass, Components3 a, Components3 v) {
  for (std::size_t i = begin; i < end; ++i)
    for (int c = 0; c < 3; ++c) {
      a[c][i] = free[c][i] * (force[i].lanes[c] + fext[c][i]) / mass[i];
      v[c][i] += 0.5 * dt * a[c][i];
    }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void correct_nodes_blended(
    double dt, std::size_t begin, std::size_t end, const NodeForce3* force, ConstComponents3 fext,
    Flags3 free, const double* mass, Components3 a, Components3 fprev, Components3 p,
    NodeForce3* a_rows) {
  for (std::size_t i = begin; i < end; ++i) {
    ForceLanes3 row{};
    for (int c = 0; c < 3; ++c) {
      const double f = free[c][i] * (force[i].lanes[c] + fext[c][i]);
      a[c][i] = f / mass[i];
      p[c][i] += 0.5 * dt * (fprev[c][i] + f);
      fprev[c][i] = f;
      row[c] = a[c][i];
    }
    a_rows[i].lanes = row;
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void correct_mass_blend(
    double dt, double alpha, std::size_t begin, std::size_t end, const NodeForce3* difference,
    Flags3 free, const double* mass, Components3 a, Components3 v) {
  for (std::size_t i = begin; i < end; ++i)
    for (int c = 0; c < 3; ++c) {
      a[c][i] -= alpha * free[c][i] * difference[i].lanes[c] / mass[i];
      v[c][i] += 0.5 * dt * a[c][i];
    }
}

std::vector<double> consistent_mass_weights(const Tet4Geometry& g, double density) {
  std::vector<double> weight(g.size());
  for (std::size_t e = 0; e < g.size(); ++e) weight[e] = density * g.volume0[e] / 20.0;
  return weight;
}

// Element by element on the rows: the three components of a corner in one 4-lane vector (the
// fourth lane stays 0), the sums and differences as the three component-wise loops computed them.
// Gathering three separate arrays into blocked buffers first cost 17 ns per element in cache and
// 20-24 at 100k; a row per corner needs one load per corner instead of three (measured below, in
// docs/performance.md "3-D").
__attribute__((target_clones("avx512f", "avx2", "default"))) void
accumulate_consistent_mass_difference(const Tet4Geometry& g, const double* weight,
                                      const NodeForce3* a, std::size_t begin, std::size_t end,
                                      NodeForce3* difference) {
  const int32_t *n0 = g.node0.data(), *n1 = g.node1.data(), *n2 = g.node2.data(),
                *n3 = g.node3.data();
  for (std::size_t e = begin; e < end; ++e) {
    const int32_t i[4] = {n0[e], n1[e], n2[e], n3[e]};
    const ForceLanes3 a0 = a[i[0]].lanes, a1 = a[i[1]].lanes, a2 = a[i[2]].lanes,
                      a3 = a[i[3]].lanes;
    const ForceLanes3 sum = a0 + a1 + a2 + a3;
    const double w = weight[e];
    // sum of the other three minus 3 a_i = sum - 4 a_i
    difference[i[0]].lanes += w * (sum - 4.0 * a0);
    difference[i[1]].lanes += w * (sum - 4.0 * a1);
    difference[i[2]].lanes += w * (sum - 4.0 * a2);
    difference[i[3]].lanes += w * (sum - 4.0 * a3);
  }
}

void blended_momentum(const Tet4Geometry& geometry, const double* weight, double alpha,
                      std::size_t nodes, const double* mass, Flags3 free, ConstComponents3 v,
                      Components3 p) {
  std::array<std::vector<double>, 3> y;
  for (int c = 0; c < 3; ++c) y[c].assign(v[c], v[c] + nodes);
  std::vector<NodeForce3> difference(nodes), y_rows(nodes);
  double size = 0;
  for (std::size_t i = 0; i < nodes; ++i)
    for (int c = 0; c < 3; ++c) {
      p[c][i] = mass[i] * v[c][i];
      size += std::fabs(p[c][i]);
    }
  for (int k = 1; k <= 400 && size > 0; ++k) {  // ratio <= 4/5: 400 terms reach any round-off
    std::fill(difference.begin(), difference.end(), NodeForce3{});
    for (std::size_t i = 0; i < nodes; ++i)
      y_rows[i].lanes = ForceLanes3{y[0][i], y[1][i], y[2][i], 0.0};
    accumulate_consistent_mass_difference(geometry, weight, y_rows.data(), 0, geometry.size(),
                                          difference.data());
    double term = 0;
    for (std::size_t i = 0; i < nodes; ++i)
      for (int c = 0; c < 3; ++c) {
        y[c][i] = alpha * free[c][i] * difference[i].lanes[c] / mass[i];
        p[c][i] += mass[i] * y[c][i];
        term += std::fabs(mass[i] * y[c][i]);
      }
    if (term <= 1e-17 * size) break;
  }
}

StepBound volume_change_step(const Tet4Geometry& g, std::span<const int32_t> elements,
                             ConstComponents3 v, ConstComponents3 a, double max_volume_change) {
  StepBound bound{std::numeric_limits<double>::infinity(), -1};
  for (const int32_t e : elements) {
    const int32_t n[4] = {g.node0[e], g.node1[e], g.node2[e], g.node3[e]};
    // div u = tr(grad u), grad u = [u_1 - u_0, u_2 - u_0, u_3 - u_0] Dm^-1: sum over components c
    // and corners k of (u_k - u_0)_c Dm^-1[k - 1][c].
    auto divergence = [&](ConstComponents3 u) {
      double div = 0.0;
      for (int k = 1; k <= 3; ++k)
        for (int c = 0; c < 3; ++c)
          div += (u[c][n[k]] - u[c][n[0]]) * g.dm_inv_at(3 * (k - 1) + c, e);
      return div;
    };
    const double p = std::fabs(divergence(v)), q = std::fabs(divergence(a));
    const double root = std::sqrt(p * p + 2.0 * q * max_volume_change);
    if (p + root > 0.0 && 2.0 * max_volume_change / (p + root) < bound.dt_s)
      bound = {2.0 * max_volume_change / (p + root), static_cast<int64_t>(e)};
  }
  return bound;
}

std::vector<int32_t> elements_on_nodes(const Tet4Geometry& g, std::span<const int32_t> nodes,
                                       std::size_t node_count) {
  std::vector<uint8_t> marked(node_count, 0);
  for (const int32_t i : nodes) marked[i] = 1;
  std::vector<int32_t> out;
  for (std::size_t e = 0; e < g.size(); ++e)
    if (marked[g.node0[e]] || marked[g.node1[e]] || marked[g.node2[e]] || marked[g.node3[e]])
      out.push_back(static_cast<int32_t>(e));
  return out;
}

}  // namespace softshock
