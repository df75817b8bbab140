// Late-time verification (docs/verification.md): the answer after the shock has rung through the
// disk is set by the physics -- a seeded perturbation and the physical viscosity -- not by the
// mesh. CI runs the 16.5k and 66k meshes; scripts/late-time-study adds 264k and writes the tables.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "solver/run_spec.hpp"
#include "solver/run_summary.hpp"
#include "solver/simulation.hpp"

namespace softshock {
namespace {

RunResult run_json(const std::string& json, Problem* problem_out = nullptr) {
  const auto spec = normalize_spec(parse_spec_json(json));
  Problem problem = make_problem(spec);
  RunResult r = run_simulation(problem, make_options(spec));
  if (problem_out) *problem_out = std::move(problem);
  return r;
}

// Distance of element e's centroid from the disk's centre, in the reference configuration.
double centroid_radius(const Mesh& mesh, std::size_t e) {
  const auto& t = mesh.triangles[e];
  return std::hypot((mesh.x[t[0]] + mesh.x[t[1]] + mesh.x[t[2]]) / 3,
                    (mesh.y[t[0]] + mesh.y[t[1]] + mesh.y[t[2]]) / 3);
}

// The first history sample at or after t (the last one if t is past the end).
std::size_t sample_at(const History& h, double t) {
  std::size_t k = 0;
  while (k + 1 < h.size() && h.time[k] < t - 1e-13) ++k;
  return k;
}

double mode_at(const History& h, int m, double t) {
  return h.modes[sample_at(h, t)][m];
}

// A seeded run: the pulse carries 1 % of mode m, the rim is smooth, the physical viscosity is the
// default's; the seed then dominates whatever the mesh seeds.
std::string seeded_spec(int elements, int mode, double end_time, double rotation = 0.0) {
  std::ostringstream o;
  o.precision(17);
  o << R"({"geometry":{"target_elements":)" << elements << R"(,"mesh_rotation":)" << rotation
    << R"(,"rim_roughness":{"amplitude":0}},"load":{"perturbation":{"mode":)" << mode
    << R"(,"amplitude":0.01}},"run":{"end_time":)" << end_time << R"(,"output_interval":0}})";
  return o.str();
}

// The seeded runs are shared between the tests below (each takes seconds to tens of seconds).
const RunResult& seeded_run(int elements, int mode, double end_time) {
  static std::map<std::string, RunResult> runs;
  const std::string json = seeded_spec(elements, mode, end_time);
  auto it = runs.find(json);
  if (it == runs.end()) it = runs.emplace(json, run_json(json)).first;
  return it->second;
}

// Largest unseeded mode (neither 0, 1 nor a multiple of the seed m, whose harmonics the seed
// makes itself) over 70-450 ns, relative to the seeded mode's amplitude so far (the running
// maximum of A_m). The seeded mode rings: each shock reflection inverts the undulation and A_m
// passes through zero (m = 8 at ~85 and ~261 ns, m = 16 at ~78 and ~245 ns), where the ratio to
// the instantaneous A_m is unbounded whatever the noise; that ratio is printed beside it.
struct Noise {
  double to_envelope = 0, to_instantaneous = 0;
  int mode = 0;
};
Noise unseeded_noise(const History& h, int seed) {
  Noise n;
  double envelope = 0;
  for (std::size_t k = 0; k < h.size(); ++k) {
    envelope = std::max(envelope, h.modes[k][seed]);
    if (h.time[k] < 70e-9) continue;
    const auto& a = h.modes[k];
    for (std::size_t m = 2; m < a.size(); ++m) {
      if (m % seed == 0) continue;
      if (a[m] / envelope > n.to_envelope) n.to_envelope = a[m] / envelope, n.mode = int(m);
      n.to_instantaneous = std::max(n.to_instantaneous, a[m] / a[seed]);
    }
  }
  return n;
}

// Largest amplitude of mode m between t0 and t1: the seeded mode rings (each shock reflection
// inverts the undulation), so its growth is measured on the crests of its envelope.
double crest(const History& h, int m, double t0, double t1) {
  double a = 0;
  for (std::size_t k = 0; k < h.size(); ++k)
    if (h.time[k] >= t0 && h.time[k] <= t1) a = std::max(a, h.modes[k][m]);
  return a;
}

// The issue's growth factor G_m(t) = A_m(t) / A_m(70 ns) of the 264k-element runs, the reference
// the issue measures against (scripts/late-time-study, 2026-12-02 19:30-19:45 UTC;
// docs/verification.md, "Seeded growth": the default, mass blend 1 at cfl 0.75; the runs of the
// former default, mass blend 1/2 at cfl 0.7, agree within 0.2 % at 250 ns and 1.5 % at 450 ns).
// Too long for CI (~4 min each), so their figures stand in here.
struct GrowthReference {
  double t, g8, g16;
};
constexpr GrowthReference kReference264k[] = {{250e-9, 1.530, 3.886}, {450e-9, 11.664, 49.622}};

// G_m(t) on 16.5k and 66k, printed with their distance from the 264k reference; returns them.
std::pair<double, double> growth_factors(const History& coarse, const History& fine, int m,
                                         double t, double reference) {
  const double g_coarse = mode_at(coarse, m, t) / mode_at(coarse, m, 70e-9);
  const double g_fine = mode_at(fine, m, t) / mode_at(fine, m, 70e-9);
  std::printf("G_%d(%.0f ns): 16.5k %.3f (%+.1f %% from 264k), 66k %.3f (%+.1f %%), 264k %.3f\n", m,
              t * 1e9, g_coarse, 100 * (g_coarse / reference - 1), g_fine,
              100 * (g_fine / reference - 1), reference);
  return {g_coarse, g_fine};
}

// The crests of mode m in two windows on 16.5k and 66k: printed, and within 15 % of each other.
// Returns the 66k crests.
std::vector<double> expect_crests_agree(const History& coarse, const History& fine, int m,
                                        std::initializer_list<std::pair<double, double>> windows) {
  std::vector<double> fine_crests;
  for (auto [t0, t1] : windows) {
    const double a_coarse = crest(coarse, m, t0, t1);
    const double a_fine = crest(fine, m, t0, t1);
    std::printf("crest of A_%d, %.0f-%.0f ns: 16.5k %.4e, 66k %.4e (%.1f %%)\n", m, t0 * 1e9,
                t1 * 1e9, a_coarse, a_fine, 100 * (a_coarse - a_fine) / a_fine);
    EXPECT_NEAR(a_coarse, a_fine, 0.15 * a_fine) << t0 * 1e9 << "-" << t1 * 1e9 << " ns";
    fine_crests.push_back(a_fine);
  }
  return fine_crests;
}

// Seeded mode m = 8: the issue's growth factor G_8 at 250 and 450 ns within 5 % of the 264k
// reference on 66k and within 15 % on 16.5k (the issue's bounds). 250 ns is 11 ns before the
// mode's inversion at ~261 ns, on its steepest descent, where a fraction of a nanosecond in the
// arrival of the shock moves it by ~10 %: with the default mass blend 16.5k is +7.0 % (66k +1.2 %;
// blend 1/2: +9.4 %); with the lumped mass it was +18.5 % and this test fails. The crests of the
// two growth cycles (150-245 ns and 350-445 ns), where the amplitude is stationary, must agree
// within the same 15 % between 16.5k and 66k. A rim of N nodes resolves the Fourier modes up to (N
// - 1) / 2: mode N - m takes the same values at the nodes as mode m, so computing it would report
// mode m's amplitude a second time (the default run on a 268-element disk, 38 rim nodes, ended with
// modes 5 and 33 equal and the summary naming 33). Here an ~800-element disk (65 rim nodes) with 5
// % of mode 5 in the pulse: at 10 ns mode 5 leads and nothing else reaches half of it (measured
// 0.29; mode 60 would equal it).
TEST(RimModes, ACoarseRimReportsOnlyTheModesItResolves) {
  Problem coarse;
  const RunResult r = run_json(R"({"geometry":{"target_elements":800,
      "rim_roughness":{"amplitude":0}}, "load":{"perturbation":{"mode":5,"amplitude":0.05}},
      "run":{"end_time":1e-8,"output_interval":0}})",
                               &coarse);
  ASSERT_EQ(r.status, RunStatus::kCompleted) << r.error;
  const std::size_t rim = coarse.mesh.boundary_nodes.size();
  ASSERT_LE(rim - 5, 64u);  // the seed's alias N - 5 is among the 64 modes asked for
  for (const auto& row : r.history.modes) ASSERT_EQ(row.size(), (rim - 1) / 2 + 1);
  const std::vector<double>& last = r.history.modes.back();
  EXPECT_EQ(summarize(coarse, r).dominant_mode_end, 5);
  for (std::size_t m = 2; m < last.size(); ++m) {
    if (m == 5) continue;
    EXPECT_LT(last[m], 0.5 * last[5]) << "mode " << m;
  }
  // A rim of 2 * 64 + 1 nodes or more keeps all 64.
  Problem fine;
  const RunResult f = run_json(R"({"geometry":{"target_elements":4000},
      "run":{"end_time":1e-9,"output_interval":0}})",
                               &fine);
  ASSERT_EQ(f.status, RunStatus::kCompleted) << f.error;
  ASSERT_GE(fine.mesh.boundary_nodes.size(), 2 * 64 + 1u);
  EXPECT_EQ(f.history.modes.back().size(), 65u);
}

