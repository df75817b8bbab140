// The Catalogue's reads of run summaries: one job's summary, the identical run to reuse, and
// QueryJobs' filtered, sorted pages.
#include <cmath>

#include "server/store/catalogue.hpp"
#include "server/store/job_rows.hpp"
#include "server/store/sqlite_connection.hpp"
#include "server/store/summary_rows.hpp"
#include "solver/summary_figures.hpp"

namespace softshock::server {

using namespace detail;

NondimensionalGroups unknown_groups() {
  NondimensionalGroups g;
  g.pbar = g.tbar_pulse = g.mubar = g.gamma = g.c1 = g.c2 = g.time_scale_s = NAN;
  return g;
}

std::optional<StoredSummary> Catalogue::summary(const std::string& id) const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare("SELECT " + stored_summary_columns() +
                            " FROM job_summaries WHERE job_id = ?");
  s.bind(1, id);
  if (!s.step()) return std::nullopt;
  return read_stored_summary(s, 0);
}

namespace {

// QueryJobs names -> SQL, from summary_figures()' queryable rows (a fixed table): user text never
// reaches the SQL. The names are the summary's (units in the name); the service maps the older ones
// (current_summary_name).
const std::vector<std::pair<std::string, std::string>>& query_columns() {
  static const std::vector<std::pair<std::string, std::string>> columns = [] {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& f : summary_figures()) {
      if (f.has(kQueryable)) out.emplace_back(f.name, std::string("j.") + f.column);
    }
    return out;
  }();
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
                                                  const std::string& except_id,
                                                  int solver_revision) const {
  std::lock_guard lock(reader_mutex_);
  std::optional<JobRecord> out;
  {
    // Only jobs that ran themselves: a reuser's file is a link to the same bytes anyway, and
    // pointing at the original keeps reused_from meaningful.
    auto s = reader_->prepare("SELECT " + job_columns() +
                              " FROM jobs WHERE spec_hash = ? AND state = ? AND reused_from = '' "
                              "AND result_path != '' AND id != ? AND EXISTS (SELECT 1 FROM "
                              "job_summaries WHERE job_id = jobs.id AND solver_revision = ?) "
                              "ORDER BY seq LIMIT 1");
    s.bind(1, spec_hash).bind(2, static_cast<int>(JobState::kSucceeded)).bind(3, except_id);
    s.bind(4, static_cast<int64_t>(solver_revision));
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
  if (!q.owner.empty()) page += " AND j.owner = ?";
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
    if (!q.owner.empty()) s.bind(i++, q.owner);
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

}  // namespace softshock::server
