// The Catalogue's parameter grids: a grid row and its points (ordinary jobs with grid_id and
// grid_index), their counts, their summaries for reductions, and cancelling them.
#include "server/policy/users.hpp"
#include "server/store/catalogue.hpp"
#include "server/store/catalogue_room.hpp"
#include "server/store/job_rows.hpp"
#include "server/store/sqlite_connection.hpp"
#include "server/store/summary_rows.hpp"

namespace softshock::server {

using namespace detail;

namespace {

constexpr const char* kGridColumns =
    "seq, id, COALESCE(request_id, ''), create_time_us, point_count, cancelled, definition, owner";

GridRecord read_grid(const Connection::Stmt& s) {
  GridRecord g;
  g.seq = s.i64(0);
  g.id = s.text(1);
  g.request_id = s.text(2);
  g.create_us = s.i64(3);
  g.point_count = static_cast<int>(s.i64(4));
  g.cancelled = s.i64(5) != 0;
  g.definition = s.text(6);
  g.owner = s.text(7);
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

}  // namespace

Catalogue::GridInsertResult Catalogue::insert_grid(const NewGrid& grid,
                                                   const std::vector<NewJob>& points,
                                                   int64_t max_owner_queued) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  if (!grid.request_id.empty()) {
    if (auto existing = get_grid_where(c, "request_id", grid.request_id)) {
      return {std::move(*existing), false, {}, false, 0};
    }
  }
  if (max_owner_queued > 0) {
    int64_t to_queue = 0;
    for (const auto& p : points) to_queue += p.reused_from.empty() ? 1 : 0;
    const int64_t queued = count_queued(c, grid.owner);
    if (to_queue > 0 && queued + to_queue > max_owner_queued) {
      return {GridRecord{}, false, {}, true, queued};
    }
  }
  {
    auto s = c.prepare(
        "INSERT INTO grids(id, request_id, create_time_us, point_count, definition, owner) "
        "VALUES (?, ?, ?, ?, ?, ?)");
    s.bind(1, grid.id);
    if (grid.request_id.empty()) {
      s.bind_null(2);
    } else {
      s.bind(2, grid.request_id);
    }
    s.bind(3, grid.create_us).bind(4, static_cast<int64_t>(points.size()));
    s.bind(5, grid.definition).bind(6, grid.owner.empty() ? std::string(kDefaultUser) : grid.owner);
    s.run();
  }
  std::vector<int64_t> seqs;
  seqs.reserve(points.size());
  for (const auto& p : points) seqs.push_back(insert_job_row(c, p));
  auto created = get_grid_where(c, "id", grid.id);
  tx.commit();
  return {std::move(*created), true, std::move(seqs), false, 0};
}

std::optional<GridRecord> Catalogue::get_grid(const std::string& id) const {
  std::lock_guard lock(reader_mutex_);
  return get_grid_where(*reader_, "id", id);
}

std::optional<GridRecord> Catalogue::find_grid_by_request_id(const std::string& request_id) const {
  std::lock_guard lock(reader_mutex_);
  return get_grid_where(*reader_, "request_id", request_id);
}

std::vector<GridRecord> Catalogue::list_grids(int64_t before_seq, int limit,
                                              const std::string& owner) const {
  std::lock_guard lock(reader_mutex_);
  auto s = reader_->prepare(std::string("SELECT ") + kGridColumns +
                            " FROM grids WHERE (? = 0 OR seq < ?) AND (? = '' OR owner = ?) "
                            "ORDER BY seq DESC LIMIT ?");
  s.bind(1, before_seq).bind(2, before_seq).bind(3, owner).bind(4, owner);
  s.bind(5, static_cast<int64_t>(limit));
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
  return with_room(room_.get(), [&]() -> GridCancellation {
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
  });
}

}  // namespace softshock::server
