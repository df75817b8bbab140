#include "diagnostics3.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>

#include "continuum.hpp"
#include "damage/damage_model.hpp"

namespace softshock {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

}  // namespace

double ElementStress3::von_mises() const {
  const double dxy = xx - yy, dyz = yy - zz, dzx = zz - xx;
  return std::sqrt(0.5 * (dxy * dxy + dyz * dyz + dzx * dzx) + 3.0 * (xy * xy + yz * yz + zx * zx));
}

Diagnostics3::Diagnostics3(const Problem& problem, const Tet4Geometry& geometry, int modes)
    : problem_(problem),
      geometry_(geometry),
      nodal_pressure_(problem.element.formulation == ElementFormulation::kAverageNodalPressure) {
  const Mesh& mesh = problem.mesh;
  const std::size_t nn = mesh.node_count();
  // The axis and R0: the problem's, else the volume centroid's (x, y) and the boundary nodes'
  // mean distance from the axis (polar_frame).
  const PolarFrame frame = polar_frame(problem);
  origin_ = frame.origin;
  z_mid_ = problem.mid_plane_z_m;

  // The lateral surface: boundary faces whose outward normal is mostly radial; each node's share
  // of their area (a third of each face).
  std::vector<double> lateral_area(nn, 0.0);
  for (const auto& f : mesh.boundary_faces) {
    if (!problem.rim_diagnostics) break;
    const double abx = mesh.x[f[1]] - mesh.x[f[0]], aby = mesh.y[f[1]] - mesh.y[f[0]],
                 abz = mesh.z[f[1]] - mesh.z[f[0]];
    const double acx = mesh.x[f[2]] - mesh.x[f[0]], acy = mesh.y[f[2]] - mesh.y[f[0]],
                 acz = mesh.z[f[2]] - mesh.z[f[0]];
    const double nx = aby * acz - abz * acy, ny = abz * acx - abx * acz, nz = abx * acy - aby * acx;
    const double norm = std::sqrt(nx * nx + ny * ny + nz * nz);
    const double cx = (mesh.x[f[0]] + mesh.x[f[1]] + mesh.x[f[2]]) / 3.0 - origin_[0];
    const double cy = (mesh.y[f[0]] + mesh.y[f[1]] + mesh.y[f[2]]) / 3.0 - origin_[1];
    const double radial = (nx * cx + ny * cy) / (norm * std::max(std::hypot(cx, cy), 1e-300));
    if (!(radial > 0.5)) continue;  // faces of the top, bottom or anything facing inwards
    for (int32_t i : f) lateral_area[i] += 0.5 * norm / 3.0;
  }
  double lateral_total = 0.0;
  for (std::size_t i = 0; i < nn; ++i) {
    if (lateral_area[i] <= 0) continue;
    lateral_nodes_.push_back(static_cast<int32_t>(i));
    lateral_total += lateral_area[i];
  }
  reference_radius_ = frame.reference_radius_m;

  // The mid-plane rim: lateral nodes at z_mid, in angle order (rim_diagnostics.hpp).
  const double tol = 1e-6 * reference_radius_;
  std::vector<std::pair<double, int32_t>> rim;
  for (int32_t i : lateral_nodes_)
    if (std::fabs(mesh.z[i] - z_mid_) <= tol)
      rim.emplace_back(std::atan2(mesh.y[i] - origin_[1], mesh.x[i] - origin_[0]), i);
  std::sort(rim.begin(), rim.end());
  std::vector<int32_t> rim_nodes;
  for (const auto& [theta, i] : rim) rim_nodes.push_back(i);
  mid_plane_ = RimRing(rim_nodes, mesh.x.data(), mesh.y.data(), origin_, reference_radius_, modes);
  // The lateral surface, weighted by area / (R0 H) with H = area / (2 pi R0): weights summing to
  // 2 pi, the modes averaged over the thickness.
  std::vector<double> lateral_weight;
  for (int32_t i : lateral_nodes_)
    lateral_weight.push_back(kTwoPi * lateral_area[i] / lateral_total);
  lateral_ =
      RimRing(lateral_nodes_, mesh.x.data(), mesh.y.data(), origin_, reference_radius_,
              mid_plane_.nodes().empty() ? modes : mid_plane_.modes(), std::move(lateral_weight));

  on_rim_node_.assign(nn, 0);
  for (int32_t i : lateral_nodes_) on_rim_node_[i] = 1;
  std::vector<uint8_t> mid_rim(nn, 0);
  for (int32_t i : mid_plane_.nodes()) mid_rim[i] = 1;

  // The centre: elements whose reference centroid lies within the radius of (origin, z_mid).
  const double rc = problem.center_region_radius_m;
  double nearest = std::numeric_limits<double>::max();
  int32_t nearest_element = 0;
  for (std::size_t e = 0; e < geometry.size(); ++e) {
    const auto& t = mesh.tetrahedra[e];
    double c[3] = {0, 0, 0};
    for (int32_t i : t) c[0] += mesh.x[i] / 4.0, c[1] += mesh.y[i] / 4.0, c[2] += mesh.z[i] / 4.0;
    const double r =
        std::sqrt((c[0] - origin_[0]) * (c[0] - origin_[0]) +
                  (c[1] - origin_[1]) * (c[1] - origin_[1]) + (c[2] - z_mid_) * (c[2] - z_mid_));
    if (r <= rc) center_elements_.push_back(static_cast<int32_t>(e));
    if (r < nearest) nearest = r, nearest_element = static_cast<int32_t>(e);
    if (mid_rim[t[0]] || mid_rim[t[1]] || mid_rim[t[2]] || mid_rim[t[3]])
      rim_elements_.push_back(static_cast<int32_t>(e));
  }
  if (center_elements_.empty() && geometry.size() > 0) center_elements_.push_back(nearest_element);
}

