#include "server/catalogue.hpp"

#include <sqlite3.h>

#include <chrono>
#include <cstring>
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

constexpr const char* kJobColumns =
    "seq, id, state, spec_json, spec_hash, priority, COALESCE(request_id, ''), create_time_us, "
    "start_time_us, finish_time_us, progress_fraction, progress_time, progress_steps, "
    "progress_dt, error, reason, attempt, result_path";

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
  return j;
}

void load_labels(Connection& c, JobRecord& j) {
  auto s = c.prepare("SELECT key, value FROM job_labels WHERE job_id = ?");
  s.bind(1, j.id);
  while (s.step()) j.labels.emplace(s.text(0), s.text(1));
}

std::optional<JobRecord> get_job(Connection& c, const std::string& id) {
  std::optional<JobRecord> out;
  {
    auto s = c.prepare(std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id = ?");
    s.bind(1, id);
    if (s.step()) out = read_job(s);
  }
  if (out) load_labels(c, *out);
  return out;
}

std::optional<JobRecord> get_by_request_id(Connection& c, const std::string& request_id) {
  std::optional<JobRecord> out;
  {
    auto s = c.prepare(std::string("SELECT ") + kJobColumns + " FROM jobs WHERE request_id = ?");
    s.bind(1, request_id);
    if (s.step()) out = read_job(s);
  }
  if (out) load_labels(c, *out);
  return out;
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
  {
    auto s = c.prepare(
        "INSERT INTO jobs(id, state, spec_json, spec_hash, priority, request_id, create_time_us, "
        "attempt) VALUES (?, ?, ?, ?, ?, ?, ?, 1)");
    s.bind(1, job.id).bind(2, static_cast<int>(JobState::kQueued)).bind(3, job.spec_json);
    s.bind(4, job.spec_hash).bind(5, job.priority);
    if (job.request_id.empty()) {
      s.bind_null(6);
    } else {
      s.bind(6, job.request_id);
    }
    s.bind(7, job.create_us);
    s.run();
  }
  for (const auto& [key, value] : job.labels) {
    auto s = c.prepare("INSERT INTO job_labels(job_id, key, value) VALUES (?, ?, ?)");
    s.bind(1, job.id).bind(2, key).bind(3, value);
    s.run();
  }
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
  std::string sql = std::string("SELECT ") + kJobColumns + " FROM jobs WHERE 1";
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
  auto s = reader_->prepare(
      "SELECT elements, nodes, steps, wall_time, end_time, pbar, tbar_pulse, mubar, gamma, c1, "
      "c2, time_scale, energy_injected, energy_after_pulse, max_abar_first_cycle, max_abar, "
      "dominant_mode_end, shock_at_center, rim_reflections, min_dt, max_dt, status, error, "
      "mode_count, mode_times, mode_amplitudes FROM job_summaries WHERE job_id = ?");
  s.bind(1, id);
  if (!s.step()) return std::nullopt;
  StoredSummary out;
  RunSummary& r = out.summary;
  r.elements = static_cast<std::size_t>(s.i64(0));
  r.nodes = static_cast<std::size_t>(s.i64(1));
  r.steps = s.i64(2);
  r.wall_time_s = s.dbl(3);
  r.end_time_s = s.dbl(4);
  r.groups.pbar = s.dbl(5);
  r.groups.tbar_pulse = s.dbl(6);
  r.groups.mubar = s.dbl(7);
  r.groups.gamma = s.dbl(8);
  r.groups.c1 = s.dbl(9);
  r.groups.c2 = s.dbl(10);
  r.groups.time_scale_s = s.dbl(11);
  r.energy_injected_J_per_m = s.dbl(12);
  r.energy_after_pulse_J_per_m = s.dbl(13);
  r.max_abar_first_cycle = s.dbl(14);
  r.max_abar = s.dbl(15);
  r.dominant_mode_end = static_cast<int>(s.i64(16));
  r.shock_at_center_s = s.dbl(17);
  r.rim_reflections_s = s.doubles(18);
  r.min_dt_s = s.dbl(19);
  r.max_dt_s = s.dbl(20);
  r.status = s.text(21);
  r.error = s.text(22);
  out.mode_count = static_cast<int>(s.i64(23));
  out.mode_times = s.doubles(24);
  out.mode_amplitudes = s.doubles(25);
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
    s.bind(5, result_path).bind(6, p.fraction).bind(7, p.simulated_time_s).bind(8, p.steps);
    s.bind(9, p.dt_s).bind(10, id).bind(11, static_cast<int>(JobState::kRunning));
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
        "mode_amplitudes) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
        "?, ?, ?, ?, ?, ?)");
    // Positional binds in column order (one statement each: clear sequencing).
    int i = 0;
    auto put = [&](auto v) { s.bind(++i, v); };
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
    s.run();
  }
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
    auto s = c.prepare("SELECT id, attempt FROM jobs WHERE state = ? ORDER BY seq");
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

}  // namespace softshock::server
