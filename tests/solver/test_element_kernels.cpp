// Patch test and frame indifference of the element kernel (physics.md section 9).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <numeric>
#include <utility>

#include "solver/continuum.hpp"
#include "solver/element_kernels.hpp"
#include "solver/integrator.hpp"
#include "solver/mesh.hpp"
#include "solver/nodal_pressure.hpp"
#include "solver/ring_mesher.hpp"

namespace softshock {
namespace {

struct KernelFixture {
  Mesh mesh;
  ElementGeometry g;
  ElementState s;
  KernelParams p;

  explicit KernelFixture(int nx = 8, int ny = 6)
      : KernelFixture(make_rectangle_mesh(4e-6, 3e-6, nx, ny)) {}
  explicit KernelFixture(Mesh m) : mesh(std::move(m)) {
    p.kappa = 2e9, p.tait_n = 7.15, p.mu = 5e3, p.rho0 = 1000.0, p.c1 = 1.0, p.c2 = 0.1;
    p.ramp_inv = 1e300;  // the thesis's on/off switch: the harder case for frame indifference
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

// compute_element_forces over [begin, end) on the packed nodes, its nodal forces added to fx
// and fy.
void add_element_forces(const ElementGeometry& g, const std::vector<PackedNode>& nodes,
                        const KernelParams& p, std::size_t begin, std::size_t end, ElementState& s,
                        KernelTotals& totals, std::vector<double>& fx, std::vector<double>& fy) {
  std::vector<NodeForce> force(fx.size());
  compute_element_forces(g, nodes.data(), p, begin, end, s, totals, force.data());
  for (std::size_t i = 0; i < fx.size(); ++i)
    fx[i] += force[i].lanes[0], fy[i] += force[i].lanes[1];
}
std::vector<PackedNode> packed_positions(const std::vector<double>& x,
                                         const std::vector<double>& y) {
  std::vector<PackedNode> nodes(x.size());
  pack_positions(x.data(), y.data(), 0, x.size(), nodes.data());
  return nodes;
}
void add_element_forces(const ElementGeometry& g, const std::vector<double>& x,
                        const std::vector<double>& y, const KernelParams& p, std::size_t begin,
                        std::size_t end, ElementState& s, KernelTotals& totals,
                        std::vector<double>& fx, std::vector<double>& fy) {
  add_element_forces(g, packed_positions(x, y), p, begin, end, s, totals, fx, fy);
}

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
  add_element_forces(fx.g, x, y, fx.p, 0, fx.g.size(), fx.s, totals, nfx, nfy);
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
    add_element_forces(fx.g, x, y, fx.p, e, e + 1, fx.s, one, ex, ey);
    const double f1x =
        -fx.g.area0[e] * (piola[0] * fx.g.dm_inv_xx[e] + piola[1] * fx.g.dm_inv_xy[e]);
    EXPECT_NEAR(ex[fx.g.node1[e]], f1x, 1e-9 * scale);
  }
}

TEST(ElementKernel, RigidRotationProducesNoElasticOrViscousStress) {
  KernelFixture fx;
  fx.p.eta = 0.2;  // Kelvin-Voigt on too: 2 eta dev(D) must vanish for a rotation as well
  std::vector<double> x, y;
  // Rotate through 60 degrees in 400 steps of 0.1 ns (angular speed ~ 2.6e7 rad/s), viscosity
  // on: the lagged viscous stress must vanish for a rigid rotation (frame indifference).
  const int steps = 400;
  const double dt = 1e-10;
  double max_force = 0;
  for (int k = 1; k <= steps; ++k) {
    const double th = std::numbers::pi / 3 * k / steps;
    fx.deform({std::cos(th), -std::sin(th), std::sin(th), std::cos(th)}, x, y);
    fx.p.dt = dt;
    KernelTotals totals;
    std::vector<double> nfx(fx.mesh.node_count(), 0.0), nfy(fx.mesh.node_count(), 0.0);
    add_element_forces(fx.g, x, y, fx.p, 0, fx.g.size(), fx.s, totals, nfx, nfy);
    ASSERT_LT(totals.bad_element, 0);
    for (std::size_t i = 0; i < nfx.size(); ++i)
      max_force = std::max(max_force, std::hypot(nfx[i], nfy[i]));
  }
  // Elastic stress vanishes exactly for F = R. Round-off in J (~1e-16) switches the viscosity
  // on now and then, and the lagged rate of a rotation by dtheta per step is symmetric only to
  // O(dtheta^2): d_dev ~ (1 - cos dtheta) / (3 dt). Bound the resulting viscous force with the
  // largest possible nu = 3/4 h rho0 c2 c (c1 term ~ 1e-16) and |grad N| A0 <= edge length:
  const double dtheta = std::numbers::pi / 3 / steps, h = 0.5e-6, edge = 0.5e-6 * std::sqrt(2.0);
  const double nu = 0.75 * h * 1000.0 * 0.1 * std::sqrt(2e9 / 1000.0) + 0.2;
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

// A history sample's element sums come from the kernel (KernelParams::sample): the stored energy
// sum_e A_e (W_dev + w W_vol(J_e)) and the largest aspect ratio of the current shapes, equal to
// the sums computed element by element here (to round-off: the kernel's J^-2/3 and J^-n take
// other paths than std::pow), for the plain element (w = 1) and the nodal-pressure one (w = 0,
// its W_vol is the nodes'); nothing without the flag.
TEST(ElementKernel, SampleSumsTheElementsStoredEnergyAndLargestAspectRatio) {
  for (const bool nodal : {false, true}) {
    KernelFixture fx;
    fx.p.mu = 3e8;  // a deviatoric energy comparable to the volumetric one
    std::vector<double> x, y;
    fx.deform({0.97, 0.05, -0.02, 1.01}, x, y);
    for (std::size_t i = 0; i < x.size(); ++i)  // non-uniform shapes: aspect ratios differ
      x[i] += 4e-8 * std::sin(3.1 * i), y[i] += 4e-8 * std::cos(1.7 * i);
    const std::size_t nn = x.size(), ne = fx.g.size();
    std::vector<PackedNode> nodes = packed_positions(x, y);
    std::vector<double> zero(nn, 0.0), shift(ne, 0.0);
    if (nodal) {
      pack_nodal_state(zero.data(), zero.data(), 0, nn, nodes.data());
      fx.p.nodal_pressure = true, fx.p.element_weight = 0.0;
      fx.p.element_stress_shift = shift.data();
    }
    double energy = 0.0, max_aspect = 0.0;
    for (std::size_t e = 0; e < ne; ++e) {
      const int32_t a = fx.g.node0[e], b = fx.g.node1[e], c = fx.g.node2[e];
      const double e1x = x[b] - x[a], e1y = y[b] - y[a], e2x = x[c] - x[a], e2y = y[c] - y[a];
      const continuum::Mat2 f = continuum::deformation_gradient(
          e1x, e1y, e2x, e2y,
          {fx.g.dm_inv_xx[e], fx.g.dm_inv_xy[e], fx.g.dm_inv_yx[e], fx.g.dm_inv_yy[e]});
      const double j = continuum::det(f);
      double w = continuum::neo_hookean_energy(3e8, continuum::first_invariant(f),
                                               std::pow(j, -2.0 / 3.0));
      if (!nodal) w += continuum::tait_energy(2e9, 7.15, j, std::pow(j, -7.15));
      energy += fx.g.area0[e] * w;
      max_aspect = std::max(max_aspect, continuum::aspect_ratio(e1x, e1y, e2x, e2y));
    }
    std::vector<double> nfx(nn), nfy(nn);
    KernelTotals plain;
    add_element_forces(fx.g, nodes, fx.p, 0, ne, fx.s, plain, nfx, nfy);
    EXPECT_EQ(plain.element_energy, 0.0);
    EXPECT_EQ(plain.max_aspect_ratio, 0.0);
    fx.p.sample = true;
    KernelTotals sampled;
    add_element_forces(fx.g, nodes, fx.p, 0, ne, fx.s, sampled, nfx, nfy);
    EXPECT_GT(max_aspect, 1.2) << nodal;
    EXPECT_NEAR(sampled.element_energy, energy, 1e-12 * std::fabs(energy)) << nodal;
    EXPECT_NEAR(sampled.max_aspect_ratio, max_aspect, 1e-14 * max_aspect) << nodal;
  }
}

// The loop's totals are reduced a block at a time, eight lanes at once: they must be what a scan
// element by element gives -- the smallest stable step exactly, and its first element, the
// dissipation to round-off, an inverted element near the end of the last block -- over a range
// that starts off a lane boundary and ends mid-lane. Every element of a 624-element mesh appears
// twice in a row (elements 2i and 2i + 1), so the smallest step is always a tie of neighbours;
// the range [3, 1240) has blocks of 256 (four) and 213.
TEST(ElementKernel, BlockReductionsMatchAnElementByElementScan) {
  KernelFixture fx(24, 13);
  fx.p.eta = 0.2;  // viscous dissipation in every element
  ElementGeometry g;
  for (std::size_t e = 0; e < fx.g.size(); ++e)
    for (int copy = 0; copy < 2; ++copy) {
      g.node0.push_back(fx.g.node0[e]), g.node1.push_back(fx.g.node1[e]);
      g.node2.push_back(fx.g.node2[e]);
      g.dm_inv_xx.push_back(fx.g.dm_inv_xx[e]), g.dm_inv_xy.push_back(fx.g.dm_inv_xy[e]);
      g.dm_inv_yx.push_back(fx.g.dm_inv_yx[e]), g.dm_inv_yy.push_back(fx.g.dm_inv_yy[e]);
      g.area0.push_back(fx.g.area0[e]);
    }
  const std::size_t ne = g.size(), begin = 3, end = 1240;
  ASSERT_EQ(ne, 1248u);
  ElementState state;
  state.resize(ne);
  std::vector<double> x, y;
  fx.deform({1.0, 0.0, 0.0, 1.0}, x, y);
  std::vector<double> nfx(x.size()), nfy(x.size());
  KernelTotals first;
  add_element_forces(g, x, y, fx.p, 0, ne, state, first, nfx, nfy);  // the lagged state
  fx.deform({0.995, 0.002, 0.0, 0.998}, x, y);
  for (std::size_t i = 0; i < x.size(); ++i)
    x[i] += 4e-8 * std::sin(3.1 * i), y[i] += 4e-8 * std::cos(1.7 * i);
  fx.p.dt = 1e-10;

  std::vector<double> step_sq(ne, 0.0);
  double smallest = 1e300, dissipation = 0.0;
  int64_t smallest_element = -1;
  for (std::size_t e = begin; e < end; ++e) {
    ElementState s = state;
    KernelTotals one;
    add_element_forces(g, x, y, fx.p, e, e + 1, s, one, nfx, nfy);
    step_sq[e] = one.min_step_sq;
    if (one.min_step_sq < smallest)
      smallest = one.min_step_sq, smallest_element = static_cast<int64_t>(e);
    dissipation += one.dissipation;
  }
  EXPECT_EQ(std::count(step_sq.begin(), step_sq.end(), smallest), 2);  // a tie, as built
  ElementState s = state;
  KernelTotals all;
  add_element_forces(g, x, y, fx.p, begin, end, s, all, nfx, nfy);
  // The value to a few ulp: one element alone runs the loop's scalar remainder, the range its
  // vector body (libmvec and contraction differ in the last bits on AVX2; AVX-512's masked
  // remainder gave the same bits). Which element, the first of the tied pair, is exact.
  EXPECT_NEAR(all.min_step_sq, smallest, 1e-15 * smallest);
  EXPECT_EQ(all.min_step_element, smallest_element);
  EXPECT_GT(std::fabs(dissipation), 0.0);
  EXPECT_NEAR(all.dissipation, dissipation, 1e-12 * std::fabs(dissipation));
  EXPECT_LT(all.bad_element, 0);

  // An element near the end of the last block (its 206th of 213: lanes 200-207, then padding)
  // turned inside out is found.
  const std::size_t victim = begin + 4 * 256 + 205;
  const int32_t a = g.node0[victim], b = g.node1[victim], c = g.node2[victim];
  x[b] = x[a] - 1e-7, y[b] = y[a], x[c] = x[a] + 1e-7, y[c] = y[a] + 1e-9;  // clockwise
  s = state;
  KernelTotals bad;
  add_element_forces(g, x, y, fx.p, begin, end, s, bad, nfx, nfy);
  // The first offender: the victim or an element sharing a moved node (2 x 48 per mesh row).
  EXPECT_GE(bad.bad_element, static_cast<int64_t>(victim - 2 * 96));
  EXPECT_LE(bad.bad_element, static_cast<int64_t>(victim));
  EXPECT_LE(bad.bad_j, 0.0);
}

TEST(ElementKernel, InvertedElementIsReported) {
  KernelFixture fx;
  std::vector<double> x = fx.mesh.x, y = fx.mesh.y;
  const int32_t victim = fx.g.node1[7];
  x[victim] = -1e-5;  // pull one node through the opposite edge
  KernelTotals totals;
  std::vector<double> nfx(x.size(), 0.0), nfy(x.size(), 0.0);
  add_element_forces(fx.g, x, y, fx.p, 0, fx.g.size(), fx.s, totals, nfx, nfy);
  EXPECT_GE(totals.bad_element, 0);
  EXPECT_LE(totals.bad_j, 0.0);
}

// ---- average nodal pressure ------------------------------------------------------------------

// Runs the nodal passes in the order the integrator does (simulation.cpp) and then the element
// loop; returns the nodal forces.
struct NodalRun {
  std::vector<double> fx, fy;
  KernelTotals totals;
};
NodalRun nodal_forces(KernelFixture& fx, const std::vector<double>& x, const std::vector<double>& y,
                      double beta) {
  const std::size_t nn = fx.mesh.node_count(), ne = fx.g.size();
  const std::vector<double> v0 = reference_nodal_areas(fx.g, nn);
  std::vector<double> area(nn, 0.0), nj(nn), sm(nn), k(nn), q(nn, 0.0), je(ne), se(ne, 0.0);
  std::vector<PackedNode> nodes = packed_positions(x, y);
  accumulate_nodal_areas(fx.g, nodes.data(), 0, ne, area.data(), je.data());
  nodal_tait_state(fx.p.kappa, fx.p.tait_n, v0.data(), area.data(), 0, nn, nj.data(), sm.data(),
                   k.data());
  accumulate_stabilization(fx.g, beta * fx.p.kappa, nj.data(), je.data(), 0, ne, se.data(),
                           q.data());
  subtract_stabilization(v0.data(), q.data(), k.data(), 0, nn, sm.data(), nodes.data());
  KernelParams p = fx.p;
  p.nodal_pressure = true;
  p.element_stress_shift = se.data(), p.stabilization_beta_kappa = beta * fx.p.kappa;
  p.element_weight = 0.0;
  NodalRun r;
  r.fx.assign(nn, 0.0), r.fy.assign(nn, 0.0);
  add_element_forces(fx.g, nodes, p, 0, ne, fx.s, r.totals, r.fx, r.fy);
  return r;
}

// Stored energy under the nodal-pressure element: sum_a V_a W_vol(J_a) + stabilisation (from
// nodal_pressure_state) + the deviatoric neo-Hookean energy of every element.
double nodal_stored_energy(const KernelFixture& fx, const std::vector<double>& x,
                           const std::vector<double>& y, double beta) {
  const std::vector<double> v0 = reference_nodal_areas(fx.g, fx.mesh.node_count());
  double w = nodal_pressure_state(fx.g, v0, fx.p.kappa, fx.p.tait_n, 0.0, beta, x.data(), y.data())
                 .stored_energy;
  for (std::size_t e = 0; e < fx.g.size(); ++e) {
    const int32_t a = fx.g.node0[e], b = fx.g.node1[e], c = fx.g.node2[e];
    const continuum::Mat2 f = continuum::deformation_gradient(
        x[b] - x[a], y[b] - y[a], x[c] - x[a], y[c] - y[a],
        {fx.g.dm_inv_xx[e], fx.g.dm_inv_xy[e], fx.g.dm_inv_yx[e], fx.g.dm_inv_yy[e]});
    const double j = continuum::det(f);
    w += fx.g.area0[e] * continuum::neo_hookean_energy(fx.p.mu, continuum::first_invariant(f),
                                                       std::pow(j, -2.0 / 3.0));
  }
  return w;
}

TEST(AverageNodalPressure, PatchTestUniformDeformationGivesNoInteriorForce) {
  KernelFixture fx;
  fx.p.mu = 3e8;
  const continuum::Mat2 f{0.93, 0.12, -0.05, 1.04};
  std::vector<double> x, y;
  fx.deform(f, x, y);
  const NodalRun r = nodal_forces(fx, x, y, 0.1);
  ASSERT_LT(r.totals.bad_element, 0);
  // Uniform F: every nodal J equals det F, so the nodal element reproduces the P1 stress.
  const double j = continuum::det(f);
  const continuum::Mat2 piola = continuum::elastic_piola(
      f, continuum::cofactor(f), j, continuum::tait_mean_stress(2e9, 7.15, std::pow(j, -7.15)), 3e8,
      std::pow(j, -2.0 / 3.0));
  const double scale = frobenius(piola) * 0.5e-6;
  for (std::size_t i = 0; i < fx.mesh.node_count(); ++i)
    if (!fx.on_boundary(i)) {
      EXPECT_LT(std::hypot(r.fx[i], r.fy[i]), 1e-11 * scale) << i;
    }
}

// Energy consistency: the forces are minus the gradient of the stored energy the diagnostics
// book (nodal Tait energy + stabilisation + deviatoric), so the energy balance closes. Checked by
// central differences on a randomly distorted mesh (step 1e-12 m on 0.5 um elements: truncation
// ~1e-12 relative, round-off ~1e-16 W / 1e-12 m; tolerance 1e-5 of the largest force).
TEST(AverageNodalPressure, ForcesAreMinusTheGradientOfTheStoredEnergy) {
  for (double beta : {0.0, 0.3}) {
    KernelFixture fx;
    fx.p.mu = 2e7;
    fx.p.viscosity = false;
    std::vector<double> x = fx.mesh.x, y = fx.mesh.y;
    for (std::size_t i = 0; i < x.size(); ++i) {  // +-4 % of the element size, deterministic
      x[i] += 0.02e-6 * std::sin(12.9898 * i) + 0.01e-6 * x[i] / 4e-6;
      y[i] += 0.02e-6 * std::cos(78.233 * i) - 0.015e-6 * y[i] / 3e-6;
    }
    const NodalRun r = nodal_forces(fx, x, y, beta);
    double largest = 0;
    for (std::size_t i = 0; i < x.size(); ++i)
      largest = std::max(largest, std::hypot(r.fx[i], r.fy[i]));
    const double step = 1e-12;
    for (std::size_t i = 0; i < x.size(); i += 7) {
      for (int axis = 0; axis < 2; ++axis) {
        std::vector<double> xp = x, yp = y, xm = x, ym = y;
        (axis == 0 ? xp : yp)[i] += step;
        (axis == 0 ? xm : ym)[i] -= step;
        const double grad =
            (nodal_stored_energy(fx, xp, yp, beta) - nodal_stored_energy(fx, xm, ym, beta)) /
            (2 * step);
        EXPECT_NEAR(axis == 0 ? r.fx[i] : r.fy[i], -grad, 1e-5 * largest)
            << "node " << i << " axis " << axis << " beta " << beta;
      }
    }
  }
}

// The stabilisation acts on element-level volume modes only: alternating element areas at fixed
// nodal areas raise its energy, a smooth (uniform) compression does not.
TEST(AverageNodalPressure, StabilizationPenalisesOnlyTheElementLevelMode) {
  KernelFixture fx;
  std::vector<double> x, y;
  fx.deform({0.98, 0.0, 0.0, 0.98}, x, y);
  const std::vector<double> v0 = reference_nodal_areas(fx.g, fx.mesh.node_count());
  auto stab_energy = [&](const std::vector<double>& px, const std::vector<double>& py) {
    return nodal_pressure_state(fx.g, v0, 2e9, 7.15, 0.0, 0.5, px.data(), py.data()).stored_energy -
           nodal_pressure_state(fx.g, v0, 2e9, 7.15, 0.0, 0.0, px.data(), py.data()).stored_energy;
  };
  EXPECT_NEAR(stab_energy(x, y), 0.0, 1e-20);
  // Move one interior node: its neighbours' areas change unevenly, a local element-level mode.
  std::size_t interior = 0;
  while (fx.on_boundary(interior)) ++interior;
  x[interior] += 0.05e-6;
  EXPECT_GT(stab_energy(x, y), 0.0);
}

// The stabilisation's pointwise law (continuum.hpp): its element stress, nodal share and tangent
// modulus are the derivatives of its energy (central differences, step 1e-6: truncation ~1e-12
// relative); for a small discrepancy it is the quadratic penalty beta kappa (J_e - Jbar)^2 / 2;
// and it is a barrier: crushing an element whose nodes keep their area costs unbounded energy
// (the quadratic form caps it at beta kappa / 2, which a strong pulse paid at the rim).
TEST(AverageNodalPressure, StabilizationIsABarrierAgainstCrushedElements) {
  namespace cm = continuum;
  const double bk = 4e7, h = 1e-6;
  for (double je : {0.3, 0.97, 1.0, 1.2}) {
    for (double jbar : {0.9, 1.0, 1.05}) {
      const double rho = jbar / je;
      const double s = cm::stabilization_element_stress(bk, rho);
      const double dw_dje = (cm::stabilization_energy(bk, je + h, jbar) -
                             cm::stabilization_energy(bk, je - h, jbar)) /
                            (2 * h);
      const double dw_djbar = (cm::stabilization_energy(bk, je, jbar + h) -
                               cm::stabilization_energy(bk, je, jbar - h)) /
                              (2 * h);
      EXPECT_NEAR(s, dw_dje, 1e-7 * bk) << je << " " << jbar;
      EXPECT_NEAR(cm::stabilization_nodal_share(bk, rho), -dw_djbar, 1e-7 * bk);
      const double ds_dje = (cm::stabilization_element_stress(bk, jbar / (je + h)) -
                             cm::stabilization_element_stress(bk, jbar / (je - h))) /
                            (2 * h);
      EXPECT_NEAR(cm::stabilization_bulk_modulus(bk, s), je * ds_dje, 1e-7 * bk);
    }
  }
  // Small discrepancy: the quadratic penalty to relative order |J_e - Jbar| (here 1e-3).
  const double quadratic = 0.5 * bk * 1e-3 * 1e-3;
  EXPECT_NEAR(cm::stabilization_energy(bk, 1.001, 1.0), quadratic, 2e-3 * quadratic);
  // Barrier: at J_e = 1e-3 under nodes at J = 1 it costs ~500 beta kappa, not the quadratic's
  // beta kappa / 2, and it keeps growing as (1 - J_e)^2 / J_e.
  EXPECT_GT(cm::stabilization_energy(bk, 1e-3, 1.0), 100 * bk);
  const double growth = 10.0 * std::pow(0.9999 / 0.999, 2);
  EXPECT_NEAR(cm::stabilization_energy(bk, 1e-4, 1.0) / cm::stabilization_energy(bk, 1e-3, 1.0),
              growth, 1e-9 * growth);
}

// ---- viscosity ---------------------------------------------------------------------------

TEST(ArtificialViscosity, ContinuousInTheCompressionMeasure) {
  namespace cm = continuum;
  const double h = 1e-6, rho0 = 1000, j = 1.0, c1 = 1.0, c2 = 0.1, a = 1414.0, ramp_inv = 50.0;
  // No jump at z = 0 (the thesis's switch jumps by 3/4 h rho0 c2 a ~ 0.1 Pa s there).
  EXPECT_EQ(cm::artificial_viscosity(h, rho0, j, c1, c2, a, -1e-3, ramp_inv), 0.0);
  EXPECT_EQ(cm::artificial_viscosity(h, rho0, j, c1, c2, a, 0.0, ramp_inv), 0.0);
  // Just above: the linear ramp, 3/4 h rho0 a (c2 z / z_ramp + c1 z), ~6e-8 of the full c2 term.
  const double tiny = cm::artificial_viscosity(h, rho0, j, c1, c2, a, 1e-9, ramp_inv);
  EXPECT_NEAR(tiny, 0.75 * h * rho0 * a * (c2 * ramp_inv + c1) * 1e-9, 1e-6 * tiny);
  // Beyond the ramp it is the thesis's form 3/4 (h rho0 / J)(c2 a + c1 h |dlnJ/dt|).
  const double z = 0.3;
  EXPECT_DOUBLE_EQ(cm::artificial_viscosity(h, rho0, j, c1, c2, a, z, ramp_inv),
                   0.75 * h * rho0 / j * (c2 * a + c1 * a * z));
  // Monotone in z.
  double last = 0;
  for (double zz = 0; zz < 0.1; zz += 0.001) {
    const double nu = cm::artificial_viscosity(h, rho0, j, c1, c2, a, zz, ramp_inv);
    EXPECT_GE(nu, last);
    last = nu;
  }
}

// The stable step with viscosity: h / (q + sqrt(q^2 + c^2)), q = nu_l / (rho h) with the
// longitudinal viscosity nu_l = 4/3 nu + zeta. Inviscid it is h / c; pure diffusion (c -> 0)
// gives the explicit diffusion limit h^2 rho / (2 nu_l).
// The blended mass's momentum p = K^-1 v (integrator.hpp, blended_momentum; the kinetic energy
// 1/2 v.p): applying the blend's operator to p as the integrator applies it to forces (a_L =
// free p / m, then the correction of correct_mass_blend) must give v back, to round-off, with
// fixed components (the left half's x) and at alpha = 1, where the series converges slowest
// (ratio 3/4). A wrong sign in the series leaves errors of order alpha (checked).
TEST(MassBlend, MomentumInvertsTheBlendedOperator) {
  KernelFixture fx(mesh_disk_rings(90e-6, 300));
  const std::size_t nn = fx.mesh.node_count(), ne = fx.mesh.element_count();
  const double density = 1000.0;
  std::vector<double> mass = reference_nodal_areas(fx.g, nn);  // lumped: rho x a third of each area
  for (double& m : mass) m *= density;
  std::vector<uint8_t> free_x(nn, 1), free_y(nn, 1);
  std::vector<double> vx(nn), vy(nn);
  uint64_t state = 12345;  // a fixed pseudo-random field, grid-scale content included
  auto uniform = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) * 0x1p-53 - 0.5;
  };
  for (std::size_t i = 0; i < nn; ++i) {
    free_x[i] = fx.mesh.x[i] < 0 ? 0 : 1;
    vx[i] = free_x[i] * uniform(), vy[i] = uniform();
  }
  const std::vector<double> weight = consistent_mass_weights(fx.g, density);
  for (const double alpha : {0.5, 1.0}) {
    SCOPED_TRACE(alpha);
    std::vector<double> px(nn), py(nn), ax(nn), ay(nn);
    blended_momentum(fx.g, weight.data(), alpha, nn, mass.data(), free_x.data(), free_y.data(),
                     vx.data(), vy.data(), px.data(), py.data());
    for (std::size_t i = 0; i < nn; ++i)
      ax[i] = free_x[i] * px[i] / mass[i], ay[i] = free_y[i] * py[i] / mass[i];
    std::vector<NodeForce> difference(nn);
    accumulate_consistent_mass_difference(fx.g, weight.data(), ax.data(), ay.data(), 0, ne,
                                          difference.data());
    std::vector<double> zero(nn, 0.0);  // dt = 0: the velocities are not advanced
    correct_mass_blend(0.0, alpha, 0, nn, difference.data(), free_x.data(), free_y.data(),
                       mass.data(), ax.data(), ay.data(), zero.data(), zero.data());
    double worst = 0, lumped_gap = 0;
    for (std::size_t i = 0; i < nn; ++i) {
      worst = std::max({worst, std::fabs(ax[i] - vx[i]), std::fabs(ay[i] - vy[i])});
      lumped_gap = std::max(lumped_gap, std::fabs(px[i] / mass[i] - vx[i]));
    }
    EXPECT_LT(worst, 1e-12) << "K p must be v";
    EXPECT_GT(lumped_gap, 1e-3) << "p is not the lumped momentum";
  }
}

TEST(StableStep, IncludesTheViscousTerm) {
  namespace cm = continuum;
  const double h = 1e-6, c = 1414.0, rho0 = 1000.0;
  EXPECT_DOUBLE_EQ(cm::stable_step_sq(h * h, c * c, 0.0, rho0, 1.0), h * h / (c * c));
  const double nu_l = 4.0 / 3.0 * 0.2;
  const double dt_visc = std::sqrt(cm::stable_step_sq(h * h, 1e-30, nu_l, rho0, 1.0));
  EXPECT_NEAR(dt_visc, h * h * rho0 / (2.0 * nu_l), 1e-9 * dt_visc);
  EXPECT_LT(cm::stable_step_sq(h * h, c * c, nu_l, rho0, 1.0), h * h / (c * c));
}

// The continuous artificial viscosity is a bulk viscosity (4/3 nu): a planar compression sees the
// same longitudinal viscous stress as the thesis's shear form, a pure shear sees none; the
// physical eta is a shear viscosity 2 eta dev(D).
TEST(ViscousStress, BulkAndShearParts) {
  namespace cm = continuum;
  const double dt = 1e-9, nu = 0.3;
  const cm::Mat2 eye{1, 0, 0, 1};
  const cm::Mat2 compress{1.0 - 1e-3, 0, 0, 1};  // rate -1e6 /s along x
  const cm::Mat2 pv_shear_form =
      cm::viscous_piola(compress, eye, cm::cofactor(compress), nu, 0, dt);
  const cm::Mat2 pv_bulk_form =
      cm::viscous_piola(compress, eye, cm::cofactor(compress), 0, 4.0 / 3.0 * nu, dt);
  EXPECT_NEAR(pv_bulk_form[0], pv_shear_form[0], 1e-12 * std::fabs(pv_shear_form[0]));
  EXPECT_NEAR(pv_shear_form[0], -4.0 / 3.0 * nu * 1e6 * compress[3], 1e-9 * 4e5);
  const cm::Mat2 shear{1, 1e-3, 0, 1};  // isochoric simple shear
  const cm::Mat2 pv_bulk_shear = cm::viscous_piola(shear, eye, cm::cofactor(shear), 0, 0.4, dt);
  for (double v : pv_bulk_shear) EXPECT_NEAR(v, 0.0, 1e-12);
  const cm::Mat2 pv_eta = cm::viscous_piola(shear, eye, cm::cofactor(shear), 0.2, 0, dt);
  EXPECT_NEAR(pv_eta[1], 0.2 * 1e6, 1e-9 * 2e5);  // sigma_xy = eta * shear rate
}

// ---- the stable step ---------------------------------------------------------------------------

// The volume-change bound of the steps taken under load (integrator.hpp): for the homogeneous
// fields v = g X and a = s X every element's area changes at the rate div v = 2g (acceleration div
// a = 2s), so the bound is the root of 2|g| dt + |s| dt^2 = m exactly: m / (2|g|) without
// acceleration, sqrt(m / |s|) from rest, and in between for both; compression and expansion alike.
TEST(StableStep, LoadStepBoundKeepsThePredictedVolumeChangeWithinTheLimit) {
  KernelFixture fx;
  const std::size_t nn = fx.mesh.node_count();
  const double m = 0.1;
  std::vector<int32_t> all(fx.g.size());
  std::iota(all.begin(), all.end(), 0);
  auto bound = [&](double g, double s) {
    std::vector<double> vx(nn), vy(nn), ax(nn), ay(nn);
    for (std::size_t i = 0; i < nn; ++i) {
      vx[i] = g * fx.mesh.x[i], vy[i] = g * fx.mesh.y[i];
      ax[i] = s * fx.mesh.x[i], ay[i] = s * fx.mesh.y[i];
    }
    return volume_change_step(fx.g, all, vx.data(), vy.data(), ax.data(), ay.data(), m).dt_s;
  };
  EXPECT_NEAR(bound(-1e6, 0.0), m / 2e6, 1e-12 * m / 2e6);
  EXPECT_NEAR(bound(1e6, 0.0), m / 2e6, 1e-12 * m / 2e6);
  EXPECT_NEAR(bound(0.0, -1e15), std::sqrt(m / 1e15), 1e-12 * std::sqrt(m / 1e15));
  const double dt = bound(-1e6, 1e15);
  EXPECT_NEAR(2e6 * dt + 1e15 * dt * dt, m, 1e-12 * m);
  EXPECT_TRUE(std::isinf(bound(0.0, 0.0)));  // at rest and unloaded: no bound

  // One node pushed: the element that sets the bound is one of its own.
  std::vector<double> vx(nn, 0.0), vy(nn, 0.0), zero(nn, 0.0);
  const int32_t pushed = fx.g.node2[17];
  vx[pushed] = 10.0;
  const StepBound one =
      volume_change_step(fx.g, all, vx.data(), vy.data(), zero.data(), zero.data(), m);
  ASSERT_GE(one.element, 0);
  auto touches = [&](std::size_t e) {
    return fx.g.node0[e] == pushed || fx.g.node1[e] == pushed || fx.g.node2[e] == pushed;
  };
  EXPECT_TRUE(touches(static_cast<std::size_t>(one.element)));
  EXPECT_EQ(
      volume_change_step(fx.g, all, zero.data(), zero.data(), zero.data(), zero.data(), m).element,
      -1);
  // Over a subset (the solver passes the loaded elements) only its elements count: without the
  // pushed node's elements nothing moves; the element that set the bound alone sets it again.
  std::vector<int32_t> others;
  for (const int32_t e : all)
    if (!touches(static_cast<std::size_t>(e))) others.push_back(e);
  EXPECT_EQ(
      volume_change_step(fx.g, others, vx.data(), vy.data(), zero.data(), zero.data(), m).element,
      -1);
  const std::vector<int32_t> setter{static_cast<int32_t>(one.element)};
  const StepBound alone =
      volume_change_step(fx.g, setter, vx.data(), vy.data(), zero.data(), zero.data(), m);
  EXPECT_EQ(alone.element, one.element);
  EXPECT_EQ(alone.dt_s, one.dt_s);
}

// The kernel's nodal forces at (px, py) as one vector over the degrees of freedom (x0, y0, x1,
// ...): plain P1, or the average nodal pressure element with beta = 0.01.
std::vector<double> dof_forces(KernelFixture& fx, bool nodal, const std::vector<double>& px,
                               const std::vector<double>& py, KernelTotals* totals) {
  const std::size_t nn = fx.mesh.node_count();
  std::vector<double> f(2 * nn, 0.0);
  if (nodal) {
    const NodalRun r = nodal_forces(fx, px, py, 0.01);
    for (std::size_t i = 0; i < nn; ++i) f[2 * i] = r.fx[i], f[2 * i + 1] = r.fy[i];
    if (totals) *totals = r.totals;
  } else {
    std::vector<double> nfx(nn, 0.0), nfy(nn, 0.0);
    KernelTotals t;
    add_element_forces(fx.g, px, py, fx.p, 0, fx.g.size(), fx.s, t, nfx, nfy);
    for (std::size_t i = 0; i < nn; ++i) f[2 * i] = nfx[i], f[2 * i + 1] = nfy[i];
    if (totals) *totals = t;
  }
  return f;
}

// Central differences are stable for dt <= 2 / omega_max, omega_max^2 the largest eigenvalue of
// M^-1 K (lumped masses M, tangent stiffness K). K is assembled here column by column from central
// differences of the kernel's own nodal forces, on a ring disk of ~300 elements at rest and
// uniformly compressed to J = 0.7 (the default run's refocus at the centre compresses elements to
// J ~ 0.67; K(J) is then 13 kappa and the initial-stress stiffness of a 3.9 GPa pressure enters),
// for plain P1 and for the average nodal pressure element (beta = 0.01). The solver's step,
// cfl sqrt(min_step_sq) at the default cfl = 0.75, must lie below 2 / omega_max. (No viscosity
// here: the damped limit is the next test's.) Measured on this disk with lumped masses: P1 0.49 of
// the limit, the nodal-pressure element 0.35 -- its nodal averaging lowers omega_max, which the
// element estimate h / c does not see (0.44 on the 4k-66k disks, scripts/stable_step_margin.py);
// the default (nodal pressure, mass blend 1) 0.33 at rest, 0.32 at J = 0.7.
TEST(StableStep, LiesWithinTheCentralDifferenceLimitOfTheAssembledOperator) {
  const double cfl = 0.75;  // examples/baseline.json
  for (const bool nodal : {false, true})
    for (const double j : {1.0, 0.7}) {
      KernelFixture fx(mesh_disk_rings(90e-6, 300));
      const std::size_t nn = fx.mesh.node_count(), dofs = 2 * nn;
      const double stretch = std::sqrt(j);
      std::vector<double> x(nn), y(nn);
      for (std::size_t i = 0; i < nn; ++i)
        x[i] = stretch * fx.mesh.x[i], y[i] = stretch * fx.mesh.y[i];
      auto forces = [&](const std::vector<double>& px, const std::vector<double>& py,
                        KernelTotals* totals) { return dof_forces(fx, nodal, px, py, totals); };
      KernelTotals at_state;
      forces(x, y, &at_state);
      ASSERT_LT(at_state.bad_element, 0);
      const double dt = cfl * std::sqrt(at_state.min_step_sq);

      // K = -d(force)/d(position), a column per degree of freedom; perturbations of 1e-7 of the
      // element size keep the response linear (second-order error ~1e-14) and far above the
      // forces' round-off.
      const double h = 90e-6 / std::sqrt(fx.g.size() / 3.0), eps = 1e-7 * h;
      Eigen::MatrixXd k(dofs, dofs);
      for (std::size_t d = 0; d < dofs; ++d) {
        std::vector<double> xp = x, yp = y, xm = x, ym = y;
        (d % 2 ? yp : xp)[d / 2] += eps;
        (d % 2 ? ym : xm)[d / 2] -= eps;
        const std::vector<double> fp = forces(xp, yp, nullptr), fm = forces(xm, ym, nullptr);
        for (std::size_t r = 0; r < dofs; ++r) k(r, d) = -(fp[r] - fm[r]) / (2.0 * eps);
      }
      const std::vector<double> v0 = reference_nodal_areas(fx.g, nn);
      Eigen::VectorXd inv_sqrt_mass(dofs);
      for (std::size_t d = 0; d < dofs; ++d)
        inv_sqrt_mass(d) = 1.0 / std::sqrt(fx.p.rho0 * v0[d / 2]);
      const Eigen::MatrixXd a =
          inv_sqrt_mass.asDiagonal() * (0.5 * (k + k.transpose())) * inv_sqrt_mass.asDiagonal();
      // The mass blend's inverse mass is M_L^-1/2 (I + alpha S) M_L^-1/2, S = I - M_L^-1/2 M_C
      // M_L^-1/2 (integrator.hpp): omega^2 from C a C with C = (I + alpha S)^1/2, and the step
      // shortened by mass_blend_step_factor (1/2, and the default and largest, 1). The
      // factor rests on the bound omega_max <= sqrt(1 + 3 alpha / 4) x the lumped one, checked too
      // (measured: P1 1.155 at alpha = 1/2, where the bound is 1.169; 1/sqrt(1 + alpha / 4) fails;
      // the nodal-pressure element 1.23 at alpha = 1, bound 1.32).
      Eigen::MatrixXd consistent = Eigen::MatrixXd::Zero(dofs, dofs);
      const std::vector<double> weight = consistent_mass_weights(fx.g, fx.p.rho0);
      for (std::size_t e = 0; e < fx.g.size(); ++e) {
        const int32_t n[3] = {fx.g.node0[e], fx.g.node1[e], fx.g.node2[e]};
        const double w = weight[e];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c)
            for (int axis = 0; axis < 2; ++axis)
              consistent(2 * n[r] + axis, 2 * n[c] + axis) += (r == c ? 2.0 : 1.0) * w;
      }
      const Eigen::MatrixXd s =
          Eigen::MatrixXd::Identity(dofs, dofs) -
          inv_sqrt_mass.asDiagonal() * consistent * inv_sqrt_mass.asDiagonal();
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> s_eigen(s);
      double lumped_limit = 0;
      for (const double alpha : {0.0, 0.5, 1.0}) {
        const Eigen::VectorXd root = (1.0 + alpha * s_eigen.eigenvalues().array()).sqrt();
        const Eigen::MatrixXd c =
            s_eigen.eigenvectors() * root.asDiagonal() * s_eigen.eigenvectors().transpose();
        const double omega_sq =
            Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(c * a * c, Eigen::EigenvaluesOnly)
                .eigenvalues()
                .maxCoeff();
        const double limit = 2.0 / std::sqrt(omega_sq);
        if (alpha == 0.0) lumped_limit = limit;
        EXPECT_GE(limit, (1 - 1e-9) * lumped_limit * mass_blend_step_factor(alpha))
            << (nodal ? "nodal pressure" : "P1") << ", J = " << j << ", mass blend " << alpha;
        const double dt_alpha = dt * mass_blend_step_factor(alpha);
        EXPECT_LT(dt_alpha, limit)
            << (nodal ? "nodal pressure" : "P1") << ", J = " << j << ", mass blend " << alpha;
        std::printf(
            "stable step, %s, J = %.1f, mass blend %.1f: dt = %.3g s, limit 2/omega_max = %.3g s "
            "(%.2f)\n",
            nodal ? "average nodal pressure" : "plain P1", j, alpha, dt_alpha, limit,
            dt_alpha / limit);
      }
    }
}

