#include "server/store/catalogue.hpp"

#include <sqlite3.h>

#include <chrono>
#include <cstring>
#include <type_traits>
#include <unordered_map>

namespace softshock::server {

const char* to_string(JobState s) {
  switch (s) {
    case JobState::kQueued:
      return "QUEUED";
    case JobState::kRunning:
      return "RUNNING";
    case JobState::kSucceeded:
      return "SUCCEEDED";
    case JobState::kFailed:
      return "FAILED";
    case JobState::kCancelled:
      return "CANCELLED";
  }
  return "JOB_STATE_UNSPECIFIED";
}

int64_t now_us() {
  using namespace std::chrono;
  return duration_cast<microseconds>(system_clock::now().time_since_epoch()).count();
}

namespace {

// Ordered migrations: entry k brings the schema from version k to k + 1. Never edit a shipped
// entry; append a new one.
const char* const kMigrations[] = {
    R"sql(
CREATE TABLE jobs (
  seq INTEGER PRIMARY KEY AUTOINCREMENT,
  id TEXT NOT NULL UNIQUE,
  state INTEGER NOT NULL,
  spec_json TEXT NOT NULL,
  spec_hash TEXT NOT NULL,
  priority INTEGER NOT NULL DEFAULT 0,
  request_id TEXT UNIQUE,
  create_time_us INTEGER NOT NULL,
  start_time_us INTEGER NOT NULL DEFAULT 0,
  finish_time_us INTEGER NOT NULL DEFAULT 0,
  progress_fraction REAL NOT NULL DEFAULT 0,
  progress_time REAL NOT NULL DEFAULT 0,
  progress_steps INTEGER NOT NULL DEFAULT 0,
  progress_dt REAL NOT NULL DEFAULT 0,
  error TEXT NOT NULL DEFAULT '',
  reason TEXT NOT NULL DEFAULT '',
  attempt INTEGER NOT NULL DEFAULT 1,
  result_path TEXT NOT NULL DEFAULT ''
);
CREATE INDEX jobs_state ON jobs(state, priority DESC, seq);
CREATE INDEX jobs_created ON jobs(create_time_us);
CREATE INDEX jobs_spec_hash ON jobs(spec_hash);
CREATE TABLE job_labels (
  job_id TEXT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  key TEXT NOT NULL,
  value TEXT NOT NULL,
  PRIMARY KEY (job_id, key)
);
CREATE INDEX job_labels_key_value ON job_labels(key, value);
CREATE TABLE job_attempts (
  job_id TEXT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  attempt INTEGER NOT NULL,
  start_time_us INTEGER NOT NULL,
  end_time_us INTEGER NOT NULL DEFAULT 0,
  outcome TEXT NOT NULL DEFAULT '',
  reason TEXT NOT NULL DEFAULT '',
  error TEXT NOT NULL DEFAULT ''
);
CREATE INDEX job_attempts_job ON job_attempts(job_id);
CREATE TABLE job_summaries (
  job_id TEXT PRIMARY KEY REFERENCES jobs(id) ON DELETE CASCADE,
  elements INTEGER NOT NULL,
  nodes INTEGER NOT NULL,
  steps INTEGER NOT NULL,
  wall_time REAL NOT NULL,
  end_time REAL NOT NULL,
  pbar REAL NOT NULL,
  tbar_pulse REAL NOT NULL,
  mubar REAL NOT NULL,
  gamma REAL NOT NULL,
  c1 REAL NOT NULL,
  c2 REAL NOT NULL,
  time_scale REAL NOT NULL,
  energy_injected REAL NOT NULL,
  energy_after_pulse REAL NOT NULL,
  max_abar_first_cycle REAL NOT NULL,
  max_abar REAL NOT NULL,
  dominant_mode_end INTEGER NOT NULL,
  shock_at_center REAL NOT NULL,
  rim_reflections BLOB,
  min_dt REAL NOT NULL,
  max_dt REAL NOT NULL,
  status TEXT NOT NULL,
  error TEXT NOT NULL,
  mode_count INTEGER NOT NULL,
  mode_times BLOB,
  mode_amplitudes BLOB
);
CREATE INDEX job_summaries_max_abar ON job_summaries(max_abar);
)sql",
    // 1 -> 2: parameter grids, result reuse, and what QueryJobs filters on. The groups
    // (known at submission, made exact from the summary when a run finishes) and the summary
    // figures are copied onto jobs, so a query is pure SQL over indexed columns of one narrow
    // table: a job_summaries row spans a page or more (its mode amplitudes), and filtering on
    // it would read one page per job. Existing jobs: groups from their summary, or
    // from the stored spec where that needs no square root (SQLite's math functions are a
    // build option); t-bar_pulse of older unfinished jobs stays NULL until they finish.
    R"sql(
ALTER TABLE jobs ADD COLUMN grid_id TEXT;
ALTER TABLE jobs ADD COLUMN grid_index INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN reused_from TEXT NOT NULL DEFAULT '';
ALTER TABLE jobs ADD COLUMN reuse_result INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN pbar REAL;
ALTER TABLE jobs ADD COLUMN tbar_pulse REAL;
ALTER TABLE jobs ADD COLUMN mubar REAL;
ALTER TABLE jobs ADD COLUMN gamma REAL;
ALTER TABLE jobs ADD COLUMN c1 REAL;
ALTER TABLE jobs ADD COLUMN c2 REAL;
UPDATE jobs SET
  pbar = json_extract(spec_json, '$.load.pressure') / json_extract(spec_json, '$.material.bulk_modulus'),
  mubar = json_extract(spec_json, '$.material.shear_modulus') / json_extract(spec_json, '$.material.bulk_modulus'),
  gamma = json_extract(spec_json, '$.material.tait_gamma'),
  c1 = json_extract(spec_json, '$.viscosity.c1'),
  c2 = json_extract(spec_json, '$.viscosity.c2')
  WHERE json_valid(spec_json);
ALTER TABLE jobs ADD COLUMN max_abar_first_cycle REAL;
ALTER TABLE jobs ADD COLUMN max_abar REAL;
ALTER TABLE jobs ADD COLUMN energy_injected REAL;
ALTER TABLE jobs ADD COLUMN energy_after_pulse REAL;
ALTER TABLE jobs ADD COLUMN dominant_mode_end INTEGER;
ALTER TABLE jobs ADD COLUMN shock_at_center REAL;
ALTER TABLE jobs ADD COLUMN wall_time REAL;
ALTER TABLE jobs ADD COLUMN elements INTEGER;
ALTER TABLE jobs ADD COLUMN steps INTEGER;
UPDATE jobs SET (pbar, tbar_pulse, mubar, gamma, c1, c2, max_abar_first_cycle, max_abar,
                 energy_injected, energy_after_pulse, dominant_mode_end, shock_at_center,
                 wall_time, elements, steps) =
  (SELECT s.pbar, s.tbar_pulse, s.mubar, s.gamma, s.c1, s.c2, s.max_abar_first_cycle, s.max_abar,
          s.energy_injected, s.energy_after_pulse, s.dominant_mode_end, s.shock_at_center,
          s.wall_time, s.elements, s.steps FROM job_summaries s WHERE s.job_id = jobs.id)
  WHERE EXISTS (SELECT 1 FROM job_summaries s WHERE s.job_id = jobs.id);
CREATE INDEX jobs_grid ON jobs(grid_id, grid_index) WHERE grid_id IS NOT NULL;
CREATE INDEX jobs_pbar ON jobs(pbar);
CREATE INDEX jobs_tbar_pulse ON jobs(tbar_pulse);
CREATE INDEX jobs_mubar ON jobs(mubar);
CREATE INDEX jobs_gamma ON jobs(gamma);
CREATE INDEX jobs_c1 ON jobs(c1);
CREATE INDEX jobs_c2 ON jobs(c2);
CREATE INDEX jobs_max_abar_first_cycle ON jobs(max_abar_first_cycle);
CREATE INDEX jobs_max_abar ON jobs(max_abar);
CREATE INDEX jobs_energy_injected ON jobs(energy_injected);
CREATE INDEX jobs_dominant_mode_end ON jobs(dominant_mode_end);
ALTER TABLE job_summaries ADD COLUMN abar_times BLOB;
ALTER TABLE job_summaries ADD COLUMN abar_values BLOB;
CREATE TABLE grids (
  seq INTEGER PRIMARY KEY AUTOINCREMENT,
  id TEXT NOT NULL UNIQUE,
  request_id TEXT UNIQUE,
  create_time_us INTEGER NOT NULL,
  point_count INTEGER NOT NULL,
  cancelled INTEGER NOT NULL DEFAULT 0,
  definition TEXT NOT NULL
);
)sql",
    // 2 -> 3: the slurm executor (server/slurm_executor.hpp). The Slurm job id ("123" or
    // "123_4" for an array task) of a job handed to Slurm; '' = not submitted (always so under
    // the local executor). A job with an id is re-attached at start-up, never run again.
    R"sql(
ALTER TABLE jobs ADD COLUMN slurm_job_id TEXT NOT NULL DEFAULT '';
CREATE INDEX jobs_slurm_job_id ON jobs(slurm_job_id) WHERE slurm_job_id != '';
)sql",
    // 3 -> 4: where a run's time went (RunSummary): the element loop alone, the meshing before
    // the run and whether the mesh came from the cache. Older rows: 0 and 'not-used'.
    R"sql(
