// Validation of the solver against analytic results and the thesis's reference points
// (physics.md section 9). Tolerances are justified where they are stated.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numbers>
#include <string>
#include <thread>
#include <utility>

#include "solver/gmsh_mesher.hpp"
#include "solver/run_spec.hpp"
#include "solver/run_summary.hpp"
#include "solver/simulation.hpp"
#include "validation_helpers.hpp"

namespace softshock {
namespace {

using testing::energy_balance_error;

v1::RunSpec spec_from(const std::string& json) {
  return normalize_spec(parse_spec_json(json));
}

RunResult run_spec(const v1::RunSpec& spec, Problem* problem_out = nullptr,
                   const RunControl& control = {}) {
  Problem problem = make_problem(spec);
  RunResult r = run_simulation(problem, make_options(spec), control);
  if (problem_out) *problem_out = std::move(problem);
  return r;
}

// (b) No viscosity, no load, an initial velocity field: central differences keep the total
// energy bounded. 2000 steps; the tolerance 0.1 % is the issue's. Lumped and with the mass blends
// 1/2 and 1 (the default), whose kinetic energy is its own mass's (½ v.K^-1 v, docs/model.md):
// counted with the lumped masses the blend's drift was 1.2e-3.
TEST(PhysicsValidation, EnergyIsConservedWithoutViscosity) {
  for (const double mass_blend : {0.0, 0.5, 1.0}) {
    SCOPED_TRACE(mass_blend);
    Problem p;
    p.element.mass_blend = mass_blend;
    p.mesh = mesh_disk(90e-6, 2000);
    p.viscosity.enabled = false;
    p.material.shear_viscosity_Pa_s = 0.0;  // no viscosity of either kind
    p.load_all_boundary = false;
    p.origin = {0, 0};
    p.reference_radius_m = 90e-6;
    const std::size_t nn = p.mesh.node_count();
    p.initial_vx.resize(nn), p.initial_vy.resize(nn);
    for (std::size_t i = 0; i < nn; ++i) {  // radial breathing plus a shear swirl, ~1 % strain
      const double X = p.mesh.x[i] / 90e-6, Y = p.mesh.y[i] / 90e-6;
      p.initial_vx[i] = 10.0 * X - 5.0 * Y * (1 - X * X - Y * Y);
      p.initial_vy[i] = 10.0 * Y + 5.0 * X * (1 - X * X - Y * Y);
    }
    SolverOptions o;
    o.end_time_s = 1.0;
    o.max_steps = 2000;
    o.history_interval_s = 1e-9;
    o.output_interval_s = 0;
    o.modes = 4;
    const RunResult r = run_simulation(p, o);
    ASSERT_EQ(r.status, RunStatus::kCompleted) << r.error;
    ASSERT_EQ(r.steps, 2000);
    const History& h = r.history;
    const double e0 = h.kinetic_energy[0] + h.elastic_energy[0];
    double worst = 0;
    for (std::size_t k = 0; k < h.size(); ++k)
      worst = std::max(worst, std::fabs(h.kinetic_energy[k] + h.elastic_energy[k] - e0) / e0);
    std::printf("mass blend %.1f: energy drift without viscosity over 2000 steps: %.2e\n",
                mass_blend, worst);
    EXPECT_LT(worst, 1e-3);
    EXPECT_EQ(h.external_work.back(), 0.0);
    EXPECT_EQ(h.dissipated_energy.back(), 0.0);
  }
}

// (c) Viscosity on, the baseline pulse: kinetic + stored elastic + dissipated = external work.
// External work and dissipation are booked as the integrator applies them (nodal forces times
// displacement increments, trapezoidal in time); the elastic energy is the stored W(F). What
// remains is the time-integration error of W inside the shock, second order in dt: at CFL 0.5
// it is 2.5 % on this mesh (docs/model.md), so the 1 % target is checked at CFL 0.25, and the
// error must fall by ~4x when dt halves again (>= 3x accepted: the shock is not smooth).
TEST(PhysicsValidation, EnergyBalanceWithViscosityClosesAndConvergesInTime) {
  auto balance_at = [](double cfl) {
    const auto spec = spec_from(R"({"geometry":{"target_elements":4000},
        "run":{"end_time":6e-8,"output_interval":0,"cfl":)" +
                                std::to_string(cfl) + "}}");
    const RunResult r = run_spec(spec);
    EXPECT_EQ(r.status, RunStatus::kCompleted) << r.error;
    return std::fabs(energy_balance_error(r.history, r.history.size() - 1));
  };
  const double at_quarter = balance_at(0.25);
  const double at_eighth = balance_at(0.125);
  std::printf("energy balance error: CFL 0.25 %.3e, CFL 0.125 %.3e\n", at_quarter, at_eighth);
  EXPECT_LT(at_quarter, 0.01);
  EXPECT_GT(at_quarter / at_eighth, 3.0) << at_quarter << " " << at_eighth;
}

// (d) Rankine-Hugoniot: a planar shock in a strip with sliding side walls, driven by a constant
// pressure on its left end. U = sqrt(p / (rho0 (1 - J))), J from p = (kappa/n)(J^-n - 1).
double measured_shock_speed(double pressure) {
  const double length = 300e-6, height = 6e-6;
  Problem p;
  p.material.shear_viscosity_Pa_s = 0.0;                  // the thesis's model: Rankine-Hugoniot's
  p.mesh = make_rectangle_mesh(length, height, 600, 12);  // h = 0.5 um
  const std::size_t nn = p.mesh.node_count();
  p.fixed_y.assign(nn, 0);
  for (std::size_t i = 0; i < nn; ++i)
    if (p.mesh.y[i] < 1e-12 || p.mesh.y[i] > height - 1e-12) p.fixed_y[i] = 1;
  for (const auto& e : p.mesh.boundary_edges)
    if (p.mesh.x[e[0]] < 1e-12 && p.mesh.x[e[1]] < 1e-12) p.loaded_edges.push_back(e);
  p.load = {PulseShape::kSquare, pressure, 1.0};  // on for the whole run
  p.origin = {0, 0};
  p.reference_radius_m = length;
  SolverOptions o;
  o.end_time_s = 80e-9;
  o.output_interval_s = 20e-9;
  o.modes = 0;
  // Front position: where the element-averaged J along x crosses the mid value between 1 and
  // the Hugoniot J, from the frames at 40 and 80 ns (after the front has formed).
  const double kappa = p.material.bulk_modulus_Pa, n = p.material.tait_n();
  const double j_down = std::pow(1.0 + n * pressure / kappa, -1.0 / n);
  std::vector<std::pair<double, double>> fronts;  // (t, x)
  RunControl control;
  control.on_frame = [&](const FieldFrame& f) {
    if (f.time_s < 39e-9) return;
    const int bins = 600;
    std::vector<double> sum(bins, 0), count(bins, 0);
    for (std::size_t e = 0; e < p.mesh.element_count(); ++e) {
      const auto& t = p.mesh.triangles[e];
      const double cx = (p.mesh.x[t[0]] + p.mesh.x[t[1]] + p.mesh.x[t[2]]) / 3;
      const int b = std::min(bins - 1, static_cast<int>(cx / length * bins));
      sum[b] += f.J[e], count[b] += 1;
    }
    const double mid = 0.5 * (1.0 + j_down);
    for (int b = bins - 1; b > 0; --b) {  // scan from the undisturbed end
      const double jb = sum[b] / count[b], ja = sum[b - 1] / count[b - 1];
      if (jb >= mid && ja < mid) {
        const double xb = (b + 0.5) * length / bins, xa = (b - 0.5) * length / bins;
        const double xm = xa + (xb - xa) * (mid - ja) / (jb - ja);
        // Reference position: the material point X; the front moves at U in the reference
        // frame (Lagrangian shock speed), which is what the Rankine-Hugoniot U is.
        fronts.push_back({f.time_s, xm});
        break;
      }
    }
  };
  const RunResult r = run_simulation(p, o, control);
  EXPECT_EQ(r.status, RunStatus::kCompleted) << r.error;
  EXPECT_EQ(fronts.size(), 3u);
  if (fronts.size() < 2) return 0;
  return (fronts.back().second - fronts.front().second) /
         (fronts.back().first - fronts.front().first);
}

double hugoniot_speed(double pressure) {
  const double kappa = 2e9, n = 7.15, rho0 = 1000;
  const double j = std::pow(1.0 + n * pressure / kappa, -1.0 / n);
  return std::sqrt(pressure / (rho0 * (1.0 - j)));
}

TEST(PhysicsValidation, PlanarShockSpeedMatchesRankineHugoniot) {
  for (double pbar : {0.5, 1.0}) {
    const double p = pbar * 2e9;
    const double u = measured_shock_speed(p), expected = hugoniot_speed(p);
    // 3 % (the issue's tolerance); the front is located to ~1 bin (0.5 um) over ~110 um.
    EXPECT_NEAR(u, expected, 0.03 * expected) << "P/kappa = " << pbar;
    std::printf(
        "planar shock P/kappa = %.1f: measured %.1f m/s, Rankine-Hugoniot %.1f m/s (%.2f %%)\n",
        pbar, u, expected, 100 * (u - expected) / expected);
  }
}

// (e) Linear acoustics: the fundamental radial mode of a free disk, u_r ~ J1(k r) with
// k R0 = 2.4048 (J0(k R0) = 0: pressure-free rim; the higher radial modes at the next zeros).
// Started in its exact shape at 0.1 m/s (strain ~ 1e-4, linear), no viscosity. Period
// 2 pi R0 / (k R0 c); returns the relative period error, signed (> 0: the mesh's wave is slow).
double fundamental_period_error(int elements, double mass_blend = 0.0,
                                double k_r0 = 2.404825557695773) {
  const double r0 = 90e-6, k = k_r0 / r0, c = std::sqrt(2e9 / 1000.0);
  Problem p;
  p.mesh = mesh_disk(r0, elements);
  p.element.mass_blend = mass_blend;
  p.viscosity.enabled = false;
  p.material.shear_viscosity_Pa_s = 0.0;  // linear acoustics: no viscosity
  p.load_all_boundary = false;
  p.origin = {0, 0};
  p.reference_radius_m = r0;
  const std::size_t nn = p.mesh.node_count();
  p.initial_vx.resize(nn), p.initial_vy.resize(nn);
  for (std::size_t i = 0; i < nn; ++i) {
    const double r = std::hypot(p.mesh.x[i], p.mesh.y[i]);
    const double vr = 0.1 * std::cyl_bessel_j(1.0, k * r) / 0.5191474972894669;  // J1 max ~ 0.58
    p.initial_vx[i] = r > 0 ? vr * p.mesh.x[i] / r : 0;
    p.initial_vy[i] = r > 0 ? vr * p.mesh.y[i] / r : 0;
  }
  SolverOptions o;
  const double period = 2 * std::numbers::pi * r0 / (k_r0 * c);
  o.end_time_s = 3.3 * period;
  o.history_interval_s = 0.25e-9;
  o.output_interval_s = 0;
  o.modes = 0;
  const RunResult r = run_simulation(p, o);
  EXPECT_EQ(r.status, RunStatus::kCompleted) << r.error;
  // The rim velocity starts at its maximum: upward zero crossings are one period apart.
  std::vector<double> v = r.history.rim_mean_radial_velocity;
  for (double& x : v) x = -x;  // first crossing after a quarter... use downward-to-upward of -v
  const auto crossings = testing::upward_zero_crossings(r.history.time, v);
  EXPECT_GE(crossings.size(), 3u);
  if (crossings.size() < 3) return 1.0;
  const double measured = (crossings.back() - crossings.front()) / (crossings.size() - 1);
  return (measured - period) / period;
}

TEST(PhysicsValidation, FundamentalRadialPeriodConvergesUnderRefinement) {
  for (const double mass_blend : {0.0, 1.0}) {  // lumped (the thesis's) and the default
    const double coarse = std::fabs(fundamental_period_error(1000, mass_blend));
    const double fine = std::fabs(fundamental_period_error(4000, mass_blend));
    EXPECT_LT(fine, 0.01) << "mass blend " << mass_blend;  // the issue's 1 %
    EXPECT_LT(coarse, 0.01) << "mass blend " << mass_blend;
    EXPECT_LT(fine, coarse) << "mass blend " << mass_blend;  // refinement reduces the error
    std::printf(
        "fundamental period error, mass blend %.0f: 1000 elements %.3e, 4000 elements %.3e\n",
        mass_blend, coarse, fine);
  }
}

// The mass blend (docs/model.md, "Mass") is there for the dispersion error: lumped masses (and
// the nodal averaging of J) make short waves slow, by O((kh)^2); a share of consistent mass speeds
// them up by O((kh)^2). Radial modes 1 and 3 (J0(k R0) = 0 at 2.40 and 8.65): the blend shortens
// the (too long) period, and by a second-order amount: refining 1000 -> 4000 elements (h / 2)
// cuts the change ~4x (measured with the default blend 1: 3.8x and 5.8x; 1/2: 3.3x and 4.7x;
// between 2.5x and 6x asserted, the meshes being only roughly similar). Even the blend 1 leaves
// the period too long (+0.21 % and +3.9 % on 1000 elements): the nodal averaging of J slows the
// waves more than the consistent mass speeds them up. It fails with the correction's sign flipped
// or its (kh)^2 form replaced by a uniform mass scaling.
TEST(PhysicsValidation, MassBlendSpeedsUpShortWavesBySecondOrder) {
  for (const double k_r0 : {2.404825557695773, 8.653727912911013}) {
    double change[2];
    for (const int refinement : {0, 1}) {
      const int elements = refinement ? 4000 : 1000;
      const double lumped = fundamental_period_error(elements, 0.0, k_r0),
                   blended = fundamental_period_error(elements, 1.0, k_r0);
      std::printf(
          "radial mode k R0 = %.2f, %d elements: period error lumped %+.3e, mass blend "
          "1 %+.3e\n",
          k_r0, elements, lumped, blended);
      EXPECT_GT(lumped, 0.0);
      EXPECT_LT(blended, lumped);
      change[refinement] = lumped - blended;
    }
    EXPECT_GT(change[0] / change[1], 2.5) << "k R0 " << k_r0;
    EXPECT_LT(change[0] / change[1], 6.0) << "k R0 " << k_r0;
  }
}

// (f) The thesis baseline (2 GPa, 8 ns, ~16,500 triangles) with the default formulation: the
// converging shock reaches the centre at 28.1 +- 1 ns and first reflects off the rim at
// 53.9 +- 1 ns (where the thesis-faithful P1 solver put them, itself within 1 ns of the thesis's
// ~29 / ~55 ns and of an independent implementation's 27.6 / 54.0 ns, physics.md section 9).
// The energy left once the shock has passed (70 ns) is 1.589 J/m for the inviscid model that
// reference describes (+- 2 %); the default's physical viscosity dissipates a further few
// percent in the converging flow (docs/verification.md gives the figure), so the energy check
// runs with eta = 0 and the default's value is printed beside it.
TEST(PhysicsValidation, BaselineEventTimesMatchTheThesis) {
  Problem problem;
  const RunResult r =
      run_spec(spec_from(R"({"run":{"end_time":7e-8,"output_interval":0}})"), &problem);
  ASSERT_EQ(r.status, RunStatus::kCompleted) << r.error;
  const RunSummary s = summarize(problem, r);
  EXPECT_NEAR(static_cast<double>(s.elements), 16500, 0.05 * 16500);
  EXPECT_NEAR(s.shock_at_center_s, 28.1e-9, 1e-9);
  ASSERT_FALSE(s.rim_reflections_s.empty());
  EXPECT_NEAR(s.rim_reflections_s.front(), 53.9e-9, 1e-9);
  const auto& h = r.history;
  const double retained_default = h.kinetic_energy.back() + h.elastic_energy.back();

  const RunResult inviscid = run_spec(spec_from(
      R"({"material":{"shear_viscosity":0},"run":{"end_time":7e-8,"output_interval":0}})"));
  ASSERT_EQ(inviscid.status, RunStatus::kCompleted) << inviscid.error;
  const double retained =
      inviscid.history.kinetic_energy.back() + inviscid.history.elastic_energy.back();
  EXPECT_NEAR(retained, 1.589, 0.02 * 1.589);
  std::printf(
      "baseline: centre %.2f ns, rim %.2f ns, retained %.3f J/m (eta = 0: %.3f J/m), "
      "%lld steps\n",
      s.shock_at_center_s * 1e9, s.rim_reflections_s.front() * 1e9, retained_default, retained,
      static_cast<long long>(r.steps));
}

// A viscosity-limited step (Kelvin-Voigt eta = 100 and 1000 Pa s: the viscous speed
// 4/3 eta / (rho h) is 10-100 times the sound speed on a 1,000-element disk) must be taken from the
// first step on. The first evaluation has no lagged rate, so no viscous stress, and its step had
// left the viscosity out too: one step of the elastic size (~1 ns, 200 viscous limits) made energy
// from nothing -- kinetic energy 137 J/m against 1.72 J/m of external work at 1000 Pa s, a +25 %
// balance error at 100 Pa s. With the viscous term in the first step the balance closes within the
// 1 % the validation asks of it (measured 1e-4).
TEST(PhysicsValidation, ViscosityLimitedStepKeepsTheEnergyBalanceFromTheFirstStep) {
  for (const double eta : {100.0, 1000.0}) {
    const RunResult r = run_spec(spec_from(R"({"geometry":{"target_elements":1000},)"
                                           R"("material":{"shear_viscosity":)" +
                                           std::to_string(eta) +
                                           R"(},"run":{"end_time":3e-8,"output_interval":0}})"));
    ASSERT_EQ(r.status, RunStatus::kCompleted) << r.error;
    const History& h = r.history;
    const double balance = energy_balance_error(h, h.size() - 1);
    const double most_kinetic = *std::max_element(h.kinetic_energy.begin(), h.kinetic_energy.end());
    std::printf(
        "eta = %.0f Pa s: %lld steps, energy balance %.2e, kinetic energy at most %.3f of "
        "the external work\n",
        eta, static_cast<long long>(r.steps), balance, most_kinetic / h.external_work.back());
    EXPECT_LT(std::fabs(balance), 0.01) << "eta " << eta;
    EXPECT_LT(most_kinetic, h.external_work.back()) << "eta " << eta;
  }
}

// A load at full strength from t = 0 (the square pulse) acts on nodes at rest, where the
// elastic step estimate is taken: before the first step was limited by its predicted volume
// change (volume_change_step, 10 %), the default's first step compressed the rim's elements by
// ~19 % at cfl 0.5, and a grid-scale instability of the rim grew during the pulse from cfl ~0.7 at
// P-bar = 1 (A-bar(8 ns) 0.127 at cfl 0.8, against 0.0020) and already at the default cfl 0.5 for
// P-bar = 2.5 (0.0133 against 0.0025 at cfl 0.3), i.e. 6-60 times the stable answer. The onset
// must not depend on the Courant number beyond the time-discretisation error of a load switched
// on at once: A-bar over the pulse within 20 % of the cfl = 0.3 run (measured: 8.6 % at cfl 0.8,
// at 2 ns, a ~7 nm difference in the rim's radius; 2.0 % at P-bar = 2.5). Bounding the first step
// alone moved the instability to the next steps at stronger loads: P-bar = 5 at cfl 0.9 (+259 %)
// and P-bar = 10 at the then default cfl 0.7 (+16 %), so the bound holds while the load acts
// (measured with it: 5.1 % and 4.0 %).
TEST(PhysicsValidation, SquarePulseOnsetDoesNotDependOnTheCourantNumber) {
  auto abar = [](double pressure, double cfl) {
    const RunResult r = run_spec(spec_from(R"({"load":{"pressure":)" + std::to_string(pressure) +
                                           R"(},"run":{"end_time":8e-9,"output_interval":0,)" +
                                           R"("cfl":)" + std::to_string(cfl) + "}}"));
    EXPECT_EQ(r.status, RunStatus::kCompleted) << r.error;
    return r.history.abar;
  };
  for (const auto& [pressure, cfl] :
       {std::pair{2e9, 0.8}, std::pair{5e9, 0.5}, std::pair{1e10, 0.9}, std::pair{2e10, 0.7}}) {
    const std::vector<double> reference = abar(pressure, 0.3), test = abar(pressure, cfl);
    ASSERT_EQ(test.size(), reference.size());
    double worst = 0.0;
    for (std::size_t k = 1; k < test.size(); ++k)
      worst = std::max(worst, std::fabs(test[k] - reference[k]) / reference[k]);
    EXPECT_LT(worst, 0.2) << "pressure " << pressure << ", cfl " << cfl;
    std::printf("square pulse %.0f GPa: A-bar over 1-8 ns at cfl %.1f within %.2f %% of cfl 0.3\n",
                pressure * 1e-9, cfl, 100.0 * worst);
  }
}

// The energy left after the first pass (70 ns) with the default formulation is a converged
// figure: 16.5k and 66k elements agree within the issue's 2 % (measured 0.3 %; 264k 1.477 J/m,
// docs/verification.md). The inviscid model is not yet converged at 16.5k (1.598 -> 1.567 ->
// 1.552 J/m on 16.5k / 66k / 264k): the issue's 1.589 J/m is its 16.5k figure.
TEST(PhysicsValidation, EnergyAfterTheFirstPassConvergesUnderRefinement) {
  auto retained = [](int elements) {
    const RunResult r =
        run_spec(spec_from(R"({"geometry":{"target_elements":)" + std::to_string(elements) +
                           R"(},"run":{"end_time":7e-8,"output_interval":0}})"));
    EXPECT_EQ(r.status, RunStatus::kCompleted) << r.error;
    return r.history.kinetic_energy.back() + r.history.elastic_energy.back();
  };
  const double coarse = retained(16500), fine = retained(66000);
  std::printf("energy after the first pass, default: 16.5k %.4f J/m, 66k %.4f J/m (%.2f %%)\n",
              coarse, fine, 100 * (coarse - fine) / fine);
  EXPECT_NEAR(coarse, fine, 0.02 * fine);
}

// Determinism: for a given thread count the run is bit-for-bit repeatable (fixed element ranges,
// per-thread force arrays summed in thread order); across thread counts only the summation order
// of the nodal forces differs, so results agree to round-off.
// The default (mass blend, whose element pass sums per thread too) and the lumped mass alike.
TEST(PhysicsValidation, ResultsAreDeterministicForAGivenThreadCount) {
  for (const std::string element : {"{}", R"({"mass_blend":0})"}) {
    SCOPED_TRACE("element " + element);
    const auto spec1 = spec_from(R"({"geometry":{"target_elements":1500},"element":)" + element +
                                 R"(,"run":{"end_time":3e-8,"output_interval":0,"threads":1}})");
    auto spec2 = spec1;
    spec2.mutable_run()->set_threads(2);
    const RunResult a = run_spec(spec1), b = run_spec(spec1), c = run_spec(spec2),
                    d = run_spec(spec2);
    EXPECT_EQ(a.history.abar, b.history.abar);
    EXPECT_EQ(a.history.kinetic_energy, b.history.kinetic_energy);
    EXPECT_EQ(c.history.abar, d.history.abar);
    EXPECT_EQ(c.history.kinetic_energy, d.history.kinetic_energy);
    EXPECT_EQ(c.history.dissipated_energy, d.history.dissipated_energy);
    EXPECT_EQ(c.history.elastic_energy, d.history.elastic_energy);
    // 1 vs 2 threads: reassociated sums (~1e-16 relative per step) grow through ~200 steps of a
    // shock; 1e-9 relative on the energies is far above that and far below any physical change.
    // (The stored energy is summed per thread by the kernel's passes and added in thread order.)
    ASSERT_EQ(a.history.size(), c.history.size());
    for (std::size_t k = 0; k < a.history.size(); ++k) {
      EXPECT_NEAR(a.history.kinetic_energy[k], c.history.kinetic_energy[k],
                  1e-9 * a.history.kinetic_energy.back());
      EXPECT_NEAR(a.history.elastic_energy[k], c.history.elastic_energy[k],
                  1e-9 * a.history.elastic_energy.back());
    }
  }
}

// (g) An inverting run stops cleanly with time, element and cause.
TEST(PhysicsValidation, InvertingRunFailsWithTimeElementAndCause) {
  Problem p;
  p.material.shear_viscosity_Pa_s = 0.0;
  p.mesh = make_rectangle_mesh(10e-6, 10e-6, 10, 10);
  p.load_all_boundary = false;
  const std::size_t nn = p.mesh.node_count();
  p.initial_vx.assign(nn, 0.0), p.initial_vy.assign(nn, 0.0);
  p.initial_vx[nn / 2] = 5e5;  // one node thrown through its neighbours
  // ... unchecked: the first step's volume-change bound would take it in small enough steps for
  // the artificial viscosity to stop it.
  p.viscosity.enabled = false;
  SolverOptions o;
  o.end_time_s = 1e-8;
  o.output_interval_s = 0;
  const RunResult r = run_simulation(p, o);
  EXPECT_EQ(r.status, RunStatus::kFailed);
  EXPECT_EQ(r.failure, FailureKind::kElementInversion);
  EXPECT_NE(r.error.find("element inversion"), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("in element"), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("ns"), std::string::npos) << r.error;
}

// The history's min_dt sees every step, not only the sampled ones: its smallest value is the
// run's (RunResult::min_dt_s, the minimum over all steps), each is at most the dt in force at
// its sample, and with samples 5 ns apart a shock run dips between them.
TEST(PhysicsValidation, HistoryRecordsTheSmallestStepBetweenSamples) {
  const RunResult r = run_spec(spec_from(
      R"({"geometry":{"target_elements":1000},"run":{"end_time":1e-7,"history_interval":5e-9}})"));
  ASSERT_EQ(r.status, RunStatus::kCompleted) << r.error;
  const History& h = r.history;
  ASSERT_EQ(h.min_dt.size(), h.size());
  ASSERT_EQ(h.min_dt_element.size(), h.size());
  EXPECT_EQ(*std::min_element(h.min_dt.begin(), h.min_dt.end()), r.min_dt_s);
  int dips = 0;
  for (std::size_t k = 0; k < h.size(); ++k) {
    EXPECT_LE(h.min_dt[k], h.dt[k]) << "sample " << k;
    EXPECT_GE(h.min_dt_element[k], 0.0) << "sample " << k;
    dips += h.min_dt[k] < h.dt[k];
  }
  EXPECT_GT(dips, 0);
  EXPECT_GT(*std::min_element(h.dt.begin(), h.dt.end()), r.min_dt_s);  // the samples miss it
}

// The stored energy and largest aspect ratio of a sample come from the evaluation the sample
// follows (the element loop's sums and, with the average nodal pressure, the nodal passes'). The
// final state is sampled however the run ends: at an end time off the history grid, at max_steps,
// on cancellation. Plain P1, where the elements carry all of the stored energy, and the nodal-
// pressure element, where the nodes carry its volumetric part: the last sample's energy balance
// closes like the one before it (the CFL-0.5 balance error of this early, shocked flow is a few
// per cent, docs/model.md; a sample without the elements' or the nodes' share is off by that whole
// share, ~40 % here), and its largest aspect ratio is the final frame's.
TEST(PhysicsValidation, TheFinalSampleHasTheStoredEnergyAndAspectRatio) {
  for (const std::string formulation : {"P1", "AVERAGE_NODAL_PRESSURE"})
    for (const std::string ending : {"end time", "max_steps", "cancel"}) {
      SCOPED_TRACE(formulation + ", " + ending);
      const v1::RunSpec spec = spec_from(
          R"({"geometry":{"target_elements":1000},"element":{"formulation":")" + formulation +
          R"("},"run":{"end_time":2.37e-8,"history_interval":5e-9,"output_interval":1e-8,)"
          R"("cfl":0.5}})");  // the step counts below are this step's
      std::atomic<bool> cancel{false};
      std::vector<double> final_aspect;
      RunControl control;
      control.cancel = &cancel;
      control.on_frame = [&](const FieldFrame& f) { final_aspect = f.aspect_ratio; };
      // Steps that end off the history grid (the default mass blend's step; 43 steps of the
      // nodal-pressure element end at 15 ns, on it).
      const int64_t max_steps = formulation == "P1" ? 37 : 39;
      const int64_t cancel_steps = formulation == "P1" ? 43 : 44;
      if (ending == "cancel")
        control.on_progress = [&](const Progress& pr) { cancel = pr.steps >= cancel_steps; };
      const Problem problem = make_problem(spec);
      SolverOptions options = make_options(spec);
      if (ending == "max_steps") options.max_steps = max_steps;
      const RunResult r = run_simulation(problem, options, control);
      ASSERT_NE(r.status, RunStatus::kFailed) << r.error;
      if (ending == "max_steps") {
        EXPECT_EQ(r.steps, max_steps);
      }
      if (ending == "cancel") {
        EXPECT_EQ(r.status, RunStatus::kCancelled);
      }
      std::printf("%s, %s: %lld steps, last sample at %.4g ns, balance %.4f (before: %.4f)\n",
                  formulation.c_str(), ending.c_str(), static_cast<long long>(r.steps),
                  r.history.time.back() * 1e9,
                  energy_balance_error(r.history, r.history.size() - 1),
                  energy_balance_error(r.history, r.history.size() - 2));
      const History& h = r.history;
      ASSERT_GE(h.size(), 3u);
      const double t_last = h.time.back();
      EXPECT_GT(std::fmod(t_last, 5e-9), 1e-11) << "the last sample must be off the grid";
      const std::size_t last = h.size() - 1;
      EXPECT_LT(std::fabs(energy_balance_error(h, last)), 0.05) << "t = " << t_last;
      EXPECT_LT(std::fabs(energy_balance_error(h, last) - energy_balance_error(h, last - 1)), 0.02);
      ASSERT_FALSE(final_aspect.empty());
      const double frame_max = *std::max_element(final_aspect.begin(), final_aspect.end());
      EXPECT_NEAR(h.max_aspect_ratio.back(), frame_max, 1e-12 * frame_max);
    }
}

