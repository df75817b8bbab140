#include "tet4_kernels.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "continuum.hpp"
#include "vector_math.hpp"

namespace softshock {

Tet4Geometry build_tet4_geometry(const Mesh& mesh) {
  if (mesh.tetrahedra.empty()) throw std::invalid_argument("Tet4: the mesh has no tetrahedra");
  const std::size_t ne = mesh.tetrahedra.size();
  Tet4Geometry g;
  for (auto* v : {&g.node0, &g.node1, &g.node2, &g.node3}) v->resize(ne);
  g.dm_inv.assign(tet4_blocked_size(ne), 0.0);
  g.volume0.resize(ne);
  g.regular_altitude0.resize(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const auto& t = mesh.tetrahedra[e];
    g.node0[e] = t[0], g.node1[e] = t[1], g.node2[e] = t[2], g.node3[e] = t[3];
    // Dm's columns are the reference edges from node 0.
    continuum::Mat3 dm;
    for (int k = 0; k < 3; ++k) {
      dm[3 * 0 + k] = mesh.x[t[k + 1]] - mesh.x[t[0]];
      dm[3 * 1 + k] = mesh.y[t[k + 1]] - mesh.y[t[0]];
      dm[3 * 2 + k] = mesh.z[t[k + 1]] - mesh.z[t[0]];
    }
    const continuum::Mat3 cof = continuum::cofactor(dm);
    const double det = continuum::det(dm, cof);
    // Dm^-1 = cof(Dm)^T / det.
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) g.dm_inv[tet4_blocked_index(3 * i + j, e)] = cof[3 * j + i] / det;
    g.volume0[e] = det / 6.0;
    g.regular_altitude0[e] = continuum::regular_tetrahedron_altitude(g.volume0[e]);
  }
  return g;
}

void Tet4State::resize(std::size_t elements) {
  f.assign(tet4_blocked_size(elements), 0.0);
  pv.assign(tet4_blocked_size(elements), 0.0f);
  viscosity.assign(elements, 0.0f);
  bulk_viscosity.assign(elements, 0.0f);
  reset_to_reference();
}

void Tet4State::reset_to_reference() {
  for (std::size_t i = 0; i < f.size(); ++i) {
    const std::size_t component = i / kTet4Block % 9;
    f[i] = component % 4 == 0 ? 1.0 : 0.0;  // the diagonal: components 0, 4, 8
  }
  std::fill(pv.begin(), pv.end(), 0.0f);
  std::fill(viscosity.begin(), viscosity.end(), 0.0f);
  std::fill(bulk_viscosity.begin(), bulk_viscosity.end(), 0.0f);
}

void pack_positions(const double* x, const double* y, const double* z, std::size_t begin,
                    std::size_t end, PackedNode3* nodes) {
  for (std::size_t i = begin; i < end; ++i)
    nodes[i].lanes[0] = x[i], nodes[i].lanes[1] = y[i], nodes[i].lanes[2] = z[i];
}

void pack_nodal_state(const double* mean_stress, const double* bulk_modulus, std::size_t begin,
                      std::size_t end, PackedNode3* nodes) {
  for (std::size_t i = begin; i < end; ++i)
    nodes[i].lanes[3] = mean_stress[i], nodes[i].lanes[4] = bulk_modulus[i];
}