TEST(LateTimeVerification, SeededModeEightGrowthConvergesUnderRefinement) {
  const RunResult& coarse = seeded_run(16500, 8, 450e-9);
  const RunResult& fine = seeded_run(66000, 8, 450e-9);
  ASSERT_EQ(coarse.status, RunStatus::kCompleted) << coarse.error;
  ASSERT_EQ(fine.status, RunStatus::kCompleted) << fine.error;
  for (const GrowthReference& ref : kReference264k) {
    const auto [g_coarse, g_fine] = growth_factors(coarse.history, fine.history, 8, ref.t, ref.g8);
    EXPECT_GT(g_fine, 1.0) << "the seeded mode grows";
    EXPECT_NEAR(g_fine, ref.g8, 0.05 * ref.g8) << "66k at " << ref.t * 1e9 << " ns";
    EXPECT_NEAR(g_coarse, ref.g8, 0.15 * ref.g8) << "16.5k at " << ref.t * 1e9 << " ns";
  }
  expect_crests_agree(coarse.history, fine.history, 8, {{150e-9, 245e-9}, {350e-9, 445e-9}});
}

// Seeded mode m = 16 (19 elements per wavelength at the rim on 16.5k): the issue's G_16 at 250 /
// 450 ns within its 5 % of the 264k reference on 66k (-2.4 / -1.6 %) and 15 % on 16.5k (-12.8 /
// -12.3 %), and the crests of its two growth cycles within 15 % between 16.5k and 66k. 250 ns is
// 5 ns after the inversion at ~245 ns and 70 ns 8 ns before the one at ~78 ns, where the amplitude
// is near zero, so those ratios measure the phase more than the growth: on 16.5k the second
// inversion comes 1.15 ns late with the mass blend 1/2 (G_16 -24.9 / -16.2 %, and this test
// fails), 0.6 ns with the blend 1 (lumped -39 / -28 %; docs/verification.md). With the stiffer
// element stabilisation used before (beta = 0.2) the second crest on 16.5k fell 23 % short: the
// test tells them apart.
TEST(LateTimeVerification, SeededModeSixteenGrowthConvergesUnderRefinement) {
  const RunResult& coarse = seeded_run(16500, 16, 450e-9);
  const RunResult& fine = seeded_run(66000, 16, 450e-9);
  ASSERT_EQ(coarse.status, RunStatus::kCompleted) << coarse.error;
  ASSERT_EQ(fine.status, RunStatus::kCompleted) << fine.error;
  for (const GrowthReference& ref : kReference264k) {
    const auto [g_coarse, g_fine] =
        growth_factors(coarse.history, fine.history, 16, ref.t, ref.g16);
    EXPECT_NEAR(g_fine, ref.g16, 0.05 * ref.g16) << "66k at " << ref.t * 1e9 << " ns";
    EXPECT_NEAR(g_coarse, ref.g16, 0.15 * ref.g16) << "16.5k at " << ref.t * 1e9 << " ns";
  }
  const auto crests =
      expect_crests_agree(coarse.history, fine.history, 16, {{150e-9, 240e-9}, {350e-9, 440e-9}});
  for (double a_fine : crests) {
    EXPECT_GT(a_fine, 10 * mode_at(fine.history, 16, 70e-9)) << "the seeded mode grows";
  }
}