ALTER TABLE job_summaries ADD COLUMN kernel_time REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN meshing_time REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN mesh_cache TEXT NOT NULL DEFAULT 'not-used';
)sql",
    // 4 -> 5: the late-time figures (RunSummary): A-bar at the end and the filtered A-bar (rebuilt
    // from the low modes), the largest element aspect ratio and when it first exceeded 10
    // (-1 = never). Older rows: 0, and -1 for the time.
    R"sql(
ALTER TABLE job_summaries ADD COLUMN max_abar_filtered_first_cycle REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN max_abar_filtered REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN abar_end REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN abar_filtered_end REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN max_aspect_ratio REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN aspect_ratio_above_10 REAL NOT NULL DEFAULT -1;
)sql",
};

std::string blob_of(const std::vector<double>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(double));
}

}  // namespace

// One sqlite3 handle with a cache of prepared statements. Not thread-safe by itself: the
// Catalogue holds the matching mutex around every use.
namespace detail {

class SqliteConnection {
 public:
  explicit SqliteConnection(const std::string& path) {
    const int rc =
        sqlite3_open_v2(path.c_str(), &db_,
                        SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
    if (rc != SQLITE_OK) {
      std::string msg = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
      sqlite3_close(db_);
      throw CatalogueError("cannot open " + path + ": " + msg);
    }
    // Waiting writers (another process, a checkpoint) retry for up to 5 s instead of failing.
    sqlite3_busy_timeout(db_, 5000);
    exec("PRAGMA foreign_keys = ON");
  }
  ~SqliteConnection() {
    for (auto& [sql, stmt] : cache_) sqlite3_finalize(stmt);
    sqlite3_close(db_);
  }

  void exec(const char* sql) {
    char* err = nullptr;
    if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
      std::string msg = err ? err : "unknown error";
      sqlite3_free(err);
      throw CatalogueError(std::string("sqlite: ") + msg);
    }
  }

  class Stmt {
   public:
    Stmt(SqliteConnection& c, sqlite3_stmt* s) : c_(c), s_(s) {}
    ~Stmt() {
      sqlite3_reset(s_);
      sqlite3_clear_bindings(s_);
    }
    Stmt(const Stmt&) = delete;
    Stmt& operator=(const Stmt&) = delete;

