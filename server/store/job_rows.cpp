#include "server/store/job_rows.hpp"

#include <cmath>
#include <cstring>

#include "server/policy/users.hpp"
#include "server/store/summary_rows.hpp"

namespace softshock::server::detail {

std::string job_columns(const std::string& t) {
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
                        "reuse_result",
                        "owner",
                        "parent_id"}) {
    const std::string name = t + c;
    const bool nullable = std::strcmp(c, "request_id") == 0 || std::strcmp(c, "grid_id") == 0;
    out += (out.empty() ? "" : ", ") + (nullable ? "COALESCE(" + name + ", '')" : name);
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
  j.owner = s.text(22);
  j.parent_id = s.text(23);
  return j;
}

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

namespace {

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

}  // namespace

std::optional<JobRecord> get_job(Connection& c, const std::string& id) {
  return get_job_by(c, "id", id);
}

std::optional<JobRecord> get_by_request_id(Connection& c, const std::string& request_id) {
  return get_job_by(c, "request_id", request_id);
}

int64_t insert_job_row(Connection& c, const NewJob& job) {
  const bool reused = !job.reused_from.empty();
  {
    auto s = c.prepare(
        "INSERT INTO jobs(id, state, spec_json, spec_hash, priority, request_id, create_time_us, "
        "attempt, grid_id, grid_index, reuse_result, reused_from, result_path, start_time_us, "
        "finish_time_us, progress_fraction, pbar, tbar_pulse, mubar, gamma, c1, c2, owner, "
        "parent_id) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, 1, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
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
    s.bind(i, job.owner.empty() ? std::string(kDefaultUser) : job.owner);
    s.bind(i + 1, job.parent_id);
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

int64_t count_queued(Connection& c, const std::string& owner) {
  auto s = c.prepare("SELECT COUNT(*) FROM jobs WHERE owner = ? AND state = ?");
  s.bind(1, owner).bind(2, static_cast<int>(JobState::kQueued));
  return s.step() ? s.i64(0) : 0;
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

}  // namespace softshock::server::detail
