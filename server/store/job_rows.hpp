// Rows of the jobs, job_labels and job_attempts tables (server/store/ only): the columns a
// JobRecord is read from, and the writes the Catalogue's transitions share.
#pragma once

#include <optional>
#include <string>

#include "server/store/catalogue.hpp"
#include "server/store/sqlite_connection.hpp"

namespace softshock::server::detail {

using Connection = SqliteConnection;

// The job columns read_job() expects, qualified with `t` (a table alias and dot, or empty) so
// queries that join job_summaries (which has its own `error`) stay unambiguous.
std::string job_columns(const std::string& t = "");
inline constexpr int kJobColumnCount = 24;
JobRecord read_job(const Connection::Stmt& s);

// A nullable REAL column: NaN for NULL, and NULL for NaN.
double nullable_double(const Connection::Stmt& s, int col);
void bind_nullable(Connection::Stmt& s, int i, double v);

void load_labels(Connection& c, JobRecord& j);
// The job with this id / request_id, with its labels.
std::optional<JobRecord> get_job(Connection& c, const std::string& id);
std::optional<JobRecord> get_by_request_id(Connection& c, const std::string& request_id);

// One job row and its labels; a job that reuses another's result goes in SUCCEEDED, finished,
// with the source's summary. Returns its seq.
int64_t insert_job_row(Connection& c, const NewJob& job);

// QUEUED jobs of `owner`.
int64_t count_queued(Connection& c, const std::string& owner);

// Ends the open job_attempts row of (id, attempt).
void close_attempt(Connection& c, const std::string& id, int attempt, const std::string& outcome,
                   const std::string& reason, const std::string& error, int64_t now);

}  // namespace softshock::server::detail