    Stmt& bind(int i, int64_t v) {
      check(sqlite3_bind_int64(s_, i, v));
      return *this;
    }
    Stmt& bind(int i, int v) { return bind(i, static_cast<int64_t>(v)); }
    Stmt& bind(int i, double v) {
      check(sqlite3_bind_double(s_, i, v));
      return *this;
    }
    Stmt& bind(int i, const std::string& v) {
      check(sqlite3_bind_text(s_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
      return *this;
    }
    Stmt& bind_null(int i) {
      check(sqlite3_bind_null(s_, i));
      return *this;
    }
    Stmt& bind_blob(int i, const std::vector<double>& v) {
      const std::string b = blob_of(v);
      check(sqlite3_bind_blob(s_, i, b.data(), static_cast<int>(b.size()), SQLITE_TRANSIENT));
      return *this;
    }
    // true while rows come back.
    bool step() {
      const int rc = sqlite3_step(s_);
      if (rc == SQLITE_ROW) return true;
      if (rc == SQLITE_DONE) return false;
      throw CatalogueError(std::string("sqlite: ") + sqlite3_errmsg(c_.db_));
    }
    void run() {
      while (step()) {
      }
    }
    int64_t i64(int col) const { return sqlite3_column_int64(s_, col); }
    bool is_null(int col) const { return sqlite3_column_type(s_, col) == SQLITE_NULL; }
    bool is_text(int col) const { return sqlite3_column_type(s_, col) == SQLITE_TEXT; }
    double dbl(int col) const { return sqlite3_column_double(s_, col); }
    std::string text(int col) const {
      const auto* p = sqlite3_column_text(s_, col);
      return p ? std::string(reinterpret_cast<const char*>(p),
                             static_cast<std::size_t>(sqlite3_column_bytes(s_, col)))
               : std::string();
    }
    std::vector<double> doubles(int col) const {
      const void* p = sqlite3_column_blob(s_, col);
      const auto bytes = static_cast<std::size_t>(sqlite3_column_bytes(s_, col));
      std::vector<double> v(bytes / sizeof(double));
      if (p && !v.empty()) std::memcpy(v.data(), p, v.size() * sizeof(double));
      return v;
    }

   private:
    void check(int rc) {
      if (rc != SQLITE_OK) throw CatalogueError(std::string("sqlite bind: ") + sqlite3_errstr(rc));
    }
    SqliteConnection& c_;
    sqlite3_stmt* s_;
  };

  Stmt prepare(const std::string& sql) {
    auto it = cache_.find(sql);
    if (it == cache_.end()) {
      sqlite3_stmt* stmt = nullptr;
      if (sqlite3_prepare_v3(db_, sql.c_str(), -1, SQLITE_PREPARE_PERSISTENT, &stmt, nullptr) !=
          SQLITE_OK) {
        throw CatalogueError(std::string("sqlite prepare: ") + sqlite3_errmsg(db_) + " in " + sql);
      }
      it = cache_.emplace(sql, stmt).first;
    }
    return Stmt(*this, it->second);
  }

  int64_t changes() const { return sqlite3_changes64(db_); }
  int64_t last_insert_rowid() const { return sqlite3_last_insert_rowid(db_); }

  // BEGIN IMMEDIATE takes the write lock up front, so a read-modify-write never fails half
  // way with SQLITE_BUSY; the destructor rolls back unless commit() ran.
  class Transaction {
   public:
    explicit Transaction(SqliteConnection& c) : c_(c) { c_.exec("BEGIN IMMEDIATE"); }
    ~Transaction() {
      if (!done_) sqlite3_exec(c_.db_, "ROLLBACK", nullptr, nullptr, nullptr);
    }
    void commit() {
      c_.exec("COMMIT");
      done_ = true;
    }

   private:
    SqliteConnection& c_;
    bool done_ = false;
  };

 private:
  sqlite3* db_ = nullptr;
  std::unordered_map<std::string, sqlite3_stmt*> cache_;
};

}  // namespace detail

namespace {

using Connection = detail::SqliteConnection;

// The job columns read_job() expects, qualified with `t` (a table alias and dot, or empty) so
// queries that join job_summaries (which has its own `error`) stay unambiguous.
std::string job_columns(const std::string& t = "") {
  std::string out;
  for (const char* c : {"seq",
                        "id",
                        "state",
                        "spec_json",
                        "spec_hash",
                        "priority",
                        "request_id",
                        "create_time_us",
                        "start_time_us",
                        "finish_time_us",
                        "progress_fraction",
                        "progress_time",
                        "progress_steps",
                        "progress_dt",
                        "error",
                        "reason",
                        "attempt",
                        "result_path",
                        "grid_id",
                        "grid_index",
                        "reused_from",
                        "reuse_result"}) {
    const std::string name = t + c;
    const bool nullable = std::strcmp(c, "request_id") == 0 || std::strcmp(c, "grid_id") == 0;
    out += (out.empty() ? "" : ", ") + (nullable ? "COALESCE(" + name + ", '')" : name);
  }
  return out;
}
constexpr int kJobColumnCount = 22;

// The summary columns read_summary() expects, qualified like job_columns() (the decimated
// mode data is read separately).
std::string summary_columns(const std::string& t = "") {
  std::string out;
  for (const char* c : {"elements",
                        "nodes",
                        "steps",
                        "wall_time",
                        "end_time",
                        "pbar",
                        "tbar_pulse",
                        "mubar",
                        "gamma",
                        "c1",
                        "c2",
                        "time_scale",
                        "energy_injected",
                        "energy_after_pulse",
                        "max_abar_first_cycle",
                        "max_abar",
                        "dominant_mode_end",
                        "shock_at_center",
                        "rim_reflections",
                        "min_dt",
                        "max_dt",
                        "status",
                        "error",
                        "kernel_time",
                        "meshing_time",
                        "mesh_cache",
                        "max_abar_filtered_first_cycle",
                        "max_abar_filtered",
                        "abar_end",
                        "abar_filtered_end",
                        "max_aspect_ratio",
                        "aspect_ratio_above_10"}) {
    out += (out.empty() ? "" : ", ") + t + c;
  }
  return out;
}

JobRecord read_job(const Connection::Stmt& s) {
  JobRecord j;
  j.seq = s.i64(0);
  j.id = s.text(1);
  j.state = static_cast<JobState>(s.i64(2));
  j.spec_json = s.text(3);
  j.spec_hash = s.text(4);
  j.priority = static_cast<int>(s.i64(5));
  j.request_id = s.text(6);
  j.create_us = s.i64(7);
  j.start_us = s.i64(8);
  j.finish_us = s.i64(9);
  j.progress.fraction = s.dbl(10);
  j.progress.simulated_time_s = s.dbl(11);
  j.progress.steps = s.i64(12);
  j.progress.dt_s = s.dbl(13);
  j.error = s.text(14);
  j.reason = s.text(15);
  j.attempt = static_cast<int>(s.i64(16));
  j.result_path = s.text(17);
  j.grid_id = s.text(18);
  j.grid_index = static_cast<int>(s.i64(19));
  j.reused_from = s.text(20);
  j.reuse_result = s.i64(21) != 0;
  return j;
}

// A summary figure. NaN cannot be stored in the NOT NULL REAL columns of job_summaries (SQLite
// binds NaN as NULL), so it is stored as the text 'NaN', which REAL affinity leaves as text;
// any text reads back as NaN. +-Inf are ordinary REAL values.
void bind_figure(Connection::Stmt& s, int i, double v) {
  if (std::isnan(v)) {
    s.bind(i, std::string("NaN"));
  } else {
    s.bind(i, v);
  }
}
double read_figure(const Connection::Stmt& s, int col) {
  return s.is_text(col) || s.is_null(col) ? NAN : s.dbl(col);
}

// summary_columns() starting at column `c`.
RunSummary read_summary(const Connection::Stmt& s, int c) {
  RunSummary r;
  r.elements = static_cast<std::size_t>(s.i64(c + 0));
  r.nodes = static_cast<std::size_t>(s.i64(c + 1));
  r.steps = s.i64(c + 2);
  r.wall_time_s = read_figure(s, c + 3);
  r.end_time_s = read_figure(s, c + 4);
  r.groups.pbar = read_figure(s, c + 5);
  r.groups.tbar_pulse = read_figure(s, c + 6);
  r.groups.mubar = read_figure(s, c + 7);
  r.groups.gamma = read_figure(s, c + 8);
  r.groups.c1 = read_figure(s, c + 9);
  r.groups.c2 = read_figure(s, c + 10);
  r.groups.time_scale_s = read_figure(s, c + 11);
  r.energy_injected_J_per_m = read_figure(s, c + 12);
  r.energy_after_pulse_J_per_m = read_figure(s, c + 13);
  r.max_abar_first_cycle = read_figure(s, c + 14);
  r.max_abar = read_figure(s, c + 15);
  r.dominant_mode_end = static_cast<int>(s.i64(c + 16));
  r.shock_at_center_s = read_figure(s, c + 17);
  r.rim_reflections_s = s.doubles(c + 18);
  r.min_dt_s = read_figure(s, c + 19);
  r.max_dt_s = read_figure(s, c + 20);
  r.status = s.text(c + 21);
  r.error = s.text(c + 22);
  r.kernel_time_s = s.dbl(c + 23);
  r.meshing_time_s = s.dbl(c + 24);
  r.mesh_cache = s.text(c + 25);
  r.max_abar_filtered_first_cycle = s.dbl(c + 26);
  r.max_abar_filtered = s.dbl(c + 27);
  r.abar_end = s.dbl(c + 28);
  r.abar_filtered_end = s.dbl(c + 29);
  r.max_aspect_ratio = s.dbl(c + 30);
  r.aspect_ratio_above_10_s = s.dbl(c + 31);
  return r;
}
constexpr int kSummaryColumnCount = 32;

// A nullable REAL column: NaN for NULL.
double nullable_double(const Connection::Stmt& s, int col) {
  return s.is_null(col) ? NAN : s.dbl(col);
}

void bind_nullable(Connection::Stmt& s, int i, double v) {
  if (std::isnan(v)) {
    s.bind_null(i);
  } else {
    s.bind(i, v);
  }
}

void load_labels(Connection& c, JobRecord& j) {
  auto s = c.prepare("SELECT key, value FROM job_labels WHERE job_id = ?");
  s.bind(1, j.id);
  while (s.step()) j.labels.emplace(s.text(0), s.text(1));
}

// The job whose unique `column` (id or request_id) equals `value`, with its labels.
std::optional<JobRecord> get_job_by(Connection& c, const char* column, const std::string& value) {
  std::optional<JobRecord> out;
  {
    auto s = c.prepare("SELECT " + job_columns() + " FROM jobs WHERE " + column + " = ?");
    s.bind(1, value);
    if (s.step()) out = read_job(s);
  }
  if (out) load_labels(c, *out);
  return out;
}

std::optional<JobRecord> get_job(Connection& c, const std::string& id) {
  return get_job_by(c, "id", id);
}

std::optional<JobRecord> get_by_request_id(Connection& c, const std::string& request_id) {
  return get_job_by(c, "request_id", request_id);
}

// The summary's query figures as numbers: the 'NaN' text of bind_figure() becomes NULL (not
// known) in the nullable jobs columns, so it never compares as text in a filter.
std::string query_figures() {
  std::string out;
  for (const char* c : {"pbar", "tbar_pulse", "mubar", "gamma", "c1", "c2", "max_abar_first_cycle",
                        "max_abar", "energy_injected", "energy_after_pulse", "dominant_mode_end",
                        "shock_at_center", "wall_time", "elements", "steps"}) {
    out += (out.empty() ? "" : ", ") + std::string("CASE WHEN typeof(") + c +
           ") IN ('real', 'integer') THEN " + c + " END";
  }
  return out;
}

// Copies a job's groups and summary figures from its summary row onto its jobs row (the
// columns QueryJobs filters on); no-op without a summary.
void refresh_query_columns(Connection& c, const std::string& id) {
  auto s = c.prepare(
      "UPDATE jobs SET (pbar, tbar_pulse, mubar, gamma, c1, c2, max_abar_first_cycle, max_abar, "
      "energy_injected, energy_after_pulse, dominant_mode_end, shock_at_center, wall_time, "
      "elements, steps) = (SELECT " +
      query_figures() +
      " FROM job_summaries WHERE job_id = ?1) WHERE id = ?1 AND "
      "EXISTS (SELECT 1 FROM job_summaries WHERE job_id = ?1)");
  s.bind(1, id);
  s.run();
}

// Copies the source job's summary row (A-bar samples and modes included) to `id`.
void copy_summary(Connection& c, const std::string& id, const std::string& source) {
  auto s = c.prepare(
      "INSERT OR REPLACE INTO job_summaries SELECT ?, elements, nodes, steps, wall_time, "
      "end_time, pbar, tbar_pulse, mubar, gamma, c1, c2, time_scale, energy_injected, "
      "energy_after_pulse, max_abar_first_cycle, max_abar, dominant_mode_end, shock_at_center, "
      "rim_reflections, min_dt, max_dt, status, error, mode_count, mode_times, mode_amplitudes, "
      "abar_times, abar_values, kernel_time, meshing_time, mesh_cache, "
      "max_abar_filtered_first_cycle, max_abar_filtered, abar_end, abar_filtered_end, "
      "max_aspect_ratio, aspect_ratio_above_10 FROM job_summaries WHERE job_id = ?");
  s.bind(1, id).bind(2, source);
  s.run();
}

// One job row and its labels; a job that reuses another's result goes in SUCCEEDED, finished,
// with the source's summary.
int64_t insert_job_row(Connection& c, const NewJob& job) {
  const bool reused = !job.reused_from.empty();
  {
    auto s = c.prepare(
        "INSERT INTO jobs(id, state, spec_json, spec_hash, priority, request_id, create_time_us, "
        "attempt, grid_id, grid_index, reuse_result, reused_from, result_path, start_time_us, "
        "finish_time_us, progress_fraction, pbar, tbar_pulse, mubar, gamma, c1, c2) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, 1, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    s.bind(1, job.id);
    s.bind(2, static_cast<int>(reused ? JobState::kSucceeded : JobState::kQueued));
    s.bind(3, job.spec_json).bind(4, job.spec_hash).bind(5, job.priority);
    if (job.request_id.empty()) {
      s.bind_null(6);
    } else {
      s.bind(6, job.request_id);
    }
    s.bind(7, job.create_us);
    if (job.grid_id.empty()) {
      s.bind_null(8);
    } else {
      s.bind(8, job.grid_id);
    }
    s.bind(9, job.grid_index).bind(10, job.reuse_result ? 1 : 0).bind(11, job.reused_from);
    s.bind(12, reused ? job.result_path : std::string());
    s.bind(13, reused ? job.create_us : int64_t{0}).bind(14, reused ? job.create_us : int64_t{0});
    s.bind(15, reused ? 1.0 : 0.0);
    const NondimensionalGroups& g = job.groups;
    int i = 16;
    for (double v : {g.pbar, g.tbar_pulse, g.mubar, g.gamma, g.c1, g.c2}) bind_nullable(s, i++, v);
    s.run();
  }
  const int64_t seq = c.last_insert_rowid();
  for (const auto& [key, value] : job.labels) {
    auto s = c.prepare("INSERT INTO job_labels(job_id, key, value) VALUES (?, ?, ?)");
    s.bind(1, job.id).bind(2, key).bind(3, value);
    s.run();
  }
  if (reused) {
    copy_summary(c, job.id, job.reused_from);
    refresh_query_columns(c, job.id);
  }
  return seq;
}

constexpr const char* kGridColumns =
    "seq, id, COALESCE(request_id, ''), create_time_us, point_count, cancelled, definition";

GridRecord read_grid(const Connection::Stmt& s) {
  GridRecord g;
  g.seq = s.i64(0);
  g.id = s.text(1);
  g.request_id = s.text(2);
  g.create_us = s.i64(3);
  g.point_count = static_cast<int>(s.i64(4));
  g.cancelled = s.i64(5) != 0;
  g.definition = s.text(6);
  return g;
}

std::optional<GridRecord> get_grid_where(Connection& c, const char* column,
                                         const std::string& value) {
  auto s =
      c.prepare(std::string("SELECT ") + kGridColumns + " FROM grids WHERE " + column + " = ?");
  s.bind(1, value);
  if (!s.step()) return std::nullopt;
  return read_grid(s);
}

void close_attempt(Connection& c, const std::string& id, int attempt, const std::string& outcome,
                   const std::string& reason, const std::string& error, int64_t now) {
  // The open row of this attempt (end_time 0); several rows per attempt can exist when an
  // orderly shutdown requeued it without counting an attempt.
  auto s = c.prepare(
      "UPDATE job_attempts SET end_time_us = ?, outcome = ?, reason = ?, error = ? "
      "WHERE job_id = ? AND attempt = ? AND end_time_us = 0");
  s.bind(1, now).bind(2, outcome).bind(3, reason).bind(4, error).bind(5, id).bind(6, attempt);
  s.run();
}

}  // namespace

using Connection = detail::SqliteConnection;

Catalogue::Catalogue(const std::string& path) {
  writer_ = std::make_unique<Connection>(path);
  writer_->exec("PRAGMA journal_mode = WAL");
  // FULL: in WAL mode every commit is fsynced, so acknowledged submissions and terminal
  // transitions survive power loss (NORMAL could roll the last commits back).
  writer_->exec("PRAGMA synchronous = FULL");
  writer_->exec("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)");
  {
    Connection::Transaction tx(*writer_);
    int64_t version = 0;
    bool have_row = false;
    {
      auto s = writer_->prepare("SELECT version FROM schema_version");
      if (s.step()) {
        version = s.i64(0);
        have_row = true;
      }
    }
    if (!have_row) writer_->prepare("INSERT INTO schema_version(version) VALUES (0)").run();
    const auto known = static_cast<int64_t>(std::size(kMigrations));
    if (version > known) {
      throw CatalogueError("catalogue " + path + " has schema version " + std::to_string(version) +
                           ", newer than this softshockd (" + std::to_string(known) + ")");
    }
    for (int64_t v = version; v < known; ++v) writer_->exec(kMigrations[v]);
    writer_->prepare("UPDATE schema_version SET version = ?").bind(1, known).run();
    tx.commit();
  }
  reader_ = std::make_unique<Connection>(path);
}

Catalogue::~Catalogue() = default;

int Catalogue::schema_version() const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare("SELECT version FROM schema_version");
  return s.step() ? static_cast<int>(s.i64(0)) : 0;
}

Catalogue::InsertResult Catalogue::insert(const NewJob& job) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  if (!job.request_id.empty()) {
    if (auto existing = get_by_request_id(c, job.request_id)) return {std::move(*existing), false};
  }
  insert_job_row(c, job);
  auto created = get_job(c, job.id);
  tx.commit();
  return {std::move(*created), true};
}

std::optional<JobRecord> Catalogue::get(const std::string& id) const {
  std::lock_guard lock(reader_mutex_);
  return get_job(*reader_, id);
}

std::optional<JobRecord> Catalogue::find_by_request_id(const std::string& request_id) const {
  std::lock_guard lock(reader_mutex_);
  return get_by_request_id(*reader_, request_id);
}

std::vector<JobRecord> Catalogue::list(const ListFilter& f) const {
  // Build the WHERE clause from the filters in use; the prepared-statement cache keys on the
  // SQL text, so each filter combination is prepared once.
  std::string sql = "SELECT " + job_columns() + " FROM jobs WHERE 1";
  if (f.state) sql += " AND state = :state";
  if (!f.label_key.empty()) {
    sql += " AND EXISTS (SELECT 1 FROM job_labels l WHERE l.job_id = jobs.id AND l.key = :key";
    if (f.label_value) sql += " AND l.value = :value";
    sql += ")";
  }
  if (f.created_after_us) sql += " AND create_time_us > :after";
  if (f.created_before_us) sql += " AND create_time_us < :before";
  if (f.before_seq) sql += " AND seq < :cursor";
  sql += " ORDER BY seq DESC LIMIT :limit";

  std::lock_guard lock(reader_mutex_);
  Connection& c = *reader_;
  std::vector<JobRecord> out;
  {
    auto s = c.prepare(sql);
    int i = 1;
    if (f.state) s.bind(i++, static_cast<int>(*f.state));
    if (!f.label_key.empty()) {
      s.bind(i++, f.label_key);
      if (f.label_value) s.bind(i++, *f.label_value);
    }
    if (f.created_after_us) s.bind(i++, f.created_after_us);
    if (f.created_before_us) s.bind(i++, f.created_before_us);
    if (f.before_seq) s.bind(i++, f.before_seq);
    s.bind(i++, static_cast<int64_t>(f.limit));
    while (s.step()) out.push_back(read_job(s));
  }
  for (auto& j : out) load_labels(c, j);
  return out;
}

std::vector<QueuedJob> Catalogue::queued_jobs() const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare(
      "SELECT id, priority, seq FROM jobs WHERE state = ? ORDER BY priority DESC, seq ASC");
  s.bind(1, static_cast<int>(JobState::kQueued));
  std::vector<QueuedJob> out;
  while (s.step()) out.push_back({s.text(0), static_cast<int>(s.i64(1)), s.i64(2)});
  return out;
}

