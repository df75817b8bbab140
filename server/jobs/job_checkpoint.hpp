// Checkpoints of a job the daemon runs in process (the local executor): every
// `checkpoint_interval_s` of wall time the run's state goes to DATA/jobs/<id>/checkpoint/
// (state.ckpt, written to a temporary name and renamed, and the frames so far sealed into
// frames_<step>.h5: solver/io/checkpoint_file.hpp, AsyncResultWriter::checkpoint). A job started
// again after a crash, a kill or a shutdown continues from its last checkpoint instead of t = 0,
// and its result is bitwise the one an uninterrupted run writes (tests/solver/test_checkpoint.cpp,
// tests/server/test_job_checkpoint.cpp). A shutdown also takes one where the run stopped. The
// folder goes when the job ends.
#pragma once

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "server/jobs/scheduler.hpp"
#include "solver/io/async_result_writer.hpp"
#include "solver/io/checkpoint_file.hpp"
#include "solver/simulation.hpp"

namespace softshock::server {

// DATA/jobs/<id>/checkpoint
std::string checkpoint_dir(const std::string& job_dir);

// The job's last checkpoint when it can continue this run: the same normalised spec, mesh
// (fingerprint) and solver thread count, and every sealed frame file present. nullopt when there
// is none, or (with `why_not` set, for the log) when it cannot be used.
std::optional<Checkpoint> load_job_checkpoint(const std::string& job_dir,
                                              const std::string& spec_json, const Mesh& mesh,
                                              int threads, std::string* why_not);

// The sealed frame files of a checkpoint, as paths for the continued result writer.
std::vector<ResultWriter::Sealed> sealed_frames(const std::string& job_dir,
                                                const CheckpointHeader& header);

// Removes the job's checkpoint folder (the job ended, or its checkpoint is unusable).
void remove_job_checkpoint(const std::string& job_dir);

// Takes the checkpoints of one run: attach() sets the RunControl's checkpoint hooks. Each
// checkpoint is written on the result writer's thread; an error writing one is logged and leaves
// the previous one in force. Checkpoints are skipped while the data folder's free space is below
// `min_free_bytes` plus the state's size.
class JobCheckpointer {
 public:
  struct Options {
    std::string job_id;
    std::string job_dir;
    double interval_s = 600;  // wall time between checkpoints; <= 0: none
    std::string spec_json;    // normalised
    std::string mesh_fingerprint;
    double min_free_bytes = 0;
    std::function<double()> free_bytes;  // of the data folder; empty: not checked
  };
  JobCheckpointer(Options options, AsyncResultWriter& writer);

  // Periodic checkpoints, and one where the run stops when `cancel` says the daemon is shutting
  // down (the job is requeued and continues from there).
  void attach(RunControl& control, const CancelToken& cancel);
  int taken() const { return taken_; }
  // Where the run stopped when it was not a shutdown (the end time, a cancellation or a failure):
  // a SUCCEEDED job keeps it so that ExtendJob can continue it (job_extension.hpp).
  const std::optional<RunState>& final_state() const { return final_state_; }

 private:
  using Clock = std::chrono::steady_clock;
  void take(const RunState& state);

  Options options_;
  AsyncResultWriter& writer_;
  Clock::time_point next_;
  int taken_ = 0;
  std::optional<RunState> final_state_;
};

}  // namespace softshock::server
