// Reduction of a finished run to the figures the CLI prints and the daemon catalogues.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "model.hpp"
#include "simulation.hpp"

namespace softshock {

// Nondimensional groups of physics.md section 7 (t-bar = t / R0 * sqrt(kappa / rho0)).
struct NondimensionalGroups {
  double pbar = 0, tbar_pulse = 0, mubar = 0, gamma = 0, c1 = 0, c2 = 0;
  double time_scale_s = 0;  // R0 / sqrt(kappa / rho0)
};
NondimensionalGroups nondimensional_groups(const Problem& problem);
// The same from the parameters and the reference radius R0 (m).
NondimensionalGroups nondimensional_groups(const Material& material,
                                           const ArtificialViscosity& viscosity,
                                           const PressurePulse& load, double r0_m);

// The revision of the numerics. Bump it whenever one and the same spec gives different results:
// the element, the viscosities, the integrator, the mesher (with mesh_cache.cpp's
// kMesherRevision) or a default that normalize_spec does not write into the spec. Every summary
// records it; the service reuses a stored result only from the same revision (docs/api.md).
// 1 is the first recorded (2026-12-02); results written before carry none and read as 0.
// 2: the ring mesher's hexagonal centre (ring_mesher.cpp).
// 3: rims of fewer than 2 run.modes + 1 nodes report only the modes they resolve (diagnostics.cpp).
// 4: with a mass blend the kinetic energy is the blended mass's, not the lumped (diagnostics.cpp).
inline constexpr int kSolverRevision = 4;

struct RunSummary {
  int solver_revision = kSolverRevision;  // of the solver that produced it; 0 = not recorded
  // 3-D: the mesh's extent along z, which the per-metre energies divide the body's by (for the
  // cylinder its thickness: per unit thickness, as a plane-strain run's); 0 in 2-D.
  int dimension = 2;
  double thickness_m = 0;
  std::size_t elements = 0, nodes = 0;
  int64_t steps = 0;
  double wall_time_s = 0;
  double end_time_s = 0;
  NondimensionalGroups groups;
  double energy_injected_J_per_m = 0;     // external work at the end of the run
  double energy_after_pulse_J_per_m = 0;  // kinetic + elastic when the pulse has ended
  double max_abar_first_cycle = 0;        // max A-bar over 0 <= t-bar <= 4
  double max_abar = 0;                    // over the whole run
  double abar_end = 0;                    // A-bar at the end of the run
  // The same from r(theta) rebuilt from modes 0..kFilteredAbarModes (History::abar_filtered):
  // a single node cannot set these.
  double max_abar_filtered_first_cycle = 0;
  double max_abar_filtered = 0;
  double abar_filtered_end = 0;
  double max_aspect_ratio = 0;            // largest longest-edge^2 / (2 area) over the samples
  double aspect_ratio_above_10_s = -1;    // first sample with an element above 10; -1 = never
  int dominant_mode_end = 0;              // largest amplitude among modes >= 2 at the end
  double shock_at_center_s = -1;          // focusing: first minimum of centre mean stress
  std::vector<double> rim_reflections_s;  // peaks of the outward rim acceleration
  double min_dt_s = 0, max_dt_s = 0;
  // Phase-field damage (written to the JSON only for a run with damage): when the damaged zone
  // (d >= 1/2, History::damaged_volume) first appears (-1 = never), its largest measure (2-D: area,
  // m^2; 3-D: volume, m^3) and the radius of the disk of that area per unit thickness (3-D: the
  // volume over the z extent), the stored energy the damage released and the crack energy at
  // the end (per metre), and the wall time and number of its updates.
  bool damage = false;
  double damage_onset_s = -1;
  double max_damaged_volume = 0;
  double max_damaged_radius_m = 0;
  double damage_dissipation_J_per_m = 0;
  double crack_energy_J_per_m = 0;
  double damage_time_s = 0;
  int64_t damage_solves = 0;
  std::string status;  // "completed", "cancelled", "failed"
  std::string error;
  std::string failure;  // "failed": its cause (failure_name, e.g. "MESH_DISTORTION"); else empty
  // Where the time went (docs/performance.md). kernel_time_s: the element loop, the nodal
  // passes before it and the mass blend's element pass (on the evaluations a history sample
  // follows, the loop also sums the elements' stored energy and largest aspect ratio), their
  // wall time on the solver thread measured in the run (a CPU clock is a system call a read).
  // meshing_time_s and mesh_cache ("hit", "miss", "replaced", "not-used") describe the mesh before
  // the run; summarize() cannot know them, the caller sets them.
  // diagnostics_time_s and output_time_s: the solver thread's wall time in history samples and
  // frames' fields, and in handing frames to the writer (RunResult), parts of wall_time_s.
  double kernel_time_s = 0;
  double diagnostics_time_s = 0, output_time_s = 0;
  double meshing_time_s = 0;
  std::string mesh_cache = "not-used";

  // Nanoseconds per element-step of the whole run and of the kernel's passes alone (wall times);
  // the share of meshing in meshing + run, and of diagnostics and output in the run's wall time.
  // NaN when undefined (no steps; no time).
  double grind_ns() const;
  double kernel_grind_ns() const;
  double meshing_share() const;
  double diagnostics_share() const;
  double output_share() const;
};

RunSummary summarize(const Problem& problem, const RunResult& result);
// The figures the run has, from the table of summary_figures.hpp (and defined there).
std::string summary_to_json(const RunSummary& summary);

// The summary's names carry their units (summary_to_json's keys, JobSummary's fields since they
// were renamed): the name a figure had before (energy_injected, shock_at_center, wall_time,
// grind_time, groups' time_scale, ...) mapped to today's (energy_injected_J_per_m,
// shock_at_center_s, wall_time_s, grind_ns, time_scale_s, ...); any other name is returned as
// it is. Grid reductions and queries accept both (docs/api.md, "Summary names").
std::string current_summary_name(const std::string& name);
// (old name, today's name) of every renamed figure.
const std::vector<std::pair<std::string, std::string>>& renamed_summary_names();

}  // namespace softshock
