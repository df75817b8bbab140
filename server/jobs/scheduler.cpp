#include "server/jobs/scheduler.hpp"

#include <algorithm>
#include <exception>

#include "server/log.hpp"

namespace softshock::server {

Scheduler::Scheduler(Options options, Work work) : options_(options), work_(std::move(work)) {
  if (options_.workers < 1) throw std::invalid_argument("scheduler: workers must be >= 1");
}

// Waits for running work however long it takes: a detached worker would outlive `this`.
Scheduler::~Scheduler() {
  shutdown(std::chrono::hours(24 * 365));
}

void Scheduler::start() {
  std::lock_guard lock(mutex_);
  if (started_ || stopping_) return;
  started_ = true;
  live_workers_ = options_.workers;
  for (int i = 0; i < options_.workers; ++i) threads_.emplace_back([this] { worker_loop(); });
}

bool Scheduler::reserve(std::size_t slots) {
  std::lock_guard lock(mutex_);
  if (stopping_) return false;
  if (slots == 0) return true;
  if (queue_.size() + reserved_ + slots > options_.max_queued) return false;
  reserved_ += slots;
  return true;
}

void Scheduler::release(std::size_t slots) {
  std::lock_guard lock(mutex_);
  reserved_ -= std::min(reserved_, slots);
}

void Scheduler::enqueue(const std::string& id, int priority, int64_t seq, bool reserved) {
  {
    std::lock_guard lock(mutex_);
    if (reserved && reserved_ > 0) --reserved_;
    if (queued_by_id_.count(id) || running_.count(id)) return;
    auto [it, inserted] = queue_.insert(Entry{priority, seq, id});
    if (inserted) queued_by_id_.emplace(id, it);
  }
  wake_.notify_one();
}

bool Scheduler::cancel(const std::string& id, StopReason why) {
  std::lock_guard lock(mutex_);
  if (auto q = queued_by_id_.find(id); q != queued_by_id_.end()) {
    queue_.erase(q->second);
    queued_by_id_.erase(q);
    return true;
  }
  if (auto r = running_.find(id); r != running_.end()) {
    r->second->request(why);
    return true;
  }
  return false;
}

bool Scheduler::is_running(const std::string& id) const {
  std::lock_guard lock(mutex_);
  return running_.count(id) != 0;
}

std::size_t Scheduler::queued() const {
  std::lock_guard lock(mutex_);
  return queue_.size();
}

std::size_t Scheduler::running() const {
  std::lock_guard lock(mutex_);
  return running_.size();
}

void Scheduler::worker_loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
    if (stopping_) break;
    Entry next = *queue_.begin();
    queue_.erase(queue_.begin());
    queued_by_id_.erase(next.id);
    auto token = std::make_shared<CancelToken>();
    running_.emplace(next.id, token);
    lock.unlock();
    try {
      work_(next.id, *token);
    } catch (const std::exception& e) {
      // The work function records failures itself; this is a last line of defence so one job
      // cannot take a worker (or the daemon) down.
      log_error("job ", next.id, ": unhandled error in worker: ", e.what());
    } catch (...) {
      log_error("job ", next.id, ": unhandled non-standard exception in worker");
    }
    lock.lock();
    running_.erase(next.id);
    idle_.notify_all();
  }
  --live_workers_;
  idle_.notify_all();
}

std::vector<std::string> Scheduler::shutdown(std::chrono::milliseconds grace) {
  std::vector<std::thread> threads;
  std::vector<std::string> still_running;
  {
    std::unique_lock lock(mutex_);
    if (!stopping_) {
      stopping_ = true;
      queue_.clear();
      queued_by_id_.clear();
      for (auto& [id, token] : running_) token->request(StopReason::kShutdown);
    }
    wake_.notify_all();
    idle_.wait_for(lock, grace, [this] { return live_workers_ == 0; });
    for (const auto& [id, token] : running_) still_running.push_back(id);
    threads.swap(threads_);
  }
  for (auto& t : threads) {
    // A worker stuck in a long uninterruptible phase (meshing) is left behind rather than
    // holding up the exit; the caller records its job as interrupted.
    if (still_running.empty()) {
      t.join();
    } else {
      t.detach();
    }
  }
  return still_running;
}

}  // namespace softshock::server