std::vector<AttemptRecord> Catalogue::attempts(const std::string& id) const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare(
      "SELECT attempt, start_time_us, end_time_us, outcome, reason, error FROM job_attempts "
      "WHERE job_id = ? ORDER BY rowid");
  s.bind(1, id);
  std::vector<AttemptRecord> out;
  while (s.step()) {
    out.push_back(
        {static_cast<int>(s.i64(0)), s.i64(1), s.i64(2), s.text(3), s.text(4), s.text(5)});
  }
  return out;
}

std::optional<StoredSummary> Catalogue::summary(const std::string& id) const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare("SELECT " + summary_columns() +
                            ", mode_count, mode_times, mode_amplitudes, abar_times, abar_values "
                            "FROM job_summaries WHERE job_id = ?");
  s.bind(1, id);
  if (!s.step()) return std::nullopt;
  StoredSummary out;
  out.summary = read_summary(s, 0);
  const int c = kSummaryColumnCount;
  out.mode_count = static_cast<int>(s.i64(c));
  out.mode_times = s.doubles(c + 1);
  out.mode_amplitudes = s.doubles(c + 2);
  out.abar_times = s.doubles(c + 3);
  out.abar_values = s.doubles(c + 4);
  return out;
}

std::map<JobState, int64_t> Catalogue::counts() const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare("SELECT state, COUNT(*) FROM jobs GROUP BY state");
  std::map<JobState, int64_t> out;
  while (s.step()) out[static_cast<JobState>(s.i64(0))] = s.i64(1);
  return out;
}

