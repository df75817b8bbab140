// Patch test and frame indifference of the element kernel (physics.md section 9).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "solver/continuum.hpp"
#include "solver/element_kernels.hpp"
#include "solver/mesh.hpp"

namespace softshock {
namespace {

struct KernelFixture {
  Mesh mesh = make_rectangle_mesh(4e-6, 3e-6, 8, 6);
  ElementGeometry g;
  ElementState s;
  KernelParams p{2e9, 7.15, 5e3, 1000.0, 1.0, 0.1, true, 0.0};

  KernelFixture() {
    const std::size_t ne = mesh.element_count();
    for (auto* v : {&g.node0, &g.node1, &g.node2}) v->resize(ne);
    for (auto* v : {&g.dm_inv_xx, &g.dm_inv_xy, &g.dm_inv_yx, &g.dm_inv_yy, &g.area0})
      v->resize(ne);
    for (std::size_t e = 0; e < ne; ++e) {
      const auto& t = mesh.triangles[e];
      g.node0[e] = t[0], g.node1[e] = t[1], g.node2[e] = t[2];
      const double a = mesh.x[t[1]] - mesh.x[t[0]], b = mesh.x[t[2]] - mesh.x[t[0]];
      const double c = mesh.y[t[1]] - mesh.y[t[0]], d = mesh.y[t[2]] - mesh.y[t[0]];
      const double det = a * d - b * c;
      g.dm_inv_xx[e] = d / det, g.dm_inv_xy[e] = -b / det, g.dm_inv_yx[e] = -c / det,
      g.dm_inv_yy[e] = a / det, g.area0[e] = 0.5 * det;
    }
    s.resize(ne);
  }
  // Deformed positions x = F X.
  void deform(const continuum::Mat2& f, std::vector<double>& x, std::vector<double>& y) const {
    x.resize(mesh.node_count()), y.resize(mesh.node_count());
    for (std::size_t i = 0; i < mesh.node_count(); ++i) {
      x[i] = f[0] * mesh.x[i] + f[1] * mesh.y[i];
      y[i] = f[2] * mesh.x[i] + f[3] * mesh.y[i];
    }
  }
  bool on_boundary(std::size_t i) const {
    const double eps = 1e-12;
    return mesh.x[i] < eps || mesh.y[i] < eps || mesh.x[i] > 4e-6 - eps || mesh.y[i] > 3e-6 - eps;
  }
};

double frobenius(const continuum::Mat2& m) {
  return std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2] + m[3] * m[3]);
}

// W(F) for the finite-difference check of the stress.
double stored_energy(const continuum::Mat2& f, double kappa, double n, double mu) {
  const double j = continuum::det(f);
  return continuum::tait_energy(kappa, n, j, std::pow(j, -n)) +
         continuum::neo_hookean_energy(mu, continuum::first_invariant(f), std::pow(j, -2.0 / 3.0));
}

TEST(ElementKernel, PatchTestUniformDeformationGivesNoInteriorForceAndExactStress) {
  KernelFixture fx;
  fx.p.mu = 3e8;  // a shear modulus comparable to kappa exercises the deviatoric part
  const continuum::Mat2 f{0.93, 0.12, -0.05, 1.04};
  std::vector<double> x, y;
  fx.deform(f, x, y);
  KernelTotals totals;
  std::vector<double> nfx(fx.mesh.node_count()), nfy(fx.mesh.node_count());
  compute_element_forces(fx.g, x.data(), y.data(), fx.p, 0, fx.g.size(), fx.s, totals, nfx.data(),
                         nfy.data());
  ASSERT_LT(totals.bad_element, 0);

  // Scale of an element's nodal force: |P| * edge length (per metre of thickness).
  const double j = continuum::det(f);
  const continuum::Mat2 cof = continuum::cofactor(f);
  const continuum::Mat2 piola = continuum::elastic_piola(
      f, cof, j, continuum::tait_mean_stress(2e9, 7.15, std::pow(j, -7.15)), 3e8,
      std::pow(j, -2.0 / 3.0));
  const double scale = frobenius(piola) * 0.5e-6;
  int interior = 0;
  for (std::size_t i = 0; i < fx.mesh.node_count(); ++i) {
    if (fx.on_boundary(i)) continue;
    ++interior;
    // Exact cancellation up to round-off: 1e-12 of the element force scale.
    EXPECT_LT(std::hypot(nfx[i], nfy[i]), 1e-12 * scale) << "node " << i;
  }
  EXPECT_GT(interior, 20);

  // The kernel's stress is dW/dF: central finite differences, step 1e-6, error ~ 1e-12 * W''',
  // compared with a relative tolerance of 1e-6.
  for (int k = 0; k < 4; ++k) {
    continuum::Mat2 fp = f, fm = f;
    fp[k] += 1e-6, fm[k] -= 1e-6;
    const double dw =
        (stored_energy(fp, 2e9, 7.15, 3e8) - stored_energy(fm, 2e9, 7.15, 3e8)) / 2e-6;
    EXPECT_NEAR(piola[k], dw, 1e-6 * frobenius(piola)) << k;
  }
  // Every element carries the same stress: its nodal forces equal -A0 P grad N (evaluated one
  // element at a time).
  for (std::size_t e = 0; e < fx.g.size(); ++e) {
    std::vector<double> ex(fx.mesh.node_count(), 0.0), ey(fx.mesh.node_count(), 0.0);
    KernelTotals one;
    compute_element_forces(fx.g, x.data(), y.data(), fx.p, e, e + 1, fx.s, one, ex.data(),
                           ey.data());
    const double f1x =
        -fx.g.area0[e] * (piola[0] * fx.g.dm_inv_xx[e] + piola[1] * fx.g.dm_inv_xy[e]);
    EXPECT_NEAR(ex[fx.g.node1[e]], f1x, 1e-9 * scale);
  }
}