// On 66k elements the unseeded modes stay below 10 % of the seeded one up to 450 ns, for m = 8
// and m = 16 (the issue's bound): the mesh seeds nothing that outgrows a 1 % seed.
TEST(LateTimeVerification, UnseededModesStayBelowTenPercentOfTheSeed) {
  for (int seed : {8, 16}) {
    const RunResult& r = seeded_run(66000, seed, 450e-9);
    ASSERT_EQ(r.status, RunStatus::kCompleted) << r.error;
    const Noise n = unseeded_noise(r.history, seed);
    std::printf(
        "seed m = %d, 66k, 70-450 ns: largest unseeded mode %.4f of the seeded amplitude "
        "(mode %d); against the instantaneous A_m (unbounded at its nodes) %.3f\n",
        seed, n.to_envelope, n.mode, n.to_instantaneous);
    EXPECT_LT(n.to_envelope, 0.10) << "seed m = " << seed;
  }
}

// The same seeded run on two meshes of equal size whose lattice is turned by 0.4 rad (the
// concentric rings' defects then sit elsewhere relative to the seed): the rim spectrum at 300 ns,
// modes 2..64 as a vector, agrees within 10 % (relative l2 norm). The largest single-mode
// difference is printed too: the mesh's own noise modes (~10 % of the seed on 16.5k) follow the
// mesh more than the seeded one does.
TEST(LateTimeVerification, RimSpectrumDoesNotFollowTheMeshOrientation) {
  const RunResult a = run_json(seeded_spec(16500, 8, 300e-9, 0.0));
  const RunResult b = run_json(seeded_spec(16500, 8, 300e-9, 0.4));
  ASSERT_EQ(a.status, RunStatus::kCompleted) << a.error;
  ASSERT_EQ(b.status, RunStatus::kCompleted) << b.error;
  const auto& ma = a.history.modes.back();
  const auto& mb = b.history.modes.back();
  double diff_sq = 0, norm_sq = 0, worst = 0;
  int worst_mode = 0;
  for (std::size_t m = 2; m < ma.size(); ++m) {
    diff_sq += (ma[m] - mb[m]) * (ma[m] - mb[m]);
    norm_sq += ma[m] * ma[m];
    if (ma[m] > 0.05 * ma[8] && std::fabs(mb[m] - ma[m]) / ma[m] > worst)
      worst = std::fabs(mb[m] - ma[m]) / ma[m], worst_mode = static_cast<int>(m);
  }
  const double relative = std::sqrt(diff_sq / norm_sq);
  std::printf(
      "rim spectrum at 300 ns, mesh turned 0.4 rad: l2 difference %.2f %%, A_8 %.4e vs "
      "%.4e, largest single-mode difference %.1f %% (mode %d, %.1f %% of A_8)\n",
      100 * relative, ma[8], mb[8], 100 * worst, worst_mode, 100 * ma[worst_mode] / ma[8]);
  EXPECT_LT(relative, 0.10);
  EXPECT_NEAR(mb[8], ma[8], 0.10 * ma[8]);
}

