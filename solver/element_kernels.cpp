#include "element_kernels.hpp"

#include <algorithm>
#include <cmath>

#include "continuum.hpp"
#include "vector_math.hpp"

namespace softshock {

ElementGeometry build_tri3_geometry(const Mesh& mesh) {
  const std::size_t ne = mesh.element_count();
  ElementGeometry g;
  for (auto* v : {&g.node0, &g.node1, &g.node2}) v->resize(ne);
  for (auto* v : {&g.dm_inv_xx, &g.dm_inv_xy, &g.dm_inv_yx, &g.dm_inv_yy, &g.area0}) v->resize(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const auto& t = mesh.triangles[e];
    g.node0[e] = t[0], g.node1[e] = t[1], g.node2[e] = t[2];
    const double a = mesh.x[t[1]] - mesh.x[t[0]], b = mesh.x[t[2]] - mesh.x[t[0]];
    const double c = mesh.y[t[1]] - mesh.y[t[0]], d = mesh.y[t[2]] - mesh.y[t[0]];
    const double det = a * d - b * c;  // Dm = [[a, b], [c, d]]
    g.dm_inv_xx[e] = d / det, g.dm_inv_xy[e] = -b / det;
    g.dm_inv_yx[e] = -c / det, g.dm_inv_yy[e] = a / det;
    g.area0[e] = 0.5 * det;
  }
  return g;
}

void ElementState::resize(std::size_t elements) {
  for (auto* v : {&f_xx, &f_xy, &f_yx, &f_yy}) v->assign(elements, 0.0);
  for (auto* v : {&pv_xx, &pv_xy, &pv_yx, &pv_yy, &viscosity, &bulk_viscosity})
    v->assign(elements, 0.0f);
  reset_to_reference();
}

void ElementState::reset_to_reference() {
  for (std::size_t e = 0; e < f_xx.size(); ++e) {
    f_xx[e] = 1.0, f_xy[e] = 0.0, f_yx[e] = 0.0, f_yy[e] = 1.0;
    pv_xx[e] = pv_xy[e] = pv_yx[e] = pv_yy[e] = 0.0f;
    viscosity[e] = bulk_viscosity[e] = 0.0f;
  }
}

void pack_positions(const double* x, const double* y, std::size_t begin, std::size_t end,
                    PackedNode* nodes) {
  for (std::size_t i = begin; i < end; ++i) nodes[i].lanes[0] = x[i], nodes[i].lanes[1] = y[i];
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void pack_nodal_state(
    const double* mean_stress, const double* bulk_modulus, std::size_t begin, std::size_t end,
    PackedNode* nodes) {
  for (std::size_t i = begin; i < end; ++i)
    nodes[i].lanes[2] = mean_stress[i], nodes[i].lanes[3] = bulk_modulus[i];
}

namespace {

// Eight doubles: the lanes of the block reductions (one AVX-512 register; two or four otherwise),
// loaded straight from the 64-byte aligned block buffers (may_alias: they are double arrays).
typedef double Lanes8 __attribute__((vector_size(64), may_alias));
typedef int64_t Mask8 __attribute__((vector_size(64)));
constexpr std::size_t kLanes = 8;
constexpr double kHuge = 1e300;  // above any squared stable step
inline const Lanes8& lanes_at(const double* p) {
  return *reinterpret_cast<const Lanes8*>(p);
}

// How an element gets its volumetric stress: its own Tait law (plain P1), the mean of its nodes'
// (average nodal pressure, element_weight 0: the default, no per-element J^-n at all), or a blend.
enum class Volumetric { kElement, kNodal, kBlend };

// The element loop, once per volumetric variant and with or without the sample's sums; inlined
// into the target_clones entry point below so each ISA gets its own vectorised copy.
template <Volumetric kVolumetric, bool kSample>
inline __attribute__((always_inline)) void element_loop(const ElementGeometry& g,
                                                        const PackedNode* nodes,
                                                        const KernelParams& p, std::size_t begin,
                                                        std::size_t end, ElementState& s,
                                                        KernelTotals& totals, NodeForce* node_force,
                                                        bool& all_valid) {
  namespace cm = continuum;
  constexpr bool kNodal = kVolumetric != Volumetric::kElement;
  const double n = p.tait_n;
  const bool lagged = p.dt > 0;
  const double artificial_on = p.viscosity && lagged ? 1.0 : 0.0;
  const double eta = lagged ? p.eta : 0.0;
  const double dt = lagged ? p.dt : 1.0;  // keeps the unused viscous branch finite
  const double kappa = p.kappa, mu = p.mu, rho0 = p.rho0, c1 = p.c1, c2 = p.c2;
  const double ramp_inv = p.ramp_inv;
  const bool smallest_altitude = p.altitude_length > 0.5;
  const double inv_rho0 = 1.0 / rho0, four_thirds_mu = 4.0 / 3.0 * mu;
  const double shear_share = p.artificial_shear;
  float *shear_out = s.viscosity.data(), *bulk_out = s.bulk_viscosity.data();
  const double w_element = kNodal ? p.element_weight : 1.0, w_nodal = 1.0 - w_element;
  const double* shift = p.element_stress_shift;
  const double beta_kappa = p.stabilization_beta_kappa;
  const double sqrt3 = std::sqrt(3.0);

  const int32_t* node0 = g.node0.data();
  const int32_t* node1 = g.node1.data();
  const int32_t* node2 = g.node2.data();
  const double *dxx = g.dm_inv_xx.data(), *dxy = g.dm_inv_xy.data(), *dyx = g.dm_inv_yx.data(),
               *dyy = g.dm_inv_yy.data(), *area0 = g.area0.data();
  double *fxx = s.f_xx.data(), *fxy = s.f_xy.data(), *fyx = s.f_yx.data(), *fyy = s.f_yy.data();
  float *pxx = s.pv_xx.data(), *pxy = s.pv_xy.data(), *pyx = s.pv_yx.data(), *pyy = s.pv_yy.data();

  // Edge vectors (and, with nodal pressures, the nodes' Tait state), one PackedNode row per
  // corner, are gathered per block into small contiguous buffers (indexed loads do not vectorise
  // well); the element loop then streams plain arrays. The loop body is branch-free and
  // reduction-free (viscosity is selected, not skipped; totals are reduced afterwards), so it
  // vectorises, exp and log included.
  constexpr std::size_t kBlock = 256;
  alignas(64) double edge1x[kBlock], edge1y[kBlock], edge2x[kBlock], edge2y[kBlock];
  alignas(64) double nodal_sm_sum[kBlock], nodal_k_max[kBlock];
  // Per-element results reduced after the (reduction-free, hence vectorisable) loop.
  alignas(64) double step_sq_out[kBlock], dissipation_out[kBlock], j_out[kBlock];
  alignas(64) double energy_out[kBlock], aspect_out[kBlock];  // kSample only
  // Corner forces of the block, scattered to the nodes after the vectorised loop.
  alignas(64) double f1x_out[kBlock], f1y_out[kBlock], f2x_out[kBlock], f2y_out[kBlock];
  double min_step_sq = totals.min_step_sq;
  int64_t min_step_element = totals.min_step_element;
  Lanes8 dissipation_lanes = {}, energy_lanes = {}, aspect_lanes = {};
  Mask8 valid_lanes = Mask8{} - 1;  // all true
  for (std::size_t block = begin; block < end; block += kBlock) {
    const std::size_t count = std::min(kBlock, end - block);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const NodeLanes na = nodes[node0[e]].lanes, nb = nodes[node1[e]].lanes,
                      nc = nodes[node2[e]].lanes;
      const NodeLanes edge1 = nb - na, edge2 = nc - na;
      edge1x[k] = edge1[0], edge1y[k] = edge1[1], edge2x[k] = edge2[0], edge2y[k] = edge2[1];
      if constexpr (kNodal) {
        const NodeLanes sum = na + nb + nc, max_ab = na > nb ? na : nb;
        const NodeLanes max_abc = max_ab > nc ? max_ab : nc;
        nodal_sm_sum[k] = sum[2], nodal_k_max[k] = max_abc[3];
      }
    }
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const double e1x = edge1x[k], e1y = edge1y[k], e2x = edge2x[k], e2y = edge2y[k];
      const cm::Mat2 dm_inv{dxx[e], dxy[e], dyx[e], dyy[e]};
      const cm::Mat2 f = cm::deformation_gradient(e1x, e1y, e2x, e2y, dm_inv);
      const double j = cm::det(f);
      j_out[k] = j;
      const cm::Mat2 cof = cm::cofactor(f);
      // J^-2/3 (below): with nodal pressures the element needs no J^-n, so one cube root
      // (libmvec) of 1/J^2 in place of a logarithm and an exponential; otherwise one logarithm
      // feeds J^-n and J^-2/3.
      double log_j = 0.0, j_minus_n = 0.0;
      if constexpr (kVolumetric != Volumetric::kNodal)
        log_j = ::log(j), j_minus_n = ::exp(-n * log_j);
      double mean_stress, bulk_modulus;
      if constexpr (kVolumetric == Volumetric::kNodal) {  // w_element = 0
        mean_stress = nodal_sm_sum[k] * cm::kThird + shift[e];
        bulk_modulus = nodal_k_max[k] + cm::stabilization_bulk_modulus(beta_kappa, shift[e]);
      } else if constexpr (kVolumetric == Volumetric::kBlend) {
        mean_stress = w_nodal * (nodal_sm_sum[k] * cm::kThird + shift[e]) +
                      w_element * cm::tait_mean_stress(kappa, n, j_minus_n);
        bulk_modulus =
            w_nodal * (nodal_k_max[k] + cm::stabilization_bulk_modulus(beta_kappa, shift[e])) +
            w_element * cm::tait_bulk_modulus(kappa, j_minus_n);
      } else {
        mean_stress = cm::tait_mean_stress(kappa, n, j_minus_n);
        bulk_modulus = cm::tait_bulk_modulus(kappa, j_minus_n);
      }
      // c^2 = (K + 4/3 mu) / rho with rho = rho0 / J (continuum::longitudinal_speed_sq).
      const double c_sq = (bulk_modulus + four_thirds_mu) * j * inv_rho0;

      // Five quotients, one division (continuum::step_reciprocals); the length is the longest
      // edge, so 1/length^2 gives the smallest altitude.
      const cm::Mat2 f_prev{fxx[e], fxy[e], fyx[e], fyy[e]};
      const double j_prev = cm::det(f_prev);  // bit for bit the J of the last evaluation
      const double l_sq = cm::longest_edge_sq(e1x, e1y, e2x, e2y);
      const auto q = cm::step_reciprocals(j, l_sq, j_prev, dt, c_sq);
      const double inv_j = q.j, inv_l_sq = q.length_sq;
      const double inv_u = q.j_sum, inv_v = q.j_prev_dt, inv_z = q.dt_c_sq;

      double j_minus_23;
      if constexpr (kVolumetric == Volumetric::kNodal)
        j_minus_23 = ::cbrt(inv_j * inv_j);
      else
        j_minus_23 = ::exp(-2.0 / 3.0 * log_j);
      const cm::Mat2 elastic = cm::elastic_piola_inv_j(f, cof, inv_j, mean_stress, mu, j_minus_23);
      if constexpr (kSample) {
        double w = cm::neo_hookean_energy(mu, cm::first_invariant(f), j_minus_23);
        if constexpr (kVolumetric != Volumetric::kNodal)
          w += w_element * cm::tait_energy(kappa, n, j, j_minus_n);
        energy_out[k] = area0[e] * w;
        aspect_out[k] = cm::aspect_ratio(e1x, e1y, e2x, e2y);
      }

      const double twice_area = e1x * e2y - e1y * e2x;
      const double h_sq = twice_area * twice_area * inv_l_sq;  // smallest altitude squared

      // Viscosity: artificial (continuous in the compression measure z) plus Kelvin-Voigt. Its
      // length h: the smallest altitude (thesis) or that of the equilateral triangle of the
      // current area. Only h c enters: z = -h ln(J / J_prev) / (dt c) = -h c ln(..) / (dt c^2)
      // and nu = 3/4 h rho c (...), so one square root gives it.
      const double hc = std::sqrt((smallest_altitude ? h_sq : sqrt3 * j * area0[e]) * c_sq);
      const double z = -hc * cm::log_ratio_u((j - j_prev) * inv_u) * inv_z;
      // The thesis's artificial viscosity is a shear viscosity; the continuous one acts on
      // compression alone, as a bulk viscosity of the same longitudinal strength (4/3 nu), so a
      // planar shock sees the same viscous stress but isochoric (shear) flow -- the rim's
      // instability -- sees only the physical eta (docs/model.md).
      const double nu_art =
          artificial_on * cm::artificial_viscosity_hc(hc, rho0 * inv_j, c1, c2, z, ramp_inv);
      const double nu = eta + shear_share * nu_art;
      const double zeta = (1.0 - shear_share) * 4.0 / 3.0 * nu_art;
      // The step sees the physical viscosity from the first step on (the stress only once there
      // is a lagged rate): a viscosity-limited first step taken at the elastic estimate made
      // energy from nothing (eta = 100 Pa s: +25 % of the external work).
      const double nu_step = p.eta + shear_share * nu_art;
      step_sq_out[k] =
          cm::stable_step_sq_kinematic(h_sq, c_sq, (4.0 / 3.0 * nu_step + zeta) * j * inv_rho0);
      const cm::Mat2 pv = cm::viscous_piola_inv(f, f_prev, cof, nu, zeta, inv_v);
      shear_out[e] = static_cast<float>(nu), bulk_out[e] = static_cast<float>(zeta);
      // Work of the viscous stress over the step, trapezoidal in time: what the integrator sees
      // as nodal viscous forces times the nodal displacement increments.
      dissipation_out[k] =
          0.5 * area0[e] *
          ((pv[0] + pxx[e]) * (f[0] - f_prev[0]) + (pv[1] + pxy[e]) * (f[1] - f_prev[1]) +
           (pv[2] + pyx[e]) * (f[2] - f_prev[2]) + (pv[3] + pyy[e]) * (f[3] - f_prev[3]));

      fxx[e] = f[0], fxy[e] = f[1], fyx[e] = f[2], fyy[e] = f[3];
      pxx[e] = static_cast<float>(pv[0]), pxy[e] = static_cast<float>(pv[1]);
      pyx[e] = static_cast<float>(pv[2]), pyy[e] = static_cast<float>(pv[3]);

      // Force on node a: -A0 P grad N_a; grad N1, grad N2 are the rows of Dm^-1.
      const double p00 = elastic[0] + pv[0], p01 = elastic[1] + pv[1];
      const double p10 = elastic[2] + pv[2], p11 = elastic[3] + pv[3];
      const double a0 = area0[e];
      const double f1x = -a0 * (p00 * dm_inv[0] + p01 * dm_inv[1]);
      const double f1y = -a0 * (p10 * dm_inv[0] + p11 * dm_inv[1]);
      const double f2x = -a0 * (p00 * dm_inv[2] + p01 * dm_inv[3]);
      const double f2y = -a0 * (p10 * dm_inv[2] + p11 * dm_inv[3]);
      f1x_out[k] = f1x, f1y_out[k] = f1y, f2x_out[k] = f2x, f2y_out[k] = f2y;
    }
    // The block's reductions, eight lanes at a time (a scalar loop was a chain of dependent adds
    // and compares, a quarter of the loop's time): the smallest stable step exactly as a scalar
    // scan finds it (its first element), the sums as eight lane-wise partial sums added in lane
    // order at the end -- deterministic for a given element range. The tail of the last block is
    // padded with values that leave every reduction unchanged.
    const std::size_t padded = (count + kLanes - 1) / kLanes * kLanes;
    for (std::size_t k = count; k < padded; ++k) {
      step_sq_out[k] = kHuge, dissipation_out[k] = 0.0, j_out[k] = 1.0;
      if constexpr (kSample) energy_out[k] = 0.0, aspect_out[k] = 0.0;
    }
    Lanes8 block_min = Lanes8{} + kHuge;
    for (std::size_t k = 0; k < padded; k += kLanes) {
      const Lanes8 step_sq = lanes_at(step_sq_out + k);
      block_min = step_sq < block_min ? step_sq : block_min;  // NaN never wins, as in a scan
      dissipation_lanes += lanes_at(dissipation_out + k);
      valid_lanes &= lanes_at(j_out + k) > 0.0;  // false for J <= 0 and for NaN
      if constexpr (kSample) {
        energy_lanes += lanes_at(energy_out + k);
        const Lanes8 aspect = lanes_at(aspect_out + k);
        aspect_lanes = aspect > aspect_lanes ? aspect : aspect_lanes;
      }
    }
    double smallest = kHuge;
    for (std::size_t lane = 0; lane < kLanes; ++lane)
      smallest = block_min[lane] < smallest ? block_min[lane] : smallest;
    if (smallest < min_step_sq) {
      std::size_t k = 0;
      while (step_sq_out[k] != smallest) ++k;
      min_step_sq = smallest, min_step_element = static_cast<int64_t>(block + k);
    }
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const ForceLanes f1{f1x_out[k], f1y_out[k]}, f2{f2x_out[k], f2y_out[k]};
      node_force[node0[e]].lanes -= f1 + f2;
      node_force[node1[e]].lanes += f1;
      node_force[node2[e]].lanes += f2;
    }
  }
  double dissipation = 0.0, element_energy = 0.0, max_aspect = totals.max_aspect_ratio;
  for (std::size_t lane = 0; lane < kLanes; ++lane) {
    dissipation += dissipation_lanes[lane];
    all_valid &= valid_lanes[lane] != 0;
    if constexpr (kSample) {
      element_energy += energy_lanes[lane];
      max_aspect = aspect_lanes[lane] > max_aspect ? aspect_lanes[lane] : max_aspect;
    }
  }
  totals.min_step_sq = min_step_sq;
  totals.min_step_element = min_step_element;
  totals.dissipation += dissipation;
  totals.element_energy += element_energy;
  totals.max_aspect_ratio = max_aspect;
}

