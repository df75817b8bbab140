// Runs one catalogued job: spec -> Problem (mesh from DATA/cache/meshes when cached) ->
// AsyncResultWriter (DATA/jobs/<id>/) -> run_simulation with throttled progress and field frames
// -> summary -> terminal transition. A job becomes SUCCEEDED only after the writer's finish()
// returned, i.e. once result.h5 is durable.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "server/jobs/admission.hpp"
#include "server/jobs/job_events.hpp"
#include "server/jobs/scheduler.hpp"
#include "server/store/catalogue.hpp"
#include "solver/run_spec.hpp"
#include "solver/simulation.hpp"

namespace softshock::server {

struct RunnerConfig {
  std::string data_dir;  // absolute
  SpecLimits limits;
  int solver_threads = 1;      // element-loop threads per job (overrides run.threads)
  double max_wall_time_s = 0;  // 0 = no limit
  // Wall time between a running job's checkpoints (jobs/job_checkpoint.hpp); 0 = none. A job
  // started again continues from its last checkpoint either way.
  double checkpoint_interval_s = 600;
  AdmissionLimits admission;  // checked again at start, with the real mesh
  // Free space the data folder keeps for the catalogue and other jobs: a job does not start
  // unless its estimated result fits above it, and stops (DISK_FULL) before a frame would
  // eat into it.
  double min_free_bytes = 256.0 * (1 << 20);
  // Free bytes on the filesystem holding a path; empty = statvfs (tests substitute one).
  std::function<double(const std::string&)> free_bytes;
  double progress_interval_s = 0.1;                         // how often live progress is published
  std::uint64_t mesh_cache_bytes = std::uint64_t{1} << 30;  // DATA/cache/meshes; 0 = no cache
  // softshock-mesh, which Gmsh meshing runs in so that cancel and the wall-time limit can stop
  // it (jobs/mesh_process.hpp); empty = mesh in this process, uninterruptibly.
  std::string mesher;
};

class JobRunner {
 public:
  JobRunner(RunnerConfig config, Catalogue& catalogue, JobEvents& events);

  // The scheduler's work function. Never leaves the job RUNNING because of an exception: it is
  // then recorded FAILED with reason INTERNAL and the error.
  void run(const std::string& id, CancelToken& cancel);

  std::string job_dir(const std::string& id) const;
  const std::string& data_dir() const { return config_.data_dir; }
  // DATA/meshes/: the only folder geometry.mesh_file is read from (the runner's limits carry
  // it as mesh_root).
  std::string meshes_dir() const;
  std::string mesh_cache_dir() const;  // DATA/cache/meshes
  const SpecLimits& limits() const { return config_.limits; }
  // Removes leftovers of an interrupted attempt (result.h5.tmp and friends) in a job folder.
  void remove_stale_files(const std::string& id) const;
  // Gives job `id` the finished result files at source_result_path (hard links); returns its
  // own result path. Throws std::runtime_error.
  std::string link_result(const std::string& source_result_path, const std::string& id) const;
  // QUEUED -> SUCCEEDED reusing an identical SUCCEEDED job's result, if there is one (true =
  // the job needs no run).
  bool reuse_identical(const JobRecord& job) const;
  // Throws ResourceExhausted while the data folder's free space is below min_free_bytes: no new
  // work is taken then (it could not run, and the catalogue keeps its room).
  void require_free_space() const;

 private:
  void run_job(const std::string& id, CancelToken& cancel);
  // The smooth mesh of a normalized spec: from the cache, in this process, or in a
  // softshock-mesh child that should_stop() can kill (then nullopt). Throws what make_problem
  // throws, and MeshingFailed.
  std::optional<Mesh> mesh_job(const std::string& id, const v1::RunSpec& spec,
                               const std::function<bool()>& should_stop, MeshingReport* report);
  double free_bytes() const;
  void fail_running(const std::string& id, const std::string& error);

  RunnerConfig config_;
  Catalogue& catalogue_;
  JobEvents& events_;
  std::unique_ptr<MeshCache> mesh_cache_;  // null: disabled or unusable
};

// FAILED reason for a solver failure: ELEMENT_INVERSION, NON_FINITE, TIME_STEP_COLLAPSE,
// MESH_DISTORTION or INTERNAL.
std::string failure_reason(FailureKind kind);
// The same from a run summary's `failure` (a cluster run's, read back from its result file): one
// of the four solver reasons, or "" when it names none of them (absent, or unknown to this build).
std::string failure_reason(const std::string& summary_failure);

// Mode amplitudes of a run decimated to about one sample per `interval_s`, modes
// 0..min(max_modes, M+1)-1, and A-bar(t) decimated to at most ~max_abar_samples, for the
// catalogue.
StoredSummary make_stored_summary(const RunSummary& summary, const History& history,
                                  double interval_s = 4e-9, int max_modes = 65,
                                  std::size_t max_abar_samples = 1000);

// A spec as the catalogue stores it (protobuf JSON); unknown fields are ignored. Throws
// SpecError.
v1::RunSpec parse_stored_spec(const std::string& json);

// The summary JSON a result file (and softshock-solve's stdout) carries, back into a RunSummary
// (null = NaN). Throws std::runtime_error.
RunSummary parse_summary_json(const std::string& json);

// The catalogue's figures of a run that wrote `h5_path` elsewhere (softshock-solve on a
// cluster): its summary, modes and A-bar(t) read back and decimated exactly as
// make_stored_summary does for an in-process run. `complete` gets the file's complete
// attribute. Throws std::runtime_error.
StoredSummary stored_summary_from_result(const std::string& h5_path, bool* complete = nullptr);

}  // namespace softshock::server