std::optional<JobRecord> Catalogue::start(const std::string& id, int64_t now) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  {
    auto s = c.prepare(
        "UPDATE jobs SET state = ?, start_time_us = ?, finish_time_us = 0, progress_fraction = 0, "
        "progress_time = 0, progress_steps = 0, progress_dt = 0, error = '', reason = '' "
        "WHERE id = ? AND state = ?");
    s.bind(1, static_cast<int>(JobState::kRunning)).bind(2, now).bind(3, id);
    s.bind(4, static_cast<int>(JobState::kQueued));
    s.run();
  }
  if (c.changes() != 1) return std::nullopt;
  auto job = get_job(c, id);
  {
    auto s = c.prepare("INSERT INTO job_attempts(job_id, attempt, start_time_us) VALUES (?, ?, ?)");
    s.bind(1, id).bind(2, job->attempt).bind(3, now);
    s.run();
  }
  tx.commit();
  return job;
}

bool Catalogue::finish(const std::string& id, int attempt, JobState terminal,
                       const std::string& reason, const std::string& error,
                       const std::string& result_path, const JobProgressRecord& p,
                       const StoredSummary* summary, int64_t now) {
  if (!is_terminal(terminal)) throw std::invalid_argument("finish: not a terminal state");
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  {
    auto s = c.prepare(
        "UPDATE jobs SET state = ?, finish_time_us = ?, reason = ?, error = ?, result_path = ?, "
        "progress_fraction = ?, progress_time = ?, progress_steps = ?, progress_dt = ? "
        "WHERE id = ? AND state = ? AND attempt = ?");
    s.bind(1, static_cast<int>(terminal)).bind(2, now).bind(3, reason).bind(4, error);
    // Progress columns are NOT NULL and only informative: a non-finite figure reads as 0.
    auto figure = [](double v) { return std::isfinite(v) ? v : 0.0; };
    s.bind(5, result_path).bind(6, figure(p.fraction)).bind(7, figure(p.simulated_time_s));
    s.bind(8, p.steps).bind(9, figure(p.dt_s)).bind(10, id);
    s.bind(11, static_cast<int>(JobState::kRunning));
    s.bind(12, attempt);
    s.run();
  }
  if (c.changes() != 1) return false;
  close_attempt(c, id, attempt, to_string(terminal), reason, error, now);
  if (summary) {
    const RunSummary& r = summary->summary;
    auto s = c.prepare(
        "INSERT OR REPLACE INTO job_summaries(job_id, elements, nodes, steps, wall_time, "
        "end_time, pbar, tbar_pulse, mubar, gamma, c1, c2, time_scale, energy_injected, "
        "energy_after_pulse, max_abar_first_cycle, max_abar, dominant_mode_end, shock_at_center, "
        "rim_reflections, min_dt, max_dt, status, error, mode_count, mode_times, "
        "mode_amplitudes, abar_times, abar_values, kernel_time, meshing_time, mesh_cache, "
        "max_abar_filtered_first_cycle, max_abar_filtered, abar_end, abar_filtered_end, "
        "max_aspect_ratio, aspect_ratio_above_10) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
        "?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    // Positional binds in column order (one statement each: clear sequencing).
    int i = 0;
    auto put = [&](auto v) {
      if constexpr (std::is_same_v<decltype(v), double>) {
        bind_figure(s, ++i, v);
      } else {
        s.bind(++i, v);
      }
    };
    auto put_blob = [&](const std::vector<double>& v) { s.bind_blob(++i, v); };
    put(id);
    put(static_cast<int64_t>(r.elements));
    put(static_cast<int64_t>(r.nodes));
    put(r.steps);
    put(r.wall_time_s);
    put(r.end_time_s);
    put(r.groups.pbar);
    put(r.groups.tbar_pulse);
    put(r.groups.mubar);
    put(r.groups.gamma);
    put(r.groups.c1);
    put(r.groups.c2);
    put(r.groups.time_scale_s);
    put(r.energy_injected_J_per_m);
    put(r.energy_after_pulse_J_per_m);
    put(r.max_abar_first_cycle);
    put(r.max_abar);
    put(r.dominant_mode_end);
    put(r.shock_at_center_s);
    put_blob(r.rim_reflections_s);
    put(r.min_dt_s);
    put(r.max_dt_s);
    put(r.status);
    put(r.error);
    put(summary->mode_count);
    put_blob(summary->mode_times);
    put_blob(summary->mode_amplitudes);
    put_blob(summary->abar_times);
    put_blob(summary->abar_values);
    put(r.kernel_time_s);
    put(r.meshing_time_s);
    put(r.mesh_cache);
    put(r.max_abar_filtered_first_cycle);
    put(r.max_abar_filtered);
    put(r.abar_end);
    put(r.abar_filtered_end);
    put(r.max_aspect_ratio);
    put(r.aspect_ratio_above_10_s);
    s.run();
    // The solver's groups are exact (a mesh_file job's R0 is known only once meshed).
    refresh_query_columns(c, id);
  }
  tx.commit();
  return true;
}

bool Catalogue::complete_reused(const std::string& id, const std::string& source,
                                const std::string& result_path, int64_t now) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  {
    auto s = c.prepare(
        "UPDATE jobs SET state = ?, reused_from = ?, result_path = ?, start_time_us = ?, "
        "finish_time_us = ?, progress_fraction = 1, reason = '', error = '' "
        "WHERE id = ? AND state = ?");
    s.bind(1, static_cast<int>(JobState::kSucceeded)).bind(2, source).bind(3, result_path);
    s.bind(4, now).bind(5, now).bind(6, id).bind(7, static_cast<int>(JobState::kQueued));
    s.run();
  }
  if (c.changes() != 1) return false;
  copy_summary(c, id, source);
  refresh_query_columns(c, id);
  tx.commit();
  return true;
}