// run.max_aspect_ratio stops a run at the first history sample whose largest aspect ratio exceeds
// it: failed (kMeshDistortion, the error naming the field), the history identical to the unlimited
// run's up to and including that sample, and a last frame there. A limit the run only reaches
// does not stop it. (1,000 elements to 60 ns: the largest aspect ratio moves between ~2.3 and
// ~2.8, not monotonically, so the limit halfway is first passed at a sample inside the run.)
TEST(PhysicsValidation, MaxAspectRatioStopsTheRunAtTheFirstSampleBeyondIt) {
  auto run = [](double limit, double* last_frame_time) {
    char exact[32];  // round-trips the double
    std::snprintf(exact, sizeof exact, "%.17g", limit);
    const v1::RunSpec spec =
        spec_from(R"({"geometry":{"target_elements":1000},"run":{"end_time":6e-8,)"
                  R"("output_interval":2e-8,"max_aspect_ratio":)" +
                  std::string(exact) + "}}");
    RunControl control;
    control.on_frame = [&](const FieldFrame& f) { *last_frame_time = f.time_s; };
    return run_simulation(make_problem(spec), make_options(spec), control);
  };
  double free_frame = 0, stopped_frame = 0, reached_frame = 0;
  const RunResult free = run(0, &free_frame);
  ASSERT_EQ(free.status, RunStatus::kCompleted) << free.error;
  const std::vector<double>& aspect = free.history.max_aspect_ratio;
  const double largest = *std::max_element(aspect.begin(), aspect.end());
  const double limit = 0.5 * (aspect.front() + largest);
  const std::size_t first =
      std::find_if(aspect.begin(), aspect.end(), [&](double a) { return a > limit; }) -
      aspect.begin();
  ASSERT_GT(first, 1u);
  ASSERT_LT(first + 5, aspect.size());  // well inside the run

  const RunResult stopped = run(limit, &stopped_frame);
  std::printf("aspect ratio %.3f at t = 0, largest %.3f; limit %.3f first passed at %.1f ns\n",
              aspect.front(), largest, limit, free.history.time[first] * 1e9);
  EXPECT_EQ(stopped.status, RunStatus::kFailed);
  EXPECT_EQ(stopped.failure, FailureKind::kMeshDistortion);
  EXPECT_NE(stopped.error.find("run.max_aspect_ratio"), std::string::npos) << stopped.error;
  ASSERT_EQ(stopped.history.size(), first + 1);
  for (std::size_t k = 0; k <= first; ++k) {
    EXPECT_EQ(stopped.history.time[k], free.history.time[k]);
    EXPECT_EQ(stopped.history.max_aspect_ratio[k], aspect[k]);
    EXPECT_EQ(stopped.history.kinetic_energy[k], free.history.kinetic_energy[k]);
  }
  EXPECT_EQ(stopped_frame, free.history.time[first]);  // the distorted state, for a look at it

  // A mesh beyond the limit from the start: stopped at t = 0.
  double unused = 0;
  const RunResult at_start = run(0.5 * (1.1547 + aspect.front()), &unused);
  EXPECT_EQ(at_start.failure, FailureKind::kMeshDistortion);
  EXPECT_EQ(at_start.steps, 0);
  EXPECT_EQ(at_start.history.size(), 1u);

  // A limit reached but not exceeded.
  const RunResult reached = run(largest, &reached_frame);
  EXPECT_EQ(reached.status, RunStatus::kCompleted) << reached.error;
  EXPECT_EQ(reached.history.size(), free.history.size());
}

