// The explicit Lagrangian run: central differences over the element kernels, with
// diagnostics sampled at the history interval and field frames at the output interval.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "model.hpp"

namespace softshock {

struct RunState;  // run_state.hpp: a run's restart state

// Time series sampled every history interval (SoA; one entry per sample).
struct History {
  std::vector<double> time;                          // s
  std::vector<double> kinetic_energy;                // J per metre of thickness
  std::vector<double> elastic_energy;                // J/m, stored W(F)
  std::vector<double> dissipated_energy;             // J/m, artificial viscosity
  std::vector<double> external_work;                 // J/m, follower pressure
  std::vector<double> abar;                          // (max r - min r) / R0 over the outer boundary
  std::vector<double> center_mean_stress;            // Pa, area-weighted over the centre region
  std::vector<double> rim_mean_radial_displacement;  // m
  std::vector<double> rim_mean_radial_velocity;      // m/s
  std::vector<double> rim_mean_radial_acceleration;  // m/s^2
  std::vector<double> rim_min_hoop_stress;  // Pa, most negative hoop stress of rim elements
  std::vector<double> dt;                   // s, the stable step in force at the sample
  // A-bar of r(theta) rebuilt from Fourier modes 0..kFilteredAbarModes of the rim radial
  // displacement: a single node cannot set it (abar is the raw max - min over rim nodes).
  std::vector<double> abar_filtered;
  std::vector<double> max_aspect_ratio;  // largest longest-edge^2 / (2 area) over all elements
  // The element that sets the stable step: index, aspect ratio, J, and 1 if it touches the rim.
  std::vector<double> dt_element;
  std::vector<double> dt_element_aspect_ratio;
  std::vector<double> dt_element_j;
  std::vector<double> dt_element_on_rim;
  // The smallest stable step of every step since the previous sample (dt is the one in force at
  // the sample: a dip between samples shows here) and the element that set it.
  std::vector<double> min_dt;
  std::vector<double> min_dt_element;
  // Fourier amplitudes of the rim radial displacement / R0: modes[k][m], m = 0..M (3-D: the rim
  // at the mid-plane).
  std::vector<std::vector<double>> modes;
  // 3-D only (empty in 2-D): the same over the whole lateral surface, averaged over the thickness.
  std::vector<std::vector<double>> modes_z_mean;
  // Phase-field damage (Problem::damage; empty without it, and then not among columns()): the
  // damaged zone's reference area (2-D, m^2; 3-D volume, m^3), the nodes' lumped volumes where
  // d >= 1/2; the largest d; the regularised crack's energy, the integral of s/2 (d^2 +
  // l^2 |grad d|^2) (J/m); the stored energy the damage has released so far, which the energy
  // balance books as dissipated (J/m).
  bool damage = false;
  std::vector<double> damaged_volume;
  std::vector<double> max_damage;
  std::vector<double> crack_energy;
  std::vector<double> damage_dissipation;