bool Catalogue::requeue(const std::string& id, int attempt, const std::string& reason,
                        int64_t now) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  {
    auto s = c.prepare(
        "UPDATE jobs SET state = ?, start_time_us = 0, reason = ? "
        "WHERE id = ? AND state = ? AND attempt = ?");
    s.bind(1, static_cast<int>(JobState::kQueued)).bind(2, reason).bind(3, id);
    s.bind(4, static_cast<int>(JobState::kRunning)).bind(5, attempt);
    s.run();
  }
  if (c.changes() != 1) return false;
  close_attempt(c, id, attempt, "REQUEUED", reason, "", now);
  tx.commit();
  return true;
}

bool Catalogue::cancel_queued(const std::string& id, int64_t now) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  auto s = c.prepare(
      "UPDATE jobs SET state = ?, finish_time_us = ?, reason = ?, error = ? "
      "WHERE id = ? AND state = ?");
  s.bind(1, static_cast<int>(JobState::kCancelled)).bind(2, now);
  s.bind(3, std::string(reason::kCancelledByUser)).bind(4, std::string("cancelled while queued"));
  s.bind(5, id).bind(6, static_cast<int>(JobState::kQueued));
  s.run();
  if (c.changes() != 1) return false;
  tx.commit();
  return true;
}

bool Catalogue::erase(const std::string& id) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  // Children first: explicit deletes do not depend on foreign_keys being enforced.
  for (const char* sql :
       {"DELETE FROM job_labels WHERE job_id = ?", "DELETE FROM job_attempts WHERE job_id = ?",
        "DELETE FROM job_summaries WHERE job_id = ?"}) {
    c.prepare(sql).bind(1, id).run();
  }
  c.prepare("DELETE FROM jobs WHERE id = ?").bind(1, id).run();
  const bool removed = c.changes() == 1;
  tx.commit();
  return removed;
}

