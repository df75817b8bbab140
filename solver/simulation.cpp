#include "simulation.hpp"

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
#include "explicit_step.hpp"
#include "run_state.hpp"

namespace softshock {

std::vector<std::pair<std::string, const std::vector<double>*>> History::columns() const {
  std::vector<std::pair<std::string, const std::vector<double>*>> out = {
      {"time", &time},
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
  if (damage) {
    out.insert(out.end(), {{"damaged_volume", &damaged_volume},
                           {"max_damage", &max_damage},
                           {"crack_energy", &crack_energy},
                           {"damage_dissipation", &damage_dissipation}});
  }
  return out;
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
      {"damaged_volume", "m^2"},
      {"max_damage", "1"},
      {"crack_energy", "J/m"},
      {"damage_dissipation", "J/m"},
  };
  for (const auto& [n, u] : kUnits)
    if (n == name) return std::string(u);
  return {};
}

namespace {

void check_problem(const Problem& p, const SolverOptions& o) {
  const std::size_t nn = p.mesh.node_count();
  if (p.mesh.element_count() == 0 || nn == 0) throw std::invalid_argument("mesh: no elements");
  if (p.mesh.y.size() != nn) throw std::invalid_argument("mesh: x and y differ in size");
  if (p.mesh.dimension() == 3 && p.mesh.z.size() != nn)
    throw std::invalid_argument("mesh: x and z differ in size");
  for (const auto* v : {&p.fixed_x, &p.fixed_y, &p.fixed_z})
    if (!v->empty() && v->size() != nn)
      throw std::invalid_argument("constraints: one flag per node expected");
  for (const auto* v : {&p.initial_vx, &p.initial_vy, &p.initial_vz})
    if (!v->empty() && v->size() != nn)
      throw std::invalid_argument("initial velocity: one value per node expected");
  if (p.mesh.dimension() == 2 && (!p.fixed_z.empty() || !p.initial_vz.empty()))
    throw std::invalid_argument("constraints: z flags and velocities need a 3-D mesh");
  if (!(o.cfl > 0 && o.cfl < 1)) throw std::invalid_argument("cfl: must be in (0, 1)");
  if (!(o.end_time_s > 0)) throw std::invalid_argument("end_time: must be > 0");
  if (!(o.history_interval_s > 0)) throw std::invalid_argument("history_interval: must be > 0");
  if (o.threads < 1) throw std::invalid_argument("threads: must be >= 1");
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

namespace {

// The run over one element type: the step (explicit_step.hpp) repeated to the end time, with
// diagnostics sampled at the history interval and field frames at the output interval; stops
// land exactly on samples, frames, the end of the pulse and the end time.
template <class Element>
RunResult run_elements(const Problem& problem, const SolverOptions& options,
                       const RunControl& control) {
  const auto wall_start = Clock::now();
  ExplicitStep<Element> step(problem, options);
  const typename Element::Diagnostics diagnostics(problem, step.geometry(), options.modes);

  RunResult result;
  result.history.damage = step.damage() != nullptr;
  const auto view = step.view();
  const KernelView kernel_view = step.kernel_view();
  double t = 0.0, dissipated = 0.0, external_work = 0.0;
  int64_t steps = 0;
  KernelTotals totals;
  const double pulse_end = step.pulse_end_s();
  double dt_stable = 0;
  // The smallest stable step since the last sample, and its element.
  double interval_min_dt = 0;
  int64_t interval_min_element = -1;
  // Whether the last evaluation summed the stored energy and the elements' aspect ratio (a sample
  // was due after it). A sample that was not -- the last state of a run stopped by max_steps or a
  // cancellation -- gets them from one more pass (ExplicitStep::sample_sums).
  bool totals_sampled = true;
  // Wall time of the solver's thread in diagnostics (history samples, frames' fields) and in
  // handing frames to the writer (RunResult): where a run's time goes beside the kernel.
  auto sample_history = [&] {
    const auto start = Clock::now();
    if (!totals_sampled) {
      step.sample_sums(totals);
      totals_sampled = true;
    }
    diagnostics.sample(view, step.state(), kernel_view, totals, t, dt_stable, dissipated,
                       external_work, result.history);
    if (step.damage()) step.damage()->sample(result.history);
    result.history.min_dt.push_back(interval_min_dt);
    result.history.min_dt_element.push_back(static_cast<double>(interval_min_element));
    interval_min_dt = std::numeric_limits<double>::infinity(), interval_min_element = -1;
    result.diagnostics_time_s += seconds_since(start);
  };
  auto write_frame = [&] {
    const auto start = Clock::now();
    FieldFrame frame =
        diagnostics.frame(view, step.state(), kernel_view, t,
                          control.spare_frame ? control.spare_frame() : FieldFrame{});
    if (step.damage()) frame.damage = step.damage()->damage();
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

  Schedule schedule{options.history_interval_s, options.output_interval_s, options.end_time_s};
  double tiny = 0;
  double last_frame_time = 0.0;
  // Timings of the run up to a resumed state: added to this run's own at the end.
  RunState before;
  if (control.resume) {
    const RunState& r = *control.resume;
    if (r.dimension != Element::kDim || r.nodes != problem.mesh.node_count() ||
        r.elements != problem.mesh.element_count() || r.threads != options.threads) {
      throw std::invalid_argument(
          "checkpoint: taken on a " + std::to_string(r.dimension) + "-D mesh of " +
          std::to_string(r.nodes) + " nodes and " + std::to_string(r.elements) + " elements with " +
          std::to_string(r.threads) + " thread(s), not this problem's " +
          std::to_string(Element::kDim) + "-D " + std::to_string(problem.mesh.node_count()) +
          " / " + std::to_string(problem.mesh.element_count()) + " with " +
          std::to_string(options.threads));
    }
    if (!(r.time_s <= options.end_time_s)) {
      throw std::invalid_argument("checkpoint: at t = " + std::to_string(r.time_s * 1e9) +
                                  " ns, past run.end_time");
    }
    step.restore_state(r.arrays);
    t = r.time_s, steps = r.steps, dt_stable = r.dt_stable_s, tiny = r.tiny_s;
    dissipated = r.dissipated, external_work = r.external_work;
    interval_min_dt = r.interval_min_dt_s, interval_min_element = r.interval_min_element;
    schedule.next_history = r.next_history, schedule.next_output = r.next_output;
    last_frame_time = r.last_frame_time_s;
    result.min_dt_s = r.min_dt_s, result.max_dt_s = r.max_dt_s;
    totals_sampled = r.totals_sampled, totals = r.totals;
    result.frames_written = r.frames_written;
    result.history = r.history;
    before.wall_time_s = r.wall_time_s, before.kernel_time_s = r.kernel_time_s;
    before.diagnostics_time_s = r.diagnostics_time_s, before.output_time_s = r.output_time_s;
    before.pass_time_s = r.pass_time_s;
  } else {
    totals = step.evaluate(0.0, 0.0, true);
    step.reset_pass_times();  // count steps only
    if (totals.bad_element >= 0) {
      result.status = RunStatus::kFailed;
      result.failure = failure_kind(totals);
      result.error = describe_failure(totals, 0.0, 0);
      return result;
    }
    dt_stable = step.next_step(t, totals);
    result.min_dt_s = result.max_dt_s = dt_stable;
    interval_min_dt = dt_stable, interval_min_element = totals.min_step_element;
    sample_history();
    if (mesh_distorted()) return result;
    if (options.output_interval_s > 0 && control.on_frame) write_frame();
    tiny = 1e-9 * dt_stable;
  }
  Progress progress{t, options.end_time_s, steps, dt_stable};
  // The state at the end of the step just taken (or where the loop stopped), with this run's
  // timings added to those before it.
  auto capture = [&](bool stopped) {
    RunState s;
    s.dimension = Element::kDim;
    s.nodes = problem.mesh.node_count(), s.elements = problem.mesh.element_count();
    s.threads = options.threads;
    s.time_s = t, s.steps = steps, s.dt_stable_s = dt_stable, s.tiny_s = tiny;
    s.dissipated = dissipated, s.external_work = external_work;
    s.interval_min_dt_s = interval_min_dt, s.interval_min_element = interval_min_element;
    s.next_history = schedule.next_history, s.next_output = schedule.next_output;
    s.last_frame_time_s = last_frame_time;
    s.min_dt_s = result.min_dt_s, s.max_dt_s = result.max_dt_s;
    s.totals_sampled = totals_sampled, s.totals = totals;
    s.frames_written = result.frames_written;
    s.wall_time_s = before.wall_time_s + seconds_since(wall_start);
    s.diagnostics_time_s = before.diagnostics_time_s + result.diagnostics_time_s;
    s.output_time_s = before.output_time_s + result.output_time_s;
    s.pass_time_s = before.pass_time_s;
    double kernel = 0;
    for (const auto& seconds : step.pass_seconds()) {
      double thread_kernel = 0;
      for (std::size_t k = 0; k < kStepPasses; ++k) {
        if (is_kernel_pass(static_cast<StepPass>(k))) thread_kernel += seconds[k];
        s.pass_time_s[k] = std::max(s.pass_time_s[k], before.pass_time_s[k] + seconds[k]);
      }
      kernel = std::max(kernel, thread_kernel);
    }
    s.kernel_time_s = before.kernel_time_s + kernel;
    s.stopped = stopped;
    s.history = result.history;
    step.save_state(s.arrays);
    return s;
  };

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
    step.remember_load();
    t = (stop - t <= dt_stable + tiny) ? stop : t + dt;
    // A sample follows at the next history time and at the end time (the final state).
    totals_sampled = t >= schedule.next_history_time() - tiny || t >= options.end_time_s - tiny;
    totals = step.evaluate(t, dt, totals_sampled);
    ++steps;
    if (totals.bad_element >= 0) {
      result.status = RunStatus::kFailed;
      result.failure = failure_kind(totals);
      result.error = describe_failure(totals, t, steps);
      break;
    }
    // Work booked as the integrator sees it: forces times displacement increments,
    // trapezoidal in time.
    step.add_load_work(external_work);
    dissipated += totals.dissipation;

    dt_stable = step.next_step(t, totals);
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
    progress.time_s = t, progress.steps = steps, progress.dt_s = dt_stable;
    if (control.on_progress) control.on_progress(progress);
    if (control.on_checkpoint && control.checkpoint_due && control.checkpoint_due(progress))
      control.on_checkpoint(capture(false));
  }
  if (control.on_checkpoint && control.checkpoint_at_stop && result.status != RunStatus::kFailed)
    control.on_checkpoint(capture(true));

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
  for (const auto& seconds : step.pass_seconds()) {
    double kernel = 0;
    for (std::size_t k = 0; k < kStepPasses; ++k) {
      if (is_kernel_pass(static_cast<StepPass>(k))) kernel += seconds[k];
      result.pass_time_s[k] = std::max(result.pass_time_s[k], before.pass_time_s[k] + seconds[k]);
    }
    result.kernel_time_s = std::max(result.kernel_time_s, before.kernel_time_s + kernel);
  }
  if (step.damage()) {
    result.damage_time_s = step.damage_seconds();
    result.damage_solves = step.damage()->solves();
  }
  result.diagnostics_time_s += before.diagnostics_time_s;
  result.output_time_s += before.output_time_s;
  result.wall_time_s = before.wall_time_s + seconds_since(wall_start);
  return result;
}

}  // namespace

RunResult run_simulation(const Problem& problem, const SolverOptions& options,
                         const RunControl& control) {
  check_problem(problem, options);
  return problem.mesh.dimension() == 3 ? run_elements<Tet4>(problem, options, control)
                                       : run_elements<Tri3>(problem, options, control);
}

}  // namespace softshock