namespace {

typedef double Lanes8 __attribute__((vector_size(64), may_alias));
typedef int64_t Mask8 __attribute__((vector_size(64)));
constexpr std::size_t kLanes = 8;
constexpr double kHuge = 1e300;  // above any squared stable step
inline const Lanes8& lanes_at(const double* p) {
  return *reinterpret_cast<const Lanes8*>(p);
}

enum class Volumetric { kElement, kNodal, kBlend };

// The triangle loop's structure (element_kernels.cpp, whose comments say why): per block, the
// corners' rows gathered into contiguous buffers, a branch-free vectorised loop, the reductions
// eight lanes at a time, then the scatter of the corner forces in element order.
template <Volumetric kVolumetric, bool kSample>
inline __attribute__((always_inline)) void tet4_loop(
    const Tet4Geometry& g, const PackedNode3* nodes, const KernelParams& p, std::size_t begin,
    std::size_t end, Tet4State& s, KernelTotals& totals, NodeForce3* node_force, bool& all_valid) {
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

  const int32_t *node0 = g.node0.data(), *node1 = g.node1.data(), *node2 = g.node2.data(),
                *node3 = g.node3.data();
  const double *volume0 = g.volume0.data(), *altitude0 = g.regular_altitude0.data();

  // Three loops per block rather than one (loop fission): one loop over the whole element's work
  // held ~80 values live and spilled most of them (82 ns per element, measured); each loop here
  // keeps its working set in registers, its intermediates in small buffers in L1.
  constexpr std::size_t kBlock = kTet4Block;
  alignas(64) double edge[9][kBlock];  // e1x, e1y, e1z, e2x, ..., e3z
  alignas(64) double nodal_sm_sum[kBlock], nodal_k_max[kBlock];
  alignas(64) double step_sq_out[kBlock], dissipation_out[kBlock], j_out[kBlock];
  alignas(64) double energy_out[kBlock], aspect_out[kBlock];  // kSample only
  alignas(64) double f_now[9][kBlock], cof_now[9][kBlock];    // F and cof(F) of the block
  // The elastic stress's two scalars (P_e = s cof + a F), the viscosities, 1 / (J_prev dt).
  alignas(64) double s_coef[kBlock], a_coef[kBlock], nu_buf[kBlock], zeta_buf[kBlock],
      inv_v_buf[kBlock];
  alignas(64) double piola[9][kBlock];      // the total P
  alignas(64) double force_out[9][kBlock];  // corner forces of nodes 1..3 (x, y, z each)
  double min_step_sq = totals.min_step_sq;
  int64_t min_step_element = totals.min_step_element;
  Lanes8 dissipation_lanes = {}, energy_lanes = {}, aspect_lanes = {};
  Mask8 valid_lanes = Mask8{} - 1;
  for (std::size_t block = begin; block < end;) {
    // The storage block holding element `block`: a range that starts inside one (a thread's, a
    // test's single element) takes the rest of it first.
    const std::size_t lane0 = block % kBlock;
    const std::size_t count = std::min(kBlock - lane0, end - block);
    const std::size_t blocked = tet4_blocked_index(0, block);
    const double* __restrict dm = g.dm_inv.data() + blocked;  // dm[c * kBlock + k]
    double* __restrict fs = s.f.data() + blocked;
    float* __restrict pvs = s.pv.data() + blocked;
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const NodeLanes3 na = nodes[node0[e]].lanes, nb = nodes[node1[e]].lanes,
                       nc = nodes[node2[e]].lanes, nd = nodes[node3[e]].lanes;
      const NodeLanes3 e1 = nb - na, e2 = nc - na, e3 = nd - na;
      for (int c = 0; c < 3; ++c)
        edge[c][k] = e1[c], edge[3 + c][k] = e2[c], edge[6 + c][k] = e3[c];
      if constexpr (kNodal) {
        const NodeLanes3 sum = na + nb + nc + nd;
        const NodeLanes3 max_ab = na > nb ? na : nb, max_cd = nc > nd ? nc : nd;
        const NodeLanes3 max_all = max_ab > max_cd ? max_ab : max_cd;
        nodal_sm_sum[k] = sum[3], nodal_k_max[k] = max_all[4];
      }
    }
    // 1. Kinematics, the pointwise law, the viscosities and the stable step.
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const double e1x = edge[0][k], e1y = edge[1][k], e1z = edge[2][k];
      const double e2x = edge[3][k], e2y = edge[4][k], e2z = edge[5][k];
      const double e3x = edge[6][k], e3y = edge[7][k], e3z = edge[8][k];
      cm::Mat3 dm_inv;
      for (int c = 0; c < 9; ++c) dm_inv[c] = dm[c * kBlock + k];
      const cm::Mat3 f =
          cm::deformation_gradient(e1x, e1y, e1z, e2x, e2y, e2z, e3x, e3y, e3z, dm_inv);
      const cm::Mat3 cof = cm::cofactor(f);
      const double j = cm::det(f, cof);
      for (int c = 0; c < 9; ++c) f_now[c][k] = f[c], cof_now[c][k] = cof[c];
      j_out[k] = j;
      double log_j = 0.0, j_minus_n = 0.0;
      if constexpr (kVolumetric != Volumetric::kNodal)
        log_j = ::log(j), j_minus_n = ::exp(-n * log_j);
      double mean_stress, bulk_modulus;
      if constexpr (kVolumetric == Volumetric::kNodal) {
        mean_stress = 0.25 * nodal_sm_sum[k] + shift[e];
        bulk_modulus = nodal_k_max[k] + cm::stabilization_bulk_modulus(beta_kappa, shift[e]);
      } else if constexpr (kVolumetric == Volumetric::kBlend) {
        mean_stress = w_nodal * (0.25 * nodal_sm_sum[k] + shift[e]) +
                      w_element * cm::tait_mean_stress(kappa, n, j_minus_n);
        bulk_modulus =
            w_nodal * (nodal_k_max[k] + cm::stabilization_bulk_modulus(beta_kappa, shift[e])) +
            w_element * cm::tait_bulk_modulus(kappa, j_minus_n);
      } else {
        mean_stress = cm::tait_mean_stress(kappa, n, j_minus_n);
        bulk_modulus = cm::tait_bulk_modulus(kappa, j_minus_n);
      }
      const double c_sq = (bulk_modulus + four_thirds_mu) * j * inv_rho0;

      cm::Mat3 f_prev;
      for (int c = 0; c < 9; ++c) f_prev[c] = fs[c * kBlock + k];
      const double j_prev = cm::det(f_prev);  // bit for bit the last evaluation's J
      const double face_sq = cm::largest_face_sq(e1x, e1y, e1z, e2x, e2y, e2z, e3x, e3y, e3z);
      // Five quotients, one division (as for triangles): 1/J, 1/face^2 (the smallest altitude),
      // 1/(J + J_prev), 1/(J_prev dt), 1/(dt c^2).
      const double den_u = j + j_prev, den_v = j_prev * dt, den_z = dt * c_sq;
      const double p_a = j * face_sq, p_b = den_u * den_v;
      const double ab = p_a * p_b, ac = p_a * den_z, bc = p_b * den_z;
      const double r = 1.0 / (ab * den_z);
      const double inv_j = r * bc * face_sq, inv_face_sq = r * bc * j;
      const double inv_u = r * ac * den_v, inv_v = r * ac * den_u, inv_z = r * ab;

      double j_minus_23;
      if constexpr (kVolumetric == Volumetric::kNodal)
        j_minus_23 = ::cbrt(inv_j * inv_j);
      else
        j_minus_23 = ::exp(-2.0 / 3.0 * log_j);
      // P_e = sigma_m cof + mu J^-2/3 (F - I1/3 F^-T) = s cof + a F (continuum's elastic_piola).
      const double a = mu * j_minus_23;
      const double i1 = cm::first_invariant(f);
      a_coef[k] = a;
      s_coef[k] = mean_stress - a * i1 * (cm::kThird * inv_j);
      const double six_volume = 6.0 * volume0[e] * j;  // det [e1 e2 e3]
      if constexpr (kSample) {
        double w = cm::neo_hookean_energy(mu, i1, j_minus_23);
        if constexpr (kVolumetric != Volumetric::kNodal)
          w += w_element * cm::tait_energy(kappa, n, j, j_minus_n);
        energy_out[k] = volume0[e] * w;
        aspect_out[k] = cm::aspect_ratio(
            cm::longest_edge_sq(e1x, e1y, e1z, e2x, e2y, e2z, e3x, e3y, e3z), six_volume, face_sq);
      }
      const double h_sq = six_volume * six_volume * inv_face_sq;  // smallest altitude squared
      // The viscosity's length: the smallest altitude (thesis) or the regular tetrahedron's of
      // the current volume, altitude0 J^(1/3) = altitude0 J J^(-2/3).
      const double regular = altitude0[e] * j * j_minus_23;
      const double hc = std::sqrt((smallest_altitude ? h_sq : regular * regular) * c_sq);
      const double z = -hc * cm::log_ratio_u((j - j_prev) * inv_u) * inv_z;
      const double nu_art =
          artificial_on * cm::artificial_viscosity_hc(hc, rho0 * inv_j, c1, c2, z, ramp_inv);
      const double nu = eta + shear_share * nu_art;
      const double zeta = (1.0 - shear_share) * 4.0 / 3.0 * nu_art;
      const double nu_step = p.eta + shear_share * nu_art;
      step_sq_out[k] =
          cm::stable_step_sq_kinematic(h_sq, c_sq, (4.0 / 3.0 * nu_step + zeta) * j * inv_rho0);
      shear_out[e] = static_cast<float>(nu), bulk_out[e] = static_cast<float>(zeta);
      nu_buf[k] = nu, zeta_buf[k] = zeta, inv_v_buf[k] = inv_v;
    }
    // 2. The viscous stress from the lagged rate, the dissipation, the state, the total P.
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      cm::Mat3 f, cof, f_prev;
      for (int c = 0; c < 9; ++c)
        f[c] = f_now[c][k], cof[c] = cof_now[c][k], f_prev[c] = fs[c * kBlock + k];
      const cm::Mat3 pv = cm::viscous_piola_inv(f, f_prev, cm::cofactor(f_prev), cof, nu_buf[k],
                                                zeta_buf[k], inv_v_buf[k]);
      double work = 0.0;
      for (int c = 0; c < 9; ++c) work += (pv[c] + pvs[c * kBlock + k]) * (f[c] - f_prev[c]);
      dissipation_out[k] = 0.5 * volume0[e] * work;
      for (int c = 0; c < 9; ++c) {
        fs[c * kBlock + k] = f[c], pvs[c * kBlock + k] = static_cast<float>(pv[c]);
        piola[c][k] = s_coef[k] * cof[c] + a_coef[k] * f[c] + pv[c];
      }
    }
    // 3. Force on node a: -V0 P grad N_a, grad N_a the rows of Dm^-1 (a = 1, 2, 3).
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const double v0 = volume0[e];
      for (int a = 0; a < 3; ++a) {
        const double g0 = dm[(3 * a) * kBlock + k], g1 = dm[(3 * a + 1) * kBlock + k],
                     g2 = dm[(3 * a + 2) * kBlock + k];
        for (int i = 0; i < 3; ++i)
          force_out[3 * a + i][k] =
              -v0 * (piola[3 * i][k] * g0 + piola[3 * i + 1][k] * g1 + piola[3 * i + 2][k] * g2);
      }
    }
    // Reductions, as in the triangle loop: the padded tail leaves each one unchanged.
    const std::size_t padded = (count + kLanes - 1) / kLanes * kLanes;
    for (std::size_t k = count; k < padded; ++k) {
      step_sq_out[k] = kHuge, dissipation_out[k] = 0.0, j_out[k] = 1.0;
      if constexpr (kSample) energy_out[k] = 0.0, aspect_out[k] = 0.0;
    }
    Lanes8 block_min = Lanes8{} + kHuge;
    for (std::size_t k = 0; k < padded; k += kLanes) {
      const Lanes8 step_sq = lanes_at(step_sq_out + k);
      block_min = step_sq < block_min ? step_sq : block_min;
      dissipation_lanes += lanes_at(dissipation_out + k);
      valid_lanes &= lanes_at(j_out + k) > 0.0;
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
      const ForceLanes3 f1{force_out[0][k], force_out[1][k], force_out[2][k], 0.0},
          f2{force_out[3][k], force_out[4][k], force_out[5][k], 0.0},
          f3{force_out[6][k], force_out[7][k], force_out[8][k], 0.0};
      node_force[node0[e]].lanes -= f1 + f2 + f3;
      node_force[node1[e]].lanes += f1;
      node_force[node2[e]].lanes += f2;
      node_force[node3[e]].lanes += f3;
    }
    block += count;
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