RecoveryReport Catalogue::recover(int max_attempts, int64_t now) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  std::vector<std::pair<std::string, int>> running;
  {
    // A job running on Slurm was not interrupted by our stop: the slurm executor re-attaches.
    auto s = c.prepare(
        "SELECT id, attempt FROM jobs WHERE state = ? AND slurm_job_id = '' ORDER BY seq");
    s.bind(1, static_cast<int>(JobState::kRunning));
    while (s.step()) running.emplace_back(s.text(0), static_cast<int>(s.i64(1)));
  }
  RecoveryReport report;
  for (const auto& [id, attempt] : running) {
    close_attempt(c, id, attempt, "INTERRUPTED", reason::kInterrupted,
                  "daemon stopped while the job was running", now);
    if (attempt + 1 > max_attempts) {
      auto s = c.prepare(
          "UPDATE jobs SET state = ?, finish_time_us = ?, reason = ?, error = ? WHERE id = ?");
      s.bind(1, static_cast<int>(JobState::kFailed)).bind(2, now);
      s.bind(3, std::string(reason::kMaxAttempts));
      s.bind(4, "interrupted " + std::to_string(attempt) + " time(s); the limit is " +
                    std::to_string(max_attempts) + " attempt(s)");
      s.bind(5, id);
      s.run();
      report.failed.push_back(id);
    } else {
      auto s = c.prepare(
          "UPDATE jobs SET state = ?, attempt = attempt + 1, start_time_us = 0, reason = ? "
          "WHERE id = ?");
      s.bind(1, static_cast<int>(JobState::kQueued)).bind(2, std::string(reason::kInterrupted));
      s.bind(3, id);
      s.run();
      report.requeued.push_back(id);
    }
  }
  tx.commit();
  return report;
}

NondimensionalGroups unknown_groups() {
  NondimensionalGroups g;
  g.pbar = g.tbar_pulse = g.mubar = g.gamma = g.c1 = g.c2 = g.time_scale_s = NAN;
  return g;
}

namespace {

// QueryJobs names -> SQL, from a fixed table: user text never reaches the SQL.
const std::vector<std::pair<std::string, std::string>>& query_columns() {
  static const std::vector<std::pair<std::string, std::string>> columns = {
      {"pbar", "j.pbar"},
      {"tbar_pulse", "j.tbar_pulse"},
      {"mubar", "j.mubar"},
      {"gamma", "j.gamma"},
      {"c1", "j.c1"},
      {"c2", "j.c2"},
      {"max_abar_first_cycle", "j.max_abar_first_cycle"},
      {"max_abar", "j.max_abar"},
      {"energy_injected", "j.energy_injected"},
      {"energy_after_pulse", "j.energy_after_pulse"},
      {"dominant_mode_end", "j.dominant_mode_end"},
      {"shock_at_center", "j.shock_at_center"},
      {"wall_time", "j.wall_time"},
      {"elements", "j.elements"},
      {"steps", "j.steps"},
  };
  return columns;
}

const std::string& query_column_sql(const std::string& name) {
  for (const auto& [n, sql] : query_columns()) {
    if (n == name) return sql;
  }
  throw std::invalid_argument("unknown query column '" + name + "'");
}

}  // namespace

const std::vector<std::string>& query_column_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const auto& [n, sql] : query_columns()) out.push_back(n);
    return out;
  }();
  return names;
}

std::optional<JobRecord> Catalogue::find_reusable(const std::string& spec_hash,
                                                  const std::string& except_id) const {
  std::lock_guard lock(reader_mutex_);
  std::optional<JobRecord> out;
  {
    // Only jobs that ran themselves: a reuser's file is a link to the same bytes anyway, and
    // pointing at the original keeps reused_from meaningful.
    auto s = reader_->prepare("SELECT " + job_columns() +
                              " FROM jobs WHERE spec_hash = ? AND state = ? AND reused_from = '' "
                              "AND result_path != '' AND id != ? AND EXISTS (SELECT 1 FROM "
                              "job_summaries WHERE job_id = jobs.id) ORDER BY seq LIMIT 1");
    s.bind(1, spec_hash).bind(2, static_cast<int>(JobState::kSucceeded)).bind(3, except_id);
    if (s.step()) out = read_job(s);
  }
  if (out) load_labels(*reader_, *out);
  return out;
}

std::vector<QueryRow> Catalogue::query(const JobQuery& q) const {
  // Rows without a value in the sort column sort last either way: the key substitutes +inf
  // (ascending) or -inf (descending) for NULL, which also keeps the keyset cursor total. When a
  // condition on the sort column already excludes NULL, the bare column is the key, so SQLite
  // can walk its index in order instead of sorting every match.
  const bool ordered = !q.order_by.empty();
  const bool desc = !ordered || q.descending;
  bool never_null = false;
  for (const auto& cond : q.conditions) {
    never_null =
        never_null || (cond.name == q.order_by && !(std::isnan(cond.gt) && std::isnan(cond.ge) &&
                                                    std::isnan(cond.lt) && std::isnan(cond.le)));
  }
  const std::string column = ordered ? query_column_sql(q.order_by) : std::string();
  const std::string key = !ordered     ? std::string("0")
                          : never_null ? column
                                       : "IFNULL(" + column + (desc ? ", -9e999)" : ", 9e999)");
  // Two steps: the page is chosen on (key, seq) alone, then only its rows are read whole —
  // sorting thousands of matches with their specs attached would cost far more than the query.
  std::string page = "SELECT j.seq AS page_seq, " + key + " AS page_key FROM jobs j WHERE 1";
  for (const auto& cond : q.conditions) {
    const std::string& col = query_column_sql(cond.name);
    if (!std::isnan(cond.gt)) page += " AND " + col + " > ?";
    if (!std::isnan(cond.ge)) page += " AND " + col + " >= ?";
    if (!std::isnan(cond.lt)) page += " AND " + col + " < ?";
    if (!std::isnan(cond.le)) page += " AND " + col + " <= ?";
  }
  if (q.state) page += " AND j.state = ?";
  if (!q.grid_id.empty()) page += " AND j.grid_id = ?";
  if (q.after_seq > 0) {
    page += ordered ? std::string(" AND (") + key + (desc ? " < ?" : " > ?") + " OR (" + key +
                          " = ? AND j.seq" + (desc ? " < ?" : " > ?") + "))"
                    : std::string(" AND j.seq < ?");
  }
  const std::string order = desc ? " DESC" : " ASC";
  page += " ORDER BY " + (ordered ? key + order + ", " : std::string()) + "j.seq" + order;
  page += " LIMIT ?";
  const std::string sql =
      "SELECT " + job_columns("j.") + ", j.pbar, j.tbar_pulse, j.mubar, j.gamma, j.c1, j.c2, " +
      "p.page_key, s.job_id IS NOT NULL, " + summary_columns("s.") + " FROM (" + page +
      ") p JOIN jobs j ON j.seq = p.page_seq LEFT JOIN job_summaries s ON s.job_id = j.id "
      "ORDER BY p.page_key" +
      order + ", p.page_seq" + order;

  std::lock_guard lock(reader_mutex_);
  Connection& c = *reader_;
  std::vector<QueryRow> out;
  {
    auto s = c.prepare(sql);
    int i = 1;
    for (const auto& cond : q.conditions) {
      for (double bound : {cond.gt, cond.ge, cond.lt, cond.le}) {
        if (!std::isnan(bound)) s.bind(i++, bound);
      }
    }
    if (q.state) s.bind(i++, static_cast<int>(*q.state));
    if (!q.grid_id.empty()) s.bind(i++, q.grid_id);
    if (q.after_seq > 0) {
      if (ordered) {
        s.bind(i++, q.after_key);
        s.bind(i++, q.after_key);
      }
      s.bind(i++, q.after_seq);
    }
    s.bind(i++, static_cast<int64_t>(q.limit));
    while (s.step()) {
      QueryRow row;
      row.job = read_job(s);
      int col = kJobColumnCount;
      NondimensionalGroups& g = row.groups;
      g = unknown_groups();
      g.pbar = nullable_double(s, col++);
      g.tbar_pulse = nullable_double(s, col++);
      g.mubar = nullable_double(s, col++);
      g.gamma = nullable_double(s, col++);
      g.c1 = nullable_double(s, col++);
      g.c2 = nullable_double(s, col++);
      row.sort_key = s.dbl(col++);
      if (s.i64(col++) != 0) {
        row.summary = read_summary(s, col);
        row.groups.time_scale_s = row.summary->groups.time_scale_s;
      }
      out.push_back(std::move(row));
    }
  }
  for (auto& row : out) load_labels(c, row.job);
  return out;
}

