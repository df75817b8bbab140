// A run's restart state: everything the run loop (simulation.cpp) and the step (explicit_step.hpp)
// carry from one step to the next, so that a run continued from it takes the same steps with the
// same arithmetic as one that never stopped -- bitwise the same history and frames. Taken at the
// end of a step (RunControl::checkpoint_due / on_checkpoint) and given back through
// RunControl::resume. The file format is solver/io/checkpoint_file.hpp's; this is plain data.
//
// Nothing random is carried: the rim roughness and the seeded perturbation are functions of the
// spec and the mesh, rebuilt with the Problem.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "element_kernels.hpp"
#include "simulation.hpp"

namespace softshock {

// One named array of the step's state, in double or in single precision (the element state's
// viscous stresses are floats); exactly one of the two is used.
struct StateArray {
  std::string name;
  std::vector<double> f64;
  std::vector<float> f32;
  bool single = false;  // f32 holds the values
};

struct RunState {
  // The problem it belongs to, checked on resume.
  int dimension = 2;
  std::size_t nodes = 0, elements = 0;
  int threads = 1;  // the thread count sets the sums' order: a resume runs with the same count
  // The loop (simulation.cpp): time, counters, accumulators and the schedule's next stops.
  double time_s = 0;
  int64_t steps = 0;
  double dt_stable_s = 0;
  double tiny_s = 0;  // the loop's landing tolerance, from the first step
  double dissipated = 0, external_work = 0;
  double interval_min_dt_s = 0;
  int64_t interval_min_element = -1;
  int64_t next_history = 1, next_output = 1;
  double last_frame_time_s = 0;
  double min_dt_s = 0, max_dt_s = 0;
  bool totals_sampled = true;
  KernelTotals totals;  // of the last evaluation
  std::size_t frames_written = 0;
  // Where the time went before this state (RunResult's timings), so that a continued run's
  // summary counts every step it reports.
  double wall_time_s = 0, kernel_time_s = 0, diagnostics_time_s = 0, output_time_s = 0;
  std::array<double, kStepPasses> pass_time_s{};
  // Where the loop stopped: false for a periodic checkpoint; true for the state on_checkpoint
  // gets where the loop ended (the end time or a cancellation), before the final sample and
  // frame that a run adds off the schedule -- a continuation to a later end time starts there.
  bool stopped = false;
  History history;
  std::vector<StateArray> arrays;  // ExplicitStep::save_state
};

}  // namespace softshock