template <Volumetric kVolumetric, typename... Args>
inline __attribute__((always_inline)) void tet4_loop_sampled(bool sample, Args&... args) {
  if (sample)
    tet4_loop<kVolumetric, true>(args...);
  else
    tet4_loop<kVolumetric, false>(args...);
}

}  // namespace

// One copy of the loops per instruction set, chosen once at run time: AVX-512, AVX2 with FMA (the
// loops are mostly multiply-adds: target_clones' "avx2" has no FMA, and its "arch=haswell" clone
// is chosen by CPU model, not features, so an AMD CPU would fall back to SSE2), and the baseline.
namespace {

#define SOFTSHOCK_TET4_ARGS g, nodes, p, begin, end, s, totals, node_force, valid
#define SOFTSHOCK_TET4_VARIANTS(args)                        \
  if (!p.nodal_pressure)                                     \
    tet4_loop_sampled<Volumetric::kElement>(p.sample, args); \
  else if (p.element_weight == 0.0)                          \
    tet4_loop_sampled<Volumetric::kNodal>(p.sample, args);   \
  else                                                       \
    tet4_loop_sampled<Volumetric::kBlend>(p.sample, args);

using LoopFn = void (*)(const Tet4Geometry&, const PackedNode3*, const KernelParams&, std::size_t,
                        std::size_t, Tet4State&, KernelTotals&, NodeForce3*, bool&);

__attribute__((target("avx512f,avx512dq,avx512vl,avx2,fma"))) void loops_avx512(
    const Tet4Geometry& g, const PackedNode3* nodes, const KernelParams& p, std::size_t begin,
    std::size_t end, Tet4State& s, KernelTotals& totals, NodeForce3* node_force, bool& valid) {
  SOFTSHOCK_TET4_VARIANTS(SOFTSHOCK_TET4_ARGS)
}
__attribute__((target("avx2,fma"))) void loops_avx2(const Tet4Geometry& g, const PackedNode3* nodes,
                                                    const KernelParams& p, std::size_t begin,
                                                    std::size_t end, Tet4State& s,
                                                    KernelTotals& totals, NodeForce3* node_force,
                                                    bool& valid) {
  SOFTSHOCK_TET4_VARIANTS(SOFTSHOCK_TET4_ARGS)
}
void loops_baseline(const Tet4Geometry& g, const PackedNode3* nodes, const KernelParams& p,
                    std::size_t begin, std::size_t end, Tet4State& s, KernelTotals& totals,
                    NodeForce3* node_force,
                    bool& valid){SOFTSHOCK_TET4_VARIANTS(SOFTSHOCK_TET4_ARGS)}

LoopFn pick_loops() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("fma"))
    return loops_avx512;
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return loops_avx2;
  return loops_baseline;
}

}  // namespace

