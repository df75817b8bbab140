// The linear tetrahedron (Tet4) with average nodal pressure (issue 32, verification item 5): patch
// tests (affine motion: no interior force, J_a = J_e, no stabilisation force; the analytic
// uniaxial stress), balance of forces and moments, f = -dW/dx by finite differences, a large
// rigid rotation without stress, the stabilisation's control of the element-volume modes the
// nodal pressure leaves free (counted from the stiffness's eigenvalues), the consistent-mass
// blend's element operator, the follower pressure on a closed surface, and energy conservation of
// whole runs.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include "solver/continuum.hpp"
#include "solver/element_traits.hpp"
#include "solver/simulation.hpp"
#include "solver/tet4_kernels.hpp"
#include "solver/tet4_passes.hpp"
#include "tests/solver/tet_box.hpp"

namespace softshock {
namespace {

using Vec3 = std::array<double, 3>;

// The element passes at given positions, by hand (what ExplicitStep does for one thread).
struct Tet4Fixture {
  Mesh mesh;
  Tet4Geometry g;
  KernelParams p;
  double beta = 0.01;  // stabilisation, fraction of kappa
  std::vector<double> volume0;

  explicit Tet4Fixture(int n = 3, double size = 3e-6)
      : mesh(testing::tet_box(size, size, size, n, n, n)), g(build_tet4_geometry(mesh)) {
    p.kappa = 2e9, p.tait_n = 7.15, p.mu = 5e3, p.rho0 = 1000;
    p.c1 = 1.0, p.c2 = 0.1, p.ramp_inv = 5.0;
    p.nodal_pressure = true;
    p.element_weight = 0.0;
    volume0 = reference_nodal_volumes(g, mesh.node_count());
  }
  std::size_t nodes() const { return mesh.node_count(); }

  // x = F X + c, every node.
  NodalVector<3> affine(const continuum::Mat3& f, const Vec3& shift = {0, 0, 0}) const {
    NodalVector<3> x;
    for (auto& c : x) c.resize(nodes());
    for (std::size_t i = 0; i < nodes(); ++i) {
      const double X[3] = {mesh.x[i], mesh.y[i], mesh.z[i]};
      for (int r = 0; r < 3; ++r)
        x[r][i] = f[3 * r] * X[0] + f[3 * r + 1] * X[1] + f[3 * r + 2] * X[2] + shift[r];
    }
    return x;
  }

  struct Result {
    std::vector<Vec3> force;  // on the nodes (= -f_int), N
    std::vector<double> nodal_j, j_element, s_element;
    KernelTotals totals;
    double stored_energy = 0;  // elements' + nodes', J
  };
  // Forces at positions x (dt = 0: no viscosity; the state's F stays the reference).
  Result evaluate(const NodalVector<3>& x) const {
    const std::size_t nn = nodes(), ne = g.size();
    std::vector<PackedNode3> rows(nn);
    pack_positions(x[0].data(), x[1].data(), x[2].data(), 0, nn, rows.data());
    Result r;
    r.nodal_j.resize(nn), r.j_element.resize(ne), r.s_element.assign(ne, 0.0);
    KernelParams q = p;
    q.dt = 0, q.sample = true;
    if (p.nodal_pressure) {
      std::vector<double> volume(nn, 0.0), sm(nn), k(nn), qsum(nn, 0.0);
      accumulate_nodal_volumes(g, rows.data(), 0, ne, volume.data(), r.j_element.data());
      const StoredEnergySum energy{1.0 - p.element_weight, &r.totals.nodal_energy};
      nodal_tait_state(p.kappa, p.tait_n, volume0.data(), volume.data(), 0, nn, r.nodal_j.data(),
                       sm.data(), k.data(), energy);
      accumulate_stabilization(g, beta * p.kappa, r.nodal_j.data(), r.j_element.data(), 0, ne,
                               r.s_element.data(), qsum.data(), energy);
      subtract_stabilization(volume0.data(), qsum.data(), k.data(), 0, nn, sm.data(), rows.data());
      q.element_stress_shift = r.s_element.data();
      q.stabilization_beta_kappa = beta * p.kappa;
    }
    Tet4State state;
    state.resize(ne);
    std::vector<NodeForce3> force(nn);
    compute_tet4_forces(g, rows.data(), q, 0, ne, state, r.totals, force.data());
    r.force.resize(nn);
    for (std::size_t i = 0; i < nn; ++i)
      r.force[i] = {force[i].lanes[0], force[i].lanes[1], force[i].lanes[2]};
    r.stored_energy = r.totals.element_energy + r.totals.nodal_energy;
    return r;
  }

