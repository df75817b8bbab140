// Live, in-memory job state shared by the runner (writer) and the service (readers): a version
// counter per job bumped on every progress or state change, so WatchJob streams sleep on a
// condition variable instead of polling the catalogue, plus the latest progress of running
// jobs (progress is not written to the catalogue every step; only terminal figures are).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "server/store/catalogue.hpp"

namespace softshock::server {

// What an observer of JobEvents hears about (the daemon's metrics): a state change (notify), live
// progress (set_progress), or a job that stopped running or was dropped (forget).
enum class JobEventKind { kChanged, kProgress, kStopped };

class JobEvents {
 public:
  // Called after every event, outside the lock, on the thread that caused it (progress: the
  // solver's, between steps; keep it cheap). `progress` is set for kProgress only. Set it
  // before the first event (the daemon does, before its workers start).
  using Observer = std::function<void(JobEventKind kind, const std::string& id,
                                      const JobProgressRecord* progress)>;
  void set_observer(Observer observer) { observer_ = std::move(observer); }

  // A state change (submit, start, finish, cancel, delete): bump the version, wake watchers.
  void notify(const std::string& id);
  // Latest progress of a running job; bumps the version too.
  void set_progress(const std::string& id, const JobProgressRecord& progress);
  std::optional<JobProgressRecord> progress(const std::string& id) const;
  // Drops the live entry (job stopped, cancelled or deleted); wakes its watchers.
  void forget(const std::string& id);

  uint64_t version(const std::string& id) const;
  // Waits until the version of `id` differs from `seen`, the deadline passes, or shutdown.
  // Returns the current version.
  uint64_t wait(const std::string& id, uint64_t seen,
                std::chrono::steady_clock::time_point deadline) const;

  // Wakes every waiter for good (daemon shutdown).
  void shutdown();
  bool shutting_down() const;

 private:
  // One condition variable per job, so a progress tick wakes only that job's watchers (with a
  // shared one, 40 running jobs x 40 watchers meant thousands of useless wake-ups a second).
  // Waiters hold the entry by shared_ptr: forget() may drop it from the map meanwhile.
  struct Entry {
    uint64_t version = 0;
    std::optional<JobProgressRecord> progress;
    std::condition_variable changed;
    int waiters = 0;
  };
  std::shared_ptr<Entry>& entry(const std::string& id);  // creates; mutex_ held

  Observer observer_;
  mutable std::mutex mutex_;
  mutable std::map<std::string, std::shared_ptr<Entry>> entries_;
  uint64_t next_version_ = 1;  // versions only grow, so a recreated entry never repeats one
  bool shutting_down_ = false;
};

}  // namespace softshock::server