// The default formulation to 800 ns on the default mesh: at most 6,000 steps, largest aspect
// ratio <= 15 at 800 ns and at any time before, raw A-bar < 0.5, and no step below 100 ps after
// 300 ns (the issue's figures). Every step counts (History::min_dt, the smallest step between
// samples; the samples' dt alone missed the deepest dips). After 300 ns the smallest step is set
// where the ringing shock refocuses at the centre (~388 ns: the equilateral elements of ring 1
// compressed to J ~ 0.62-0.70, where the Tait bulk modulus is 13-30 kappa): 101.7 ps at the
// default cfl 0.75 with the default mass blend 1, whose stable step is 0.756 of the lumped one's
// (blend 1/2 at cfl 0.7: 104.5 ps; blend 1 at cfl 0.7: 94.5 ps, which misses the 100 ps; lumped at
// cfl 0.7: 118.1 ps, at the former cfl 0.5 84.4 ps; docs/verification.md, "The time step").
// Asserted too: elements within 10 um of the rim (where the issue saw the slivers that set the
// step) and the stretched elements of the erupting lobes (aspect ratio >= 5, from ~590 ns; sampled)
// set no step below 100 ps. Then the 66k mesh: its raw A-bar within the issue's 25 % of the 16.5k
// one at 400-800 ns (measured with the mass blend 1: -5.4 to -3.3 %, -5.4 % at 800 ns; blend 1/2
// +0.6 % at 800 ns; lumped +19.7 % at 800 ns, +22 % at cfl 0.5, +32 % with beta = 0.02;
// docs/verification.md).
TEST(LateTimeVerification, DefaultRunIsRobustAndItsAbarConvergesTo800ns) {
  Problem problem;
  const RunResult r = run_json(R"({"run":{"output_interval":0}})", &problem);
  ASSERT_EQ(r.status, RunStatus::kCompleted) << r.error;
  const History& h = r.history;
  const Mesh& mesh = problem.mesh;
  double radius = 0;
  for (std::size_t i = 0; i < mesh.node_count(); ++i)
    radius = std::max(radius, std::hypot(mesh.x[i], mesh.y[i]));
  double min_dt_late = 1, min_dt_first_cycle = 1, min_dt_late_sampled = 1;
  double min_dt_rim = 1, min_dt_stretched = 1, farthest_below_floor = 0;
  double worst_dt_element_aspect = 0;
  int below_floor = 0;
  for (std::size_t k = 1; k < h.size(); ++k) {
    ASSERT_GE(h.min_dt_element[k], 0.0);
    const double element_radius =
        centroid_radius(mesh, static_cast<std::size_t>(h.min_dt_element[k]));
    // min_dt[k] covers the steps after sample k - 1.
    if (h.time[k - 1] < 254.6e-9) min_dt_first_cycle = std::min(min_dt_first_cycle, h.min_dt[k]);
    if (h.time[k - 1] < 300e-9) continue;
    min_dt_late = std::min(min_dt_late, h.min_dt[k]);
    min_dt_late_sampled = std::min(min_dt_late_sampled, h.dt[k]);
    if (element_radius > radius - 10e-6) min_dt_rim = std::min(min_dt_rim, h.min_dt[k]);
    worst_dt_element_aspect = std::max(worst_dt_element_aspect, h.dt_element_aspect_ratio[k]);
    if (h.dt_element_aspect_ratio[k] >= 5.0) min_dt_stretched = std::min(min_dt_stretched, h.dt[k]);
    if (h.min_dt[k] < 100e-12) {
      ++below_floor;
      farthest_below_floor = std::max(farthest_below_floor, element_radius);
    }
  }
  const RunSummary s = summarize(problem, r);
  std::printf(
      "default 16.5k: %lld steps, min dt first cycle %.1f ps, after 300 ns %.1f ps (samples "
      "alone: %.1f ps); %d sample intervals with a step below 100 ps, set at most %.2f um from "
      "the centre; smallest step an element within 10 um of the rim set %.1f ps; largest aspect "
      "ratio of a "
      "step-setting element %.2f (sampled), smallest step such an element with aspect ratio >= 5 "
      "set %.1f ps; max aspect ratio %.2f (%.2f at 800 ns), A-bar(800 ns) %.4f (filtered %.4f), "
      "mode %d\n",
      static_cast<long long>(r.steps), min_dt_first_cycle * 1e12, min_dt_late * 1e12,
      min_dt_late_sampled * 1e12, below_floor, farthest_below_floor * 1e6, min_dt_rim * 1e12,
      worst_dt_element_aspect, min_dt_stretched * 1e12, s.max_aspect_ratio,
      h.max_aspect_ratio.back(), s.abar_end, s.abar_filtered_end, s.dominant_mode_end);
  EXPECT_LE(r.steps, 6000);
  EXPECT_LE(h.max_aspect_ratio.back(), 15.0);
  EXPECT_LE(s.max_aspect_ratio, 15.0);
  EXPECT_LT(s.abar_end, 0.5);
  EXPECT_GE(min_dt_late, min_dt_first_cycle);
  EXPECT_GE(min_dt_late, 100e-12);
  EXPECT_EQ(below_floor, 0) << "set at most " << farthest_below_floor * 1e6
                            << " um from the centre";
  EXPECT_GE(min_dt_rim, 100e-12);
  EXPECT_GE(min_dt_stretched, 100e-12);

  const RunResult fine = run_json(R"({"geometry":{"target_elements":66000},
                                      "run":{"output_interval":0}})");
  ASSERT_EQ(fine.status, RunStatus::kCompleted) << fine.error;
  for (double t : {400e-9, 500e-9, 600e-9, 700e-9, 800e-9}) {
    const double coarse = h.abar[sample_at(h, t)];
    const double fine_abar = fine.history.abar[sample_at(fine.history, t)];
    std::printf("A-bar(%.0f ns): 16.5k %.4f, 66k %.4f (%.1f %% from 16.5k)\n", t * 1e9, coarse,
                fine_abar, 100 * (fine_abar - coarse) / coarse);
    EXPECT_NEAR(fine_abar, coarse, 0.25 * coarse) << "at " << t * 1e9 << " ns";
  }
}

