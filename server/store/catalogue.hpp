// The job catalogue: one SQLite file (DATA/catalogue.sqlite) holding jobs, their labels, attempt
// history, run summaries and parameter grids. It is the single source of truth for job state: every
// transition is a conditional UPDATE inside BEGIN IMMEDIATE on the one writer connection, so a
// worker that lost a race (job cancelled, deleted, or requeued by shutdown) simply sees "false".
// WAL mode; synchronous=FULL so an acknowledged submission or terminal state survives power
// loss. WAL needs a local filesystem (not NFS/SMB).
#pragma once

#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/store/resource_exhausted.hpp"
#include "solver/run_summary.hpp"

namespace softshock::server {

namespace detail {
class SqliteConnection;
class CatalogueRoom;
}  // namespace detail

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
inline constexpr const char* kMeshDistortion = "MESH_DISTORTION";
inline constexpr const char* kWallTimeExceeded = "WALL_TIME_EXCEEDED";
inline constexpr const char* kDiskFull = "DISK_FULL";
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

// A write failed because the disk is full (SQLITE_FULL): RESOURCE_EXHAUSTED for a client, not
// the catalogue's fault.
class CatalogueFull : public ResourceExhausted {
 public:
  using ResourceExhausted::ResourceExhausted;
};

// The space the catalogue keeps on its disk for deletions and outcomes (catalogue_room.hpp).
inline constexpr std::int64_t kCatalogueRoomBytes = std::int64_t{8} << 20;

struct JobProgressRecord {
  double fraction = 0, simulated_time_s = 0, dt_s = 0;
  int64_t steps = 0;
  int64_t elements = 0;  // of the running mesh, when the runner knows it (live only, not stored)
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
  std::string grid_id;  // empty = not a grid point
  int grid_index = 0;
  std::string reused_from;  // the SUCCEEDED job whose result this one reuses; empty = ran itself
  bool reuse_result = false;
  std::string owner;      // the user who submitted it (server/policy/users.hpp)
  std::string parent_id;  // ExtendJob: the job it continues; empty = none
};

// The nondimensional groups of a job as catalogued (indexed columns; NaN = not known yet, e.g.
// t-bar_pulse of a mesh_file job before it has been meshed).
NondimensionalGroups unknown_groups();

struct NewJob {
  std::string id, spec_json, spec_hash, request_id;
  std::map<std::string, std::string> labels;
  int priority = 0;
  int64_t create_us = 0;
  NondimensionalGroups groups = unknown_groups();
  std::string grid_id;  // empty = a lone job
  int grid_index = 0;
  bool reuse_result = false;  // may reuse an identical SUCCEEDED run (at start)
  // Inserted already SUCCEEDED, reusing this job's result (its summary is copied); result_path
  // must then name the linked result file.
  std::string reused_from;
  std::string result_path;
  std::string owner;      // the submitting user
  std::string parent_id;  // ExtendJob: the job it continues
};

// The catalogued figures of a finished run: the solver's summary plus the mode amplitudes
// decimated to ~4 ns (row-major mode_times.size() x mode_count, modes 0..mode_count-1) and
// A-bar(t) decimated to at most ~1000 samples (so grid reductions never open result files).
struct StoredSummary {
  RunSummary summary;
  std::vector<double> mode_times;
  int mode_count = 0;
  std::vector<double> mode_amplitudes;
  std::vector<double> abar_times, abar_values;
};

// A parameter grid. `definition` is the service's own encoding of the base spec and axes (the
// catalogue stores it opaquely); the points are ordinary jobs carrying grid_id and grid_index.
struct GridRecord {
  int64_t seq = 0;
  std::string id;
  std::string request_id;
  int64_t create_us = 0;
  int point_count = 0;
  bool cancelled = false;
  std::string definition;
  std::string owner;
};

struct NewGrid {
  std::string id, request_id, definition, owner;
  int64_t create_us = 0;
};

struct GridCounts {
  std::map<JobState, int> by_state;
  int reused = 0;
  std::vector<std::string> running;  // ids of the running points (for live progress)
};

struct GridCancellation {
  std::vector<std::string> cancelled;  // were QUEUED, now CANCELLED
  std::vector<std::string> running;    // still RUNNING: to be stopped
};

// One point of a grid with its catalogued summary, if it has one.
struct GridPoint {
  int index = 0;
  std::string job_id;
  JobState state = JobState::kQueued;
  std::optional<StoredSummary> summary;  // mode data left out
};

// A numeric condition of a query: lower/upper bounds (NaN = none) on a named column.
struct RangeCondition {
  std::string name;  // one of query_column_names()
  double gt = NAN, ge = NAN, lt = NAN, le = NAN;
};

struct JobQuery {
  std::vector<RangeCondition> conditions;
  std::optional<JobState> state;
  std::string grid_id;     // empty = any
  std::string owner;       // empty = any
  std::string order_by;    // a query column; empty = newest first
  bool descending = true;  // for order_by
  // Keyset cursor: rows after (after_key, after_seq) in the sort order; after_seq 0 = first page.
  double after_key = 0;
  int64_t after_seq = 0;
  int limit = 50;
};

struct QueryRow {
  JobRecord job;
  NondimensionalGroups groups;
  std::optional<RunSummary> summary;
  double sort_key = 0;  // the cursor value of this row
};

// Names QueryJobs accepts: the groups, then the summary figures.
const std::vector<std::string>& query_column_names();

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
  std::string owner;                       // empty = any
  int limit = 50;
};