TEST(ElementKernel, RigidRotationProducesNoElasticOrViscousStress) {
  KernelFixture fx;
  std::vector<double> x, y;
  // Rotate through 60 degrees in 200 steps of 0.1 ns (angular speed ~ 5e7 rad/s), viscosity
  // on: the lagged viscous stress must vanish for a rigid rotation (frame indifference).
  const int steps = 200;
  const double dt = 1e-10;
  double max_force = 0;
  for (int k = 1; k <= steps; ++k) {
    const double th = std::numbers::pi / 3 * k / steps;
    fx.deform({std::cos(th), -std::sin(th), std::sin(th), std::cos(th)}, x, y);
    fx.p.dt = dt;
    KernelTotals totals;
    std::vector<double> nfx(fx.mesh.node_count(), 0.0), nfy(fx.mesh.node_count(), 0.0);
    compute_element_forces(fx.g, x.data(), y.data(), fx.p, 0, fx.g.size(), fx.s, totals, nfx.data(),
                           nfy.data());
    ASSERT_LT(totals.bad_element, 0);
    for (std::size_t i = 0; i < nfx.size(); ++i)
      max_force = std::max(max_force, std::hypot(nfx[i], nfy[i]));
  }
  // Elastic stress vanishes exactly for F = R. Round-off in J (~1e-16) switches the viscosity
  // on now and then, and the lagged rate of a rotation by dtheta per step is symmetric only to
  // O(dtheta^2): d_dev ~ (1 - cos dtheta) / (3 dt). Bound the resulting viscous force with the
  // largest possible nu = 3/4 h rho0 c2 c (c1 term ~ 1e-16) and |grad N| A0 <= edge length:
  const double dtheta = std::numbers::pi / 3 / steps, h = 0.5e-6, edge = 0.5e-6 * std::sqrt(2.0);
  const double nu = 0.75 * h * 1000.0 * 0.1 * std::sqrt(2e9 / 1000.0);
  // ... per element corner, times the largest number of elements meeting at a node.
  std::vector<int> valence(fx.mesh.node_count(), 0);
  for (const auto& t : fx.mesh.triangles)
    for (int32_t i : t) ++valence[i];
  const int max_valence = *std::max_element(valence.begin(), valence.end());
  const double bound = 2.0 * nu * (1.0 - std::cos(dtheta)) / (3.0 * dt) * edge * 2.0 * max_valence;
  // ... about 5e-2 N/m at a node, while a 1 % volumetric strain gives kappa * 0.01 * edge
  // ~ 1e1 N/m per element: the bound stays below 1 % of a real 1 % strain.
  EXPECT_LT(max_force, bound);
  EXPECT_LT(bound, 1e-2 * 2e9 * 0.01 * edge);
}

TEST(ElementKernel, InvertedElementIsReported) {
  KernelFixture fx;
  std::vector<double> x = fx.mesh.x, y = fx.mesh.y;
  const int32_t victim = fx.g.node1[7];
  x[victim] = -1e-5;  // pull one node through the opposite edge
  KernelTotals totals;
  std::vector<double> nfx(x.size(), 0.0), nfy(x.size(), 0.0);
  compute_element_forces(fx.g, x.data(), y.data(), fx.p, 0, fx.g.size(), fx.s, totals, nfx.data(),
                         nfy.data());
  EXPECT_GE(totals.bad_element, 0);
  EXPECT_LE(totals.bad_j, 0.0);
}

}  // namespace
}  // namespace softshock
