#include "tet4_kernels.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "continuum.hpp"
#include "tet4_lanes.hpp"
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
  reset_to_reference();
}

void Tet4State::reset_to_reference() {
  for (std::size_t i = 0; i < f.size(); ++i) {
    const std::size_t component = i / kTet4Block % 9;
    f[i] = component % 4 == 0 ? 1.0 : 0.0;  // the diagonal: components 0, 4, 8
  }
  std::fill(pv.begin(), pv.end(), 0.0f);
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

using namespace tet4_lanes;

constexpr double kHuge = 1e300;  // above any squared stable step

enum class Volumetric { kElement, kNodal, kBlend };

// Where a group of W consecutive elements keeps its data: straight in the geometry and state, or,
// for a group only partly in the range (a thread's range that starts or ends inside one, a test's
// single element), in a copy whose lanes outside the range repeat an element inside it.
struct GroupData {
  const int32_t* corner[4];  // node indices, lane l at corner[a][l]
  const double *volume0, *altitude0, *shift;
  const double* dm;  // blocked: component c of lane l at dm[c * kTet4Block + l]
  double* f;
  float* pv;
};

template <std::size_t W>
struct GroupCopy {
  int32_t corner[4][W];
  double volume0[W], altitude0[W], shift[W];
  alignas(64) double dm[9][kTet4Block], f[9][kTet4Block];
  alignas(64) float pv[9][kTet4Block];
};

// The element loop, W tetrahedra at a time (one per lane), in one pass per group: gather the
// corners' rows, then kinematics, the pointwise law, the viscosities, the stable step, the lagged
// viscous stress and the nodal forces, each group's state read and written once, and the forces
// scattered in element order. Written with GCC vector types rather than left to the
// auto-vectoriser: the auto-vectorised loop (one loop, or three per block of 64 to keep the
// working set small) spent most of its time storing and reloading intermediates (perf).
template <std::size_t W, Volumetric kVolumetric, bool kSample>
SOFTSHOCK_ALWAYS_INLINE void tet4_loop(const Tet4Geometry& g, const PackedNode3* nodes,
                                       const KernelParams& p, std::size_t begin, std::size_t end,
                                       Tet4State& s, KernelTotals& totals, NodeForce3* node_force,
                                       bool& all_valid) {
  namespace cm = continuum;
  using V = typename Lanes<W>::D;
  using VF = typename Lanes<W>::F;
  using Mask = typename Lanes<W>::M;
  using M3 = cm::Mat3Of<V>;
  constexpr bool kNodal = kVolumetric != Volumetric::kElement;
  constexpr auto kLaneIndex = std::make_index_sequence<W>{};
  constexpr std::size_t kBlock = kTet4Block;
  static_assert(kBlock % W == 0 && 8 % W == 0, "groups tile the blocks and the 8 sum lanes");
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
  const double w_element = kNodal ? p.element_weight : 1.0, w_nodal = 1.0 - w_element;
  const double beta_kappa = p.stabilization_beta_kappa;

  // The sums in 8 lanes by element index mod 8, as the loop always summed them (so the totals do
  // not depend on W); the smallest step per lane with the first element that has it.
  constexpr std::size_t kSums = 8 / W;
  V dissipation_sum[kSums] = {}, energy_sum[kSums] = {};
  V aspect_max = V{} + 0.0, step_min = V{} + kHuge;
  Mask step_element = Mask{} - 1, valid_lanes = Mask{} - 1;

  GroupCopy<W> copy;
  for (std::size_t group = begin / W * W; group < end; group += W) {
    const std::size_t lane_begin = group < begin ? begin - group : 0;
    const std::size_t lane_end = std::min(W, end - group);
    const bool whole = lane_begin == 0 && lane_end == W;
    const std::size_t blocked = tet4_blocked_index(0, group);
    GroupData d{{g.node0.data() + group, g.node1.data() + group, g.node2.data() + group,
                 g.node3.data() + group},
                g.volume0.data() + group,
                g.regular_altitude0.data() + group,
                kNodal ? p.element_stress_shift + group : nullptr,
                g.dm_inv.data() + blocked,
                s.f.data() + blocked,
                s.pv.data() + blocked};
    if (!whole) {  // lanes outside [lane_begin, lane_end) repeat the element at lane_begin
      for (std::size_t l = 0; l < W; ++l) {
        const std::size_t from = l >= lane_begin && l < lane_end ? l : lane_begin;
        for (int a = 0; a < 4; ++a) copy.corner[a][l] = d.corner[a][from];
        copy.volume0[l] = d.volume0[from], copy.altitude0[l] = d.altitude0[from];
        copy.shift[l] = kNodal ? d.shift[from] : 0.0;
        for (int c = 0; c < 9; ++c) {
          copy.dm[c][l] = d.dm[c * kBlock + from], copy.f[c][l] = d.f[c * kBlock + from];
          copy.pv[c][l] = d.pv[c * kBlock + from];
        }
      }
      d = GroupData{{copy.corner[0], copy.corner[1], copy.corner[2], copy.corner[3]},
                    copy.volume0,
                    copy.altitude0,
                    copy.shift,
                    copy.dm[0],
                    copy.f[0],
                    copy.pv[0]};
    }
    const Mask in_range = make_lanes<Mask>(
        [&](std::size_t l) { return l >= lane_begin && l < lane_end ? int64_t{-1} : int64_t{0}; },
        kLaneIndex);

    // The corners' rows: positions, and the nodal state of the average nodal pressure. With 4
    // lanes, each row's first four entries in one load and a transpose (x, y, z and the mean
    // stress of four elements' corner), instead of 16 scalar loads and inserts.
    V px[4], py[4], pz[4], sm[4], nodal_sm_sum{}, nodal_k_max{};
    for (int a = 0; a < 4; ++a) {
      const int32_t* corner = d.corner[a];
      if constexpr (W == 4) {
        // One 32-byte load per row (a memcpy into an array of rows became two 16-byte moves and a
        // 32-byte reload: a failed store forwarding per row, +11 ns per element).
        const V rows[4] = {row_head(nodes[corner[0]]), row_head(nodes[corner[1]]),
                           row_head(nodes[corner[2]]), row_head(nodes[corner[3]])};
        V columns[4];
        transpose4(rows, columns);
        px[a] = columns[0], py[a] = columns[1], pz[a] = columns[2], sm[a] = columns[3];
      } else {
        auto entry = [&](int c) {
          return make_lanes<V>([&](std::size_t l) { return nodes[corner[l]].lanes[c]; },
                               kLaneIndex);
        };
        px[a] = entry(0), py[a] = entry(1), pz[a] = entry(2);
        if constexpr (kNodal) sm[a] = entry(3);
      }
    }
    if constexpr (kNodal) {
      V k[4];
      for (int a = 0; a < 4; ++a) {
        const int32_t* corner = d.corner[a];
        k[a] = make_lanes<V>([&](std::size_t l) { return nodes[corner[l]].lanes[4]; }, kLaneIndex);
      }
      nodal_sm_sum = sm[0] + sm[1] + sm[2] + sm[3];
      const V max_ab = k[0] > k[1] ? k[0] : k[1], max_cd = k[2] > k[3] ? k[2] : k[3];
      nodal_k_max = max_ab > max_cd ? max_ab : max_cd;
    }
    const V e1x = px[1] - px[0], e1y = py[1] - py[0], e1z = pz[1] - pz[0];
    const V e2x = px[2] - px[0], e2y = py[2] - py[0], e2z = pz[2] - pz[0];
    const V e3x = px[3] - px[0], e3y = py[3] - py[0], e3z = pz[3] - pz[0];
    const V face_sq = cm::largest_face_sq(e1x, e1y, e1z, e2x, e2y, e2z, e3x, e3y, e3z);
    V longest_edge_sq{};
    if constexpr (kSample)
      longest_edge_sq = cm::longest_edge_sq(e1x, e1y, e1z, e2x, e2y, e2z, e3x, e3y, e3z);

    // Kinematics: F, cof F, J, and the same of the last evaluation's F.
    M3 dm_inv, f_prev;
    for (int c = 0; c < 9; ++c)
      dm_inv[c] = load_lanes<V>(d.dm + c * kBlock), f_prev[c] = load_lanes<V>(d.f + c * kBlock);
    const M3 f = cm::deformation_gradient(e1x, e1y, e1z, e2x, e2y, e2z, e3x, e3y, e3z, dm_inv);
    const M3 cof = cm::cofactor(f);
    const V j = cm::det(f, cof);
    const M3 cof_prev = cm::cofactor(f_prev);
    const V j_prev = cm::det(f_prev, cof_prev);  // bit for bit the last evaluation's J

    // The pointwise law.
    const V volume0 = load_lanes<V>(d.volume0);
    V log_j{}, j_minus_n{}, mean_stress, bulk_modulus;
    if constexpr (kVolumetric != Volumetric::kNodal) {
      log_j = lanewise<V>([](double x) { return ::log(x); }, j);
      j_minus_n = lanewise<V>([n](double x) { return ::exp(-n * x); }, log_j);
    }
    if constexpr (kNodal) {
      const V shift = load_lanes<V>(d.shift);
      const V nodal_mean = 0.25 * nodal_sm_sum + shift;
      const V nodal_k = nodal_k_max + lanewise<V>(
                                          [beta_kappa](double x) {
                                            return cm::stabilization_bulk_modulus(beta_kappa, x);
                                          },
                                          shift);
      if constexpr (kVolumetric == Volumetric::kNodal) {
        mean_stress = nodal_mean, bulk_modulus = nodal_k;
      } else {
        mean_stress =
            w_nodal * nodal_mean +
            w_element *
                lanewise<V>([=](double x) { return cm::tait_mean_stress(kappa, n, x); }, j_minus_n);
        bulk_modulus =
            w_nodal * nodal_k +
            w_element *
                lanewise<V>([=](double x) { return cm::tait_bulk_modulus(kappa, x); }, j_minus_n);
      }
    } else {
      mean_stress =
          lanewise<V>([=](double x) { return cm::tait_mean_stress(kappa, n, x); }, j_minus_n);
      bulk_modulus =
          lanewise<V>([=](double x) { return cm::tait_bulk_modulus(kappa, x); }, j_minus_n);
    }
    const V c_sq = (bulk_modulus + four_thirds_mu) * j * inv_rho0;

    // Five quotients, one division (continuum::step_reciprocals, as for triangles); face_sq is
    // the largest face's |cross product|^2 (twice its area, squared): the smallest altitude.
    const auto q = cm::step_reciprocals(j, face_sq, j_prev, dt, c_sq);
    const V inv_j = q.j, inv_face_sq = q.length_sq;
    const V inv_u = q.j_sum, inv_v = q.j_prev_dt, inv_z = q.dt_c_sq;

    V j_minus_23;
    if constexpr (kVolumetric == Volumetric::kNodal)
      j_minus_23 = lanewise<V>([](double x) { return ::cbrt(x * x); }, inv_j);
    else
      j_minus_23 = lanewise<V>([](double x) { return ::exp(-2.0 / 3.0 * x); }, log_j);
    // P_e = sigma_m cof + mu J^-2/3 (F - I1/3 F^-T) = s cof + a F (continuum's elastic_piola).
    const V a_coef = mu * j_minus_23;
    const V i1 = cm::first_invariant(f);
    const V s_coef = mean_stress - a_coef * i1 * (cm::kThird * inv_j);
    const V six_volume = 6.0 * volume0 * j;  // det [e1 e2 e3]
    V energy{}, aspect{};
    if constexpr (kSample) {
      V w = lanewise<V>([mu](double x, double y) { return cm::neo_hookean_energy(mu, x, y); }, i1,
                        j_minus_23);
      if constexpr (kVolumetric != Volumetric::kNodal)
        w += w_element *
             lanewise<V>([=](double x, double y) { return cm::tait_energy(kappa, n, x, y); }, j,
                         j_minus_n);
      energy = volume0 * w;
      aspect = lanewise<V>([](double x, double y, double z) { return cm::aspect_ratio(x, y, z); },
                           longest_edge_sq, six_volume, face_sq);
    }

    // The viscosities and the stable step.
    const V h_sq = six_volume * six_volume * inv_face_sq;  // smallest altitude squared
    // The viscosity's length: the smallest altitude (thesis) or the regular tetrahedron's of the
    // current volume, altitude0 J^(1/3) = altitude0 J J^(-2/3).
    const V regular = load_lanes<V>(d.altitude0) * j * j_minus_23;
    const V hc = lanewise<V>([](double x) { return std::sqrt(x); },
                             (smallest_altitude ? h_sq : regular * regular) * c_sq);
    const V z = -hc *
                lanewise<V>([](double x) { return cm::log_ratio_u(x); }, (j - j_prev) * inv_u) *
                inv_z;
    const V nu_art =
        artificial_on * lanewise<V>(
                            [=](double x, double y, double zz) {
                              return cm::artificial_viscosity_hc(x, y, c1, c2, zz, ramp_inv);
                            },
                            hc, rho0 * inv_j, z);
    const V nu = eta + shear_share * nu_art;
    const V zeta = (1.0 - shear_share) * 4.0 / 3.0 * nu_art;

    // The viscous stress from the lagged rate, the dissipation (trapezoidal in P_v), the state.
    const M3 pv = cm::viscous_piola_inv(f, f_prev, cof_prev, cof, nu, zeta, inv_v);
    V work{};
    for (int c = 0; c < 9; ++c)
      work += (pv[c] + load_float_lanes<V, VF>(d.pv + c * kBlock)) * (f[c] - f_prev[c]);
    const V dissipation = 0.5 * volume0 * work;
    for (int c = 0; c < 9; ++c) {
      store_lanes(d.f + c * kBlock, f[c]);
      store_float_lanes<V, VF>(d.pv + c * kBlock, pv[c]);
    }
    // Force on node a: -V0 P grad N_a, grad N_a the rows of Dm^-1 (a = 1, 2, 3), P the total.
    M3 piola;
    for (int c = 0; c < 9; ++c) piola[c] = s_coef * cof[c] + a_coef * f[c] + pv[c];
    V force[3][3];  // [a - 1][component]
    for (int a = 0; a < 3; ++a) {
      // Dm^-1 read again rather than kept in registers through the whole group.
      const V g0 = dm_inv[3 * a], g1 = dm_inv[3 * a + 1], g2 = dm_inv[3 * a + 2];
      for (int i = 0; i < 3; ++i)
        force[a][i] =
            -volume0 * (piola[3 * i] * g0 + piola[3 * i + 1] * g1 + piola[3 * i + 2] * g2);
    }

    // The sums, the lanes outside the range left out.
    const std::size_t sum = group / W % kSums;
    dissipation_sum[sum] += in_range ? dissipation : 0.0;
    valid_lanes &= (in_range ? j : 1.0) > 0.0;
    if constexpr (kSample) {
      energy_sum[sum] += in_range ? energy : 0.0;
      const V aspect_in_range = in_range ? aspect : 0.0;
      aspect_max = aspect_in_range > aspect_max ? aspect_in_range : aspect_max;
    }

    if (!whole) {  // the state of the lanes in the range back where it belongs
      const std::size_t storage = tet4_blocked_index(0, group);
      for (std::size_t l = lane_begin; l < lane_end; ++l)
        for (int c = 0; c < 9; ++c) {
          s.f[storage + c * kBlock + l] = copy.f[c][l];
          s.pv[storage + c * kBlock + l] = copy.pv[c][l];
        }
    }
    // The forces onto the nodes, element by element in index order.
    const V total_x = force[0][0] + force[1][0] + force[2][0],
            total_y = force[0][1] + force[1][1] + force[2][1],
            total_z = force[0][2] + force[1][2] + force[2][2];
    if constexpr (W == 4) {  // the four elements' forces as rows (x, y, z, 0) by a transpose
      const V zero{};
      V rows[4][4];  // [corner][lane]
      transpose4({total_x, total_y, total_z, zero}, rows[0]);
      for (int a = 0; a < 3; ++a)
        transpose4({force[a][0], force[a][1], force[a][2], zero}, rows[a + 1]);
      for (std::size_t l = lane_begin; l < lane_end; ++l) {
        const std::size_t e = group + l;
        node_force[g.node0[e]].lanes -= rows[0][l];
        node_force[g.node1[e]].lanes += rows[1][l];
        node_force[g.node2[e]].lanes += rows[2][l];
        node_force[g.node3[e]].lanes += rows[3][l];
      }
    } else {
      for (std::size_t l = lane_begin; l < lane_end; ++l) {
        const std::size_t e = group + l;
        node_force[g.node0[e]].lanes -= ForceLanes3{total_x[l], total_y[l], total_z[l], 0.0};
        node_force[g.node1[e]].lanes +=
            ForceLanes3{force[0][0][l], force[0][1][l], force[0][2][l], 0.0};
        node_force[g.node2[e]].lanes +=
            ForceLanes3{force[1][0][l], force[1][1][l], force[1][2][l], 0.0};
        node_force[g.node3[e]].lanes +=
            ForceLanes3{force[2][0][l], force[2][1][l], force[2][2][l], 0.0};
      }
    }

    // Last in the group, the stable step: nothing else waits for its root and quotient, so the
    // core goes on with the next group while they finish (computed before the forces, they held
    // up everything after them in the window: +3.5 ns an element).
    const V nu_step = p.eta + shear_share * nu_art;
    const V step_sq = lanewise<V>(
        [](double x, double y, double zz) { return cm::stable_step_sq_kinematic(x, y, zz); }, h_sq,
        c_sq, (4.0 / 3.0 * nu_step + zeta) * j * inv_rho0);
    const V step_in_range = in_range ? step_sq : kHuge;
    const Mask smaller = step_in_range < step_min;
    step_min = smaller ? step_in_range : step_min;
    step_element =
        smaller ? make_lanes<Mask>([&](std::size_t l) { return static_cast<int64_t>(group + l); },
                                   kLaneIndex)
                : step_element;
  }

  double dissipation = 0.0, element_energy = 0.0, max_aspect = totals.max_aspect_ratio;
  for (std::size_t k = 0; k < kSums; ++k)
    for (std::size_t l = 0; l < W; ++l) {
      dissipation += dissipation_sum[k][l];
      if constexpr (kSample) element_energy += energy_sum[k][l];
    }
  // The smallest step of all lanes, the lowest element index on a tie: the first element that has
  // it.
  double min_step_sq = kHuge;
  int64_t min_step_element = -1;
  for (std::size_t l = 0; l < W; ++l) {
    all_valid &= valid_lanes[l] != 0;
    if constexpr (kSample) max_aspect = aspect_max[l] > max_aspect ? aspect_max[l] : max_aspect;
    if (step_min[l] < min_step_sq ||
        (step_min[l] == min_step_sq && step_min[l] < kHuge && step_element[l] < min_step_element))
      min_step_sq = step_min[l], min_step_element = step_element[l];
  }
  if (!(min_step_sq < totals.min_step_sq))
    min_step_sq = totals.min_step_sq, min_step_element = totals.min_step_element;
  totals.min_step_sq = min_step_sq;
  totals.min_step_element = min_step_element;
  totals.dissipation += dissipation;
  totals.element_energy += element_energy;
  totals.max_aspect_ratio = max_aspect;
}

template <std::size_t W, Volumetric kVolumetric, typename... Args>
SOFTSHOCK_ALWAYS_INLINE void tet4_loop_sampled(bool sample, Args&... args) {
  if (sample)
    tet4_loop<W, kVolumetric, true>(args...);
  else
    tet4_loop<W, kVolumetric, false>(args...);
}

}  // namespace