struct QueuedJob {
  std::string id;
  int priority = 0;
  int64_t seq = 0;
};

// A job handed to Slurm that has not finished (slurm executor).
struct SubmittedJob {
  std::string id, slurm_job_id;
  JobState state = JobState::kQueued;
};

struct RecoveryReport {
  std::vector<std::string> requeued;  // were RUNNING: back to QUEUED, attempt + 1
  std::vector<std::string> failed;    // were RUNNING with no attempts left: FAILED MAX_ATTEMPTS
};

class Catalogue {
 public:
  // Opens (creating if needed) the database and applies pending migrations in order, and takes
  // `room_bytes` of the disk beside it (path with the extension .room) for the writes that must
  // work on a full disk (catalogue_room.hpp; 0 = none).
  explicit Catalogue(const std::string& path, int64_t room_bytes = kCatalogueRoomBytes);
  ~Catalogue();
  Catalogue(const Catalogue&) = delete;
  Catalogue& operator=(const Catalogue&) = delete;

  int schema_version() const;

  // Inserts a QUEUED job, durably. With a request_id already known, returns that job instead
  // (created = false) — the AIP-155 idempotent create. With max_owner_queued > 0, refuses
  // (refused = true, created = false, owner_queued = the owner's QUEUED jobs) a job whose owner
  // has that many QUEUED jobs already; counted in the insert's own transaction, so concurrent
  // submissions cannot pass the bound together. A full disk throws CatalogueFull.
  struct InsertResult {
    JobRecord job;
    bool created = false;
    bool refused = false;
    int64_t owner_queued = 0;
  };
  InsertResult insert(const NewJob& job, int64_t max_owner_queued = 0);

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
  // QUEUED jobs of one owner.
  int64_t queued_of(const std::string& owner) const;
  // (job id, geometry.mesh_file) of every QUEUED or RUNNING job whose spec names a mesh file, in
  // submission order: what DeleteMesh must not pull from under a job.
  std::vector<std::pair<std::string, std::string>> unfinished_mesh_files() const;
  // The first SUCCEEDED job with this spec hash that ran itself, has a result file and a summary
  // from solver revision `solver_revision` (the running one), other than `except_id`: what an
  // identical run may reuse. A result of other numerics is never passed off as this solver's.
  std::optional<JobRecord> find_reusable(const std::string& spec_hash,
                                         const std::string& except_id = "",
                                         int solver_revision = kSolverRevision) const;
  // Jobs matching every condition, in the requested order, one page.
  std::vector<QueryRow> query(const JobQuery& query) const;