// Where a run's time goes (RunResult, the summary's shares): handing a frame over counts as
// output, however long the writer makes the solver wait -- here 20 ms a frame -- and the parts
// are disjoint parts of the run's wall time. Without frames nothing counts as output.
TEST(PhysicsValidation, TheRunAccountsForItsDiagnosticsAndOutputTime) {
  const std::string run = R"({"geometry":{"target_elements":1000},"run":{"end_time":2e-8,)";
  RunControl control;
  control.on_frame = [](FieldFrame) { std::this_thread::sleep_for(std::chrono::milliseconds(20)); };
  Problem problem;
  const RunResult r = run_spec(
      spec_from(run + R"("history_interval":1e-9,"output_interval":5e-9}})"), &problem, control);
  ASSERT_EQ(r.status, RunStatus::kCompleted);
  EXPECT_EQ(r.frames_written, 5u);  // 0, 5, 10, 15, 20 ns
  EXPECT_GE(r.output_time_s, 5 * 0.020);
  EXPECT_GT(r.diagnostics_time_s, 0.0);  // 21 history samples and 5 frames' fields
  EXPECT_LE(r.kernel_time_s + r.diagnostics_time_s + r.output_time_s, r.wall_time_s);
  const RunSummary s = summarize(problem, r);
  EXPECT_DOUBLE_EQ(s.output_share(), r.output_time_s / r.wall_time_s);
  EXPECT_DOUBLE_EQ(s.diagnostics_share(), r.diagnostics_time_s / r.wall_time_s);

  const RunResult quiet = run_spec(spec_from(run + R"("output_interval":0}})"), nullptr, control);
  EXPECT_EQ(quiet.frames_written, 0u);
  EXPECT_EQ(quiet.output_time_s, 0.0);
  EXPECT_GT(quiet.diagnostics_time_s, 0.0);
}

