#include "diagnostics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <unordered_set>

#include "continuum.hpp"
#include "damage/damage_model.hpp"
#include "vector_math.hpp"

namespace softshock {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

int64_t edge_key(int32_t a, int32_t b) {
  return (static_cast<int64_t>(std::min(a, b)) << 32) | static_cast<uint32_t>(std::max(a, b));
}

// An element's Cauchy stress from its F, its volumetric mean stress sm and the viscous P_v and
// viscosities of the last evaluation: elastic sigma_m I + (mu J^-2/3 / J)(B - I1/3 I), B = F F^T
// (B_zz = 1), plus the viscous P_v F^T / J and its zz part from the shear and bulk viscosities
// that made it. Branch-free, so the frame's loop over every element vectorises.
inline ElementStress cauchy_stress(const continuum::Mat2& f, double sm, double mu,
                                   const ElementState& s, std::size_t e) {
  namespace cm = continuum;
  const double j = cm::det(f);
  const double j_minus_23 = ::cbrt(1.0 / (j * j));  // as the kernel; cheaper than pow
  const double i1 = cm::first_invariant(f);
  const double k = mu * j_minus_23 / j;
  ElementStress out;
  out.xx = sm + k * (f[0] * f[0] + f[1] * f[1] - i1 / 3.0);
  out.xy = k * (f[0] * f[2] + f[1] * f[3]);
  out.yy = sm + k * (f[2] * f[2] + f[3] * f[3] - i1 / 3.0);
  out.zz = sm + k * (1.0 - i1 / 3.0);
  const double vxx = (s.pv_xx[e] * f[0] + s.pv_xy[e] * f[1]) / j;
  const double vxy = (s.pv_xx[e] * f[2] + s.pv_xy[e] * f[3]) / j;
  const double vyy = (s.pv_yx[e] * f[2] + s.pv_yy[e] * f[3]) / j;
  out.xx += vxx, out.xy += vxy, out.yy += vyy;
  out.zz += cm::viscous_zz(s.viscosity[e], s.bulk_viscosity[e], vxx + vyy);
  out.j = j;
  return out;
}

// The frame's element fields over elements [0, ne): J, aspect ratio, mean, radial, hoop and von
// Mises stress.
// volumetric[e]: the element's volumetric mean stress (the nodal-pressure element's), or null for
// plain P1 (its own Tait stress from J). degradation[e] (kDamaged): the phase-field damage's g_e
// of the deviatoric and, for P1, the tensile volumetric stress (the nodal one comes degraded).
// Blocked like the kernel: indexed loads into small buffers, then a branch-free loop with
// libmvec's cbrt, exp and log.
template <bool kPlain, bool kDamaged>
inline __attribute__((always_inline)) void element_fields(
    const ElementGeometry& g, const NodalView& nodes, const ElementState& s,
    const double* volumetric, const double* degradation, double kappa, double n, double mu,
    double ox, double oy, FieldFrame& fr) {
  namespace cm = continuum;
  constexpr std::size_t kBlock = 256;
  alignas(64) double e1x[kBlock], e1y[kBlock], e2x[kBlock], e2y[kBlock], cx[kBlock], cy[kBlock];
  const std::size_t ne = g.size();
  // Plain pointers to the outputs: through fr's vectors the loop reloaded each one's data pointer
  // per element and did not vectorise.
  double *__restrict out_j = fr.J.data(), *__restrict out_aspect = fr.aspect_ratio.data(),
                     *__restrict out_mean = fr.mean_stress.data(),
                     *__restrict out_radial = fr.radial_stress.data(),
                     *__restrict out_hoop = fr.hoop_stress.data(),
                     *__restrict out_von_mises = fr.von_mises.data();
  for (std::size_t block = 0; block < ne; block += kBlock) {
    const std::size_t count = std::min(kBlock, ne - block);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const int32_t a = g.node0[e], b = g.node1[e], c = g.node2[e];
      e1x[k] = nodes.x[b] - nodes.x[a], e1y[k] = nodes.y[b] - nodes.y[a];
      e2x[k] = nodes.x[c] - nodes.x[a], e2y[k] = nodes.y[c] - nodes.y[a];
      cx[k] = (nodes.x[a] + nodes.x[b] + nodes.x[c]) / 3.0 - ox;
      cy[k] = (nodes.y[a] + nodes.y[b] + nodes.y[c]) / 3.0 - oy;
    }
#pragma GCC ivdep
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t e = block + k;
      const cm::Mat2 f = cm::deformation_gradient(
          e1x[k], e1y[k], e2x[k], e2y[k],
          {g.dm_inv_xx[e], g.dm_inv_xy[e], g.dm_inv_yx[e], g.dm_inv_yy[e]});
      double sm, mu_e = mu;
      if constexpr (kPlain)
        sm = cm::tait_mean_stress(kappa, n, ::exp(-n * ::log(cm::det(f))));
      else
        sm = volumetric[e];
      if constexpr (kDamaged) {
        mu_e = degradation[e] * mu;
        if constexpr (kPlain) sm = damage::degraded_mean_stress(sm, degradation[e]);
      }
      const ElementStress st = cauchy_stress(f, sm, mu_e, s, e);
      const double r = std::sqrt(cx[k] * cx[k] + cy[k] * cy[k]);
      const double ex = r > 0 ? cx[k] / r : 1, ey = r > 0 ? cy[k] / r : 0;
      out_j[e] = st.j;
      out_aspect[e] = cm::aspect_ratio(e1x[k], e1y[k], e2x[k], e2y[k]);
      out_mean[e] = st.mean();
      out_radial[e] = ex * ex * st.xx + 2 * ex * ey * st.xy + ey * ey * st.yy;
      out_hoop[e] = ey * ey * st.xx - 2 * ex * ey * st.xy + ex * ex * st.yy;
      const double dxy = st.xx - st.yy, dyz = st.yy - st.zz, dzx = st.zz - st.xx;
      out_von_mises[e] = std::sqrt(0.5 * (dxy * dxy + dyz * dyz + dzx * dzx) + 3.0 * st.xy * st.xy);
    }
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void frame_element_fields(
    const ElementGeometry& g, const NodalView& nodes, const ElementState& s,
    const double* volumetric, const double* degradation, double kappa, double n, double mu,
    double ox, double oy, FieldFrame& fr) {
  if (degradation != nullptr) {
    if (volumetric == nullptr)
      element_fields<true, true>(g, nodes, s, volumetric, degradation, kappa, n, mu, ox, oy, fr);
    else
      element_fields<false, true>(g, nodes, s, volumetric, degradation, kappa, n, mu, ox, oy, fr);
  } else if (volumetric == nullptr) {
    element_fields<true, false>(g, nodes, s, volumetric, degradation, kappa, n, mu, ox, oy, fr);
  } else {
    element_fields<false, false>(g, nodes, s, volumetric, degradation, kappa, n, mu, ox, oy, fr);
  }
}

}  // namespace