// The loop with or without the sample's sums.
template <Volumetric kVolumetric, typename... Args>
inline __attribute__((always_inline)) void element_loop_sampled(bool sample, Args&... args) {
  if (sample)
    element_loop<kVolumetric, true>(args...);
  else
    element_loop<kVolumetric, false>(args...);
}

}  // namespace

// Compiled for AVX-512, AVX2 and the baseline ISA; the loader picks one at start-up.
__attribute__((target_clones("avx512f", "avx2", "default"))) void compute_element_forces(
    const ElementGeometry& g, const PackedNode* nodes, const KernelParams& p, std::size_t begin,
    std::size_t end, ElementState& s, KernelTotals& totals, NodeForce* node_force) {
  namespace cm = continuum;
  const int32_t *node0 = g.node0.data(), *node1 = g.node1.data(), *node2 = g.node2.data();
  const double *dxx = g.dm_inv_xx.data(), *dxy = g.dm_inv_xy.data(), *dyx = g.dm_inv_yx.data(),
               *dyy = g.dm_inv_yy.data();
  bool all_valid = true;
  if (!p.nodal_pressure)
    element_loop_sampled<Volumetric::kElement>(p.sample, g, nodes, p, begin, end, s, totals,
                                               node_force, all_valid);
  else if (p.element_weight == 0.0)
    element_loop_sampled<Volumetric::kNodal>(p.sample, g, nodes, p, begin, end, s, totals,
                                             node_force, all_valid);
  else
    element_loop_sampled<Volumetric::kBlend>(p.sample, g, nodes, p, begin, end, s, totals,
                                             node_force, all_valid);

  if (!all_valid && totals.bad_element < 0) {  // rare: recompute J to name the first offender
    for (std::size_t e = begin; e < end; ++e) {
      const NodeLanes edge1 = nodes[node1[e]].lanes - nodes[node0[e]].lanes,
                      edge2 = nodes[node2[e]].lanes - nodes[node0[e]].lanes;
      const double j = cm::det(cm::deformation_gradient(edge1[0], edge1[1], edge2[0], edge2[1],
                                                        {dxx[e], dxy[e], dyx[e], dyy[e]}));
      if (!(j > 0.0)) {
        totals.bad_element = static_cast<int64_t>(e), totals.bad_j = j;
        break;
      }
    }
  }
}

}  // namespace softshock
