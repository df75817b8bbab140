// Rows of the job_summaries table (server/store/ only). Its columns are the catalogued figures
// of solver/summary_figures.hpp's table, then the decimated series (a table in
// summary_rows.cpp); the SELECT lists, the reads, the INSERT and the copy of a reused run's row
// are all generated from them.
#pragma once

#include <string>

#include "server/store/catalogue.hpp"
#include "server/store/sqlite_connection.hpp"

namespace softshock::server::detail {

// The RunSummary figures' columns, qualified with `t` (a table alias and dot, or empty), in
// the order read_summary() reads them; summary_column_count() of them.
std::string summary_columns(const std::string& t = "");
int summary_column_count();
// The RunSummary whose summary_columns() start at column `c`.
RunSummary read_summary(const SqliteConnection::Stmt& s, int c);

// Every job_summaries column but job_id: the figures, then the decimated series (modes,
// A-bar), as read_stored_summary() reads them.
std::string stored_summary_columns();
StoredSummary read_stored_summary(const SqliteConnection::Stmt& s, int c);

// Inserts or replaces job `id`'s summary row.
void write_summary(SqliteConnection& c, const std::string& id, const StoredSummary& stored);
// Copies the source job's summary row (A-bar samples and modes included) to `id`.
void copy_summary(SqliteConnection& c, const std::string& id, const std::string& source);
// Copies a job's groups and summary figures from its summary row onto its jobs row (the
// columns QueryJobs filters on); no-op without a summary.
void refresh_query_columns(SqliteConnection& c, const std::string& id);

}  // namespace softshock::server::detail