PolarFrame polar_frame(const Problem& problem) {
  if (problem.reference_radius_m > 0) return {problem.origin, problem.reference_radius_m};
  const Mesh& mesh = problem.mesh;
  if (mesh.dimension() == 3) {  // about the z axis through the volume centroid
    const auto c = tet_mesh_centroid(mesh);
    std::vector<uint8_t> on_boundary(mesh.node_count(), 0);
    for (const auto& f : mesh.boundary_faces)
      for (int32_t i : f) on_boundary[i] = 1;
    double sum = 0;
    std::size_t count = 0;
    for (std::size_t i = 0; i < mesh.node_count(); ++i)
      if (on_boundary[i]) sum += std::hypot(mesh.x[i] - c[0], mesh.y[i] - c[1]), ++count;
    return {{c[0], c[1]}, count ? sum / static_cast<double>(count) : 1.0};
  }
  const auto origin = mesh_centroid(mesh);
  double sum = 0;
  for (int32_t i : mesh.boundary_nodes)
    sum += std::hypot(mesh.x[i] - origin[0], mesh.y[i] - origin[1]);
  const auto n = mesh.boundary_nodes.size();
  return {origin, n ? sum / static_cast<double>(n) : 1.0};
}

Diagnostics::Diagnostics(const Problem& problem, const ElementGeometry& geometry, int modes)
    : problem_(problem),
      geometry_(geometry),
      nodal_pressure_(problem.element.formulation == ElementFormulation::kAverageNodalPressure) {
  const Mesh& mesh = problem.mesh;
  const PolarFrame frame = polar_frame(problem);
  origin_ = frame.origin;
  reference_radius_ = frame.reference_radius_m;
  // The rim: the outer boundary loop (rim_diagnostics.hpp).
  rim_ =
      RimRing(mesh.boundary_nodes, mesh.x.data(), mesh.y.data(), origin_, reference_radius_, modes);
  const std::size_t nr = rim_.nodes().size();
  const std::vector<int32_t>& rim_nodes = rim_.nodes();

  // Centre region: elements whose reference centroid lies within the radius (else nearest).
  const double rc = problem.center_region_radius_m;
  double nearest = std::numeric_limits<double>::max();
  int32_t nearest_element = 0;
  for (std::size_t e = 0; e < geometry.size(); ++e) {
    const auto& t = mesh.triangles[e];
    const double cx = (mesh.x[t[0]] + mesh.x[t[1]] + mesh.x[t[2]]) / 3.0 - origin_[0];
    const double cy = (mesh.y[t[0]] + mesh.y[t[1]] + mesh.y[t[2]]) / 3.0 - origin_[1];
    const double r = std::hypot(cx, cy);
    if (r <= rc) center_elements_.push_back(static_cast<int32_t>(e));
    if (r < nearest) nearest = r, nearest_element = static_cast<int32_t>(e);
  }
  if (center_elements_.empty() && geometry.size() > 0) center_elements_.push_back(nearest_element);

  on_rim_node_.assign(mesh.node_count(), 0);
  for (int32_t i : rim_nodes) on_rim_node_[i] = 1;

  std::unordered_set<int64_t> rim_edges;
  for (std::size_t k = 0; k < nr; ++k)
    rim_edges.insert(edge_key(rim_nodes[k], rim_nodes[(k + 1) % nr]));
  for (std::size_t e = 0; e < geometry.size(); ++e) {
    const auto& t = mesh.triangles[e];
    if (rim_edges.count(edge_key(t[0], t[1])) || rim_edges.count(edge_key(t[1], t[2])) ||
        rim_edges.count(edge_key(t[2], t[0])))
      rim_elements_.push_back(static_cast<int32_t>(e));
  }
}