// The damped limit, for the scheme itself. With a viscosity the step's stability is that of the
// integrator's map (simulation.cpp: velocity Verlet, i.e. central differences, whose viscous
// stress sees the rate (F - F_prev) / dt over the step), linearised at rest:
//   x_n+1 = 2 x_n - x_n-1 - dt^2 M^-1 (K x_n + C (x_n - x_n-1) / dt).
// K and C are assembled from central differences of the kernel's forces: K with dt = 0 (no viscous
// stress), K + C / tau after a step tau from rest. At the solver's step (cfl 0.75; the stable step
// with eta in it) the map's spectral radius must stay at 1 (the free disk's rigid modes sit there,
// as a Jordan block whose computed eigenvalues move by ~sqrt(round-off) ~ 1e-8). eta = 1, 30 and
// 1000 Pa s on a 300-element disk put the viscous speed 4 eta / (3 rho h) at 0.1, 3 and 100 times
// the sound speed: elastic-, mixed- and viscosity-limited steps. Measured: radius 1 + 1e-8 in all
// six cases; P1 at eta = 1 goes unstable between 2.0 and 2.4 times the step (the elastic margin),
// the others are still stable at 2.8 times (the viscous estimate h^2 rho / (2 nu_l), with the
// smallest altitude for h, is that conservative). Without the viscous term in the step the radius
// is 4.4-5.0 at eta = 30 and ~180 at eta = 1000.
TEST(StableStep, KeepsTheDampedOneStepMapStableWithThePhysicalViscosity) {
  const double cfl = 0.75;
  for (const bool nodal : {false, true})
    for (const double eta : {1.0, 30.0, 1000.0}) {
      KernelFixture fx(mesh_disk_rings(90e-6, 300));
      fx.p.viscosity = false;  // the physical viscosity alone (the artificial one is not linear)
      fx.p.eta = eta;
      const std::size_t nn = fx.mesh.node_count(), dofs = 2 * nn;
      const std::vector<double> x(fx.mesh.x.begin(), fx.mesh.x.end()),
          y(fx.mesh.y.begin(), fx.mesh.y.end());
      // Forces at (px, py) after a step of length tau from rest (tau = 0: elastic only).
      auto forces = [&](const std::vector<double>& px, const std::vector<double>& py, double tau,
                        KernelTotals* totals) {
        fx.s.reset_to_reference();  // F_prev = I: the step starts at rest
        fx.p.dt = tau;
        return dof_forces(fx, nodal, px, py, totals);
      };
      KernelTotals at_rest;
      forces(x, y, 0.0, &at_rest);
      const double dt = cfl * std::sqrt(at_rest.min_step_sq);

      const double h = 90e-6 / std::sqrt(fx.g.size() / 3.0), eps = 1e-7 * h;
      Eigen::MatrixXd k(dofs, dofs), c(dofs, dofs);
      for (std::size_t d = 0; d < dofs; ++d) {
        std::vector<double> xp = x, yp = y, xm = x, ym = y;
        (d % 2 ? yp : xp)[d / 2] += eps;
        (d % 2 ? ym : xm)[d / 2] -= eps;
        const std::vector<double> ep = forces(xp, yp, 0.0, nullptr),
                                  em = forces(xm, ym, 0.0, nullptr);
        const std::vector<double> vp = forces(xp, yp, dt, nullptr),
                                  vm = forces(xm, ym, dt, nullptr);
        for (std::size_t r = 0; r < dofs; ++r) {
          k(r, d) = -(ep[r] - em[r]) / (2.0 * eps);
          c(r, d) = -dt * ((vp[r] - vm[r]) - (ep[r] - em[r])) / (2.0 * eps);
        }
      }
      const std::vector<double> v0 = reference_nodal_areas(fx.g, nn);
      Eigen::VectorXd inv_mass(dofs);
      for (std::size_t d = 0; d < dofs; ++d) inv_mass(d) = 1.0 / (fx.p.rho0 * v0[d / 2]);
      // On (x_n, x_n-1), with Kh = dt^2 M^-1 K and Ch = dt M^-1 C (all blocks O(1)).
      const Eigen::MatrixXd kh = dt * dt * (inv_mass.asDiagonal() * k),
                            ch = dt * (inv_mass.asDiagonal() * c);
      const Eigen::MatrixXd id = Eigen::MatrixXd::Identity(dofs, dofs);
      Eigen::MatrixXd map(2 * dofs, 2 * dofs);
      map << 2.0 * id - kh - ch, ch - id, id, Eigen::MatrixXd::Zero(dofs, dofs);
      const double radius =
          Eigen::EigenSolver<Eigen::MatrixXd>(map, false).eigenvalues().cwiseAbs().maxCoeff();
      EXPECT_LT(radius, 1.0 + 1e-6) << (nodal ? "nodal pressure" : "P1") << ", eta " << eta;
      std::printf("damped one-step map, %s, eta = %g Pa s: dt = %.3g s, spectral radius %.9f\n",
                  nodal ? "average nodal pressure" : "plain P1", eta, dt, radius);
    }
}

}  // namespace
}  // namespace softshock
