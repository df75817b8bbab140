#include "simulation.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "diagnostics.hpp"
#include "element_kernels.hpp"
#include "integrator.hpp"
#include "nodal_pressure.hpp"

namespace softshock {

std::vector<std::pair<std::string, const std::vector<double>*>> History::columns() const {
  return {{"time", &time},
          {"kinetic_energy", &kinetic_energy},
          {"elastic_energy", &elastic_energy},
          {"dissipated_energy", &dissipated_energy},
          {"external_work", &external_work},
          {"abar", &abar},
          {"center_mean_stress", &center_mean_stress},
          {"rim_mean_radial_displacement", &rim_mean_radial_displacement},
          {"rim_mean_radial_velocity", &rim_mean_radial_velocity},
          {"rim_mean_radial_acceleration", &rim_mean_radial_acceleration},
          {"rim_min_hoop_stress", &rim_min_hoop_stress},
          {"dt", &dt},
          {"abar_filtered", &abar_filtered},
          {"max_aspect_ratio", &max_aspect_ratio},
          {"dt_element", &dt_element},
          {"dt_element_aspect_ratio", &dt_element_aspect_ratio},
          {"dt_element_j", &dt_element_j},
          {"dt_element_on_rim", &dt_element_on_rim},
          {"min_dt", &min_dt},
          {"min_dt_element", &min_dt_element}};
}

std::string series_units(std::string_view name) {
  static constexpr std::pair<std::string_view, std::string_view> kUnits[] = {
      {"time", "s"},
      {"kinetic_energy", "J/m"},
      {"elastic_energy", "J/m"},
      {"dissipated_energy", "J/m"},
      {"external_work", "J/m"},
      {"abar", "1"},
      {"center_mean_stress", "Pa"},
      {"rim_mean_radial_displacement", "m"},
      {"rim_mean_radial_velocity", "m/s"},
      {"rim_mean_radial_acceleration", "m/s^2"},
      {"rim_min_hoop_stress", "Pa"},
      {"dt", "s"},
      {"abar_filtered", "1"},
      {"max_aspect_ratio", "1"},
      {"dt_element", "1"},
      {"dt_element_aspect_ratio", "1"},
      {"dt_element_j", "1"},
      {"dt_element_on_rim", "1"},
      {"min_dt", "s"},
      {"min_dt_element", "1"},
  };
  for (const auto& [n, u] : kUnits)
    if (n == name) return std::string(u);
  return {};
}

namespace {

// The largest predicted area change of any element in one step while the load acts (a fraction;
// LULESH's volume-change limit per step, dvovmax, is 0.1 too).
constexpr double kLoadStepVolumeChange = 0.1;

void check_problem(const Problem& p, const SolverOptions& o) {
  const std::size_t nn = p.mesh.node_count();
  if (p.mesh.element_count() == 0 || nn == 0) throw std::invalid_argument("mesh: no elements");
  if (p.mesh.y.size() != nn) throw std::invalid_argument("mesh: x and y differ in size");
  for (const auto* v : {&p.fixed_x, &p.fixed_y})
    if (!v->empty() && v->size() != nn)
      throw std::invalid_argument("constraints: one flag per node expected");
  for (const auto* v : {&p.initial_vx, &p.initial_vy})
    if (!v->empty() && v->size() != nn)
      throw std::invalid_argument("initial velocity: one value per node expected");
  if (!(o.cfl > 0 && o.cfl < 1)) throw std::invalid_argument("cfl: must be in (0, 1)");
  if (!(o.end_time_s > 0)) throw std::invalid_argument("end_time: must be > 0");
  if (!(o.history_interval_s > 0)) throw std::invalid_argument("history_interval: must be > 0");
  if (o.threads < 1) throw std::invalid_argument("threads: must be >= 1");
}

ElementGeometry build_geometry(const Mesh& mesh) {
  const std::size_t ne = mesh.element_count();
  ElementGeometry g;
  for (auto* v : {&g.node0, &g.node1, &g.node2}) v->resize(ne);
  for (auto* v : {&g.dm_inv_xx, &g.dm_inv_xy, &g.dm_inv_yx, &g.dm_inv_yy, &g.area0}) v->resize(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const auto& t = mesh.triangles[e];
    g.node0[e] = t[0], g.node1[e] = t[1], g.node2[e] = t[2];
    const double a = mesh.x[t[1]] - mesh.x[t[0]], b = mesh.x[t[2]] - mesh.x[t[0]];
    const double c = mesh.y[t[1]] - mesh.y[t[0]], d = mesh.y[t[2]] - mesh.y[t[0]];
    const double det = a * d - b * c;  // Dm = [[a, b], [c, d]]
    g.dm_inv_xx[e] = d / det, g.dm_inv_xy[e] = -b / det;
    g.dm_inv_yx[e] = -c / det, g.dm_inv_yy[e] = a / det;
    g.area0[e] = 0.5 * det;
  }
  return g;
}

// Stops at which a step must land exactly: history samples, frames, the end of the pulse.
struct Schedule {
  double history, output, end;
  int64_t next_history = 1, next_output = 1;
  double next_history_time() const { return next_history * history; }
  double next_output_time() const { return output > 0 ? next_output * output : end; }
};

// The run's one clock, for its wall time and for where that went (kernel, diagnostics, output):
// the steady clock, read in user space (vDSO, ~30 ns here). The kernel was timed with the
// thread's CPU clock until 2026-12-03, a system call (1.3 us on this VM) whose 4 reads a step
// made the t-bar = 4 run 5 % slower (0.527 -> 0.500 s, docs/performance.md).
using Clock = std::chrono::steady_clock;
double seconds_between(Clock::time_point start, Clock::time_point end) {
  return std::chrono::duration<double>(end - start).count();
}
double seconds_since(Clock::time_point start) {
  return seconds_between(start, Clock::now());
}

}  // namespace

const char* step_pass_name(StepPass pass) {
  static constexpr std::array<const char*, kStepPasses> kNames = {
      "predict_and_load", "nodal_areas",           "nodal_state",
      "stabilization",    "stabilized_state",      "element_forces",
      "correct",          "mass_blend_difference", "mass_blend_correct"};
  return kNames.at(static_cast<std::size_t>(pass));
}

bool is_kernel_pass(StepPass pass) {
  return pass != StepPass::kPredictAndLoad && pass != StepPass::kCorrect &&
         pass != StepPass::kMassBlendCorrect;
}

const char* failure_name(FailureKind kind) {
  switch (kind) {
    case FailureKind::kElementInversion:
      return "ELEMENT_INVERSION";
    case FailureKind::kNonFinite:
      return "NON_FINITE";
    case FailureKind::kTimeStepCollapse:
      return "TIME_STEP_COLLAPSE";
    case FailureKind::kMeshDistortion:
      return "MESH_DISTORTION";
    case FailureKind::kNone:
      break;
  }
  return "";
}

namespace {

FailureKind failure_kind(const KernelTotals& k) {
  return std::isfinite(k.bad_j) ? FailureKind::kElementInversion : FailureKind::kNonFinite;
}

std::string describe_failure(const KernelTotals& k, double t, int64_t steps) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s in element %lld at t = %.6g ns (step %lld): J = %.6g",
                std::isfinite(k.bad_j) ? "element inversion (J <= 0)" : "non-finite state",
                static_cast<long long>(k.bad_element), t * 1e9, static_cast<long long>(steps),
                k.bad_j);
  return buf;
}

}  // namespace