// Where the kernel's time goes (RunResult::pass_time_s, bench_solver's pass_*_ns): each pass the
// element runs is timed, a pass it does not run is 0, and on one thread the kernel's passes are
// exactly kernel_time_s; with two threads kernel_time_s is the busiest thread's sum, so between
// the largest kernel pass and the sum of the passes' busiest threads.
TEST(PhysicsValidation, TheKernelTimeIsTheSumOfItsPasses) {
  auto kernel_sum = [](const RunResult& r) {
    double sum = 0;
    for (std::size_t k = 0; k < kStepPasses; ++k)
      if (is_kernel_pass(static_cast<StepPass>(k))) sum += r.pass_time_s[k];
    return sum;
  };
  const std::string run = R"("run":{"end_time":1e-8,"output_interval":0)";
  const RunResult standard =
      run_spec(spec_from(R"({"geometry":{"target_elements":1000},)" + run + "}}"));
  ASSERT_EQ(standard.status, RunStatus::kCompleted);
  double all = 0;
  for (std::size_t k = 0; k < kStepPasses; ++k) {
    EXPECT_GT(standard.pass_time_s[k], 0.0) << step_pass_name(static_cast<StepPass>(k));
    all += standard.pass_time_s[k];
  }
  EXPECT_EQ(kernel_sum(standard), standard.kernel_time_s);
  EXPECT_LT(standard.kernel_time_s, all);
  EXPECT_LE(all, standard.wall_time_s);

  // Plain P1, lumped: no nodal-pressure passes, no mass blend.
  const RunResult p1 =
      run_spec(spec_from(R"({"geometry":{"target_elements":1000},"element":{"formulation":"P1",)"
                         R"("mass_blend":0},)" +
                         run + "}}"));
  ASSERT_EQ(p1.status, RunStatus::kCompleted);
  for (std::size_t k = 0; k < kStepPasses; ++k) {
    const auto pass = static_cast<StepPass>(k);
    const bool runs = pass == StepPass::kPredictAndLoad || pass == StepPass::kElementForces ||
                      pass == StepPass::kCorrect;
    EXPECT_EQ(p1.pass_time_s[k] > 0.0, runs) << step_pass_name(pass);
  }
  EXPECT_EQ(p1.kernel_time_s, p1.pass_time_s[static_cast<std::size_t>(StepPass::kElementForces)]);

  const RunResult two =
      run_spec(spec_from(R"({"geometry":{"target_elements":1000},)" + run + R"(,"threads":2}})"));
  ASSERT_EQ(two.status, RunStatus::kCompleted);
  for (std::size_t k = 0; k < kStepPasses; ++k) {
    EXPECT_GT(two.pass_time_s[k], 0.0) << step_pass_name(static_cast<StepPass>(k));
    if (is_kernel_pass(static_cast<StepPass>(k))) {
      EXPECT_LE(two.pass_time_s[k], two.kernel_time_s) << step_pass_name(static_cast<StepPass>(k));
    }
  }
  EXPECT_LE(two.kernel_time_s, kernel_sum(two));
}

