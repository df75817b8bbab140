#include "nodal_pressure.hpp"

#include <algorithm>
#include <cmath>

#include "continuum.hpp"
#include "vector_math.hpp"

namespace softshock {

std::vector<double> reference_nodal_areas(const ElementGeometry& g, std::size_t nodes) {
  std::vector<double> v(nodes, 0.0);
  for (std::size_t e = 0; e < g.size(); ++e) {
    const double third = g.area0[e] / 3.0;
    v[g.node0[e]] += third, v[g.node1[e]] += third, v[g.node2[e]] += third;
  }
  return v;
}

// The element passes follow the element kernel's pattern: indexed loads into small contiguous
// buffers, a vectorised loop (the divisions eight at a time), then the scatter to the nodes in
// element order. Built without FMA contraction (CMakeLists.txt), so every clone computes what the
// scalar code did, bit for bit.
namespace {
constexpr std::size_t kBlock = 256;

// sum[k] = the three corner values of element block + k, for k < count (a block's gather).
inline __attribute__((always_inline)) void gather_corner_sums(const ElementGeometry& g,
                                                              const double* nodal,
                                                              std::size_t block, std::size_t count,
                                                              double* sum) {
  const int32_t *n0 = g.node0.data(), *n1 = g.node1.data(), *n2 = g.node2.data();
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t e = block + k;
    sum[k] = nodal[n0[e]] + nodal[n1[e]] + nodal[n2[e]];
  }
}
}  // namespace

__attribute__((target_clones("avx512f", "avx2", "default"))) void accumulate_nodal_areas(
    const ElementGeometry& g, const PackedNode* nodes, std::size_t begin, std::size_t end,
    double* area, double* j_element) {
  const int32_t *n0 = g.node0.data(), *n1 = g.node1.data(), *n2 = g.node2.data();
  const double* area0 = g.area0.data();
  alignas(64) double e1x[kBlock], e1y[kBlock], e2x[kBlock], e2y[kBlock], third[kBlock];
  for (std::size_t block = begin; block < end; block += kBlock) {
    const std::size_t count = std::min(kBlock, end - block);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const NodeLanes na = nodes[n0[e]].lanes;
      const NodeLanes edge1 = nodes[n1[e]].lanes - na, edge2 = nodes[n2[e]].lanes - na;
      e1x[k] = edge1[0], e1y[k] = edge1[1], e2x[k] = edge2[0], e2y[k] = edge2[1];
    }
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const double current = 0.5 * (e1x[k] * e2y[k] - e1y[k] * e2x[k]);
      j_element[block + k] = current / area0[block + k];
      third[k] = current / 3.0;
    }
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      area[n0[e]] += third[k], area[n1[e]] += third[k], area[n2[e]] += third[k];
    }
  }
}

namespace {
// Pass 2 over nodes [begin, end), in blocks so that with kEnergy the stored energy is summed in
// node order after each block's vectorised loop.
template <bool kEnergy>
inline __attribute__((always_inline)) void tait_state_blocks(
    double kappa, double n, const double* reference_area, const double* area, std::size_t begin,
    std::size_t end, double* nodal_j, double* mean_stress, double* bulk_modulus,
    StoredEnergySum energy) {
  alignas(64) double out[kBlock];
  for (std::size_t block = begin; block < end; block += kBlock) {
    const std::size_t count = std::min(kBlock, end - block);
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t i = block + k;
      const double j = area[i] / reference_area[i];
      const double j_minus_n = ::exp(-n * ::log(j));
      nodal_j[i] = j;
      mean_stress[i] = continuum::tait_mean_stress(kappa, n, j_minus_n);
      bulk_modulus[i] = continuum::tait_bulk_modulus(kappa, j_minus_n);
      if constexpr (kEnergy)
        out[k] = energy.weight * reference_area[i] * continuum::tait_energy(kappa, n, j, j_minus_n);
    }
    if constexpr (kEnergy)
      for (std::size_t k = 0; k < count; ++k) *energy.sum += out[k];
  }
}
}  // namespace

__attribute__((target_clones("avx512f", "avx2", "default"))) void nodal_tait_state(
    double kappa, double n, const double* reference_area, const double* area, std::size_t begin,
    std::size_t end, double* nodal_j, double* mean_stress, double* bulk_modulus,
    StoredEnergySum energy) {
  // Spelled out here and in pass 3: dispatching through a generic lambda compiled the body outside
  // this target clone (other libmvec variants: results moved by ~1e-14, measured).
  if (energy.sum)
    tait_state_blocks<true>(kappa, n, reference_area, area, begin, end, nodal_j, mean_stress,
                            bulk_modulus, energy);
  else
    tait_state_blocks<false>(kappa, n, reference_area, area, begin, end, nodal_j, mean_stress,
                             bulk_modulus, energy);
}

