// The Catalogue's job rows and their transitions; its reads of summaries are in
// catalogue_queries.cpp, its grids in catalogue_grids.cpp, the schema in catalogue_schema.cpp.
#include "server/store/catalogue.hpp"

#include <chrono>
#include <filesystem>

#include "server/store/catalogue_room.hpp"
#include "server/store/catalogue_schema.hpp"
#include "server/store/job_rows.hpp"
#include "server/store/sqlite_connection.hpp"
#include "server/store/summary_rows.hpp"

namespace softshock::server {

using namespace detail;

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

Catalogue::Catalogue(const std::string& path, int64_t room_bytes) {
  if (room_bytes > 0) {
    // Taken before the database grows, so a disk that fills later still has it.
    room_ = std::make_unique<CatalogueRoom>(
        std::filesystem::path(path).replace_extension(".room").string(), room_bytes);
    refill_room();
  }
  writer_ = std::make_unique<Connection>(path);
  writer_->exec("PRAGMA journal_mode = WAL");
  // FULL: in WAL mode every commit is fsynced, so acknowledged submissions and terminal
  // transitions survive power loss (NORMAL could roll the last commits back).
  writer_->exec("PRAGMA synchronous = FULL");
  migrate_catalogue(*writer_, path);
  reader_ = std::make_unique<Connection>(path);
}

Catalogue::~Catalogue() = default;

bool Catalogue::refill_room() {
  return room_ && room_->refill();
}

bool Catalogue::room_held() const {
  return room_ && room_->held();
}

void Catalogue::keep_room() {
  if (room_ && !room_->held()) room_->refill();
}

int Catalogue::schema_version() const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare("SELECT version FROM schema_version");
  return s.step() ? static_cast<int>(s.i64(0)) : 0;
}

Catalogue::InsertResult Catalogue::insert(const NewJob& job, int64_t max_owner_queued) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  if (!job.request_id.empty()) {
    if (auto existing = get_by_request_id(c, job.request_id)) {
      return {std::move(*existing), false, false, 0};
    }
  }
  if (max_owner_queued > 0 && job.reused_from.empty()) {
    const int64_t queued = count_queued(c, job.owner);
    if (queued + 1 > max_owner_queued) return {JobRecord{}, false, true, queued};
  }
  insert_job_row(c, job);
  auto created = get_job(c, job.id);
  tx.commit();
  return {std::move(*created), true, false, 0};
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
  if (!f.owner.empty()) sql += " AND owner = :owner";
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
    if (!f.owner.empty()) s.bind(i++, f.owner);
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

std::map<JobState, int64_t> Catalogue::counts() const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare("SELECT state, COUNT(*) FROM jobs GROUP BY state");
  std::map<JobState, int64_t> out;
  while (s.step()) out[static_cast<JobState>(s.i64(0))] = s.i64(1);
  return out;
}

int64_t Catalogue::queued_of(const std::string& owner) const {
  std::lock_guard lock(reader_mutex_);
  return count_queued(*reader_, owner);
}

std::vector<std::pair<std::string, std::string>> Catalogue::unfinished_mesh_files() const {
  std::lock_guard lock(reader_mutex_);
  // Stored specs are protobuf JSON with the proto field names (geometry.mesh_file).
  auto s = reader_->prepare(
      "SELECT id, json_extract(spec_json, '$.geometry.mesh_file') FROM jobs "
      "WHERE state IN (?, ?) AND json_valid(spec_json) "
      "AND json_extract(spec_json, '$.geometry.mesh_file') IS NOT NULL ORDER BY seq");
  s.bind(1, static_cast<int>(JobState::kQueued)).bind(2, static_cast<int>(JobState::kRunning));
  std::vector<std::pair<std::string, std::string>> out;
  while (s.step()) {
    if (s.is_text(1)) out.emplace_back(s.text(0), s.text(1));
  }
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
  return with_room(room_.get(), [&]() -> bool {
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
      write_summary(c, id, *summary);
      // The solver's groups are exact (a mesh_file job's R0 is known only once meshed).
      refresh_query_columns(c, id);
    }
    tx.commit();
    return true;
  });
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
  return with_room(room_.get(), [&]() -> bool {
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
  });
}

bool Catalogue::cancel_queued(const std::string& id, int64_t now) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  return with_room(room_.get(), [&]() -> bool {
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
  });
}

bool Catalogue::erase(const std::string& id) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  // Needed on a full disk too: the room is used if it must be.
  return with_room(room_.get(), [&]() -> bool {
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
  });
}

RecoveryReport Catalogue::recover(int max_attempts, int64_t now) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  return with_room(room_.get(), [&]() -> RecoveryReport {
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
  });
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
