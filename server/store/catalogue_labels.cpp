// The Catalogue's label edits after submission (UpdateJobLabels): removals and upserts of one
// job's rows in job_labels, bounded in count, in one transaction. Like a submission, an edit
// never uses the room kept for a full disk (catalogue_room.hpp): it frees nothing.
#include "server/store/catalogue.hpp"
#include "server/store/job_rows.hpp"
#include "server/store/sqlite_connection.hpp"

namespace softshock::server {

using namespace detail;

Catalogue::LabelUpdate Catalogue::update_labels(const std::string& id,
                                                const std::map<std::string, std::string>& set,
                                                const std::vector<std::string>& remove,
                                                std::size_t max_labels) {
  std::lock_guard lock(writer_mutex_);
  Connection& c = *writer_;
  Connection::Transaction tx(c);
  LabelUpdate out;
  if (!get_job(c, id)) return out;  // rolled back: nothing was written
  for (const auto& key : remove) {
    c.prepare("DELETE FROM job_labels WHERE job_id = ? AND key = ?").bind(1, id).bind(2, key).run();
  }
  for (const auto& [key, value] : set) {
    c.prepare(
         "INSERT INTO job_labels(job_id, key, value) VALUES (?, ?, ?) "
         "ON CONFLICT(job_id, key) DO UPDATE SET value = excluded.value")
        .bind(1, id)
        .bind(2, key)
        .bind(3, value)
        .run();
  }
  auto count = c.prepare("SELECT COUNT(*) FROM job_labels WHERE job_id = ?");
  count.bind(1, id);
  const auto labels = count.step() ? static_cast<std::size_t>(count.i64(0)) : 0;
  if (labels > max_labels) {
    out.too_many = labels;
    return out;  // the transaction rolls back
  }
  tx.commit();
  out.job = get_job(c, id);
  return out;
}

}  // namespace softshock::server