Catalogue::GridInsertResult Catalogue::insert_grid(const NewGrid& grid,
                                                   const std::vector<NewJob>& points) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  if (!grid.request_id.empty()) {
    if (auto existing = get_grid_where(c, "request_id", grid.request_id)) {
      return {std::move(*existing), false, {}};
    }
  }
  {
    auto s = c.prepare(
        "INSERT INTO grids(id, request_id, create_time_us, point_count, definition) "
        "VALUES (?, ?, ?, ?, ?)");
    s.bind(1, grid.id);
    if (grid.request_id.empty()) {
      s.bind_null(2);
    } else {
      s.bind(2, grid.request_id);
    }
    s.bind(3, grid.create_us).bind(4, static_cast<int64_t>(points.size()));
    s.bind(5, grid.definition);
    s.run();
  }
  std::vector<int64_t> seqs;
  seqs.reserve(points.size());
  for (const auto& p : points) seqs.push_back(insert_job_row(c, p));
  auto created = get_grid_where(c, "id", grid.id);
  tx.commit();
  return {std::move(*created), true, std::move(seqs)};
}

std::optional<GridRecord> Catalogue::get_grid(const std::string& id) const {
  std::lock_guard lock(reader_mutex_);
  return get_grid_where(*reader_, "id", id);
}

std::optional<GridRecord> Catalogue::find_grid_by_request_id(const std::string& request_id) const {
  std::lock_guard lock(reader_mutex_);
  return get_grid_where(*reader_, "request_id", request_id);
}

std::vector<GridRecord> Catalogue::list_grids(int64_t before_seq, int limit) const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare(std::string("SELECT ") + kGridColumns +
                            " FROM grids WHERE (? = 0 OR seq < ?) ORDER BY seq DESC LIMIT ?");
  s.bind(1, before_seq).bind(2, before_seq).bind(3, static_cast<int64_t>(limit));
  std::vector<GridRecord> out;
  while (s.step()) out.push_back(read_grid(s));
  return out;
}

GridCounts Catalogue::grid_counts(const std::string& grid_id) const {
  std::lock_guard lock(reader_mutex_);
  GridCounts out;
  {
    auto s = reader_->prepare(
        "SELECT state, COUNT(*), SUM(reused_from != '') FROM jobs WHERE grid_id = ? "
        "GROUP BY state");
    s.bind(1, grid_id);
    while (s.step()) {
      out.by_state[static_cast<JobState>(s.i64(0))] = static_cast<int>(s.i64(1));
      out.reused += static_cast<int>(s.i64(2));
    }
  }
  auto s = reader_->prepare("SELECT id FROM jobs WHERE grid_id = ? AND state = ?");
  s.bind(1, grid_id).bind(2, static_cast<int>(JobState::kRunning));
  while (s.step()) out.running.push_back(s.text(0));
  return out;
}

std::vector<GridPoint> Catalogue::grid_points(const std::string& grid_id) const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare(std::string("SELECT j.grid_index, j.id, j.state, s.job_id IS NOT "
                                        "NULL, s.abar_times, s.abar_values, ") +
                            summary_columns("s.") +
                            " FROM jobs j LEFT JOIN job_summaries s ON s.job_id = j.id "
                            "WHERE j.grid_id = ? ORDER BY j.grid_index");
  s.bind(1, grid_id);
  std::vector<GridPoint> out;
  while (s.step()) {
    GridPoint p;
    p.index = static_cast<int>(s.i64(0));
    p.job_id = s.text(1);
    p.state = static_cast<JobState>(s.i64(2));
    if (s.i64(3) != 0) {
      StoredSummary stored;
      stored.abar_times = s.doubles(4);
      stored.abar_values = s.doubles(5);
      stored.summary = read_summary(s, 6);
      p.summary = std::move(stored);
    }
    out.push_back(std::move(p));
  }
  return out;
}

GridCancellation Catalogue::cancel_grid(const std::string& grid_id, int64_t now) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  c.prepare("UPDATE grids SET cancelled = 1 WHERE id = ?").bind(1, grid_id).run();
  GridCancellation out;
  {
    auto s = c.prepare("SELECT id FROM jobs WHERE grid_id = ? AND state = ?");
    s.bind(1, grid_id).bind(2, static_cast<int>(JobState::kQueued));
    while (s.step()) out.cancelled.push_back(s.text(0));
  }
  {
    auto s = c.prepare(
        "UPDATE jobs SET state = ?, finish_time_us = ?, reason = ?, error = ? "
        "WHERE grid_id = ? AND state = ?");
    s.bind(1, static_cast<int>(JobState::kCancelled)).bind(2, now);
    s.bind(3, std::string(reason::kCancelledByUser)).bind(4, std::string("grid cancelled"));
    s.bind(5, grid_id).bind(6, static_cast<int>(JobState::kQueued));
    s.run();
  }
  {
    auto s = c.prepare("SELECT id FROM jobs WHERE grid_id = ? AND state = ?");
    s.bind(1, grid_id).bind(2, static_cast<int>(JobState::kRunning));
    while (s.step()) out.running.push_back(s.text(0));
  }
  tx.commit();
  return out;
}

int Catalogue::mark_submitted(const std::vector<std::pair<std::string, std::string>>& ids) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  int marked = 0;
  for (const auto& [id, slurm_id] : ids) {
    auto s = c.prepare(
        "UPDATE jobs SET slurm_job_id = ? WHERE id = ? AND slurm_job_id = '' AND state = ?");
    s.bind(1, slurm_id).bind(2, id).bind(3, static_cast<int>(JobState::kQueued));
    s.run();
    marked += static_cast<int>(c.changes());
  }
  tx.commit();
  return marked;
}

std::vector<SubmittedJob> Catalogue::submitted_jobs() const {
  std::lock_guard lock(reader_mutex_);
  std::vector<SubmittedJob> out;
  auto s = reader_->prepare(
      "SELECT id, slurm_job_id, state FROM jobs WHERE slurm_job_id != '' AND state IN (?, ?) "
      "ORDER BY seq");
  s.bind(1, static_cast<int>(JobState::kQueued)).bind(2, static_cast<int>(JobState::kRunning));
  while (s.step()) {
    out.push_back({s.text(0), s.text(1), static_cast<JobState>(s.i64(2))});
  }
  return out;
}

std::string Catalogue::slurm_job_id(const std::string& id) const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare("SELECT slurm_job_id FROM jobs WHERE id = ?");
  s.bind(1, id);
  return s.step() ? s.text(0) : std::string();
}

}  // namespace softshock::server
