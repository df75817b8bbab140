// A fixed pool of worker threads fed by a bounded priority queue (higher priority first, FIFO
// within a priority). The scheduler knows job ids only: what running a job means is the work
// function's business (server/job_runner.hpp), and the catalogue stays the source of truth for
// job state — the queue is a cache of "QUEUED" rows, rebuilt from the catalogue at start-up.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

namespace softshock::server {

// Why a running job was asked to stop; the first request wins.
enum class StopReason : int { kNone = 0, kUser = 1, kWallTime = 2, kShutdown = 3, kInternal = 4 };

// Handed to the work function: the solver polls `flag` every step.
class CancelToken {
 public:
  void request(StopReason why) {
    int expected = static_cast<int>(StopReason::kNone);
    reason_.compare_exchange_strong(expected, static_cast<int>(why));
    flag_.store(true);
  }
  bool requested() const { return flag_.load(std::memory_order_relaxed); }
  StopReason reason() const { return static_cast<StopReason>(reason_.load()); }
  const std::atomic<bool>* flag() const { return &flag_; }

 private:
  std::atomic<bool> flag_{false};
  std::atomic<int> reason_{static_cast<int>(StopReason::kNone)};
};

class Scheduler {
 public:
  using Work = std::function<void(const std::string& job_id, CancelToken& cancel)>;

  struct Options {
    int workers = 1;
    std::size_t max_queued = 1000;
  };

  Scheduler(Options options, Work work);
  ~Scheduler();  // shutdown(), waiting for every running job to return
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  // Starts the worker threads. Jobs enqueued before start() wait until then (start-up
  // recovery fills the queue first so the order is the catalogue's).
  void start();

  // A submission slot: reserve() before committing a new job (false = queue full, so the
  // caller answers RESOURCE_EXHAUSTED without writing anything), then enqueue with the slot
  // or release it. Keeps concurrent submissions from overshooting max_queued.
  // A grid reserves all its points at once: all or nothing.
  bool reserve(std::size_t slots = 1);
  void release(std::size_t slots = 1);
  // `seq` is the FIFO key (the catalogue's insertion order). `reserved` consumes a slot;
  // without it the job is queued regardless of the bound (start-up recovery).
  void enqueue(const std::string& id, int priority, int64_t seq, bool reserved);

  // Removes a queued job (true), or signals a running one (true); false = unknown here.
  bool cancel(const std::string& id, StopReason why);
  bool is_running(const std::string& id) const;

  std::size_t queued() const;
  std::size_t running() const;

  // Stops handing out work, asks every running job to stop (kShutdown) and waits up to
  // `grace` for the workers. Returns the ids still running when the grace period ran out
  // (their threads are detached; the caller decides what to record for them).
  std::vector<std::string> shutdown(std::chrono::milliseconds grace);

 private:
  struct Entry {
    int priority;
    int64_t seq;
    std::string id;
    bool operator<(const Entry& o) const {
      // std::set ordering = run order: priority descending, then seq ascending.
      if (priority != o.priority) return priority > o.priority;
      if (seq != o.seq) return seq < o.seq;
      return id < o.id;
    }
  };
  void worker_loop();

  const Options options_;
  const Work work_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;  // workers: work available or stopping
  std::condition_variable idle_;  // shutdown: a worker finished
  std::set<Entry> queue_;
  std::map<std::string, std::set<Entry>::iterator> queued_by_id_;
  std::map<std::string, std::shared_ptr<CancelToken>> running_;
  std::size_t reserved_ = 0;
  bool started_ = false;
  bool stopping_ = false;
  int live_workers_ = 0;
  std::vector<std::thread> threads_;
};

}  // namespace softshock::server
