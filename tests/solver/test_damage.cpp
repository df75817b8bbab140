// Phase-field damage (solver/damage/, docs/model.md "Damage"): the damage equation's finite
// elements and solve against closed forms, and the damage pass's driver and degradation on
// homogeneous bars, for triangles (plane strain) and tetrahedra. Tolerances are stated with the
// theory that sets them; docs/verification.md, "Phase-field damage", has the figures.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "solver/continuum.hpp"
#include "solver/damage/damage_model.hpp"
#include "solver/damage/damage_pass.hpp"
#include "solver/damage/damage_solver.hpp"
#include "solver/element_kernels.hpp"
#include "solver/explicit_step.hpp"
#include "solver/mesh.hpp"
#include "solver/run_spec.hpp"
#include "solver/run_state.hpp"
#include "solver/simulation.hpp"
#include "solver/tet4_kernels.hpp"

namespace softshock::damage {
namespace {

// A thin bar [0, length] along x: one row of cells, h = length / cells on each side.
Mesh bar(int dim, double length, int cells) {
  const double h = length / cells;
  return dim == 2 ? make_rectangle_mesh(length, h, cells, 1)
                  : make_box_mesh(length, h, h, cells, 1, 1);
}
// Its cross-section (2-D: the height, per metre of thickness; 3-D: the area).
double section(int dim, double length, int cells) {
  const double h = length / cells;
  return dim == 2 ? h : h * h;
}
const std::vector<double>& coordinate(const Mesh& m, int c) {
  return c == 0 ? m.x : c == 1 ? m.y : m.z;
}

// ---- the 1-D optimal profile ------------------------------------------------------------------
// d(0) = 1 held, no flux at x = L, H = 0: d - l^2 d'' = 0 gives d = cosh((L - x)/l) / cosh(L/l),
// and the crack energy s/2 (d^2 + l^2 d'^2) integrates to (G_c / 2) tanh(L / l) per unit of
// section, G_c = s l (model 1's eps_f l, model 2's G). P1 elements with the lumped mass: the
// energy error is O((h/l)^2), about (h/l)^2 / 12 relative; the issue asks for 1 % at h/l = 0.2
// and first order or better.
struct ProfileError {
  double energy, profile;  // relative error of the energy; largest nodal |d - exact|
};

template <int dim>
ProfileError optimal_profile(const Coefficients& c, double length, int cells) {
  const Mesh mesh = bar(dim, length, cells);
  DamageSolver<dim> solver(mesh, c, DamageLinearSolver::kDirect);
  std::vector<int32_t> crack;
  for (std::size_t i = 0; i < mesh.node_count(); ++i)
    if (mesh.x[i] < 1e-9 * length) crack.push_back(static_cast<int32_t>(i));
  solver.fix(crack, 1.0);
  std::vector<double> d(mesh.node_count(), 0.0);
  const std::vector<double> h(mesh.element_count(), 0.0);
  solver.solve(h, 1.0, d);
  const double l = c.length_m;
  ProfileError e{0, 0};
  for (std::size_t i = 0; i < mesh.node_count(); ++i)
    e.profile = std::max(
        e.profile, std::fabs(d[i] - std::cosh((length - mesh.x[i]) / l) / std::cosh(length / l)));
  const double exact = 0.5 * c.fracture_energy_J_m2() * std::tanh(length / l);
  e.energy = (solver.crack_energy(d) / section(dim, length, cells) - exact) / exact;
  return e;
}

template <int dim>
void check_optimal_profile(const Coefficients& c) {
  const double l = c.length_m, length = 4 * l;
  ProfileError e[3];
  const int cells[3] = {10, 20, 40};  // h / l = 0.4, 0.2, 0.1
  for (int k = 0; k < 3; ++k) {
    e[k] = optimal_profile<dim>(c, length, cells[k]);
    std::printf("dim %d, h/l = %.2f: crack energy error %+.3e, profile error %.3e\n", dim,
                length / cells[k] / l, e[k].energy, e[k].profile);
  }
  EXPECT_LT(std::fabs(e[1].energy), 0.01);  // h / l = 0.2
  const double order = std::log2(std::fabs(e[1].energy / e[2].energy));
  std::printf("dim %d: observed order of the energy %.2f, of the profile %.2f\n", dim, order,
              std::log2(e[1].profile / e[2].profile));
  EXPECT_GE(order, 1.0);
  EXPECT_GE(std::log2(std::fabs(e[0].energy / e[1].energy)), 1.0);
  EXPECT_GE(std::log2(e[1].profile / e[2].profile), 1.0);
}

TEST(DamageSolver, OptimalProfileAndHalfCrackEnergyOnAStripOfTriangles) {
  Damage talamini;
  talamini.model = DamageModel::kTalamini, talamini.length_m = 5e-6, talamini.epsilon_f_Pa = 2e6;
  check_optimal_profile<2>(coefficients(talamini));
  Damage giovanardi;
  giovanardi.model = DamageModel::kGiovanardi, giovanardi.length_m = 2e-6;
  giovanardi.fracture_energy_J_m2 = 100;
  check_optimal_profile<2>(coefficients(giovanardi));
}

TEST(DamageSolver, OptimalProfileAndHalfCrackEnergyOnABarOfTetrahedra) {
  Damage giovanardi;
  giovanardi.model = DamageModel::kGiovanardi, giovanardi.length_m = 5e-6;
  check_optimal_profile<3>(coefficients(giovanardi));
}

// The iterative solver (incomplete Cholesky, conjugate gradients) gives the direct one's answer:
// to its relative residual 1e-10, so 1e-8 in d.
TEST(DamageSolver, IterativeSolveAgreesWithTheDirectOne) {
  Damage p;
  p.model = DamageModel::kTalamini, p.length_m = 3e-6, p.zeta_Pa_s = 1e-3;
  const Mesh mesh = make_rectangle_mesh(40e-6, 30e-6, 40, 30);
  DamageSolver<2> direct(mesh, coefficients(p), DamageLinearSolver::kDirect);
  DamageSolver<2> iterative(mesh, coefficients(p), DamageLinearSolver::kIterative);
  EXPECT_TRUE(direct.direct());
  EXPECT_FALSE(iterative.direct());
  std::vector<double> h(mesh.element_count(), 0.0);
  for (std::size_t e = 0; e < h.size(); ++e) {  // a spot of driving energy near one corner
    const auto& t = mesh.triangles[e];
    const double x = (mesh.x[t[0]] + mesh.x[t[1]] + mesh.x[t[2]]) / 3;
    const double y = (mesh.y[t[0]] + mesh.y[t[1]] + mesh.y[t[2]]) / 3;
    h[e] = 5e6 * std::exp(-((x - 10e-6) * (x - 10e-6) + (y - 8e-6) * (y - 8e-6)) / 4e-11);
  }
  std::vector<double> a(mesh.node_count(), 0.0), b = a;
  for (int step = 0; step < 3; ++step) {
    direct.solve(h, 1e-9, a);
    const auto report = iterative.solve(h, 1e-9, b);
    EXPECT_GT(report.iterations, 0);
    double worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::fabs(a[i] - b[i]));
    std::printf("step %d: %d iterations, largest |d_direct - d_iterative| %.2e, max d %.3f\n", step,
                report.iterations, worst, *std::max_element(a.begin(), a.end()));
    EXPECT_LT(worst, 1e-8);
  }
}

// ---- the damage ODE at a point ------------------------------------------------------------------
// A uniform H makes every node a point (K 1 = 0): zeta dd/dt + (s + 2H) d = 2H, whose solution from
// d = 0 is d_inf (1 - exp(-(2H + s) t / zeta)). Each solve must be exactly the backward Euler step
// (to round-off), and backward Euler converges to it at first order: the error halves with dt.
template <int dim>
void check_point_ode() {
  Damage p;
  p.model = DamageModel::kTalamini, p.length_m = 2e-6, p.epsilon_f_Pa = 2e6;
  p.zeta_Pa_s = 2e-3;  // tau = zeta / (2H + eps_f) = 0.5 ns at H = 1 MPa
  const Coefficients c = coefficients(p);
  const Mesh mesh = bar(dim, 10e-6, 5);
  const double h = 1e6, tau = c.zeta_Pa_s / (2 * h + c.s_Pa), end = 2 * tau;
  double errors[3];
  for (int k = 0; k < 3; ++k) {
    const int steps = 10 << k;
    const double dt = end / steps;
    DamageSolver<dim> solver(mesh, c, DamageLinearSolver::kDirect);
    std::vector<double> d(mesh.node_count(), 0.0);
    const std::vector<double> hs(mesh.element_count(), h);
    double recurrence = 0.0, worst_step = 0.0;
    for (int n = 0; n < steps; ++n) {
      solver.solve(hs, dt, d);
      recurrence = point_damage_step(recurrence, h, c.s_Pa, c.zeta_Pa_s, dt);
      for (double v : d) worst_step = std::max(worst_step, std::fabs(v - recurrence));
    }
    EXPECT_LT(worst_step, 1e-13) << "not the backward Euler step";
    errors[k] = std::fabs(d[0] - point_damage(h, c.s_Pa, c.zeta_Pa_s, end));
    std::printf("dim %d, dt = tau / %d: d(2 tau) = %.6f, exact %.6f, error %.3e\n", dim, steps / 2,
                d[0], point_damage(h, c.s_Pa, c.zeta_Pa_s, end), errors[k]);
  }
  for (int k = 0; k < 2; ++k) {
    const double ratio = errors[k] / errors[k + 1];
    EXPECT_GT(ratio, 1.8) << "first order: the error halves with dt";
    EXPECT_LT(ratio, 2.2);
  }
  // At dt = tau / 20 the first-order error, (dt / 2 tau) t e^(-t / tau) d_inf at t = 2 tau, is
  // within 2 % of d_inf.
  EXPECT_LT(errors[2] / homogeneous_damage(h, c.s_Pa), 0.02);
}

TEST(DamageSolver, DamageOdeAtAPointIsBackwardEulerAndConvergesAtFirstOrder) {
  check_point_ode<2>();
  check_point_ode<3>();
}

// ---- irreversibility --------------------------------------------------------------------------
// The damage never decreases, and the clamp that makes sure of it does bite: on a mesh of obtuse
// triangles K has positive off-diagonal entries, so a second spot of driving energy lowers the
// unprojected solution next to the first. A dense solve of the same system shows that it would.
TEST(DamageSolver, DamageNeverDecreasesEvenWhereTheUnprojectedSolveWould) {
  // A sheared grid: half its triangles have an angle of ~162 degrees, so K has positive
  // off-diagonal entries across their long edges.
  Mesh mesh = make_rectangle_mesh(4e-6, 4e-6, 4, 4);
  for (std::size_t i = 0; i < mesh.node_count(); ++i) mesh.x[i] += 3.0 * mesh.y[i];
  finalize_mesh(mesh);
  Damage p;
  p.model = DamageModel::kGiovanardi, p.length_m = 2e-6, p.fracture_energy_J_m2 = 2.0;
  const Coefficients c = coefficients(p);
  const std::size_t nn = mesh.node_count(), ne = mesh.element_count();
  DamageSolver<2> solver(mesh, c, DamageLinearSolver::kDirect);
  // The same system, dense and unprojected.
  auto unprojected = [&](const std::vector<double>& h) {
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(nn, nn);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(nn);
    for (std::size_t e = 0; e < ne; ++e) {
      const auto& n = solver.corners()[e];
      const double v = solver.element_volume(e);
      for (int i = 0; i < 3; ++i) {
        a(n[i], n[i]) += v / 3 * (c.s_Pa + 2 * h[e]);
        b(n[i]) += v / 3 * 2 * h[e];
        for (int j = 0; j < 3; ++j) {
          const auto &gi = solver.gradient(e, i), &gj = solver.gradient(e, j);
          a(n[i], n[j]) += c.gradient_N() * v * (gi[0] * gj[0] + gi[1] * gj[1]);
        }
      }
    }
    return Eigen::VectorXd(a.ldlt().solve(b));
  };
  const std::vector<double> uniform(ne, 1e6);  // d = 2/3 everywhere
  const Eigen::VectorXd before = unprojected(uniform);
  // One element driven hard: the first whose rise lowers a neighbour's unprojected d.
  std::vector<double> h;
  double lowest_free = 0.0;
  for (std::size_t k = 0; k < ne && lowest_free > -1e-3; ++k) {
    h = uniform, h[k] = 1e9;
    lowest_free = (unprojected(h) - before).minCoeff();
  }
  std::vector<double> d(nn, 0.0);
  solver.solve(uniform, 1.0, d);
  const std::vector<double> old = d;
  solver.solve(h, 1.0, d);
  double lowest = 0.0;
  for (std::size_t i = 0; i < nn; ++i) lowest = std::min(lowest, d[i] - old[i]);
  std::printf("largest decrease: unprojected %.3e, solver %.3e\n", -lowest_free, -lowest);
  EXPECT_LT(lowest_free, -1e-3) << "this case no longer tests the projection";
  EXPECT_EQ(lowest, 0.0);
  for (double v : d) EXPECT_LE(v, 1.0);
}

// ---- homogeneous bars through the damage pass ---------------------------------------------------
// A bar stretched quasi-statically and homogeneously, x = F X: the pass computes the driver, H and
// one damage solve per loading step (rate independent, zeta = 0), and its degradation forces
// added to the element loop's give the bar's stress, read as the end face's force over its area.
// The closed forms are those of a 1-D bar of modulus E with psi = E e^2 / 2:
//   model 2: d = E e^2 / (E e^2 + G / eps), peak stress (9/16) sqrt(E G / (3 eps)) at
//            e = sqrt(G / (3 eps E));
//   model 1: elastic until psi = eps_f / 2, then d = 1 - eps_f / (2 psi), peak stress
//            sqrt(E eps_f) at e = sqrt(eps_f / E).
// The gel maps onto it in uniaxial stress (lateral stretch with zero lateral stress, found by
// bisection on the law): E = 9 kappa mu / (3 kappa + mu) for the tetrahedra, and in plane strain
// (sigma_yy = 0, eps_zz = 0) E' = E / (1 - nu^2) for the triangles; J > 1 there, so the
// tension-only driver is the whole strain energy W_dev + W_vol, E e^2 / 2 to first order. The
// neo-Hookean and Tait laws differ from the linear bar at O(e): parameters put the peak at e* =
// 0.004, so the closed forms hold to ~e* (measured below) and the tolerances are 2 e*.
struct Bar {
  int dim;
  double kappa = 2e9, mu = 5e3, tait_n = 7.15;
  double young() const {
    const double e = 9 * kappa * mu / (3 * kappa + mu),
                 nu = (3 * kappa - 2 * mu) / (6 * kappa + 2 * mu);
    return dim == 3 ? e : e / (1 - nu * nu);
  }
  // The stretch tensor of uniaxial stress along x at strain e (the undamaged law; with J > 1 the
  // degradation scales the whole stress, so the lateral stress stays zero).
  std::vector<double> stretches(double e) const {
    namespace cm = continuum;
    auto lateral_stress = [&](double lambda) {
      if (dim == 2) {
        const cm::Mat2 f{1 + e, 0, 0, lambda};
        const double j = cm::det(f);
        const cm::Mat2 p = cm::elastic_piola(
            f, cm::cofactor(f), j, cm::tait_mean_stress(kappa, tait_n, std::pow(j, -tait_n)), mu,
            std::pow(j, -2.0 / 3.0));
        return p[3];
      }
      const cm::Mat3 f{1 + e, 0, 0, 0, lambda, 0, 0, 0, lambda};
      const double j = cm::det(f);
      const cm::Mat3 p = cm::elastic_piola(
          f, cm::cofactor(f), j, cm::tait_mean_stress(kappa, tait_n, std::pow(j, -tait_n)), mu,
          std::pow(j, -2.0 / 3.0));
      return p[4];
    };
    double lo = 0.9, hi = 1.0;  // lateral_stress(lo) < 0 < lateral_stress(hi) for e > 0
    for (int k = 0; k < 200; ++k) {
      const double mid = 0.5 * (lo + hi);
      (lateral_stress(mid) > 0 ? hi : lo) = mid;
    }
    std::vector<double> s(dim, 0.5 * (lo + hi));
    s[0] = 1 + e;
    return s;
  }
};

struct BarPoint {
  double strain, damage, stress;
};

// The loading path of a bar under the pass: d (every node, checked uniform) and the stress.
template <int dim>
std::vector<BarPoint> load_bar(const Bar& b, const Damage& damage, double max_strain, int points) {
  Problem problem;
  problem.mesh = bar(dim, 20e-6, 4);
  problem.material.bulk_modulus_Pa = b.kappa, problem.material.shear_modulus_Pa = b.mu;
  problem.material.tait_gamma = b.tait_n - 1;
  problem.element.formulation = ElementFormulation::kP1;
  problem.damage = damage;
  const Mesh& mesh = problem.mesh;
  const std::size_t nn = mesh.node_count();
  DamagePass<dim> pass(problem, nullptr);
  KernelParams params;
  params.kappa = b.kappa, params.tait_n = b.tait_n, params.mu = b.mu, params.rho0 = 1000;
  params.viscosity = false;  // dt = 0: no viscous stress either
  std::vector<BarPoint> path;
  std::array<std::vector<double>, dim> x;
  for (auto& c : x) c.resize(nn);
  for (int k = 1; k <= points; ++k) {
    const double e = max_strain * k / points;
    const std::vector<double> s = b.stretches(e);
    for (int c = 0; c < dim; ++c)
      for (std::size_t i = 0; i < nn; ++i) x[c][i] = s[c] * coordinate(mesh, c)[i];
    std::array<const double*, dim> positions;
    for (int c = 0; c < dim; ++c) positions[c] = x[c].data();
    pass.update(positions, nullptr);
    // The element loop's forces, then the pass's: their sum on the end face x = L.
    std::vector<double> fx(nn, 0.0);
    KernelTotals totals;
    if constexpr (dim == 2) {
      const ElementGeometry g = build_tri3_geometry(mesh);
      ElementState state;
      state.resize(mesh.element_count());
      std::vector<PackedNode> rows(nn);
      pack_positions(x[0].data(), x[1].data(), 0, nn, rows.data());
      std::vector<NodeForce> force(nn);
      compute_element_forces(g, rows.data(), params, 0, mesh.element_count(), state, totals,
                             force.data());
      pass.add_forces(0, mesh.element_count(), positions, force.data(), nullptr);
      for (std::size_t i = 0; i < nn; ++i) fx[i] = force[i].lanes[0];
    } else {
      const Tet4Geometry g = build_tet4_geometry(mesh);
      Tet4State state;
      state.resize(mesh.element_count());
      std::vector<PackedNode3> rows(nn);
      pack_positions(x[0].data(), x[1].data(), x[2].data(), 0, nn, rows.data());
      std::vector<NodeForce3> force(nn);
      compute_tet4_forces(g, rows.data(), params, 0, mesh.element_count(), state, totals,
                          force.data());
      pass.add_forces(0, mesh.element_count(), positions, force.data(), nullptr);
      for (std::size_t i = 0; i < nn; ++i) fx[i] = force[i].lanes[0];
    }
    double end_force = 0.0;
    for (std::size_t i = 0; i < nn; ++i)
      if (mesh.x[i] > 20e-6 * (1 - 1e-9)) end_force -= fx[i];  // the internal force pulls back
    const auto& d = pass.damage();
    const auto [lo, hi] = std::minmax_element(d.begin(), d.end());
    // Uniform to round-off: the Tait energy near J = 1 loses ~10 eps kappa / n ~ 6e-7 Pa to
    // cancellation, and dd/dH <= 2 / s.
    const double round_off = 10 * std::numeric_limits<double>::epsilon() * b.kappa / b.tait_n;
    EXPECT_LT(*hi - *lo, 2 * round_off / coefficients(damage).s_Pa)
        << "a homogeneous bar damages uniformly";
    path.push_back({e, *hi, end_force / section(dim, 20e-6, 4)});
  }
  return path;
}

// The largest stress on the path and its strain, refined by the parabola through its neighbours.
BarPoint peak(const std::vector<BarPoint>& path) {
  std::size_t k = 0;
  for (std::size_t i = 1; i < path.size(); ++i)
    if (path[i].stress > path[k].stress) k = i;
  if (k == 0 || k + 1 == path.size()) return path[k];
  const double a = path[k - 1].stress, b = path[k].stress, c = path[k + 1].stress;
  const double shift = 0.5 * (a - c) / (a - 2 * b + c), de = path[k + 1].strain - path[k].strain;
  return {path[k].strain + shift * de, path[k].damage, b - 0.25 * (a - c) * shift};
}

template <int dim>
void check_model_2_bar() {
  const Bar b{dim};
  const double e_star = 0.004, young = b.young();
  Damage p;
  p.model = DamageModel::kGiovanardi, p.length_m = 5e-6;
  p.fracture_energy_J_m2 = 3 * young * e_star * e_star * p.length_m;  // e* = sqrt(G / (3 eps E))
  const double g_over_eps = p.fracture_energy_J_m2 / p.length_m;
  const auto path = load_bar<dim>(b, p, 3 * e_star, 240);
  double worst = 0;  // |d - d(1-D)| <= d (1 - d) |dpsi / psi|, dpsi / psi = O(e) (-2e/3 for
                     // the incompressible neo-Hookean bar)
  for (const auto& q : path) {
    const double expected =
        young * q.strain * q.strain / (young * q.strain * q.strain + g_over_eps);
    worst = std::max(worst, std::fabs(q.damage - expected));
  }
  const BarPoint top = peak(path);
  const double stress = 9.0 / 16.0 * std::sqrt(young * p.fracture_energy_J_m2 / (3 * p.length_m));
  std::printf(
      "dim %d, model 2: d within %.2e of E e^2/(E e^2 + G/eps); peak %.5g Pa at "
      "e = %.5f (expected %.5g Pa at %.5f): %+.2e, %+.2e\n",
      dim, worst, top.stress, top.strain, stress, e_star, top.stress / stress - 1,
      top.strain / e_star - 1);
  EXPECT_LT(worst, 2 * 3 * e_star);  // the largest strain on the path is 3 e*
  EXPECT_NEAR(top.stress / stress, 1.0, 2 * e_star);
  EXPECT_NEAR(top.strain / e_star, 1.0, 2 * e_star + 0.01);  // + the sweep's spacing, 1 %
}

template <int dim>
void check_model_1_bar() {
  const Bar b{dim};
  const double e_star = 0.004, young = b.young();
  Damage p;
  p.model = DamageModel::kTalamini, p.length_m = 5e-6;
  p.epsilon_f_Pa = young * e_star * e_star;  // e* = sqrt(eps_f / E)
  const auto path = load_bar<dim>(b, p, 3 * e_star, 240);
  double worst = 0;  // |d - d(1-D)| = (1 - d) |dpsi / psi| = O(e), as for model 2
  for (const auto& q : path) {
    const double psi = 0.5 * young * q.strain * q.strain;
    if (q.strain < e_star * (1 - 2 * e_star)) {
      EXPECT_EQ(q.damage, 0.0) << "elastic below the threshold, e = " << q.strain;
      continue;
    }
    const double expected = std::max(0.0, 1 - p.epsilon_f_Pa / (2 * psi));
    worst = std::max(worst, std::fabs(q.damage - expected));
  }
  const BarPoint top = peak(path);
  const double stress = std::sqrt(young * p.epsilon_f_Pa);
  std::printf(
      "dim %d, model 1: d within %.2e of 1 - eps_f/(2 psi); peak %.5g Pa at "
      "e = %.5f (expected %.5g Pa at %.5f): %+.2e, %+.2e\n",
      dim, worst, top.stress, top.strain, stress, e_star, top.stress / stress - 1,
      top.strain / e_star - 1);
  EXPECT_LT(worst, 2 * 3 * e_star);
  EXPECT_NEAR(top.stress / stress, 1.0, 2 * e_star);
  EXPECT_NEAR(top.strain / e_star, 1.0, 2 * e_star + 0.0125);  // + the sweep's spacing
}

TEST(DamagePass, HomogeneousBarOfTrianglesFollowsTheOneDimensionalLaws) {
  check_model_2_bar<2>();
  check_model_1_bar<2>();
}

TEST(DamagePass, HomogeneousBarOfTetrahedraFollowsTheOneDimensionalLaws) {
  check_model_2_bar<3>();
  check_model_1_bar<3>();
}

// An update whose driving energy grew nowhere, with no rate term (zeta = 0), poses the last solve's
// system again, whose projected solution d already is: the pass skips it (damage_pass.cpp), and d
// stays as it was. With zeta > 0 the same configuration still moves d towards d_inf.
TEST(DamagePass, ASolveOnlyWhenTheDrivingEnergyGrowsOrTheRateTermActs) {
  const Bar b{2};
  Problem problem;
  problem.mesh = bar(2, 20e-6, 4);
  problem.material.bulk_modulus_Pa = b.kappa, problem.material.shear_modulus_Pa = b.mu;
  problem.material.tait_gamma = b.tait_n - 1;
  problem.element.formulation = ElementFormulation::kP1;
  const double e_star = 0.004;
  problem.damage.model = DamageModel::kTalamini;
  problem.damage.epsilon_f_Pa = b.young() * e_star * e_star;
  const std::size_t nn = problem.mesh.node_count();
  auto stretched = [&](double e, std::array<std::vector<double>, 2>& x) {
    const std::vector<double> s = b.stretches(e);
    for (int c = 0; c < 2; ++c) {
      x[c].resize(nn);
      for (std::size_t i = 0; i < nn; ++i) x[c][i] = s[c] * coordinate(problem.mesh, c)[i];
    }
    return std::array<const double*, 2>{x[0].data(), x[1].data()};
  };
  std::array<std::vector<double>, 2> x;
  // zeta / dt = eps_f: at 2 e*, 2H = 3 eps_f, so d = 0.6 after one step and 0.72 after two.
  for (double zeta : {0.0, problem.damage.epsilon_f_Pa * 1e-9}) {
    problem.damage.zeta_Pa_s = zeta;
    DamagePass<2> pass(problem, nullptr);
    const auto loaded = stretched(2 * e_star, x);
    pass.advance(1e-9), pass.update(loaded, nullptr);
    ASSERT_EQ(pass.solves(), 1);
    const std::vector<double> first = pass.damage();
    ASSERT_GT(first[0], 0.5);
    pass.advance(1e-9), pass.update(loaded, nullptr);  // the same configuration
    const auto unloaded = stretched(e_star, x);
    pass.advance(1e-9), pass.update(unloaded, nullptr);  // H is a maximum: unloading leaves it
    if (zeta == 0) {
      EXPECT_EQ(pass.solves(), 1) << "no H grew and zeta = 0: nothing to solve";
      EXPECT_EQ(pass.damage(), first);
    } else {
      EXPECT_EQ(pass.solves(), 3) << "zeta > 0: d relaxes towards d_inf at a fixed H";
      EXPECT_GT(pass.damage()[0], first[0]);
    }
  }
}

// The update reads the configuration the step's forces are evaluated at, the predicted one
// (explicit_step.cpp): after every step an update at the step's end positions finds no driving
// energy left to grow -- H already holds it -- and so solves nothing. Read at the start of the
// step, as before 2026-12-06, it lagged a step and the loading elements' H grew here. A 400
// triangle disk (plain P1, whose update needs the positions alone) to 30 ns: the release at its
// coarse rim damages it from ~10 ns (docs/verification.md).
TEST(DamageRun, TheUpdateSeesTheConfigurationTheForcesAreEvaluatedAt) {
  const v1::RunSpec spec = normalize_spec(parse_spec_json(
      R"({"geometry": {"disk": {"radius": 9e-5}, "target_elements": 400},
          "element": {"formulation": "P1"}, "damage": {"model": "TALAMINI"}})"));
  const Problem problem = make_problem(spec);
  SolverOptions options = make_options(spec);
  options.threads = 1;
  ExplicitStep<Tri3> step(problem, options);
  ASSERT_EQ(problem.damage.update_every, 1);
  KernelTotals totals = step.evaluate(0.0, 0.0, false);
  double t = 0, dt = step.next_step(t, totals);
  int grown = 0;  // steps whose own update solved (H grew)
  while (t < 30e-9) {
    const int solves = step.damage()->solves();
    t += dt;
    totals = step.evaluate(t, dt, false);
    if (step.damage()->solves() == solves) {
      dt = step.next_step(t, totals);
      continue;
    }
    ++grown;
    std::vector<StateArray> state;
    step.save_state(state);
    auto array = [&state](const std::string& name) -> std::vector<double>& {
      for (auto& a : state)
        if (a.name == name) return a.f64;
      throw std::runtime_error("no state array " + name);
    };
    DamagePass<2> replay(problem, nullptr);
    auto restore = [&](const char* name, double* data, std::size_t count) {
      const std::vector<double>& from = array(name);
      ASSERT_EQ(from.size(), count);
      std::copy(from.begin(), from.end(), data);
    };
    replay.visit_state(restore);
    replay.advance(dt);
    replay.update({array("node.x_0").data(), array("node.x_1").data()}, nullptr);
    EXPECT_EQ(replay.solves(), step.damage()->solves()) << "H grew at the step's end, t = " << t;
    EXPECT_EQ(replay.damage(), step.damage()->damage());
    dt = step.next_step(t, totals);
  }
  std::printf("%d steps to 30 ns whose update solved\n", grown);
  EXPECT_GT(grown, 20);
}

// ---- the disk: compression alone, and model NONE ------------------------------------------------
RunResult run_json(const std::string& json, double* min_j = nullptr) {
  const v1::RunSpec spec = normalize_spec(parse_spec_json(json));
  const Problem problem = make_problem(spec);
  RunControl control;
  if (min_j) {
    *min_j = 1.0;
    control.on_frame = [min_j](FieldFrame f) {
      for (double j : f.J) *min_j = std::min(*min_j, j);
    };
  }
  return run_simulation(problem, make_options(spec), control);
}

// The converging 2 GPa shock on its own -- the pulse held beyond the end of the run, so that no
// release wave follows it (with the default 8 ns pulse the release puts this coarse mesh's
// outermost elements into tension, J up to 1.28 at 12 ns, a discretisation error that vanishes
// under refinement: test_damage_disk.cpp, docs/verification.md) -- through the centre (21.7 ns) and
// back out to 24 ns, on 4k triangles. The gel is compressed to J = 0.60 at the focus (~160 MJ/m^3
// of volumetric energy behind the incoming shock, 860 MJ/m^3 at J = 0.60): a total-energy driver
// would set d >= 1 - eps_f / (2 W) > 0.98 there (tested below: W > 50 eps_f / 2). The tension-only
// driver sees the deviatoric energy (mu = 5 kPa: ~1 kJ/m^3) and the ringing behind the front
// (J <= 1.02, W_vol+ < 0.4 MJ/m^3): model 1 (threshold eps_f / 2 = 1 MPa) never solves and d stays
// exactly 0; model 2 (no threshold, G / eps = 2 MPa) d = 2H / (2H + G / eps) < 0.02 (measured
// 0.0119 at N_d = 1) and no damaged zone (d >= 1/2) anywhere.
TEST(DamageRun, TheCompressiveShockAloneCreatesNoDamage) {
  const std::string base =
      R"({"geometry": {"target_elements": 4000}, "load": {"duration": 1e-7},
          "run": {"end_time": 2.4e-8}, "damage": {"model": ")";
  double min_j = 1.0;
  const RunResult talamini = run_json(base + R"(TALAMINI"}})", &min_j);
  ASSERT_EQ(talamini.status, RunStatus::kCompleted);
  const History& h = talamini.history;
  ASSERT_TRUE(h.damage);
  ASSERT_EQ(h.max_damage.size(), h.size());
  EXPECT_EQ(talamini.damage_solves, 0);
  EXPECT_EQ(*std::max_element(h.max_damage.begin(), h.max_damage.end()), 0.0);
  EXPECT_EQ(*std::max_element(h.damaged_volume.begin(), h.damaged_volume.end()), 0.0);
  EXPECT_EQ(h.damage_dissipation.back(), 0.0);
  // The test means something: the compression's total energy is far above the threshold.
  const Damage defaults;
  const double kappa = 2e9, n = 7.15;
  const double w_compressed = continuum::tait_energy(kappa, n, min_j, std::pow(min_j, -n));
  std::printf("smallest J %.3f, its volumetric energy %.3g J/m^3 = %.0f x eps_f / 2\n", min_j,
              w_compressed, w_compressed / (0.5 * defaults.epsilon_f_Pa));
  EXPECT_GT(w_compressed, 50 * 0.5 * defaults.epsilon_f_Pa);