  std::size_t size() const { return time.size(); }
  // Names and columns of the scalar series, in a fixed order (for writers and clients).
  std::vector<std::pair<std::string, const std::vector<double>*>> columns() const;
};

// Highest Fourier mode in History::abar_filtered (fewer if the run computes fewer modes).
inline constexpr int kFilteredAbarModes = 32;

// SI units of a History series by name ("J/m", "Pa", "1" for A-bar, ...); empty if unknown.
std::string series_units(std::string_view name);

// Fields at one instant: nodal vectors and per-element scalars.
struct FieldFrame {
  double time_s = 0;
  int dimension = 2;                 // of the mesh: 2 (triangles) or 3 (tetrahedra)
  std::vector<double> displacement;  // N x dimension, interleaved (ux, uy[, uz]), m
  std::vector<double> velocity;      // N x dimension, m/s
  std::vector<double> J;             // per element
  std::vector<double> mean_stress;   // Pa, tension positive (includes viscous stress)
  // Pa, sigma_rr and sigma_tt in the current polar frame (3-D: cylindrical, about the z axis
  // through the frame's origin)
  std::vector<double> radial_stress;
  std::vector<double> hoop_stress;
  std::vector<double> von_mises;  // Pa (2-D: plane strain, includes sigma_zz)
  // Longest edge / smallest altitude of the current shape (a triangle's longest edge^2 /
  // (2 area); equilateral 1.1547, regular tetrahedron 1.2247)
  std::vector<double> aspect_ratio;
  // Phase-field damage d per node (model 2: 1 - c); empty without damage.
  std::vector<double> damage;
};

struct Progress {
  double time_s = 0;
  double end_time_s = 0;
  int64_t steps = 0;
  double dt_s = 0;
  double fraction() const { return end_time_s > 0 ? time_s / end_time_s : 0; }
};

enum class RunStatus { kCompleted, kCancelled, kFailed };

// Why a kFailed run stopped, for callers that act on the cause (the daemon's job reasons).
enum class FailureKind {
  kNone,
  kElementInversion,
  kNonFinite,
  kTimeStepCollapse,
  kMeshDistortion  // SolverOptions::max_aspect_ratio exceeded
};
// The cause's name as the run summary records it ("ELEMENT_INVERSION", "NON_FINITE",
// "TIME_STEP_COLLAPSE", "MESH_DISTORTION"; "" for kNone): the daemon's job reasons, so that a run
// on a cluster, read back from its result file, fails with the same reason as a local one.
const char* failure_name(FailureKind kind);

// A step's passes in the order they run (docs/performance.md, "Pass by pass"). The
// kernel's: the nodal-pressure passes, the element loop and the mass blend's element pass.
enum class StepPass {
  kPredictAndLoad,       // predictor (node pass) and the follower pressure on the boundary
  kNodalAreas,           // nodal pressure, pass 1 (elements)
  kNodalState,           // pass 2 (nodes)
  kStabilization,        // pass 3 (elements)
  kStabilizedState,      // pass 4 (nodes)
  kElementForces,        // compute_element_forces (elements)
  kCorrect,              // corrector (nodes)
  kMassBlendDifference,  // the mass blend's element pass
  kMassBlendCorrect,     // its node correction
};
inline constexpr std::size_t kStepPasses = 9;
static_assert(static_cast<std::size_t>(StepPass::kMassBlendCorrect) + 1 == kStepPasses);
const char* step_pass_name(StepPass pass);  // "predict_and_load", "nodal_areas", ...
bool is_kernel_pass(StepPass pass);

struct RunResult {
  RunStatus status = RunStatus::kCompleted;
  std::string error;  // for kFailed: time, element and cause
  FailureKind failure = FailureKind::kNone;
  History history;
  int64_t steps = 0;
  double wall_time_s = 0;
  // The kernel: wall time in the nodal passes, compute_element_forces and the mass blend's
  // element pass over the steps (the busiest thread's, barrier waits excluded), for the
  // summary's kernel grind time beside the whole run's wall time.
  double kernel_time_s = 0;
  // Each pass's wall time over the steps, indexed by StepPass (0 for a pass the element does not
  // run); with threads, the busiest thread's per pass. One thread: the kernel passes sum to
  // kernel_time_s.
  std::array<double, kStepPasses> pass_time_s{};
  // Wall time of the solver's thread in diagnostics (history samples and the fields of frames;
  // the sample sums the element loop adds are the kernel's) and in output (handing frames to
  // RunControl::on_frame: with a writer thread, the copy and any wait while its queue is full).
  double diagnostics_time_s = 0, output_time_s = 0;
  double min_dt_s = 0, max_dt_s = 0;
  std::size_t frames_written = 0;
  // Phase-field damage: the wall time of its updates (the driver, the solve, the degradations;
  // the degradation's node and element passes are in their passes' times) and their number.
  double damage_time_s = 0;
  int64_t damage_solves = 0;
};

struct RunControl {
  // Called after every step; keep it cheap (the caller throttles any output).
  std::function<void(const Progress&)> on_progress;
  // Called for each field frame (t = 0, every output interval, and the final state), which it
  // owns: a writer can take it without a copy (a frame is ~1 MB at 16.5k elements; copying it
  // into fresh pages cost ~4 % of a short run).
  std::function<void(FieldFrame)> on_frame;
  // Optional: a frame that on_frame's receiver is done with, for the next frame to fill in place
  // (its buffers are already in memory: a fresh ~1 MB frame cost its page faults, ~0.6 ms a frame
  // at 16.5k elements, measured), or an empty frame when there is none.
  std::function<FieldFrame()> spare_frame;
  // Checked every step; when set the run stops with kCancelled.
  const std::atomic<bool>* cancel = nullptr;
  // Checkpoints (run_state.hpp). checkpoint_due is asked after every step (keep it cheap: a clock
  // read); when it says yes, on_checkpoint gets the state at the end of that step. With
  // checkpoint_at_stop, on_checkpoint also gets the state where the loop stopped
  // (RunState::stopped: the end time or a cancellation; not a failure), before the final sample and
  // frame. The state is the callee's to keep (move it: a copy doubles its memory at the end).
  std::function<bool(const Progress&)> checkpoint_due;
  std::function<void(RunState&&)> on_checkpoint;
  bool checkpoint_at_stop = false;
  // Continue from this state (taken from a run of the same problem and options, but for a later
  // or equal end time) instead of starting at t = 0. Throws std::invalid_argument when it does
  // not fit the problem (sizes, dimension, thread count, a missing array).
  const RunState* resume = nullptr;
};

// Runs the problem to options.end_time_s. Never throws for physical failures (element
// inversion, non-finite values): those return kFailed with a message naming time, element and
// cause. Throws std::invalid_argument for an inconsistent Problem (sizes, empty mesh).
RunResult run_simulation(const Problem& problem, const SolverOptions& options,
                         const RunControl& control = {});

}  // namespace softshock