double Diagnostics3::volumetric_mean_stress(const KernelView& kernel, std::size_t e) const {
  const Tet4Geometry& g = geometry_;
  const double *sm = kernel.nodal_mean_stress, *shift = kernel.element_stress_shift;
  const double w_element = problem_.element.element_weight, w_nodal = 1.0 - w_element;
  const double nodal_mean =
      (sm[g.node0[e]] + sm[g.node1[e]] + sm[g.node2[e]] + sm[g.node3[e]]) / 4.0 + shift[e];
  double v = w_nodal * nodal_mean;
  if (w_element > 0) {
    const double kappa = problem_.material.bulk_modulus_Pa, n = problem_.material.tait_n();
    double own = continuum::tait_mean_stress(kappa, n, std::pow(kernel.element_j[e], -n));
    if (kernel.element_degradation)
      own = damage::degraded_mean_stress(own, kernel.element_degradation[e]);
    v += w_element * own;
  }
  return v;
}

ElementStress3 Diagnostics3::element_stress(const NodalView3& nodes, const Tet4State& s,
                                            const KernelView& kernel, std::size_t e) const {
  namespace cm = continuum;
  const Tet4Geometry& g = geometry_;
  const Material& mat = problem_.material;
  const int32_t n[4] = {g.node0[e], g.node1[e], g.node2[e], g.node3[e]};
  double edge[9];
  for (int k = 0; k < 3; ++k)
    for (int c = 0; c < 3; ++c) edge[3 * k + c] = nodes.x[c][n[k + 1]] - nodes.x[c][n[0]];
  cm::Mat3 dm_inv;
  for (int k = 0; k < 9; ++k) dm_inv[k] = g.dm_inv_at(k, e);
  const cm::Mat3 f = cm::deformation_gradient(edge[0], edge[1], edge[2], edge[3], edge[4], edge[5],
                                              edge[6], edge[7], edge[8], dm_inv);
  const double j = cm::det(f);
  const double n_tait = mat.tait_n();
  // With damage: g_e on the deviatoric and (P1) the tensile volumetric stress.
  const double degradation = kernel.element_degradation ? kernel.element_degradation[e] : 1.0;
  const double sm =
      nodal_pressure_ && kernel.nodal_mean_stress != nullptr
          ? volumetric_mean_stress(kernel, e)
          : damage::degraded_mean_stress(
                cm::tait_mean_stress(mat.bulk_modulus_Pa, n_tait, std::pow(j, -n_tait)),
                degradation);
  // sigma = sm I + (mu J^-2/3 / J)(B - I1/3 I) + P_v F^T / J, B = F F^T.
  const double k = degradation * mat.shear_modulus_Pa * std::cbrt(1.0 / (j * j)) / j;
  const double i1 = cm::first_invariant(f);
  auto b = [&](int r, int c) {
    return f[3 * r] * f[3 * c] + f[3 * r + 1] * f[3 * c + 1] + f[3 * r + 2] * f[3 * c + 2];
  };
  auto viscous = [&](int r, int c) {  // (P_v F^T)_rc / J
    return (s.pv_at(3 * r, e) * f[3 * c] + s.pv_at(3 * r + 1, e) * f[3 * c + 1] +
            s.pv_at(3 * r + 2, e) * f[3 * c + 2]) /
           j;
  };
  ElementStress3 out;
  out.xx = sm + k * (b(0, 0) - i1 / 3.0) + viscous(0, 0);
  out.yy = sm + k * (b(1, 1) - i1 / 3.0) + viscous(1, 1);
  out.zz = sm + k * (b(2, 2) - i1 / 3.0) + viscous(2, 2);
  out.xy = k * b(0, 1) + 0.5 * (viscous(0, 1) + viscous(1, 0));
  out.yz = k * b(1, 2) + 0.5 * (viscous(1, 2) + viscous(2, 1));
  out.zx = k * b(2, 0) + 0.5 * (viscous(2, 0) + viscous(0, 2));
  out.j = j;
  return out;
}