  // --- grids
  // Inserts the grid and all its points in one durable transaction (points with reused_from
  // go in SUCCEEDED, the rest QUEUED). With a request_id already known, returns that grid
  // instead (created = false) and inserts nothing.
  // max_owner_queued as for insert(), for the points that go in QUEUED (all or none).
  struct GridInsertResult {
    GridRecord grid;
    bool created = false;
    std::vector<int64_t> point_seqs;  // the points' seq (FIFO key), in the order given
    bool refused = false;
    int64_t owner_queued = 0;
  };
  GridInsertResult insert_grid(const NewGrid& grid, const std::vector<NewJob>& points,
                               int64_t max_owner_queued = 0);
  std::optional<GridRecord> get_grid(const std::string& id) const;
  std::optional<GridRecord> find_grid_by_request_id(const std::string& request_id) const;
  // Newest first; before_seq 0 = from the newest; owner empty = any.
  std::vector<GridRecord> list_grids(int64_t before_seq, int limit,
                                     const std::string& owner = "") const;
  GridCounts grid_counts(const std::string& grid_id) const;
  // Every point in index order, with summaries (A-bar samples included, modes left out).
  std::vector<GridPoint> grid_points(const std::string& grid_id) const;
  // Marks the grid cancelled and cancels its QUEUED points at once. The caller drops those from
  // the scheduler's queue and stops the RUNNING ones through it.
  GridCancellation cancel_grid(const std::string& grid_id, int64_t now_us);

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
  // QUEUED -> SUCCEEDED without running: the job reuses the result of `source` (linked into
  // its own folder as result_path) and gets a copy of its summary.
  bool complete_reused(const std::string& id, const std::string& source,
                       const std::string& result_path, int64_t now_us);
  // QUEUED -> CANCELLED.
  bool cancel_queued(const std::string& id, int64_t now_us);
  // Removes the job, its labels, attempts and summary.
  bool erase(const std::string& id);
  // Sets and removes labels of one job in one transaction (catalogue_labels.cpp); the job as it
  // now is, or nullopt when it does not exist. With more than max_labels labels afterwards
  // nothing changes and `too_many` holds the count the change would have left.
  struct LabelUpdate {
    std::optional<JobRecord> job;
    std::size_t too_many = 0;
  };
  LabelUpdate update_labels(const std::string& id, const std::map<std::string, std::string>& set,
                            const std::vector<std::string>& remove, std::size_t max_labels);
  // --- the slurm executor
  // Records the Slurm job ids of QUEUED jobs that are not submitted yet, all in one durable
  // transaction (a whole array job at once); returns how many were recorded.
  int mark_submitted(const std::vector<std::pair<std::string, std::string>>& ids);
  // QUEUED and RUNNING jobs that have a Slurm job id, in seq order (re-attached at start-up).
  std::vector<SubmittedJob> submitted_jobs() const;
  // The job's Slurm job id; empty when not submitted or unknown.
  std::string slurm_job_id(const std::string& id) const;

  // At start-up: every RUNNING job was interrupted by a crash (except one with a Slurm job
  // id, which ran on and is re-attached instead). Requeue it with attempt + 1
  // (INTERRUPTED in the attempt history), or fail it with MAX_ATTEMPTS beyond max_attempts.
  RecoveryReport recover(int max_attempts, int64_t now_us);

  // --- the room kept for a full disk (catalogue_room.hpp)
  // Takes the room back if it was used (after something was deleted); false while the disk
  // lacks the space.
  bool refill_room();
  bool room_held() const;
  // refill_room() unless the room is held (a stat when it is): after deletions, and before a
  // submission is taken.
  void keep_room();

 private:
  std::unique_ptr<detail::CatalogueRoom> room_;
  std::unique_ptr<detail::SqliteConnection> writer_;
  std::unique_ptr<detail::SqliteConnection> reader_;
  mutable std::mutex writer_mutex_;
  mutable std::mutex reader_mutex_;
};

int64_t now_us();

}  // namespace softshock::server