double Diagnostics::volumetric_mean_stress(const KernelView& kernel, std::size_t e) const {
  const ElementGeometry& g = geometry_;
  const double *sm = kernel.nodal_mean_stress, *shift = kernel.element_stress_shift;
  const double w_element = problem_.element.element_weight, w_nodal = 1.0 - w_element;
  const double nodal_mean = (sm[g.node0[e]] + sm[g.node1[e]] + sm[g.node2[e]]) / 3.0 + shift[e];
  double v = w_nodal * nodal_mean;
  // The element's own Tait stress blended in (J_e = current / reference area, from pass 1).
  if (w_element > 0) {
    const double kappa = problem_.material.bulk_modulus_Pa, n = problem_.material.tait_n();
    double own = continuum::tait_mean_stress(kappa, n, std::pow(kernel.element_j[e], -n));
    if (kernel.element_degradation)
      own = damage::degraded_mean_stress(own, kernel.element_degradation[e]);
    v += w_element * own;
  }
  return v;
}

ElementStress Diagnostics::element_stress(const NodalView& nodes, const ElementState& s,
                                          const KernelView& kernel, std::size_t e) const {
  namespace cm = continuum;
  const ElementGeometry& g = geometry_;
  const Material& mat = problem_.material;
  const int32_t a = g.node0[e], b = g.node1[e], c = g.node2[e];
  const cm::Mat2 f = cm::deformation_gradient(
      nodes.x[b] - nodes.x[a], nodes.y[b] - nodes.y[a], nodes.x[c] - nodes.x[a],
      nodes.y[c] - nodes.y[a], {g.dm_inv_xx[e], g.dm_inv_xy[e], g.dm_inv_yx[e], g.dm_inv_yy[e]});
  const double n = mat.tait_n();
  // Average nodal pressure: the mean stress the kernel applied; plain P1: the element's own.
  const double degradation = kernel.element_degradation ? kernel.element_degradation[e] : 1.0;
  const double sm =
      nodal_volumetric(kernel)
          ? volumetric_mean_stress(kernel, e)
          : damage::degraded_mean_stress(
                cm::tait_mean_stress(mat.bulk_modulus_Pa, n, std::pow(cm::det(f), -n)),
                degradation);
  return cauchy_stress(f, sm, degradation * mat.shear_modulus_Pa, s, e);
}

double Diagnostics::kinetic_energy(const NodalView& nodes) const {
  const std::size_t nn = problem_.mesh.node_count();
  double energy = 0;
  if (nodes.px)  // a mass blend: 1/2 v . K^-1 v (integrator.hpp, blended_momentum)
    for (std::size_t i = 0; i < nn; ++i)
      energy += 0.5 * (nodes.vx[i] * nodes.px[i] + nodes.vy[i] * nodes.py[i]);
  else
    for (std::size_t i = 0; i < nn; ++i)
      energy += 0.5 * nodes.mass[i] * (nodes.vx[i] * nodes.vx[i] + nodes.vy[i] * nodes.vy[i]);
  return energy;
}