// One copy of the loops per instruction set, chosen once at run time: AVX-512, AVX2 with FMA (the
// loops are mostly multiply-adds: target_clones' "avx2" has no FMA, and its "arch=haswell" clone
// is chosen by CPU model, not features, so an AMD CPU would fall back to SSE2), and the baseline.
namespace {

#define SOFTSHOCK_TET4_ARGS g, nodes, p, begin, end, s, totals, node_force, valid
#define SOFTSHOCK_TET4_VARIANTS(W, args)                        \
  if (!p.nodal_pressure)                                        \
    tet4_loop_sampled<W, Volumetric::kElement>(p.sample, args); \
  else if (p.element_weight == 0.0)                             \
    tet4_loop_sampled<W, Volumetric::kNodal>(p.sample, args);   \
  else                                                          \
    tet4_loop_sampled<W, Volumetric::kBlend>(p.sample, args);

using LoopFn = void (*)(const Tet4Geometry&, const PackedNode3*, const KernelParams&, std::size_t,
                        std::size_t, Tet4State&, KernelTotals&, NodeForce3*, bool&);

__attribute__((target("avx512f,avx512dq,avx512vl,avx2,fma"))) void loops_avx512(
    const Tet4Geometry& g, const PackedNode3* nodes, const KernelParams& p, std::size_t begin,
    std::size_t end, Tet4State& s, KernelTotals& totals, NodeForce3* node_force, bool& valid) {
  SOFTSHOCK_TET4_VARIANTS(8, SOFTSHOCK_TET4_ARGS)
}
__attribute__((target("avx2,fma"))) void loops_avx2(const Tet4Geometry& g, const PackedNode3* nodes,
                                                    const KernelParams& p, std::size_t begin,
                                                    std::size_t end, Tet4State& s,
                                                    KernelTotals& totals, NodeForce3* node_force,
                                                    bool& valid) {
  SOFTSHOCK_TET4_VARIANTS(4, SOFTSHOCK_TET4_ARGS)
}
void loops_baseline(const Tet4Geometry& g, const PackedNode3* nodes, const KernelParams& p,
                    std::size_t begin, std::size_t end, Tet4State& s, KernelTotals& totals,
                    NodeForce3* node_force,
                    bool& valid){SOFTSHOCK_TET4_VARIANTS(2, SOFTSHOCK_TET4_ARGS)}

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