double Diagnostics3::kinetic_energy(const NodalView3& nodes) const {
  const std::size_t nn = problem_.mesh.node_count();
  double energy = 0;
  for (std::size_t i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c)
      energy += nodes.p[c] ? 0.5 * nodes.v[c][i] * nodes.p[c][i]
                           : 0.5 * nodes.mass[i] * nodes.v[c][i] * nodes.v[c][i];
  return energy;
}

void Diagnostics3::sample(const NodalView3& nodes, const Tet4State& s, const KernelView& kernel,
                          const KernelTotals& totals, double t, double dt, double dissipated,
                          double external_work, History& h) const {
  const double kinetic = kinetic_energy(nodes);
  const double elastic = totals.nodal_energy + totals.element_energy;

  // The mid-plane rim, as the 2-D disk's outer loop, and the modes over the lateral surface.
  RimRing::Sample rim =
      mid_plane_.sample(nodes.x[0], nodes.x[1], nodes.v[0], nodes.v[1], nodes.a[0], nodes.a[1]);
  RimRing::Sample lateral =
      lateral_.sample(nodes.x[0], nodes.x[1], nodes.v[0], nodes.v[1], nodes.a[0], nodes.a[1]);

  double center_volume = 0, center_stress = 0;
  for (int32_t e : center_elements_) {
    const double v = geometry_.volume0[e];
    center_volume += v;
    center_stress += v * element_stress(nodes, s, kernel, e).mean();
  }
  double min_hoop = std::numeric_limits<double>::max();
  for (int32_t e : rim_elements_) {
    const ElementStress3 st = element_stress(nodes, s, kernel, e);
    double cx = -origin_[0], cy = -origin_[1];
    for (int32_t i :
         {geometry_.node0[e], geometry_.node1[e], geometry_.node2[e], geometry_.node3[e]})
      cx += nodes.x[0][i] / 4.0, cy += nodes.x[1][i] / 4.0;
    const double r = std::sqrt(cx * cx + cy * cy);
    const double tx = r > 0 ? -cy / r : 0, ty = r > 0 ? cx / r : 1;
    min_hoop = std::min(min_hoop, tx * tx * st.xx + 2 * tx * ty * st.xy + ty * ty * st.yy);
  }
  if (rim_elements_.empty()) min_hoop = 0;

  h.time.push_back(t);
  h.kinetic_energy.push_back(kinetic);
  h.elastic_energy.push_back(elastic);
  h.dissipated_energy.push_back(dissipated);
  h.external_work.push_back(external_work);
  h.abar.push_back(rim.abar);
  h.center_mean_stress.push_back(center_volume > 0 ? center_stress / center_volume : 0);
  h.rim_mean_radial_displacement.push_back(rim.mean_u);
  h.rim_mean_radial_velocity.push_back(rim.mean_v);
  h.rim_mean_radial_acceleration.push_back(rim.mean_a);
  h.rim_min_hoop_stress.push_back(min_hoop);
  h.dt.push_back(dt);
  h.abar_filtered.push_back(rim.abar_filtered);
  h.max_aspect_ratio.push_back(totals.max_aspect_ratio);
  const int64_t de_signed = totals.min_step_element;
  const bool known = de_signed >= 0 && static_cast<std::size_t>(de_signed) < geometry_.size();
  const std::size_t de = known ? static_cast<std::size_t>(de_signed) : 0;
  double de_aspect = 0.0, de_j = 0.0;
  bool de_on_rim = false;
  if (known) {
    const int32_t n[4] = {geometry_.node0[de], geometry_.node1[de], geometry_.node2[de],
                          geometry_.node3[de]};
    double e[9];
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) e[3 * k + c] = nodes.x[c][n[k + 1]] - nodes.x[c][n[0]];
    const double cx = e[4] * e[8] - e[5] * e[7], cy = e[5] * e[6] - e[3] * e[8],
                 cz = e[3] * e[7] - e[4] * e[6];
    const double six_volume = e[0] * cx + e[1] * cy + e[2] * cz;
    de_aspect = continuum::aspect_ratio(
        continuum::longest_edge_sq(e[0], e[1], e[2], e[3], e[4], e[5], e[6], e[7], e[8]),
        six_volume,
        continuum::largest_face_sq(e[0], e[1], e[2], e[3], e[4], e[5], e[6], e[7], e[8]));
    de_j = six_volume / (6.0 * geometry_.volume0[de]);
    for (int32_t i : n) de_on_rim = de_on_rim || on_rim_node_[i];
  }
  h.dt_element.push_back(known ? static_cast<double>(de) : -1.0);
  h.dt_element_aspect_ratio.push_back(de_aspect);
  h.dt_element_j.push_back(de_j);
  h.dt_element_on_rim.push_back(de_on_rim ? 1.0 : 0.0);
  // Both tables the same width (a lateral ring of fewer nodes than the mid-plane's: padded).
  lateral.amplitude.resize(rim.amplitude.size(), 0.0);
  h.modes.push_back(std::move(rim.amplitude));
  h.modes_z_mean.push_back(std::move(lateral.amplitude));
}