// A pulse twice the baseline's (2 x 2 GPa, P-bar = 2) on the default mesh, to 400 ns: the rim
// erupts into jets (A-bar ~ 0.65 by 400 ns) and the elements in them stretch, but none is crushed.
// With the quadratic stabilisation (finite energy to crush an element at fixed nodal areas; beta
// = 0.02) rim elements fell to J = 0.04 by 375 ns and 0.005 by 400 ns, and the step to 0.4 ps;
// with the barrier form the element setting the step keeps J >= 0.20 (measured; 0.30 with beta =
// 0.02). Asserted: >= 0.1. The run goes past the default stop at aspect ratio 100 (389 ns here):
// what is tested is how the element holds up beyond it.
TEST(LateTimeVerification, StrongPulseDoesNotCrushRimElements) {
  const RunResult r = run_json(R"({"load":{"pressure":4e9},
                                   "run":{"end_time":4e-7,"output_interval":0,
                                          "max_aspect_ratio":0}})");
  ASSERT_EQ(r.status, RunStatus::kCompleted) << r.error;
  const History& h = r.history;
  double smallest_j = 1e300, smallest_dt = 1;
  for (std::size_t k = 1; k < h.size(); ++k)
    smallest_j = std::min(smallest_j, h.dt_element_j[k]),
    smallest_dt = std::min(smallest_dt, h.dt[k]);
  std::printf(
      "P-bar = 2 to 400 ns: %lld steps, smallest J of the step-setting element %.3f, "
      "smallest dt %.2f ps, A-bar(400 ns) %.3f\n",
      static_cast<long long>(r.steps), smallest_j, smallest_dt * 1e12, h.abar.back());
  EXPECT_GE(smallest_j, 0.1);
}

