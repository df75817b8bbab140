// Where jobs run. The service and the daemon hand jobs to an Executor by id and never learn
// how they run: `local` (LocalExecutor: the worker pool of server/scheduler.hpp, running
// jobs in-process) or `slurm` (server/slurm_executor.hpp: sbatch on a cluster). The catalogue
// stays the source of truth for job state under both; an executor's own bookkeeping is a cache
// rebuilt from it at start-up.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "server/jobs/scheduler.hpp"

namespace softshock::server {

class Executor {
 public:
  virtual ~Executor() = default;

  // Begins running what was enqueued (start-up recovery enqueues first, in catalogue order).
  virtual void start() = 0;
  // Submission slots, as Scheduler::reserve/release: false = the queue is full.
  virtual bool reserve(std::size_t slots = 1) = 0;
  virtual void release(std::size_t slots = 1) = 0;
  // A QUEUED job to run; `reserved` consumes a slot from reserve().
  virtual void enqueue(const std::string& id, int priority, int64_t seq, bool reserved) = 0;
  // Stops a queued or running job (true), false = unknown here. Asynchronous: the job's
  // terminal state lands in the catalogue when it has stopped.
  virtual bool cancel(const std::string& id, StopReason why) = 0;
  virtual bool is_running(const std::string& id) const = 0;
  virtual std::size_t queued() const = 0;
  virtual std::size_t running() const = 0;
  // Orderly stop within `grace`; returns the ids of jobs that did not stop (the daemon records
  // them as QUEUED). An executor whose jobs outlive the daemon returns none.
  virtual std::vector<std::string> shutdown(std::chrono::milliseconds grace) = 0;
};

// The default: a fixed pool of in-process workers (unchanged behaviour of the worker pool).
class LocalExecutor final : public Executor {
 public:
  LocalExecutor(Scheduler::Options options, Scheduler::Work work)
      : scheduler_(options, std::move(work)) {}

  void start() override { scheduler_.start(); }
  bool reserve(std::size_t slots) override { return scheduler_.reserve(slots); }
  void release(std::size_t slots) override { scheduler_.release(slots); }
  void enqueue(const std::string& id, int priority, int64_t seq, bool reserved) override {
    scheduler_.enqueue(id, priority, seq, reserved);
  }
  bool cancel(const std::string& id, StopReason why) override { return scheduler_.cancel(id, why); }
  bool is_running(const std::string& id) const override { return scheduler_.is_running(id); }
  std::size_t queued() const override { return scheduler_.queued(); }
  std::size_t running() const override { return scheduler_.running(); }
  std::vector<std::string> shutdown(std::chrono::milliseconds grace) override {
    return scheduler_.shutdown(grace);
  }

 private:
  Scheduler scheduler_;
};

}  // namespace softshock::server