// A frame filled into a recycled one (RunControl::spare_frame) is the fresh frame to the bit:
// every value of the spare -- here poisoned with NaN -- is overwritten.
TEST(PhysicsValidation, AFrameFilledInASpareIsTheFreshFrame) {
  const v1::RunSpec spec = spec_from(
      R"({"geometry":{"target_elements":1000},"run":{"end_time":2e-8,"output_interval":5e-9}})");
  std::vector<FieldFrame> fresh, recycled;
  RunControl plain;
  plain.on_frame = [&](FieldFrame f) { fresh.push_back(std::move(f)); };
  run_spec(spec, nullptr, plain);
  RunControl reusing;
  reusing.on_frame = [&](FieldFrame f) { recycled.push_back(std::move(f)); };
  reusing.spare_frame = [&] {
    if (recycled.empty()) return FieldFrame{};
    FieldFrame spare = recycled.back();  // the buffers of a frame of this size, poisoned
    for (auto* v :
         {&spare.displacement, &spare.velocity, &spare.J, &spare.mean_stress, &spare.radial_stress,
          &spare.hoop_stress, &spare.von_mises, &spare.aspect_ratio})
      std::fill(v->begin(), v->end(), std::nan(""));
    return spare;
  };
  run_spec(spec, nullptr, reusing);
  ASSERT_EQ(recycled.size(), fresh.size());
  for (std::size_t k = 0; k < fresh.size(); ++k) {
    SCOPED_TRACE(k);
    EXPECT_EQ(recycled[k].time_s, fresh[k].time_s);
    EXPECT_EQ(recycled[k].displacement, fresh[k].displacement);
    EXPECT_EQ(recycled[k].velocity, fresh[k].velocity);
    EXPECT_EQ(recycled[k].J, fresh[k].J);
    EXPECT_EQ(recycled[k].mean_stress, fresh[k].mean_stress);
    EXPECT_EQ(recycled[k].radial_stress, fresh[k].radial_stress);
    EXPECT_EQ(recycled[k].hoop_stress, fresh[k].hoop_stress);
    EXPECT_EQ(recycled[k].von_mises, fresh[k].von_mises);
    EXPECT_EQ(recycled[k].aspect_ratio, fresh[k].aspect_ratio);
  }
}

TEST(PhysicsValidation, CancellationStopsTheRun) {
  std::atomic<bool> cancel{false};
  RunControl control;
  control.cancel = &cancel;
  control.on_progress = [&](const Progress& pr) {
    if (pr.steps == 10) cancel = true;
  };
  const RunResult r =
      run_spec(spec_from(R"({"geometry":{"target_elements":500},"run":{"end_time":1e-6}})"),
               nullptr, control);
  EXPECT_EQ(r.status, RunStatus::kCancelled);
  EXPECT_EQ(r.steps, 10);
}

}  // namespace
}  // namespace softshock
