#include "integrator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace softshock {

__attribute__((target_clones("avx512f", "avx2", "default"))) void predict_nodes(
    double dt, std::size_t begin, std::size_t end, double* __restrict x, double* __restrict y,
    double* __restrict vx, double* __restrict vy, const double* __restrict ax,
    const double* __restrict ay, PackedNode* __restrict nodes) {
  for (std::size_t i = begin; i < end; ++i) {
    x[i] += dt * vx[i] + 0.5 * dt * dt * ax[i];
    y[i] += dt * vy[i] + 0.5 * dt * dt * ay[i];
    nodes[i].lanes[0] = x[i], nodes[i].lanes[1] = y[i];
    vx[i] += 0.5 * dt * ax[i];
    vy[i] += 0.5 * dt * ay[i];
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void correct_nodes(
    double dt, std::size_t begin, std::size_t end, const NodeForce* __restrict force,
    const double* __restrict fext_x, const double* __restrict fext_y,
    const uint8_t* __restrict free_x, const uint8_t* __restrict free_y,
    const double* __restrict mass, double* __restrict ax, double* __restrict ay,
    double* __restrict vx, double* __restrict vy) {
  for (std::size_t i = begin; i < end; ++i) {
    ax[i] = free_x[i] * (force[i].lanes[0] + fext_x[i]) / mass[i];
    ay[i] = free_y[i] * (force[i].lanes[1] + fext_y[i]) / mass[i];
    vx[i] += 0.5 * dt * ax[i];
    vy[i] += 0.5 * dt * ay[i];
  }
}

std::vector<double> consistent_mass_weights(const ElementGeometry& g, double density) {
  std::vector<double> weight(g.size());
  for (std::size_t e = 0; e < g.size(); ++e) weight[e] = density * g.area0[e] / 12.0;
  return weight;
}

void accumulate_consistent_mass_difference(const ElementGeometry& g, const double* weight,
                                           const double* ax, const double* ay, std::size_t begin,
                                           std::size_t end, NodeForce* difference) {
  for (std::size_t e = begin; e < end; ++e) {
    const int32_t i = g.node0[e], j = g.node1[e], k = g.node2[e];
    const double w = weight[e];
    const ForceLanes ai{ax[i], ay[i]}, aj{ax[j], ay[j]}, ak{ax[k], ay[k]};
    difference[i].lanes += w * (aj + ak - 2.0 * ai);
    difference[j].lanes += w * (ai + ak - 2.0 * aj);
    difference[k].lanes += w * (ai + aj - 2.0 * ak);
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void correct_mass_blend(
    double dt, double alpha, std::size_t begin, std::size_t end,
    const NodeForce* __restrict difference, const uint8_t* __restrict free_x,
    const uint8_t* __restrict free_y, const double* __restrict mass, double* __restrict ax,
    double* __restrict ay, double* __restrict vx, double* __restrict vy) {
  for (std::size_t i = begin; i < end; ++i) {
    ax[i] -= alpha * free_x[i] * difference[i].lanes[0] / mass[i];
    ay[i] -= alpha * free_y[i] * difference[i].lanes[1] / mass[i];
    vx[i] += 0.5 * dt * ax[i];
    vy[i] += 0.5 * dt * ay[i];
  }
}

void blended_momentum(const ElementGeometry& geometry, const double* weight, double alpha,
                      std::size_t nodes, const double* mass, const uint8_t* free_x,
                      const uint8_t* free_y, const double* vx, const double* vy, double* px,
                      double* py) {
  // y_0 = v, y_k = alpha M_L^-1 (M_C - M_L) y_(k-1) on the free components; p = M_L sum_k y_k.
  std::vector<double> yx(vx, vx + nodes), yy(vy, vy + nodes);
  std::vector<NodeForce> difference(nodes);
  double size = 0;  // sum |M_L v|, for the stopping test
  for (std::size_t i = 0; i < nodes; ++i) {
    px[i] = mass[i] * vx[i], py[i] = mass[i] * vy[i];
    size += std::fabs(px[i]) + std::fabs(py[i]);
  }
  for (int k = 1; k <= 400 && size > 0; ++k) {  // ratio <= 3/4: 400 terms reach any round-off
    std::fill(difference.begin(), difference.end(), NodeForce{});
    accumulate_consistent_mass_difference(geometry, weight, yx.data(), yy.data(), 0,
                                          geometry.size(), difference.data());
    double term = 0;
    for (std::size_t i = 0; i < nodes; ++i) {
      yx[i] = alpha * free_x[i] * difference[i].lanes[0] / mass[i];
      yy[i] = alpha * free_y[i] * difference[i].lanes[1] / mass[i];
      px[i] += mass[i] * yx[i], py[i] += mass[i] * yy[i];
      term += std::fabs(mass[i] * yx[i]) + std::fabs(mass[i] * yy[i]);
    }
    if (term <= 1e-17 * size) break;
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void correct_nodes_blended(
    double dt, std::size_t begin, std::size_t end, const NodeForce* __restrict force,
    const double* __restrict fext_x, const double* __restrict fext_y,
    const uint8_t* __restrict free_x, const uint8_t* __restrict free_y,
    const double* __restrict mass, double* __restrict ax, double* __restrict ay,
    double* __restrict fprev_x, double* __restrict fprev_y, double* __restrict px,
    double* __restrict py) {
  for (std::size_t i = begin; i < end; ++i) {
    const double fx = free_x[i] * (force[i].lanes[0] + fext_x[i]);
    const double fy = free_y[i] * (force[i].lanes[1] + fext_y[i]);
    ax[i] = fx / mass[i], ay[i] = fy / mass[i];
    px[i] += 0.5 * dt * (fprev_x[i] + fx), py[i] += 0.5 * dt * (fprev_y[i] + fy);
    fprev_x[i] = fx, fprev_y[i] = fy;
  }
}

StepBound volume_change_step(const ElementGeometry& g, std::span<const int32_t> elements,
                             const double* vx, const double* vy, const double* ax, const double* ay,
                             double max_volume_change) {
  StepBound bound{std::numeric_limits<double>::infinity(), -1};
  for (const int32_t e : elements) {
    const int32_t a = g.node0[e], b = g.node1[e], c = g.node2[e];
    const double d0 = g.dm_inv_xx[e], d1 = g.dm_inv_xy[e], d2 = g.dm_inv_yx[e], d3 = g.dm_inv_yy[e];
    // div u = tr(grad u), grad u = [u_b - u_a, u_c - u_a] Dm^-1 (continuum::deformation_gradient).
    auto divergence = [&](const double* ux, const double* uy) {
      return (ux[b] - ux[a]) * d0 + (ux[c] - ux[a]) * d2 + (uy[b] - uy[a]) * d1 +
             (uy[c] - uy[a]) * d3;
    };
    const double p = std::fabs(divergence(vx, vy)), q = std::fabs(divergence(ax, ay));
    // The positive root of p dt + q dt^2 / 2 = m, written without cancellation (q = 0: m / p).
    const double root = std::sqrt(p * p + 2.0 * q * max_volume_change);
    if (p + root > 0.0 && 2.0 * max_volume_change / (p + root) < bound.dt_s)
      bound = {2.0 * max_volume_change / (p + root), static_cast<int64_t>(e)};
  }
  return bound;
}

std::vector<int32_t> elements_on_nodes(const ElementGeometry& g, std::span<const int32_t> nodes,
                                       std::size_t node_count) {
  std::vector<uint8_t> marked(node_count, 0);
  for (const int32_t i : nodes) marked[i] = 1;
  std::vector<int32_t> out;
  for (std::size_t e = 0; e < g.size(); ++e)
    if (marked[g.node0[e]] || marked[g.node1[e]] || marked[g.node2[e]])
      out.push_back(static_cast<int32_t>(e));
  return out;
}

}  // namespace softshock
