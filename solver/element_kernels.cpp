#include "element_kernels.hpp"

#include <cmath>

#include "continuum.hpp"

namespace softshock {

void ElementState::resize(std::size_t elements) {
  for (auto* v : {&f_xx, &f_xy, &f_yx, &f_yy, &log_j, &pv_xx, &pv_xy, &pv_yx, &pv_yy}) {
    v->assign(elements, 0.0);
  }
  force_x.assign(3 * elements, 0.0);
  force_y.assign(3 * elements, 0.0);
  reset_to_reference();
}

void ElementState::reset_to_reference() {
  for (std::size_t e = 0; e < log_j.size(); ++e) {
    f_xx[e] = 1.0, f_xy[e] = 0.0, f_yx[e] = 0.0, f_yy[e] = 1.0;
    log_j[e] = 0.0;
    pv_xx[e] = pv_xy[e] = pv_yx[e] = pv_yy[e] = 0.0;
  }
}

void compute_element_forces(const ElementGeometry& g, const double* x, const double* y,
                            const KernelParams& p, std::size_t begin, std::size_t end,
                            ElementState& s, KernelTotals& totals) {
  namespace cm = continuum;
  const std::size_t ne = g.size();
  const double n = p.tait_n;
  const bool lagged = p.viscosity && p.dt > 0;
  double min_step_sq = totals.min_step_sq;
  double dissipation = 0.0;

  for (std::size_t e = begin; e < end; ++e) {
    const int32_t a = g.node0[e], b = g.node1[e], c = g.node2[e];
    const double e1x = x[b] - x[a], e1y = y[b] - y[a];
    const double e2x = x[c] - x[a], e2y = y[c] - y[a];
    const cm::Mat2 dm_inv{g.dm_inv_xx[e], g.dm_inv_xy[e], g.dm_inv_yx[e], g.dm_inv_yy[e]};
    const cm::Mat2 f = cm::deformation_gradient(e1x, e1y, e2x, e2y, dm_inv);
    const double j = cm::det(f);
    if (!(j > 0.0) || !std::isfinite(j)) {  // inversion or NaN: report the first one
      if (totals.bad_element < 0) totals.bad_element = static_cast<int64_t>(e), totals.bad_j = j;
      continue;
    }
    // One logarithm feeds J^-n, J^-2/3 and the viscosity's ln(J / J_prev).
    const double log_j = std::log(j);
    const double j_minus_n = std::exp(-n * log_j);
    const double j_minus_23 = std::exp(-2.0 / 3.0 * log_j);
    const double mean_stress = cm::tait_mean_stress(p.kappa, n, j_minus_n);
    const cm::Mat2 cof = cm::cofactor(f);
    cm::Mat2 piola = cm::elastic_piola(f, cof, j, mean_stress, p.mu, j_minus_23);

    const double c_sq =
        cm::longitudinal_speed_sq(cm::tait_bulk_modulus(p.kappa, j_minus_n), p.mu, p.rho0, j);
    const double h_sq = cm::smallest_altitude_sq(e1x, e1y, e2x, e2y);
    min_step_sq = std::fmin(min_step_sq, h_sq / c_sq);

    const cm::Mat2 f_prev{s.f_xx[e], s.f_xy[e], s.f_yx[e], s.f_yy[e]};
    const double log_j_ratio = log_j - s.log_j[e];
    cm::Mat2 pv{0.0, 0.0, 0.0, 0.0};
    if (lagged && log_j_ratio < 0.0) {  // viscosity only while the element is compressed
      const double h = std::sqrt(h_sq);
      const double nu = cm::artificial_viscosity(h, p.rho0, j, p.c1, p.c2, std::sqrt(c_sq),
                                                 log_j_ratio, p.dt);
      pv = cm::viscous_piola(f, f_prev, cof, nu, p.dt);
    }
    if (lagged) {
      // Work of the viscous stress over the step, trapezoidal in time: what the integrator
      // sees as nodal viscous forces times the nodal displacement increments.
      const double df0 = f[0] - f_prev[0], df1 = f[1] - f_prev[1], df2 = f[2] - f_prev[2],
                   df3 = f[3] - f_prev[3];
      dissipation += 0.5 * g.area0[e] *
                     ((pv[0] + s.pv_xx[e]) * df0 + (pv[1] + s.pv_xy[e]) * df1 +
                      (pv[2] + s.pv_yx[e]) * df2 + (pv[3] + s.pv_yy[e]) * df3);
    }
    for (int k = 0; k < 4; ++k) piola[k] += pv[k];

    s.f_xx[e] = f[0], s.f_xy[e] = f[1], s.f_yx[e] = f[2], s.f_yy[e] = f[3];
    s.log_j[e] = log_j;
    s.pv_xx[e] = pv[0], s.pv_xy[e] = pv[1], s.pv_yx[e] = pv[2], s.pv_yy[e] = pv[3];

    // Force on node k: -A0 P grad N_k; grad N1, grad N2 are the rows of Dm^-1.
    const double a0 = g.area0[e];
    const double f1x = -a0 * (piola[0] * dm_inv[0] + piola[1] * dm_inv[1]);
    const double f1y = -a0 * (piola[2] * dm_inv[0] + piola[3] * dm_inv[1]);
    const double f2x = -a0 * (piola[0] * dm_inv[2] + piola[1] * dm_inv[3]);
    const double f2y = -a0 * (piola[2] * dm_inv[2] + piola[3] * dm_inv[3]);
    s.force_x[e] = -(f1x + f2x), s.force_y[e] = -(f1y + f2y);
    s.force_x[ne + e] = f1x, s.force_y[ne + e] = f1y;
    s.force_x[2 * ne + e] = f2x, s.force_y[2 * ne + e] = f2y;
  }
  totals.min_step_sq = min_step_sq;
  totals.dissipation += dissipation;
}

NodeCorners build_node_corners(const ElementGeometry& g, std::size_t nodes) {
  const std::size_t ne = g.size();
  NodeCorners adj;
  adj.offset.assign(nodes + 1, 0);
  const std::vector<int32_t>* corners[3] = {&g.node0, &g.node1, &g.node2};
  for (int k = 0; k < 3; ++k)
    for (std::size_t e = 0; e < ne; ++e) ++adj.offset[(*corners[k])[e] + 1];
  for (std::size_t i = 0; i < nodes; ++i) adj.offset[i + 1] += adj.offset[i];
  adj.corner.resize(3 * ne);
  std::vector<int64_t> fill(adj.offset.begin(), adj.offset.end() - 1);
  for (int k = 0; k < 3; ++k)
    for (std::size_t e = 0; e < ne; ++e)
      adj.corner[fill[(*corners[k])[e]]++] = static_cast<int64_t>(k * ne + e);
  return adj;
}

void gather_nodal_forces(const NodeCorners& adj, const ElementState& s, std::size_t begin,
                         std::size_t end, double* fx, double* fy) {
  const double* cx = s.force_x.data();
  const double* cy = s.force_y.data();
  for (std::size_t i = begin; i < end; ++i) {
    double sx = 0.0, sy = 0.0;
    for (int64_t k = adj.offset[i]; k < adj.offset[i + 1]; ++k) {
      sx += cx[adj.corner[k]];
      sy += cy[adj.corner[k]];
    }
    fx[i] = sx, fy[i] = sy;
  }
}

}  // namespace softshock