RunResult run_simulation(const Problem& problem, const SolverOptions& options,
                         const RunControl& control) {
  check_problem(problem, options);
  const auto wall_start = Clock::now();
  const Mesh& mesh = problem.mesh;
  const std::size_t nn = mesh.node_count();
  const std::size_t ne = mesh.element_count();
  const int threads = options.threads;

  const ElementGeometry geometry = build_geometry(mesh);
  ElementState elements;
  elements.resize(ne);
  const Diagnostics diagnostics(problem, geometry, options.modes);

  // Lumped (row-sum) mass: rho0 A_e / 3 to each node.
  std::vector<double> mass(nn, 0.0);
  for (std::size_t e = 0; e < ne; ++e)
    for (int32_t i : mesh.triangles[e])
      mass[i] += problem.material.density_kg_m3 * geometry.area0[e] / 3.0;

  std::vector<double> x = mesh.x, y = mesh.y;
  std::vector<double> vx(nn, 0.0), vy(nn, 0.0), ax(nn, 0.0), ay(nn, 0.0);
  std::vector<NodeForce> force(nn);
  std::vector<PackedNode> nodes(nn);  // the element passes' rows: position (+ nodal state)
  if (!problem.initial_vx.empty()) vx = problem.initial_vx;
  if (!problem.initial_vy.empty()) vy = problem.initial_vy;
  std::vector<uint8_t> free_x(nn, 1), free_y(nn, 1);
  for (std::size_t i = 0; i < nn; ++i) {
    if (!problem.fixed_x.empty() && problem.fixed_x[i]) free_x[i] = 0, vx[i] = 0;
    if (!problem.fixed_y.empty() && problem.fixed_y[i]) free_y[i] = 0, vy[i] = 0;
  }
  // With a mass blend: the blended mass's momentum (its kinetic energy) and the last forces.
  const double mass_blend = problem.element.mass_blend;
  std::vector<double> px, py, fprev_x, fprev_y, blend_weight;
  if (mass_blend > 0) {
    px.resize(nn), py.resize(nn), fprev_x.assign(nn, 0.0), fprev_y.assign(nn, 0.0);
    blend_weight = consistent_mass_weights(geometry, problem.material.density_kg_m3);
    blended_momentum(geometry, blend_weight.data(), mass_blend, nn, mass.data(), free_x.data(),
                     free_y.data(), vx.data(), vy.data(), px.data(), py.data());
  }

  // Follower pressure: loaded edges and the nodes they touch.
  const auto& loaded_edges = problem.loaded_edges.empty() && problem.load_all_boundary
                                 ? mesh.boundary_edges
                                 : problem.loaded_edges;
  std::vector<int32_t> loaded_nodes;
  for (const auto& edge : loaded_edges)
    loaded_nodes.insert(loaded_nodes.end(), edge.begin(), edge.end());
  std::sort(loaded_nodes.begin(), loaded_nodes.end());
  loaded_nodes.erase(std::unique(loaded_nodes.begin(), loaded_nodes.end()), loaded_nodes.end());
  // Seeded perturbation: each loaded edge's pressure times 1 + amplitude cos(mode theta), theta
  // the reference polar angle of its midpoint.
  std::vector<double> edge_factor(loaded_edges.size(), 1.0);
  if (problem.perturbation.amplitude != 0.0) {
    const auto origin = polar_frame(problem).origin;
    for (std::size_t k = 0; k < loaded_edges.size(); ++k) {
      const auto [a, b] = loaded_edges[k];
      const double theta = std::atan2(0.5 * (mesh.y[a] + mesh.y[b]) - origin[1],
                                      0.5 * (mesh.x[a] + mesh.x[b]) - origin[0]);
      edge_factor[k] +=
          problem.perturbation.amplitude * std::cos(problem.perturbation.mode * theta);
    }
  }
  std::vector<double> fext_x(nn, 0.0), fext_y(nn, 0.0);
  std::vector<double> fext_old_x(loaded_nodes.size()), fext_old_y(loaded_nodes.size());
  std::vector<double> x_old(loaded_nodes.size()), y_old(loaded_nodes.size());

  // Force on node i = p |e| n_inward, half to each end; body on the left of (a -> b), so the
  // inward normal times the length is the edge vector turned by +90 degrees.
  auto apply_follower_pressure = [&](double t) {
    for (int32_t i : loaded_nodes) fext_x[i] = 0.0, fext_y[i] = 0.0;
    const double p = problem.load.at(t);
    if (p == 0.0) return;
    for (std::size_t k = 0; k < loaded_edges.size(); ++k) {
      const auto [a, b] = loaded_edges[k];
      const double pk = p * edge_factor[k];
      const double hx = -0.5 * pk * (y[b] - y[a]), hy = 0.5 * pk * (x[b] - x[a]);
      fext_x[a] += hx, fext_y[a] += hy, fext_x[b] += hx, fext_y[b] += hy;
    }
  };

  KernelParams params;
  params.kappa = problem.material.bulk_modulus_Pa;
  params.tait_n = problem.material.tait_n();
  params.mu = problem.material.shear_modulus_Pa;
  params.rho0 = problem.material.density_kg_m3;
  params.c1 = problem.viscosity.c1;
  params.c2 = problem.viscosity.c2;
  params.viscosity = problem.viscosity.enabled;
  const bool thesis_switch = problem.viscosity.switch_kind == ViscositySwitch::kCompressionOnly;
  params.ramp_inv = thesis_switch ? 1e300 : 1.0 / problem.viscosity.ramp;
  params.altitude_length = thesis_switch ? 1.0 : 0.0;
  params.artificial_shear = thesis_switch ? 1.0 : 0.0;
  params.eta = problem.material.shear_viscosity_Pa_s;

  // Average nodal pressure: nodal areas, each node's Tait state, then the stabilisation of the
  // element-level volume modes, before the element loop (nodal_pressure.hpp); the last nodal
  // pass writes each node's state into its row beside the position the predictor wrote.
  const bool nodal = problem.element.formulation == ElementFormulation::kAverageNodalPressure;
  const double beta_kappa = problem.element.stabilization * params.kappa;
  const std::size_t nodal_n = nodal ? nn : 0, nodal_e = nodal ? ne : 0;
  const std::vector<double> nodal_area0 =
      nodal ? reference_nodal_areas(geometry, nn) : std::vector<double>{};
  std::vector<double> nodal_area(nodal_n), nodal_j(nodal_n), nodal_sm(nodal_n), nodal_k(nodal_n),
      nodal_q(nodal_n), j_element(nodal_e), s_element(nodal_e, 0.0);
  std::vector<std::vector<double>> thread_area(nodal && threads > 1 ? threads : 0),
      thread_q(nodal && threads > 1 ? threads : 0);
  for (auto* v : {&thread_area, &thread_q})
    for (auto& a : *v) a.resize(nn);
  if (nodal) {
    params.nodal_pressure = true;
    params.element_stress_shift = s_element.data();
    params.element_weight = problem.element.element_weight;
    params.stabilization_beta_kappa = beta_kappa;
  }

  // One step's node and element work: the predictor moves the nodes by dt (dt = 0: evaluate at
  // the current state), then internal + external forces give the new accelerations and the
  // corrector completes the velocities. Each thread owns a fixed range of nodes and of
  // elements and adds its elements' forces into its own nodal arrays; those and the partial
  // totals are summed in thread order, so results depend only on the thread count.
  std::vector<KernelTotals> partial(threads);
  const double w_nodal = 1.0 - problem.element.element_weight;
  // Per thread, each pass's seconds (RunResult::pass_time_s, kernel_time_s).
  std::vector<std::array<double, kStepPasses>> pass_seconds(threads);
  std::vector<std::vector<NodeForce>> thread_force(threads > 1 ? threads : 0);
  for (auto& f : thread_force) f.resize(nn);
  auto evaluate = [&](double t, double dt, bool sample) {
    params.dt = dt, params.sample = sample;
    std::fill(partial.begin(), partial.end(), KernelTotals{});  // each thread's sums of this step
    auto node_range = [&](int tid) {
      return std::pair<std::size_t, std::size_t>{nn * tid / threads, nn * (tid + 1) / threads};
    };
    auto predict = [&](int tid) {  // x+ = x + dt v + dt^2/2 a; v* = v + dt/2 a
      const auto [n0, n1] = node_range(tid);
      predict_nodes(dt, n0, n1, x.data(), y.data(), vx.data(), vy.data(), ax.data(), ay.data(),
                    nodes.data());
    };
    auto element_range = [&](int tid) {
      return std::pair<std::size_t, std::size_t>{ne * tid / threads, ne * (tid + 1) / threads};
    };
    // Per-thread partial nodal sums, added in thread order by each thread's node range, which
    // it also clears for the next step's sums (while the lines are in cache: no separate pass).
    auto sum_threads = [&](auto& parts, std::size_t n0, std::size_t n1, auto* out) {
      using Value = std::remove_cvref_t<decltype(*out)>;  // double or NodeForce
      for (std::size_t i = n0; i < n1; ++i) {
        Value sum{};
        for (int k = 0; k < threads; ++k) sum += parts[k][i], parts[k][i] = Value{};
        out[i] = sum;
      }
    };
    auto nodal_areas = [&](int tid) {  // pass 1: this thread's elements' shares of the areas
      const auto [e0, e1] = element_range(tid);
      double* out = threads > 1 ? thread_area[tid].data() : nodal_area.data();
      if (threads == 1) std::fill(out, out + nn, 0.0);  // else cleared by sum_threads
      accumulate_nodal_areas(geometry, nodes.data(), e0, e1, out, j_element.data());
    };
    // On a sample, passes 2 and 3 also sum the stored energy they see, per thread.
    auto energy_sum = [&](int tid) {
      return sample ? StoredEnergySum{w_nodal, &partial[tid].nodal_energy} : StoredEnergySum{};
    };
    auto nodal_state = [&](int tid) {  // pass 2: J, mean stress, bulk modulus of the nodes
      const auto [n0, n1] = node_range(tid);
      if (threads > 1) sum_threads(thread_area, n0, n1, nodal_area.data());
      nodal_tait_state(params.kappa, params.tait_n, nodal_area0.data(), nodal_area.data(), n0, n1,
                       nodal_j.data(), nodal_sm.data(), nodal_k.data(), energy_sum(tid));
      if (beta_kappa <= 0) pack_nodal_state(nodal_sm.data(), nodal_k.data(), n0, n1, nodes.data());
    };
    auto stabilization = [&](int tid) {  // pass 3: element discrepancies, their nodal shares
      const auto [e0, e1] = element_range(tid);
      double* out = threads > 1 ? thread_q[tid].data() : nodal_q.data();
      if (threads == 1) std::fill(out, out + nn, 0.0);  // else cleared by sum_threads
      accumulate_stabilization(geometry, beta_kappa, nodal_j.data(), j_element.data(), e0, e1,
                               s_element.data(), out, energy_sum(tid));
    };
    auto stabilized_state = [&](int tid) {  // pass 4: nodal stress less the patch mean of s
      const auto [n0, n1] = node_range(tid);
      if (threads > 1) sum_threads(thread_q, n0, n1, nodal_q.data());
      subtract_stabilization(nodal_area0.data(), nodal_q.data(), nodal_k.data(), n0, n1,
                             nodal_sm.data(), nodes.data());
    };
    auto work = [&](int tid) {
      const auto [e0, e1] = element_range(tid);
      NodeForce* out = threads > 1 ? thread_force[tid].data() : force.data();
      if (threads == 1) std::fill(out, out + nn, NodeForce{});  // else cleared by correct
      compute_element_forces(geometry, nodes.data(), params, e0, e1, elements, partial[tid], out);
    };
    auto correct = [&](int tid) {  // a+ = M^-1 f; v+ = v* + dt/2 a+
      const auto [n0, n1] = node_range(tid);
      if (threads > 1) sum_threads(thread_force, n0, n1, force.data());
      // With a mass blend the velocities wait for the corrected accelerations (correct_blend).
      if (mass_blend > 0)
        correct_nodes_blended(dt, n0, n1, force.data(), fext_x.data(), fext_y.data(), free_x.data(),
                              free_y.data(), mass.data(), ax.data(), ay.data(), fprev_x.data(),
                              fprev_y.data(), px.data(), py.data());
      else
        correct_nodes(dt, n0, n1, force.data(), fext_x.data(), fext_y.data(), free_x.data(),
                      free_y.data(), mass.data(), ax.data(), ay.data(), vx.data(), vy.data());
    };
    // The mass blend (integrator.hpp): an element pass over the lumped accelerations, summed in
    // the force arrays (free again once the accelerations are made), then the node correction.
    auto blend_difference = [&](int tid) {
      const auto [e0, e1] = element_range(tid);
      NodeForce* out = threads > 1 ? thread_force[tid].data() : force.data();
      if (threads == 1) std::fill(out, out + nn, NodeForce{});  // else cleared by sum_threads
      accumulate_consistent_mass_difference(geometry, blend_weight.data(), ax.data(), ay.data(), e0,
                                            e1, out);
    };
    auto correct_blend = [&](int tid) {
      const auto [n0, n1] = node_range(tid);
      if (threads > 1) sum_threads(thread_force, n0, n1, force.data());
      correct_mass_blend(dt, mass_blend, n0, n1, force.data(), free_x.data(), free_y.data(),
                         mass.data(), ax.data(), ay.data(), vx.data(), vy.data());
    };
    if (threads == 1) {
      // The passes back to back: one clock read between two (~30 ns; a pass takes ~5-170 us at
      // 16.5k elements).
      auto& seconds = pass_seconds[0];
      auto last = Clock::now();
      auto lap = [&](StepPass pass) {
        const auto now = Clock::now();
        seconds[static_cast<std::size_t>(pass)] += seconds_between(last, now);
        last = now;
      };
      predict(0), apply_follower_pressure(t), lap(StepPass::kPredictAndLoad);
      if (nodal) {
        nodal_areas(0), lap(StepPass::kNodalAreas);
        nodal_state(0), lap(StepPass::kNodalState);
        if (beta_kappa > 0) {
          stabilization(0), lap(StepPass::kStabilization);
          stabilized_state(0), lap(StepPass::kStabilizedState);
        }
      }
      work(0), lap(StepPass::kElementForces);
      correct(0), lap(StepPass::kCorrect);
      if (mass_blend > 0) {
        blend_difference(0), lap(StepPass::kMassBlendDifference);
        correct_blend(0), lap(StepPass::kMassBlendCorrect);
      }
    } else {
      // Each pass timed on its own, so that the barrier waits between passes are left out.
      auto timed = [&](int tid, StepPass pass, const auto& run_pass) {
        const auto start = Clock::now();
        run_pass(tid);
        pass_seconds[tid][static_cast<std::size_t>(pass)] += seconds_since(start);
      };
#pragma omp parallel num_threads(threads)
      {
        const int tid = omp_get_thread_num();
        timed(tid, StepPass::kPredictAndLoad, predict);
#pragma omp barrier
        // The follower pressure (boundary edges only) on one thread; the single's barrier follows.
#pragma omp single
        timed(tid, StepPass::kPredictAndLoad, [&](int) { apply_follower_pressure(t); });
        if (nodal) {
          timed(tid, StepPass::kNodalAreas, nodal_areas);
#pragma omp barrier
          timed(tid, StepPass::kNodalState, nodal_state);
#pragma omp barrier
          if (beta_kappa > 0) {
            timed(tid, StepPass::kStabilization, stabilization);
#pragma omp barrier
            timed(tid, StepPass::kStabilizedState, stabilized_state);
#pragma omp barrier
          }
        }
        timed(tid, StepPass::kElementForces, work);
#pragma omp barrier
        timed(tid, StepPass::kCorrect, correct);
        if (mass_blend > 0) {
#pragma omp barrier
          timed(tid, StepPass::kMassBlendDifference, blend_difference);
#pragma omp barrier
          timed(tid, StepPass::kMassBlendCorrect, correct_blend);
        }
      }
    }
    KernelTotals total;
    for (const auto& k : partial) {
      if (k.min_step_sq < total.min_step_sq)
        total.min_step_sq = k.min_step_sq, total.min_step_element = k.min_step_element;
      total.dissipation += k.dissipation;
      total.element_energy += k.element_energy;
      total.nodal_energy += k.nodal_energy;
      total.max_aspect_ratio = std::max(total.max_aspect_ratio, k.max_aspect_ratio);
      if (total.bad_element < 0 && k.bad_element >= 0)
        total.bad_element = k.bad_element, total.bad_j = k.bad_j;
    }
    return total;
  };

  RunResult result;
  const NodalView view{x.data(),
                       y.data(),
                       vx.data(),
                       vy.data(),
                       ax.data(),
                       ay.data(),
                       mass.data(),
                       mass_blend > 0 ? px.data() : nullptr,
                       mass_blend > 0 ? py.data() : nullptr};
  const KernelView kernel_view =
      nodal ? KernelView{nodal_j.data(), nodal_sm.data(), s_element.data(), j_element.data()}
            : KernelView{};
  double t = 0.0, dissipated = 0.0, external_work = 0.0;
  int64_t steps = 0;
  KernelTotals totals = evaluate(0.0, 0.0, true);
  pass_seconds.assign(threads, {});  // count steps only
  if (totals.bad_element >= 0) {
    result.status = RunStatus::kFailed;
    result.failure = failure_kind(totals);
    result.error = describe_failure(totals, 0.0, 0);
    return result;
  }
  // While the load acts, every step also keeps the predicted area change of each element the load
  // acts on within kLoadStepVolumeChange. The stable step sees the material's stiffness, not the
  // load: the elastic estimate of the first step is taken at rest, and a load at full strength
  // from t = 0 (the square pulse) would compress the loaded elements by ~20 % in the first step at
  // cfl 0.5 and drive a grid-scale instability at the rim from cfl ~0.7 (P-bar = 1). Bounding the
  // first step alone moved that to the next ones: at P-bar = 5 and cfl 0.9 the rim went unstable
  // in the second and third steps (A-bar +266 % over 30 ns), at P-bar = 10 and cfl 0.7 +23 %.
  // Those elements have a corner on a loaded node; the rest move under internal forces alone,
  // which the stable step sees. Over every element the bound gave the same steps (P-bar 1-10, cfl
  // 0.7-0.9) at ~20 % of the element loop's cost per step.
  const double pulse_end = problem.load.end_s();
  const std::vector<int32_t> loaded_elements = elements_on_nodes(geometry, loaded_nodes, nn);
  // The next step after an evaluation at time t: cfl times the elements' stable step, bounded
  // while the load acts; the element that sets it is recorded in k (the history's dt_element).
  const double cfl_with_mass = options.cfl * mass_blend_step_factor(mass_blend);
  auto next_step = [&](KernelTotals& k) {
    const double dt_elastic = cfl_with_mass * std::sqrt(k.min_step_sq);
    if (t >= pulse_end) return dt_elastic;
    const StepBound bound = volume_change_step(geometry, loaded_elements, vx.data(), vy.data(),
                                               ax.data(), ay.data(), kLoadStepVolumeChange);
    if (!(bound.dt_s < dt_elastic)) return dt_elastic;
    k.min_step_element = bound.element;
    return bound.dt_s;
  };
  double dt_stable = next_step(totals);
  result.min_dt_s = result.max_dt_s = dt_stable;
  // The smallest stable step since the last sample, and its element.
  double interval_min_dt = dt_stable;
  int64_t interval_min_element = totals.min_step_element;
  // Whether the last evaluation summed the stored energy and the elements' aspect ratio (a sample
  // was due after it). A sample that was not -- the last state of a run stopped by max_steps or a
  // cancellation -- gets them from one more pass over a copy of the element state and the nodal
  // passes (the sums depend on the positions alone).
  bool totals_sampled = true;
  // Wall time of the solver's thread in diagnostics (history samples, frames' fields) and in
  // handing frames to the writer (RunResult): where a run's time goes beside the kernel.
  auto sample_history = [&] {
    const auto start = Clock::now();
    if (!totals_sampled) {
      ElementState scratch = elements;
      KernelParams sums_only = params;
      sums_only.sample = true, sums_only.dt = 0.0;
      KernelTotals sums;
      std::vector<NodeForce> unused(nn);
      compute_element_forces(geometry, nodes.data(), sums_only, 0, ne, scratch, sums,
                             unused.data());
      totals.element_energy = sums.element_energy;
      totals.max_aspect_ratio = sums.max_aspect_ratio;
      if (nodal)
        totals.nodal_energy =
            nodal_pressure_state(geometry, nodal_area0, params.kappa, params.tait_n,
                                 problem.element.element_weight, problem.element.stabilization,
                                 x.data(), y.data())
                .stored_energy;
      totals_sampled = true;
    }
    diagnostics.sample(view, elements, kernel_view, totals, t, dt_stable, dissipated, external_work,
                       result.history);
    result.history.min_dt.push_back(interval_min_dt);
    result.history.min_dt_element.push_back(static_cast<double>(interval_min_element));
    interval_min_dt = std::numeric_limits<double>::infinity(), interval_min_element = -1;
    result.diagnostics_time_s += seconds_since(start);
  };
  auto write_frame = [&] {
    const auto start = Clock::now();
    FieldFrame frame = diagnostics.frame(
        view, elements, kernel_view, t, control.spare_frame ? control.spare_frame() : FieldFrame{});
    const auto handed = Clock::now();
    result.diagnostics_time_s += seconds_between(start, handed);
    control.on_frame(std::move(frame));
    result.output_time_s += seconds_since(handed);
    ++result.frames_written;
  };
  // Whether the sample just taken has an element beyond the mesh's regime (max_aspect_ratio): the
  // run stops there as failed, with its history and a last frame kept.
  auto mesh_distorted = [&] {
    const double aspect = result.history.max_aspect_ratio.back();
    if (!(options.max_aspect_ratio > 0 && aspect > options.max_aspect_ratio)) return false;
    result.status = RunStatus::kFailed;
    result.failure = FailureKind::kMeshDistortion;
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "mesh distortion: an element's aspect ratio reached %.4g (run.max_aspect_ratio = "
                  "%.4g) at t = %.6g ns (step %lld): the mesh no longer follows the flow, so the "
                  "run stops here with its history so far (a limit of 0 runs on regardless)",
                  aspect, options.max_aspect_ratio, t * 1e9, static_cast<long long>(steps));
    result.error = buf;
    return true;
  };
  sample_history();
  if (mesh_distorted()) return result;
  if (options.output_interval_s > 0 && control.on_frame) write_frame();

  Schedule schedule{options.history_interval_s, options.output_interval_s, options.end_time_s};
  const double tiny = 1e-9 * dt_stable;
  Progress progress{0.0, options.end_time_s, 0, dt_stable};
  double last_frame_time = 0.0;

  while (t < options.end_time_s - tiny) {
    if (control.cancel && control.cancel->load(std::memory_order_relaxed)) {
      result.status = RunStatus::kCancelled;
      break;
    }
    if (options.max_steps > 0 && steps >= options.max_steps) break;
    // Land exactly on the next sample, frame, pulse end or end time.
    double stop =
        std::min({schedule.next_history_time(), schedule.next_output_time(), options.end_time_s});
    if (t < pulse_end - tiny) stop = std::min(stop, pulse_end);
    const double dt = (stop - t <= dt_stable + tiny) ? stop - t : dt_stable;

    // Predictor, forces and corrector (evaluate); the loaded nodes' state before the step is
    // kept for the external work.
    for (std::size_t k = 0; k < loaded_nodes.size(); ++k) {
      const int32_t i = loaded_nodes[k];
      x_old[k] = x[i], y_old[k] = y[i], fext_old_x[k] = fext_x[i], fext_old_y[k] = fext_y[i];
    }
    t = (stop - t <= dt_stable + tiny) ? stop : t + dt;
    // A sample follows at the next history time and at the end time (the final state).
    totals_sampled = t >= schedule.next_history_time() - tiny || t >= options.end_time_s - tiny;
    totals = evaluate(t, dt, totals_sampled);
    ++steps;
    if (totals.bad_element >= 0) {
      result.status = RunStatus::kFailed;
      result.failure = failure_kind(totals);
      result.error = describe_failure(totals, t, steps);
      break;
    }
    // Work booked as the integrator sees it: forces times displacement increments,
    // trapezoidal in time.
    for (std::size_t k = 0; k < loaded_nodes.size(); ++k) {
      const int32_t i = loaded_nodes[k];
      external_work += 0.5 * ((fext_old_x[k] + fext_x[i]) * (x[i] - x_old[k]) +
                              (fext_old_y[k] + fext_y[i]) * (y[i] - y_old[k]));
    }
    dissipated += totals.dissipation;

    dt_stable = next_step(totals);
    result.min_dt_s = std::min(result.min_dt_s, dt_stable);
    result.max_dt_s = std::max(result.max_dt_s, dt_stable);
    if (dt_stable < interval_min_dt)
      interval_min_dt = dt_stable, interval_min_element = totals.min_step_element;
    if (!(dt_stable > options.end_time_s * 1e-12)) {
      result.status = RunStatus::kFailed;
      result.failure = FailureKind::kTimeStepCollapse;
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    "stable time step collapsed to %.3g s at t = %.6g ns (step %lld)", dt_stable,
                    t * 1e9, static_cast<long long>(steps));
      result.error = buf;
      break;
    }

    if (t >= schedule.next_history_time() - tiny) {
      while (schedule.next_history_time() <= t + tiny) ++schedule.next_history;
      sample_history();
      if (!std::isfinite(result.history.kinetic_energy.back())) {
        result.status = RunStatus::kFailed;
        result.failure = FailureKind::kNonFinite;
        result.error = "non-finite kinetic energy at t = " + std::to_string(t * 1e9) + " ns";
        break;
      }
      if (mesh_distorted()) break;
    }
    if (options.output_interval_s > 0 && t >= schedule.next_output_time() - tiny) {
      while (schedule.next_output_time() <= t + tiny) ++schedule.next_output;
      if (control.on_frame) {
        write_frame();
        last_frame_time = t;
      }
    }
    if (control.on_progress) {
      progress.time_s = t, progress.steps = steps, progress.dt_s = dt_stable;
      control.on_progress(progress);
    }
  }

  // The final state is always in the history and (when frames are on) in the last frame.
  if (result.history.time.back() < t - tiny && result.status != RunStatus::kFailed)
    sample_history();
  // (A distorted mesh is a valid state: its frame shows where the mesh left the flow.)
  const bool state_valid =
      result.status != RunStatus::kFailed || result.failure == FailureKind::kMeshDistortion;
  if (options.output_interval_s > 0 && control.on_frame && last_frame_time < t - tiny &&
      steps > 0 && state_valid)
    write_frame();
  result.steps = steps;
  for (const auto& seconds : pass_seconds) {
    double kernel = 0;
    for (std::size_t k = 0; k < kStepPasses; ++k) {
      if (is_kernel_pass(static_cast<StepPass>(k))) kernel += seconds[k];
      result.pass_time_s[k] = std::max(result.pass_time_s[k], seconds[k]);
    }
    result.kernel_time_s = std::max(result.kernel_time_s, kernel);
  }
  result.wall_time_s = seconds_since(wall_start);
  return result;
}

}  // namespace softshock