  const RunResult giovanardi = run_json(base + R"(GIOVANARDI"}})");
  ASSERT_EQ(giovanardi.status, RunStatus::kCompleted);
  const History& g = giovanardi.history;
  const double largest = *std::max_element(g.max_damage.begin(), g.max_damage.end());
  std::printf("model 2: largest d %.4f in %lld solves\n", largest,
              static_cast<long long>(giovanardi.damage_solves));
  EXPECT_LT(largest, 0.02);
  EXPECT_EQ(*std::max_element(g.damaged_volume.begin(), g.damaged_volume.end()), 0.0);
}

// model NONE is no damage at all: the spec normalises to the one without it, and the run's
// history is bitwise the same, with no damage series.
TEST(DamageRun, ModelNoneIsExactlyTheRunWithoutDamage) {
  const std::string plain = R"({"geometry": {"target_elements": 2000}, "run": {"end_time": 1e-8}})";
  const std::string none =
      R"({"geometry": {"target_elements": 2000}, "run": {"end_time": 1e-8},
          "damage": {"model": "NONE", "length": 1e-6}})";
  EXPECT_EQ(spec_to_json(normalize_spec(parse_spec_json(plain))),
            spec_to_json(normalize_spec(parse_spec_json(none))));
  const RunResult a = run_json(plain), b = run_json(none);
  EXPECT_FALSE(b.history.damage);
  EXPECT_TRUE(b.history.max_damage.empty());
  ASSERT_EQ(a.history.columns().size(), b.history.columns().size());
  for (std::size_t c = 0; c < a.history.columns().size(); ++c)
    EXPECT_EQ(*a.history.columns()[c].second, *b.history.columns()[c].second)
        << a.history.columns()[c].first;
}

}  // namespace
}  // namespace softshock::damage