FieldFrame Diagnostics3::frame(const NodalView3& nodes, const Tet4State& s,
                               const KernelView& kernel, double t, FieldFrame reuse) const {
  const Mesh& mesh = problem_.mesh;
  const std::size_t nn = mesh.node_count(), ne = geometry_.size();
  FieldFrame fr = std::move(reuse);
  fr.time_s = t;
  fr.dimension = 3;
  fr.displacement.resize(3 * nn);
  fr.velocity.resize(3 * nn);
  const std::array<const std::vector<double>*, 3> reference = {&mesh.x, &mesh.y, &mesh.z};
  for (std::size_t i = 0; i < nn; ++i)
    for (int c = 0; c < 3; ++c) {
      fr.displacement[3 * i + c] = nodes.x[c][i] - (*reference[c])[i];
      fr.velocity[3 * i + c] = nodes.v[c][i];
    }
  fr.J.resize(ne), fr.mean_stress.resize(ne), fr.radial_stress.resize(ne);
  fr.hoop_stress.resize(ne), fr.von_mises.resize(ne), fr.aspect_ratio.resize(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const ElementStress3 st = element_stress(nodes, s, kernel, e);
    const int32_t n[4] = {geometry_.node0[e], geometry_.node1[e], geometry_.node2[e],
                          geometry_.node3[e]};
    double cx = -origin_[0], cy = -origin_[1], edge[9];
    for (int32_t i : n) cx += nodes.x[0][i] / 4.0, cy += nodes.x[1][i] / 4.0;
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) edge[3 * k + c] = nodes.x[c][n[k + 1]] - nodes.x[c][n[0]];
    const double r = std::sqrt(cx * cx + cy * cy);
    const double ex = r > 0 ? cx / r : 1, ey = r > 0 ? cy / r : 0;
    fr.J[e] = st.j;
    fr.mean_stress[e] = st.mean();
    fr.radial_stress[e] = ex * ex * st.xx + 2 * ex * ey * st.xy + ey * ey * st.yy;
    fr.hoop_stress[e] = ey * ey * st.xx - 2 * ex * ey * st.xy + ex * ex * st.yy;
    fr.von_mises[e] = st.von_mises();
    fr.aspect_ratio[e] = continuum::aspect_ratio(
        continuum::longest_edge_sq(edge[0], edge[1], edge[2], edge[3], edge[4], edge[5], edge[6],
                                   edge[7], edge[8]),
        6.0 * geometry_.volume0[e] * st.j,
        continuum::largest_face_sq(edge[0], edge[1], edge[2], edge[3], edge[4], edge[5], edge[6],
                                   edge[7], edge[8]));
  }
  return fr;
}

}  // namespace softshock
