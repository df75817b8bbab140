// The slurm executor (docs/cluster.md): every job runs as `softshock-solve` in a Slurm batch
// job, its spec and output in a directory the daemon and the compute nodes share; the points
// of a grid go out together as one array job (throttled with %N). One thread submits with
// `sbatch --parsable`, polls `squeue` (falling back to `scontrol show job`, then `sacct`), maps
// Slurm's states onto ours, cancels with `scancel`, and ingests finished results into the
// catalogue through the same summary code the in-process runner uses.
//
// Restart safety: the Slurm id is committed in the catalogue right after sbatch returns; the
// jobs then stay on Slurm when the daemon stops and are re-attached from the catalogue at the
// next start. For the window between sbatch returning and that commit, every submission has a
// job name (softshock-<first job id>) and a list of its job ids in the shared directory; at
// start-up, QUEUED jobs without an id are matched against squeue by that name before anything
// is submitted, so no job goes to Slurm twice.
#pragma once

#include <condition_variable>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "server/jobs/executor.hpp"
#include "server/jobs/job_events.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/jobs/slurm_protocol.hpp"
#include "server/store/catalogue.hpp"

namespace softshock::server {

struct SlurmConfig {
  std::string shared_dir;                // absolute; jobs/<id>/ and batches/ below it
  std::string partition, account;        // empty = the cluster's default
  std::string time_limit;                // sbatch --time; empty = the partition's
  std::vector<std::string> sbatch_args;  // appended verbatim
  std::string solver = "softshock-solve";
  int solver_threads = 1;  // --cpus-per-task and softshock-solve --threads
  // The daemon's limits, applied on the compute nodes too: spec limits through softshock-solve,
  // the wall limit as sbatch --time (whole minutes, rounded up) unless time_limit is set.
  int max_elements = 2'000'000;
  double max_end_time_s = 1e-5;
  double max_wall_time_s = 0;  // 0 = none
  // softshock-solve --checkpoint-dir <job>/checkpoint every this many seconds (0 = none): a job
  // that Slurm requeues (node failure, preemption) or that runs again continues from there.
  double checkpoint_interval_s = 0;
  int array_throttle = 0;  // %N of array jobs; 0 = none
  double poll_s = 1.0;
  std::size_t max_queued = 1000;  // not yet submitted + PENDING on Slurm
};

class SlurmExecutor final : public Executor {
 public:
  // Loads the submitted, unfinished jobs from the catalogue (re-attach). Throws
  // std::runtime_error if the shared directory cannot be created.
  SlurmExecutor(SlurmConfig config, Catalogue& catalogue, JobRunner& runner, JobEvents& events);
  ~SlurmExecutor() override;

  void start() override;
  bool reserve(std::size_t slots) override;
  void release(std::size_t slots) override;
  void enqueue(const std::string& id, int priority, int64_t seq, bool reserved) override;
  bool cancel(const std::string& id, StopReason why) override;
  bool is_running(const std::string& id) const override;
  std::size_t queued() const override;
  std::size_t running() const override;
  // Stops polling; sends the cancellations already asked for. Jobs stay on Slurm and are
  // re-attached at the next start, so none is reported as stuck.
  std::vector<std::string> shutdown(std::chrono::milliseconds grace) override;

 private:
  struct Pending {
    std::string id;
    int priority = 0;
    int64_t seq = 0;
  };
  struct Tracked {
    std::string slurm_id;
    bool running = false;  // the catalogue has it RUNNING
    int attempt = 0;
    StopReason cancel = StopReason::kNone;
    bool cancel_sent = false;
  };
  struct Observed {
    std::string state, detail;
  };

  void loop();
  void adopt_submitted_before_crash();
  void submit_pending();
  void collect_batches(const std::vector<Pending>& batch, std::size_t& next,
                       std::vector<JobRecord>& singles,
                       std::map<std::string, std::vector<JobRecord>>& grids,
                       std::set<std::string>& taken);
  void submit_batch_safely(const std::vector<JobRecord>& jobs);
  void submit_batch(const std::vector<JobRecord>& jobs);
  void record_unmarked();  // retries mark_submitted for what sbatch took but was not recorded
  void send_cancels();
  void poll();
  void on_state(const std::string& id, const Observed& observed);
  void finish(const std::string& id, const SlurmOutcome& outcome, const Observed& observed);
  // An id Slurm no longer lists (aged out): scontrol, then sacct, then the files decide.
  Observed look_up_gone(const std::string& id, const std::string& slurm_id);
  void fail_unsubmitted(const JobRecord& job, const std::string& why, const std::string& error);
  std::string job_dir(const std::string& id) const;  // in the shared directory

  SlurmConfig config_;
  Catalogue& catalogue_;
  JobRunner& runner_;
  JobEvents& events_;
  std::string user_;

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<Pending> pending_;                               // QUEUED, not yet handed to Slurm
  std::map<std::string, Tracked> jobs_;                        // handed to Slurm, not finished
  std::vector<std::pair<std::string, std::string>> unmarked_;  // on Slurm, id not committed
  std::size_t reserved_ = 0;
  bool started_ = false, stopping_ = false, nudged_ = false;
  bool adopted_ = false;  // the start-up crash-window check has run
  std::thread thread_;
};

}  // namespace softshock::server
