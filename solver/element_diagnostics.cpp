#include "element_diagnostics.hpp"

#include <algorithm>
#include <cmath>

#include "continuum.hpp"

// libmvec's vector log/exp (see element_kernels.cpp for why they are declared here).
extern "C" {
__attribute__((simd("notinbranch"))) double exp(double) noexcept;
__attribute__((simd("notinbranch"))) double log(double) noexcept;
}

namespace softshock {

__attribute__((target_clones("avx512f", "avx2", "default"))) ElementScan scan_elements(
    const ElementGeometry& g, const double* x, const double* y, double mu, double kappa, double n,
    double w_element, double energy) {
  namespace cm = continuum;
  const int32_t *node0 = g.node0.data(), *node1 = g.node1.data(), *node2 = g.node2.data();
  const double *dxx = g.dm_inv_xx.data(), *dxy = g.dm_inv_xy.data(), *dyx = g.dm_inv_yx.data(),
               *dyy = g.dm_inv_yy.data(), *area0 = g.area0.data();
  const double volumetric_on = w_element > 0 ? 1.0 : 0.0;
  constexpr std::size_t kBlock = 256;
  alignas(64) double e1x[kBlock], e1y[kBlock], e2x[kBlock], e2y[kBlock];
  alignas(64) double energy_out[kBlock], aspect_out[kBlock];
  double max_aspect = 0.0;
  const std::size_t ne = g.size();
  for (std::size_t block = 0; block < ne; block += kBlock) {
    const std::size_t count = std::min(kBlock, ne - block);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const int32_t a = node0[e], b = node1[e], c = node2[e];
      e1x[k] = x[b] - x[a], e1y[k] = y[b] - y[a];
      e2x[k] = x[c] - x[a], e2y[k] = y[c] - y[a];
    }
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const cm::Mat2 f = cm::deformation_gradient(e1x[k], e1y[k], e2x[k], e2y[k],
                                                  {dxx[e], dxy[e], dyx[e], dyy[e]});
      const double j = cm::det(f);
      const double log_j = ::log(j);
      double w = cm::neo_hookean_energy(mu, cm::first_invariant(f), ::exp(-2.0 / 3.0 * log_j));
      // Selected, not branched (vectorises); the element's own W_vol only where it is blended in.
      const double w_vol = cm::tait_energy(kappa, n, j, ::exp(-n * log_j));
      w += volumetric_on > 0.0 ? w_element * w_vol : 0.0;
      energy_out[k] = area0[e] * w;
      aspect_out[k] = cm::aspect_ratio(e1x[k], e1y[k], e2x[k], e2y[k]);
    }
    for (std::size_t k = 0; k < count; ++k) {
      energy += energy_out[k];
      const double r = aspect_out[k];
      max_aspect = (block == 0 && k == 0) || r > max_aspect ? r : max_aspect;
    }
  }
  return {energy, max_aspect};
}

__attribute__((target_clones("avx512f", "avx2", "default"))) double add_nodal_volumetric_energy(
    const double* reference_area, const double* nodal_j, std::size_t nodes, double kappa, double n,
    double w, double energy) {
  constexpr std::size_t kBlock = 256;
  alignas(64) double out[kBlock];
  for (std::size_t block = 0; block < nodes; block += kBlock) {
    const std::size_t count = std::min(kBlock, nodes - block);
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const double j = nodal_j[block + k];
      out[k] =
          w * reference_area[block + k] * continuum::tait_energy(kappa, n, j, ::exp(-n * ::log(j)));
    }
    for (std::size_t k = 0; k < count; ++k) energy += out[k];
  }
  return energy;
}

}  // namespace softshock