void compute_tet4_forces(const Tet4Geometry& g, const PackedNode3* nodes, const KernelParams& p,
                         std::size_t begin, std::size_t end, Tet4State& s, KernelTotals& totals,
                         NodeForce3* node_force) {
  static const LoopFn loops = pick_loops();
  bool all_valid = true;
  loops(g, nodes, p, begin, end, s, totals, node_force, all_valid);

  if (!all_valid && totals.bad_element < 0) {  // rare: recompute J to name the first offender
    for (std::size_t e = begin; e < end; ++e) {
      const NodeLanes3 a = nodes[g.node0[e]].lanes;
      const NodeLanes3 e1 = nodes[g.node1[e]].lanes - a, e2 = nodes[g.node2[e]].lanes - a,
                       e3 = nodes[g.node3[e]].lanes - a;
      continuum::Mat3 dm_inv;
      for (int k = 0; k < 9; ++k) dm_inv[k] = g.dm_inv_at(k, e);
      const double j = continuum::det(continuum::deformation_gradient(
          e1[0], e1[1], e1[2], e2[0], e2[1], e2[2], e3[0], e3[1], e3[2], dm_inv));
      if (!(j > 0.0)) {
        totals.bad_element = static_cast<int64_t>(e), totals.bad_j = j;
        break;
      }
    }
  }
}

}  // namespace softshock