namespace {
// Pass 3 over elements [begin, end); with kEnergy the stabilisation energy is summed in element
// order after each block's vectorised loop.
template <bool kEnergy>
inline __attribute__((always_inline)) void stabilization_blocks(
    const ElementGeometry& g, double beta_kappa, const double* nodal_j, const double* j_element,
    std::size_t begin, std::size_t end, double* s_element, double* q_sum, StoredEnergySum energy) {
  const int32_t *n0 = g.node0.data(), *n1 = g.node1.data(), *n2 = g.node2.data();
  const double* area0 = g.area0.data();
  alignas(64) double j_sum[kBlock], share[kBlock], out[kBlock];
  for (std::size_t block = begin; block < end; block += kBlock) {
    const std::size_t count = std::min(kBlock, end - block);
    gather_corner_sums(g, nodal_j, block, count, j_sum);
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const double rho = j_sum[k] / (3.0 * j_element[e]);  // Jbar_e / J_e
      s_element[e] = continuum::stabilization_element_stress(beta_kappa, rho);
      share[k] = area0[e] * continuum::stabilization_nodal_share(beta_kappa, rho) / 3.0;
      if constexpr (kEnergy)
        out[k] = energy.weight * area0[e] *
                 continuum::stabilization_energy(beta_kappa, j_element[e], j_sum[k] / 3.0);
    }
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      q_sum[n0[e]] += share[k], q_sum[n1[e]] += share[k], q_sum[n2[e]] += share[k];
    }
    if constexpr (kEnergy)
      for (std::size_t k = 0; k < count; ++k) *energy.sum += out[k];
  }
}
}  // namespace

__attribute__((target_clones("avx512f", "avx2", "default"))) void accumulate_stabilization(
    const ElementGeometry& g, double beta_kappa, const double* nodal_j, const double* j_element,
    std::size_t begin, std::size_t end, double* s_element, double* q_sum, StoredEnergySum energy) {
  if (energy.sum)
    stabilization_blocks<true>(g, beta_kappa, nodal_j, j_element, begin, end, s_element, q_sum,
                               energy);
  else
    stabilization_blocks<false>(g, beta_kappa, nodal_j, j_element, begin, end, s_element, q_sum,
                                energy);
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void subtract_stabilization(
    const double* __restrict reference_area, const double* __restrict q_sum,
    const double* __restrict bulk_modulus, std::size_t begin, std::size_t end,
    double* __restrict mean_stress, PackedNode* __restrict nodes) {
  for (std::size_t i = begin; i < end; ++i) {
    mean_stress[i] -= q_sum[i] / reference_area[i];
    nodes[i].lanes[2] = mean_stress[i], nodes[i].lanes[3] = bulk_modulus[i];
  }
}

NodalPressureState nodal_pressure_state(const ElementGeometry& g,
                                        const std::vector<double>& reference_area, double kappa,
                                        double n, double element_weight, double beta,
                                        const double* x, const double* y) {
  const std::size_t nn = reference_area.size(), ne = g.size();
  std::vector<double> area(nn, 0.0), nodal_j(nn), sm(nn), k(nn), j_element(ne), s(ne, 0.0),
      q(nn, 0.0);
  std::vector<PackedNode> nodes(nn);
  pack_positions(x, y, 0, nn, nodes.data());
  accumulate_nodal_areas(g, nodes.data(), 0, ne, area.data(), j_element.data());
  NodalPressureState out;
  const double w_nodal = 1.0 - element_weight;
  const StoredEnergySum energy{w_nodal, &out.stored_energy};
  nodal_tait_state(kappa, n, reference_area.data(), area.data(), 0, nn, nodal_j.data(), sm.data(),
                   k.data(), energy);
  accumulate_stabilization(g, beta * kappa, nodal_j.data(), j_element.data(), 0, ne, s.data(),
                           q.data(), beta > 0 ? energy : StoredEnergySum{});
  subtract_stabilization(reference_area.data(), q.data(), k.data(), 0, nn, sm.data(), nodes.data());
  out.element_mean_stress.resize(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const double je = j_element[e];
    const double nodal_mean = (sm[g.node0[e]] + sm[g.node1[e]] + sm[g.node2[e]]) / 3.0 + s[e];
    out.element_mean_stress[e] =
        w_nodal * nodal_mean +
        element_weight * continuum::tait_mean_stress(kappa, n, std::pow(je, -n));
  }
  return out;
}

}  // namespace softshock