  bool on_boundary(std::size_t i, double size) const {
    const double tol = 1e-9 * size;
    for (double c : {mesh.x[i], mesh.y[i], mesh.z[i]})
      if (c < tol || c > size - tol) return true;
    return false;
  }
};

double norm(const Vec3& v) {
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

// Uniform F: every interior node's force vanishes (its elements' stresses are equal and their
// gradients sum to zero around it), nodal J equals element J equals det F, and the stabilisation
// stress s_e vanishes (Jbar_e = J_e).
TEST(Tet4, AffineMotionGivesNoInteriorForceNodalJEqualToElementJ) {
  Tet4Fixture fx(4, 4e-6);
  fx.p.mu = 3e8;  // a shear modulus comparable to kappa exercises the deviatoric part
  const continuum::Mat3 f{1.04, 0.02, -0.01, 0.015, 0.97, 0.03, -0.02, 0.01, 1.02};
  const double j = continuum::det(f);
  const auto r = fx.evaluate(fx.affine(f, {1e-6, -2e-6, 3e-7}));
  double boundary_scale = 0;
  for (std::size_t i = 0; i < fx.nodes(); ++i)
    if (fx.on_boundary(i, 4e-6)) boundary_scale = std::max(boundary_scale, norm(r.force[i]));
  ASSERT_GT(boundary_scale, 0);
  for (std::size_t i = 0; i < fx.nodes(); ++i) {
    if (!fx.on_boundary(i, 4e-6)) {
      EXPECT_LT(norm(r.force[i]), 1e-12 * boundary_scale) << i;
    }
    EXPECT_NEAR(r.nodal_j[i], j, 1e-14) << i;
  }
  for (std::size_t e = 0; e < fx.g.size(); ++e) {
    EXPECT_NEAR(r.j_element[e], j, 1e-14) << e;
    EXPECT_LT(std::fabs(r.s_element[e]), 1e-13 * fx.beta * fx.p.kappa) << e;
  }
}

// Uniaxial strain F = diag(lambda, 1, 1): the face x = L carries the first Piola stress P_xx =
// sigma_xx = sigma_m(J) + (2 mu / 3) J^(-5/3) (J^2 - 1), J = lambda (the uniaxial-strain shock's
// p(J), issue 32), summed over the face's nodes, for the nodal (ANP) and the plain element.
TEST(Tet4, UniaxialStrainGivesTheAnalyticStress) {
  for (const bool nodal : {true, false}) {
    Tet4Fixture fx(3, 3e-6);
    fx.p.mu = 2e8;
    fx.p.nodal_pressure = nodal;
    const double lambda = 0.85;
    const auto r = fx.evaluate(fx.affine({lambda, 0, 0, 0, 1, 0, 0, 0, 1}));
    const double kappa = fx.p.kappa, n = fx.p.tait_n, mu = fx.p.mu, jj = lambda;
    const double sigma_xx = kappa / n * (1 - std::pow(jj, -n)) +
                            2.0 * mu / 3.0 * std::pow(jj, -5.0 / 3.0) * (jj * jj - 1.0);
    double fx_sum = 0;
    for (std::size_t i = 0; i < fx.nodes(); ++i)
      if (fx.mesh.x[i] > 3e-6 * (1 - 1e-9)) fx_sum += r.force[i][0];
    // The face's area is 9e-12 m^2; the force on it is -P_xx A0 (tension pulls it back).
    EXPECT_NEAR(fx_sum / (-9e-12), sigma_xx, 1e-12 * std::fabs(sigma_xx)) << nodal;
  }
}

// Internal forces are equilibrated: sum f = 0 and sum x cross f = 0 for any state.
TEST(Tet4, ForcesBalanceAndCarryNoMoment) {
  Tet4Fixture fx(3, 3e-6);
  fx.p.mu = 1e8;
  auto x = fx.affine({1.02, 0.05, 0, -0.03, 0.98, 0.01, 0.02, 0, 1.01});
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> jitter(-5e-8, 5e-8);
  for (auto& c : x)
    for (double& v : c) v += jitter(rng);
  const auto r = fx.evaluate(x);
  Vec3 sum{0, 0, 0}, moment{0, 0, 0};
  double scale = 0;
  for (std::size_t i = 0; i < fx.nodes(); ++i) {
    const auto& f = r.force[i];
    for (int c = 0; c < 3; ++c) sum[c] += f[c];
    moment[0] += x[1][i] * f[2] - x[2][i] * f[1];
    moment[1] += x[2][i] * f[0] - x[0][i] * f[2];
    moment[2] += x[0][i] * f[1] - x[1][i] * f[0];
    scale += norm(f);
  }
  EXPECT_LT(norm(sum), 1e-13 * scale);
  EXPECT_LT(norm(moment), 1e-13 * scale * 3e-6);
}

// The forces are the exact gradient of the stored energy (elements' deviatoric, nodes' Tait,
// elements' stabilisation): -dW/dx by central differences, relative error O(h^2).
TEST(Tet4, ForceIsMinusTheGradientOfTheStoredEnergy) {
  for (const double weight : {0.0, 0.4}) {
    Tet4Fixture fx(2, 2e-6);
    fx.p.mu = 4e8;
    fx.p.element_weight = weight;
    auto x = fx.affine({0.95, 0.04, 0, 0, 1.03, -0.02, 0.01, 0, 0.99});
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> jitter(-4e-8, 4e-8);
    for (auto& c : x)
      for (double& v : c) v += jitter(rng);
    const auto r = fx.evaluate(x);
    const double h = 1e-11;
    for (std::size_t i : {std::size_t{0}, std::size_t{13}, std::size_t{26}}) {
      for (int c = 0; c < 3; ++c) {
        auto plus = x, minus = x;
        plus[c][i] += h, minus[c][i] -= h;
        const double dw =
            (fx.evaluate(plus).stored_energy - fx.evaluate(minus).stored_energy) / (2 * h);
        EXPECT_NEAR(r.force[i][c], -dw, 1e-6 * std::max(std::fabs(dw), 1e-3))
            << "node " << i << " component " << c << " weight " << weight;
      }
    }
  }
}

// F = R (60 degrees about an oblique axis) plus a translation: no stress, so no force beyond the
// round-off in J (~1e-16 kappa).
TEST(Tet4, LargeRigidRotationGivesNoStress) {
  Tet4Fixture fx(3, 3e-6);
  fx.p.mu = 3e8;
  const double th = std::numbers::pi / 3;
  Vec3 axis{1, 2, 2};
  for (double& a : axis) a /= 3.0;
  const double c = std::cos(th), s = std::sin(th), t = 1 - c;
  const double x = axis[0], y = axis[1], z = axis[2];
  const continuum::Mat3 rot{t * x * x + c,     t * x * y - s * z, t * x * z + s * y,
                            t * x * y + s * z, t * y * y + c,     t * y * z - s * x,
                            t * x * z - s * y, t * y * z + s * x, t * z * z + c};
  const auto r = fx.evaluate(fx.affine(rot, {2e-6, -1e-6, 5e-6}));
  // A stress of 1e-6 kappa on an element face (~1e-12 m^2) would give ~2e-3 N.
  for (std::size_t i = 0; i < fx.nodes(); ++i) EXPECT_LT(norm(r.force[i]), 1e-12 * 2e9 * 1e-12);
  EXPECT_NEAR(r.stored_energy, 0.0, 1e-12 * 2e9 * 27e-18);
}

// The element-volume modes (issue 32: ANP tetrahedra have more per node than triangles). With
// mu = 0 the stiffness is volumetric only, so its zero-energy modes are the motions that keep what
// the element constrains. Average nodal pressure alone constrains one volume per node: its zero
// modes are the null space of the nodal volumes' Jacobian, at least DOF - nodes = 2 per node
// (triangles: 1). The stabilisation constrains each element's volume as well: what is left is the
// null space of the element volumes' Jacobian -- the isochoric motions plain P1 allows too. Both
// counted from the eigenvalues of the finite-difference stiffness and checked against the ranks.
TEST(Tet4, StabilisationControlsTheElementVolumeModes) {
  Tet4Fixture fx(3, 3e-6);
  fx.p.mu = 0.0;
  const std::size_t nn = fx.nodes(), ne = fx.g.size(), dof = 3 * nn;
  const auto x0 = fx.affine({1, 0, 0, 0, 1, 0, 0, 0, 1});
  const double h = 1e-12;
  // Stiffness (beta given) and the Jacobians of the nodal and element volumes, by differences.
  auto analyse = [&](double beta, Eigen::MatrixXd* nodal_volumes, Eigen::MatrixXd* volumes) {
    fx.beta = beta;
    Eigen::MatrixXd k(dof, dof);
    if (nodal_volumes) nodal_volumes->resize(nn, dof), volumes->resize(ne, dof);
    for (std::size_t j = 0; j < dof; ++j) {
      auto plus = x0, minus = x0;
      plus[j % 3][j / 3] += h, minus[j % 3][j / 3] -= h;
      const auto fp = fx.evaluate(plus), fm = fx.evaluate(minus);
      for (std::size_t i = 0; i < dof; ++i)
        k(i, j) = -(fp.force[i / 3][i % 3] - fm.force[i / 3][i % 3]) / (2 * h);
      if (!nodal_volumes) continue;
      for (std::size_t a = 0; a < nn; ++a)
        (*nodal_volumes)(a, j) = (fp.nodal_j[a] - fm.nodal_j[a]) * fx.volume0[a] / (2 * h);
      for (std::size_t e = 0; e < ne; ++e)
        (*volumes)(e, j) = (fp.j_element[e] - fm.j_element[e]) * fx.g.volume0[e] / (2 * h);
    }
    const Eigen::VectorXd ev =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (k + k.transpose())).eigenvalues();
    const double largest = ev.cwiseAbs().maxCoeff();
    int zero = 0;
    for (Eigen::Index a = 0; a < ev.size(); ++a) zero += std::fabs(ev[a]) < 1e-7 * largest;
    return zero;
  };
  auto null_space = [&](const Eigen::MatrixXd& jacobian) {
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(jacobian);
    const auto sv = svd.singularValues();
    int rank = 0;
    for (Eigen::Index a = 0; a < sv.size(); ++a) rank += sv[a] > 1e-9 * sv[0];
    return static_cast<int>(dof) - rank;
  };
  Eigen::MatrixXd nodal_volumes, volumes;
  const int free_modes = analyse(0.0, &nodal_volumes, &volumes);
  const int stabilised_modes = analyse(0.01, nullptr, nullptr);
  const int nodal_null = null_space(nodal_volumes), element_null = null_space(volumes);
  std::printf(
      "%zu nodes, %zu DOF: %d zero-energy modes with nodal pressure alone, %d stabilised "
      "(the isochoric motions)\n",
      nn, dof, free_modes, stabilised_modes);
  EXPECT_EQ(free_modes, nodal_null);
  EXPECT_EQ(stabilised_modes, element_null);
  EXPECT_GE(nodal_null, static_cast<int>(2 * nn));  // 64 nodes, 192 DOF
  // The modes only the stabilisation controls: element volumes changing under fixed nodal ones.
  EXPECT_GE(nodal_null - element_null, static_cast<int>(nn) / 2);
  fx.p.nodal_pressure = false;  // plain P1 leaves the same isochoric motions
  EXPECT_EQ(analyse(0.0, nullptr, nullptr), element_null);
}

// The mass blend's element operator S = M_L^-1 (M_L - M_C) on one tetrahedron: eigenvalues 0 (a
// uniform field: momentum unchanged) and 4/5, so the blended step shrinks by 1/sqrt(1 + 0.8 alpha).
TEST(Tet4, ConsistentMassBlendOperator) {
  const Mesh one = [] {
    Mesh m;
    m.x = {0, 1e-6, 0, 0}, m.y = {0, 0, 1e-6, 0}, m.z = {0, 0, 0, 1e-6};
    m.tetrahedra = {{0, 1, 2, 3}};
    return m;
  }();
  const Tet4Geometry g = build_tet4_geometry(one);
  const auto weight = consistent_mass_weights(g, 1000.0);
  const double lumped = 1000.0 * g.volume0[0] / 4.0;
  Eigen::Matrix4d s;
  for (int j = 0; j < 4; ++j) {
    std::vector<NodeForce3> a(4), diff(4);  // rows (x, y, z, 0)
    a[j].lanes[0] = 1.0;
    accumulate_consistent_mass_difference(g, weight.data(), a.data(), 0, 1, diff.data());
    for (int i = 0; i < 4; ++i) s(i, j) = -diff[i].lanes[0] / lumped;  // (M_L - M_C) a / m
  }
  Eigen::Vector4d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d>(s).eigenvalues();
  EXPECT_NEAR(ev[0], 0.0, 1e-14);
  for (int k = 1; k < 4; ++k) EXPECT_NEAR(ev[k], 0.8, 1e-14);
  EXPECT_NEAR(tet4_mass_blend_step_factor(1.0), 1.0 / std::sqrt(1.8), 1e-15);
}

// A uniform follower pressure on a closed surface has no resultant (sum of the faces' area
// vectors is zero), and on a face of the deformed box it is p times that face's current area.
TEST(Tet4, FollowerPressureOnFacesFollowsTheCurrentArea) {
  Tet4Fixture fx(3, 3e-6);
  NodalArrays<3> s;
  const auto x = fx.affine({1.1, 0.05, 0, 0, 0.9, 0, 0, 0, 1.2});
  s.x = x;
  NodalVector<3> fext;
  for (auto& c : fext) c.assign(fx.nodes(), 0.0);
  const double p = 1e9;
  for (const auto& f : fx.mesh.boundary_faces) Tet4::add_follower_pressure(f, p, s, fext);
  Vec3 total{0, 0, 0};
  double scale = 0, on_top = 0;
  for (std::size_t i = 0; i < fx.nodes(); ++i) {
    for (int c = 0; c < 3; ++c) total[c] += fext[c][i];
    scale += std::fabs(fext[2][i]);
    if (fx.mesh.z[i] > 3e-6 * (1 - 1e-9)) on_top += fext[2][i];
  }
  EXPECT_LT(norm(total), 1e-13 * scale);
  // The top z = 3 um maps to z = 3.6 um with in-plane area (1.1 * 0.9) 9e-12; its normal stays
  // +z (F's third column is (0, 0, 1.2)): force -p A in z, pushing down. Edge nodes also carry
  // the side faces' share, which has no z component (their normals have none).
  EXPECT_NEAR(on_top, -p * 1.1 * 0.9 * 9e-12, 1e-9 * p * 9e-12);
}

// The element loop runs W tetrahedra at a time; a range that starts or ends inside such a group
// (a thread's share, a single element) must give what one call over all the elements gives: the
// same forces on every node (added in element order either way), the same state, the same
// smallest step and the element that sets it. With the lagged viscosity on (dt > 0) and the
// state of an earlier evaluation, so that every term runs.
TEST(Tet4, RangesSplitInsideAGroupGiveTheWholeRangesResult) {
  Tet4Fixture fx(3, 3e-6);  // 162 tetrahedra
  fx.p.mu = 1e8, fx.p.eta = 0.25, fx.p.dt = 1e-12;
  fx.p.nodal_pressure = false;  // no nodal state needed in the rows
  const std::size_t nn = fx.nodes(), ne = fx.g.size();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> jitter(-5e-8, 5e-8);
  auto rows_at = [&](double scale) {
    auto x = fx.affine({1.02, 0.05, 0, -0.03, 0.98, 0.01, 0.02, 0, 1.01});
    for (auto& c : x)
      for (double& v : c) v += scale * jitter(rng);
    std::vector<PackedNode3> rows(nn);
    pack_positions(x[0].data(), x[1].data(), x[2].data(), 0, nn, rows.data());
    return rows;
  };
  const auto before = rows_at(1.0), now = rows_at(1.0);
  Tet4State start;
  start.resize(ne);
  {
    KernelTotals unused;
    std::vector<NodeForce3> force(nn);
    compute_tet4_forces(fx.g, before.data(), fx.p, 0, ne, start, unused, force.data());
  }
  auto evaluate = [&](const std::vector<std::size_t>& cuts, Tet4State& state, KernelTotals& t) {
    std::vector<NodeForce3> force(nn);
    for (std::size_t k = 0; k + 1 < cuts.size(); ++k)
      compute_tet4_forces(fx.g, now.data(), fx.p, cuts[k], cuts[k + 1], state, t, force.data());
    return force;
  };
  Tet4State whole_state = start;
  KernelTotals whole;
  const auto whole_force = evaluate({0, ne}, whole_state, whole);
  ASSERT_GE(whole.min_step_element, 0);
  for (const std::vector<std::size_t>& cuts : std::vector<std::vector<std::size_t>>{
           {0, 1, ne}, {0, 3, 77, ne}, {0, 13, 14, 15, ne - 5, ne}, {0, 9, 64, 100, 141, ne}}) {
    Tet4State state = start;
    KernelTotals split;
    const auto force = evaluate(cuts, state, split);
    for (std::size_t i = 0; i < nn; ++i)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(force[i].lanes[c], whole_force[i].lanes[c]) << i;
    EXPECT_EQ(state.f, whole_state.f);
    EXPECT_EQ(state.pv, whole_state.pv);
    EXPECT_EQ(split.min_step_sq, whole.min_step_sq);
    EXPECT_EQ(split.min_step_element, whole.min_step_element);
    EXPECT_NEAR(split.dissipation, whole.dissipation, 1e-14 * std::fabs(whole.dissipation));
  }
}

// Whole runs (ExplicitStep + run loop) without viscosity conserve energy to the integrator's
// order: a box set moving with a smooth initial velocity, lumped and blended mass, average nodal
// pressure and plain P1. Central differences keep K + W bounded, off by O(dt^2) (measured: 1.3e-2,
// 2.5e-3, 6.1e-4, 1.5e-4 at cfl 0.5, 0.25, 0.125, 0.0625 for P1 lumped): halving the step must
// divide the largest departure by ~4.
TEST(Tet4, FreeVibrationConservesEnergyToSecondOrder) {
  for (const double blend : {0.0, 1.0}) {
    for (const auto formulation :
         {ElementFormulation::kAverageNodalPressure, ElementFormulation::kP1}) {
      auto departure = [&](double cfl) {
        Problem problem;
        problem.mesh = testing::tet_box(4e-6, 4e-6, 4e-6, 4, 4, 4);
        problem.material.shear_modulus_Pa = 2e8;
        problem.viscosity.enabled = false;
        problem.material.shear_viscosity_Pa_s = 0.0;
        problem.element.formulation = formulation;
        problem.element.mass_blend = blend;
        problem.load.pressure_Pa = 0.0;
        problem.load_all_boundary = false;
        const std::size_t nn = problem.mesh.node_count();
        for (auto* v : {&problem.initial_vx, &problem.initial_vy, &problem.initial_vz})
          v->resize(nn);
        for (std::size_t i = 0; i < nn; ++i) {
          const double X = problem.mesh.x[i] / 4e-6, Y = problem.mesh.y[i] / 4e-6,
                       Z = problem.mesh.z[i] / 4e-6;
          problem.initial_vx[i] = 5.0 * std::sin(std::numbers::pi * X) * Y;
          problem.initial_vy[i] = -3.0 * std::sin(std::numbers::pi * Y) * Z;
          problem.initial_vz[i] = 4.0 * std::sin(std::numbers::pi * Z) * X;
        }
        SolverOptions options;
        options.end_time_s = 20e-9;  // ~ 7 wave transits of the box
        options.history_interval_s = 0.5e-9;
        options.output_interval_s = 0;
        options.cfl = cfl;
        const RunResult r = run_simulation(problem, options);
        EXPECT_EQ(r.status, RunStatus::kCompleted) << r.error;
        const History& h = r.history;
        const double e0 = h.kinetic_energy[0] + h.elastic_energy[0];
        double worst = 0;
        for (std::size_t k = 0; k < h.size(); ++k)
          worst = std::max(worst, std::fabs(h.kinetic_energy[k] + h.elastic_energy[k] - e0) / e0);
        return worst;
      };
      const double coarse = departure(0.25), fine = departure(0.125);
      EXPECT_LT(fine, 2e-3) << "blend " << blend;
      EXPECT_GT(coarse / fine, 3.2) << "blend " << blend;
      EXPECT_LT(coarse / fine, 5.0) << "blend " << blend;
    }
  }
}

}  // namespace
}  // namespace softshock
