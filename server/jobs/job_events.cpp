#include "server/jobs/job_events.hpp"

namespace softshock::server {

std::shared_ptr<JobEvents::Entry>& JobEvents::entry(const std::string& id) {
  auto& e = entries_[id];
  if (!e) e = std::make_shared<Entry>();
  return e;
}

void JobEvents::notify(const std::string& id) {
  {
    std::lock_guard lock(mutex_);
    auto& e = entry(id);
    e->version = next_version_++;
    e->changed.notify_all();
  }
  if (observer_) observer_(JobEventKind::kChanged, id, nullptr);
}

void JobEvents::set_progress(const std::string& id, const JobProgressRecord& progress) {
  {
    std::lock_guard lock(mutex_);
    auto& e = entry(id);
    e->version = next_version_++;
    e->progress = progress;
    e->changed.notify_all();
  }
  if (observer_) observer_(JobEventKind::kProgress, id, &progress);
}

std::optional<JobProgressRecord> JobEvents::progress(const std::string& id) const {
  std::lock_guard lock(mutex_);
  auto it = entries_.find(id);
  return it == entries_.end() ? std::nullopt : it->second->progress;
}

void JobEvents::forget(const std::string& id) {
  {
    std::lock_guard lock(mutex_);
    auto it = entries_.find(id);
    if (it != entries_.end()) {
      // Waiters still hold the entry: give it a new version so they wake and re-read the job.
      it->second->version = next_version_++;
      it->second->changed.notify_all();
      entries_.erase(it);
    }
  }
  if (observer_) observer_(JobEventKind::kStopped, id, nullptr);
}

uint64_t JobEvents::version(const std::string& id) const {
  std::lock_guard lock(mutex_);
  auto it = entries_.find(id);
  // 0 = no live entry; any later notify() gives a non-zero version, so waiters still wake.
  return it == entries_.end() ? 0 : it->second->version;
}

uint64_t JobEvents::wait(const std::string& id, uint64_t seen,
                         std::chrono::steady_clock::time_point deadline) const {
  std::unique_lock lock(mutex_);
  auto it = entries_.find(id);
  if (it == entries_.end()) {
    if (seen != 0 || shutting_down_) return 0;  // the entry seen before is gone: a change
    // No entry yet (a job queued before a restart): wait on a placeholder that the job's
    // first notify() or set_progress() will use.
    it = entries_.emplace(id, std::make_shared<Entry>()).first;
  }
  std::shared_ptr<Entry> e = it->second;
  ++e->waiters;
  e->changed.wait_until(lock, deadline, [&] { return shutting_down_ || e->version != seen; });
  --e->waiters;
  const uint64_t now = e->version;
  // Drop a placeholder nobody else uses, so watchers of idle jobs leave nothing behind.
  if (auto cur = entries_.find(id); cur != entries_.end() && cur->second == e && e->version == 0 &&
                                    e->waiters == 0 && !e->progress) {
    entries_.erase(cur);
  }
  return now;
}

void JobEvents::shutdown() {
  std::lock_guard lock(mutex_);
  shutting_down_ = true;
  for (auto& [id, e] : entries_) e->changed.notify_all();
}

bool JobEvents::shutting_down() const {
  std::lock_guard lock(mutex_);
  return shutting_down_;
}

}  // namespace softshock::server
