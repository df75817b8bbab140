// Runs one catalogued job: spec -> Problem -> ResultWriter (DATA/jobs/<id>/) -> run_simulation
// with throttled progress and field frames -> summary -> terminal transition. A job becomes
// SUCCEEDED only after ResultWriter::finish() returned, i.e. once result.h5 is durable.
#pragma once

#include <string>

#include "server/catalogue.hpp"
#include "server/job_events.hpp"
#include "server/scheduler.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {

struct RunnerConfig {
  std::string data_dir;  // absolute
  SpecLimits limits;
  int solver_threads = 1;            // element-loop threads per job (overrides run.threads)
  double max_wall_time_s = 0;        // 0 = no limit
  double progress_interval_s = 0.1;  // how often live progress is published
};

class JobRunner {
 public:
  JobRunner(RunnerConfig config, Catalogue& catalogue, JobEvents& events);

  // The scheduler's work function.
  void run(const std::string& id, CancelToken& cancel);

  std::string job_dir(const std::string& id) const;
  std::string meshes_dir() const;
  // Removes leftovers of an interrupted attempt (result.h5.tmp and friends) in a job folder.
  void remove_stale_files(const std::string& id) const;

 private:
  RunnerConfig config_;
  Catalogue& catalogue_;
  JobEvents& events_;
};

// The daemon's rule for geometry.mesh_file: a relative path without "..", resolved under
// DATA/meshes/ — clients must not make the server open arbitrary files. Throws SpecError.
void check_mesh_file(const v1::RunSpec& spec);

// FAILED reason for a solver failure message: ELEMENT_INVERSION, NON_FINITE,
// TIME_STEP_COLLAPSE or INTERNAL.
std::string classify_failure(const std::string& solver_error);

// Mode amplitudes of a run decimated to about one sample per `interval_s`, modes
// 0..min(max_modes, M+1)-1, for the catalogue.
StoredSummary make_stored_summary(const RunSummary& summary, const History& history,
                                  double interval_s = 4e-9, int max_modes = 65);

}  // namespace softshock::server