void Diagnostics::sample(const NodalView& nodes, const ElementState& s, const KernelView& kernel,
                         const KernelTotals& totals, double t, double dt, double dissipated,
                         double external_work, History& h) const {
  const int64_t dt_element = totals.min_step_element;
  const Mesh& mesh = problem_.mesh;
  const double kinetic = kinetic_energy(nodes);
  // The stored energy of the whole body (J/m): the nodal passes' volumetric and stabilisation
  // energy (average nodal pressure) plus the elements'.
  const double elastic = totals.nodal_energy + totals.element_energy;

  // The rim (rim_diagnostics.hpp): A-bar, its mean radial motion, the Fourier modes.
  RimRing::Sample rim = rim_.sample(nodes.x, nodes.y, nodes.vx, nodes.vy, nodes.ax, nodes.ay);

  double center_area = 0, center_stress = 0;
  for (int32_t e : center_elements_) {
    const double area = geometry_.area0[e];
    center_area += area;
    center_stress += area * element_stress(nodes, s, kernel, e).mean();
  }

  double min_hoop = std::numeric_limits<double>::max();
  for (int32_t e : rim_elements_) {
    const ElementStress st = element_stress(nodes, s, kernel, e);
    const auto& tri = mesh.triangles[e];
    const double cx = (nodes.x[tri[0]] + nodes.x[tri[1]] + nodes.x[tri[2]]) / 3.0 - origin_[0];
    const double cy = (nodes.y[tri[0]] + nodes.y[tri[1]] + nodes.y[tri[2]]) / 3.0 - origin_[1];
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
  h.center_mean_stress.push_back(center_area > 0 ? center_stress / center_area : 0);
  h.rim_mean_radial_displacement.push_back(rim.mean_u);
  h.rim_mean_radial_velocity.push_back(rim.mean_v);
  h.rim_mean_radial_acceleration.push_back(rim.mean_a);
  h.rim_min_hoop_stress.push_back(min_hoop);
  h.dt.push_back(dt);
  h.abar_filtered.push_back(rim.abar_filtered);
  h.max_aspect_ratio.push_back(totals.max_aspect_ratio);
  const bool known = dt_element >= 0 && static_cast<std::size_t>(dt_element) < geometry_.size();
  const std::size_t de = known ? static_cast<std::size_t>(dt_element) : 0;
  h.dt_element.push_back(known ? static_cast<double>(dt_element) : -1.0);
  h.dt_element_aspect_ratio.push_back(
      known ? continuum::aspect_ratio(nodes.x[geometry_.node1[de]] - nodes.x[geometry_.node0[de]],
                                      nodes.y[geometry_.node1[de]] - nodes.y[geometry_.node0[de]],
                                      nodes.x[geometry_.node2[de]] - nodes.x[geometry_.node0[de]],
                                      nodes.y[geometry_.node2[de]] - nodes.y[geometry_.node0[de]])
            : 0.0);
  h.dt_element_j.push_back(known ? element_stress(nodes, s, kernel, de).j : 0.0);
  h.dt_element_on_rim.push_back(known && (on_rim_node_[geometry_.node0[de]] ||
                                          on_rim_node_[geometry_.node1[de]] ||
                                          on_rim_node_[geometry_.node2[de]])
                                    ? 1.0
                                    : 0.0);
  h.modes.push_back(std::move(rim.amplitude));
}

FieldFrame Diagnostics::frame(const NodalView& nodes, const ElementState& s,
                              const KernelView& kernel, double t, FieldFrame reuse) const {
  const Mesh& mesh = problem_.mesh;
  const std::size_t nn = mesh.node_count(), ne = geometry_.size();
  FieldFrame fr = std::move(reuse);  // every value below is written
  fr.time_s = t;
  fr.displacement.resize(2 * nn);
  fr.velocity.resize(2 * nn);
  for (std::size_t i = 0; i < nn; ++i) {
    fr.displacement[2 * i] = nodes.x[i] - mesh.x[i];
    fr.displacement[2 * i + 1] = nodes.y[i] - mesh.y[i];
    fr.velocity[2 * i] = nodes.vx[i];
    fr.velocity[2 * i + 1] = nodes.vy[i];
  }
  fr.J.resize(ne), fr.mean_stress.resize(ne), fr.radial_stress.resize(ne);
  fr.hoop_stress.resize(ne), fr.von_mises.resize(ne), fr.aspect_ratio.resize(ne);
  const Material& mat = problem_.material;
  std::vector<double> volumetric;
  if (nodal_volumetric(kernel)) {
    volumetric.resize(ne);
    for (std::size_t e = 0; e < ne; ++e) volumetric[e] = volumetric_mean_stress(kernel, e);
  }
  frame_element_fields(geometry_, nodes, s, volumetric.empty() ? nullptr : volumetric.data(),
                       kernel.element_degradation, mat.bulk_modulus_Pa, mat.tait_n(),
                       mat.shear_modulus_Pa, origin_[0], origin_[1], fr);
  return fr;
}

}  // namespace softshock