// Checkerboard index of the mean stress at 300 ns near the rim (reference radius > 60 um): the
// rms jump between edge neighbours over the rms of the field. A smooth field on this mesh has
// ~0.05 (the gradient over one element); P1's locked pressure alternates between neighbours,
// ~0.7. The default must stay below 0.2; the thesis's P1 shows the test can fail (> 0.4).
double rim_checkerboard_index(const std::string& json) {
  Problem problem;
  const auto spec = normalize_spec(parse_spec_json(json));
  problem = make_problem(spec);
  std::vector<double> mean_stress;
  RunControl control;
  control.on_frame = [&](const FieldFrame& f) { mean_stress = f.mean_stress; };
  const RunResult r = run_simulation(problem, make_options(spec), control);
  EXPECT_EQ(r.status, RunStatus::kCompleted) << r.error;
  const Mesh& mesh = problem.mesh;
  std::vector<double> radius(mesh.element_count());
  std::map<std::pair<int32_t, int32_t>, int32_t> first_owner;
  double jump_sq = 0, field_sq = 0;
  int pairs = 0, elements = 0;
  for (std::size_t e = 0; e < mesh.element_count(); ++e) {
    radius[e] = centroid_radius(mesh, e);
    if (radius[e] > 60e-6) field_sq += mean_stress[e] * mean_stress[e], ++elements;
  }
  for (std::size_t e = 0; e < mesh.element_count(); ++e) {
    const auto& t = mesh.triangles[e];
    for (int k = 0; k < 3; ++k) {
      const auto edge = std::minmax(t[k], t[(k + 1) % 3]);
      const auto [it, fresh] = first_owner.emplace(edge, static_cast<int32_t>(e));
      if (fresh || radius[e] <= 60e-6 || radius[it->second] <= 60e-6) continue;
      const double d = mean_stress[e] - mean_stress[it->second];
      jump_sq += d * d, ++pairs;
    }
  }
  return std::sqrt(jump_sq / pairs) / std::sqrt(field_sq / elements);
}

TEST(LateTimeVerification, NoPressureCheckerboardAtTheRim) {
  const double robust =
      rim_checkerboard_index(R"({"run":{"end_time":3e-7,"output_interval":3e-7}})");
  const double thesis = rim_checkerboard_index(R"({"geometry":{"mesher":"FRONTAL_DELAUNAY",
      "rim_roughness":{"amplitude":0}},"material":{"shear_viscosity":0},
      "viscosity":{"activation":"COMPRESSION_ONLY"},"element":{"formulation":"P1","mass_blend":0},
      "run":{"end_time":3e-7,"output_interval":3e-7}})");
  std::printf(
      "mean-stress checkerboard index at 300 ns (r > 60 um): default %.3f, thesis P1 %.3f\n",
      robust, thesis);
  EXPECT_LT(robust, 0.2);
  EXPECT_GT(thesis, 0.4);
}

}  // namespace
}  // namespace softshock
