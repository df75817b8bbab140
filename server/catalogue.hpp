// The job catalogue: one SQLite file (DATA/catalogue.sqlite) holding jobs, their labels, attempt
// history and run summaries. It is the single source of truth for job state: every transition
// is a conditional UPDATE inside BEGIN IMMEDIATE on the one writer connection, so a worker
// that lost a race (job cancelled, deleted, or requeued by shutdown) simply sees "false".
// WAL mode; synchronous=FULL so an acknowledged submission or terminal state survives power
// loss. WAL needs a local filesystem (not NFS/SMB).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "solver/run_summary.hpp"

namespace softshock::server {

namespace detail {
class SqliteConnection;
}

// Numbers match softshock.v1.JobState so the service maps them one to one.
enum class JobState { kQueued = 1, kRunning = 2, kSucceeded = 3, kFailed = 4, kCancelled = 5 };
inline bool is_terminal(JobState s) {
  return s == JobState::kSucceeded || s == JobState::kFailed || s == JobState::kCancelled;
}
const char* to_string(JobState s);

// Machine-readable reasons (Job.reason).
namespace reason {
inline constexpr const char* kElementInversion = "ELEMENT_INVERSION";
inline constexpr const char* kNonFinite = "NON_FINITE";
inline constexpr const char* kTimeStepCollapse = "TIME_STEP_COLLAPSE";
inline constexpr const char* kWallTimeLimit = "WALL_TIME_LIMIT";
inline constexpr const char* kInterrupted = "INTERRUPTED";
inline constexpr const char* kMaxAttempts = "MAX_ATTEMPTS";
inline constexpr const char* kCancelledByUser = "CANCELLED_BY_USER";
inline constexpr const char* kInvalidSpec = "INVALID_SPEC";
inline constexpr const char* kShutdown = "SHUTDOWN";
inline constexpr const char* kInternal = "INTERNAL";
}  // namespace reason

class CatalogueError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct JobProgressRecord {
  double fraction = 0, simulated_time_s = 0, dt_s = 0;
  int64_t steps = 0;
};

struct JobRecord {
  int64_t seq = 0;  // insertion order: FIFO key and pagination cursor
  std::string id;
  JobState state = JobState::kQueued;
  std::string spec_json;  // normalised spec, every field present
  std::string spec_hash;
  std::map<std::string, std::string> labels;
  int priority = 0;
  std::string request_id;                              // empty = none
  int64_t create_us = 0, start_us = 0, finish_us = 0;  // µs since the epoch; 0 = not yet
  JobProgressRecord progress;
  std::string error, reason;
  int attempt = 1;  // 1 for the first run; +1 per restart after an interrupted run
  std::string result_path;
};

struct NewJob {
  std::string id, spec_json, spec_hash, request_id;
  std::map<std::string, std::string> labels;
  int priority = 0;
  int64_t create_us = 0;
};

// The catalogued figures of a finished run: the solver's summary plus the mode amplitudes
// decimated to ~4 ns (row-major mode_times.size() x mode_count, modes 0..mode_count-1).
struct StoredSummary {
  RunSummary summary;
  std::vector<double> mode_times;
  int mode_count = 0;
  std::vector<double> mode_amplitudes;
};

struct AttemptRecord {
  int attempt = 0;
  int64_t start_us = 0, end_us = 0;
  std::string outcome, reason, error;  // outcome: a JobState name, or "REQUEUED"
};

struct ListFilter {
  std::optional<JobState> state;
  std::string label_key;                   // empty = any
  std::optional<std::string> label_value;  // unset = any value of label_key
  int64_t created_after_us = 0;            // exclusive; 0 = no bound
  int64_t created_before_us = 0;           // exclusive; 0 = no bound
  int64_t before_seq = 0;                  // page cursor: only seq < this; 0 = from the newest
  int limit = 50;
};

struct QueuedJob {
  std::string id;
  int priority = 0;
  int64_t seq = 0;
};

struct RecoveryReport {
  std::vector<std::string> requeued;  // were RUNNING: back to QUEUED, attempt + 1
  std::vector<std::string> failed;    // were RUNNING with no attempts left: FAILED MAX_ATTEMPTS
};

class Catalogue {
 public:
  // Opens (creating if needed) the database and applies pending migrations in order.
  explicit Catalogue(const std::string& path);
  ~Catalogue();
  Catalogue(const Catalogue&) = delete;
  Catalogue& operator=(const Catalogue&) = delete;

  int schema_version() const;

  // Inserts a QUEUED job, durably. With a request_id already known, returns that job instead
  // (created = false) — the AIP-155 idempotent create.
  struct InsertResult {
    JobRecord job;
    bool created = false;
  };
  InsertResult insert(const NewJob& job);

  std::optional<JobRecord> get(const std::string& id) const;
  std::optional<JobRecord> find_by_request_id(const std::string& request_id) const;
  // Newest first (seq descending).
  std::vector<JobRecord> list(const ListFilter& filter) const;
  // Every QUEUED job, in run order: priority descending, then FIFO.
  std::vector<QueuedJob> queued_jobs() const;
  std::vector<AttemptRecord> attempts(const std::string& id) const;
  std::optional<StoredSummary> summary(const std::string& id) const;
  // Counts per state (for the start-up log).
  std::map<JobState, int64_t> counts() const;

  // --- transitions (each one transaction; false when the job is not in the expected state)
  // QUEUED -> RUNNING; returns the job as started.
  std::optional<JobRecord> start(const std::string& id, int64_t now_us);
  // RUNNING (this attempt) -> SUCCEEDED / FAILED / CANCELLED, with an optional summary.
  bool finish(const std::string& id, int attempt, JobState terminal, const std::string& reason,
              const std::string& error, const std::string& result_path,
              const JobProgressRecord& progress, const StoredSummary* summary, int64_t now_us);
  // RUNNING (this attempt) -> QUEUED, same attempt: an orderly shutdown interrupted the run,
  // which is not the job's fault.
  bool requeue(const std::string& id, int attempt, const std::string& reason, int64_t now_us);
  // QUEUED -> CANCELLED.
  bool cancel_queued(const std::string& id, int64_t now_us);
  // Removes the job, its labels, attempts and summary.
  bool erase(const std::string& id);
  // At start-up: every RUNNING job was interrupted by a crash. Requeue it with attempt + 1
  // (INTERRUPTED in the attempt history), or fail it with MAX_ATTEMPTS beyond max_attempts.
  RecoveryReport recover(int max_attempts, int64_t now_us);

 private:
  std::unique_ptr<detail::SqliteConnection> writer_;
  std::unique_ptr<detail::SqliteConnection> reader_;
  mutable std::mutex writer_mutex_;
  mutable std::mutex reader_mutex_;
};

int64_t now_us();

}  // namespace softshock::server
