// The scheduler: priority then FIFO order, the bounded queue, cancellation of queued and
// running work, shutdown.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "server/jobs/scheduler.hpp"

namespace softshock::server {
namespace {

using namespace std::chrono_literals;

// Work that runs until cancelled (or `release` is set), like a long solver run.
struct Blocking {
  std::mutex mutex;
  std::vector<std::string> started;
  std::atomic<bool> release{false};
  std::atomic<int> finished{0};
  StopReason last_reason = StopReason::kNone;

  Scheduler::Work work() {
    return [this](const std::string& id, CancelToken& cancel) {
      {
        std::lock_guard lock(mutex);
        started.push_back(id);
      }
      while (!cancel.requested() && !release) std::this_thread::sleep_for(1ms);
      {
        std::lock_guard lock(mutex);
        last_reason = cancel.reason();
      }
      ++finished;
    };
  }
  bool wait_started(std::size_t n, std::chrono::milliseconds timeout = 5s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      {
        std::lock_guard lock(mutex);
        if (started.size() >= n) return true;
      }
      std::this_thread::sleep_for(1ms);
    }
    return false;
  }
};

TEST(Scheduler, HigherPriorityFirstThenFifo) {
  std::mutex mutex;
  std::vector<std::string> order;
  Scheduler s({1, 100}, [&](const std::string& id, CancelToken&) {
    std::lock_guard lock(mutex);
    order.push_back(id);
  });
  s.enqueue("a", 0, 1, false);
  s.enqueue("b", 5, 2, false);
  s.enqueue("c", 0, 3, false);
  s.enqueue("d", 5, 4, false);
  s.enqueue("e", -2, 5, false);
  s.enqueue("a", 0, 1, false);  // duplicate ignored
  s.start();
  for (int i = 0; i < 500 && s.queued() + s.running() > 0; ++i) std::this_thread::sleep_for(2ms);
  s.shutdown(5s);
  EXPECT_EQ(order, (std::vector<std::string>{"b", "d", "a", "c", "e"}));
}

TEST(Scheduler, QueueIsBounded) {
  Blocking b;
  Scheduler s({1, 2}, b.work());
  ASSERT_TRUE(s.reserve());
  ASSERT_TRUE(s.reserve());
  EXPECT_FALSE(s.reserve()) << "two reserved slots fill a queue of two";
  s.enqueue("a", 0, 1, true);
  EXPECT_FALSE(s.reserve());
  s.release();
  EXPECT_TRUE(s.reserve());
  s.enqueue("b", 0, 2, true);
  EXPECT_EQ(s.queued(), 2u);
  EXPECT_FALSE(s.reserve());
  // Once a worker takes one, a slot frees up.
  s.start();
  ASSERT_TRUE(b.wait_started(1));
  EXPECT_TRUE(s.reserve());
  s.release();
  b.release = true;
  s.shutdown(5s);
}

TEST(Scheduler, CancelQueuedRemovesItAtOnce) {
  Blocking b;
  Scheduler s({1, 10}, b.work());
  s.enqueue("running", 0, 1, false);
  s.enqueue("waiting", 0, 2, false);
  s.start();
  ASSERT_TRUE(b.wait_started(1));
  EXPECT_TRUE(s.cancel("waiting", StopReason::kUser));
  EXPECT_EQ(s.queued(), 0u);
  EXPECT_FALSE(s.cancel("unknown", StopReason::kUser));
  b.release = true;
  s.shutdown(5s);
  EXPECT_EQ(b.started, (std::vector<std::string>{"running"}));
}

TEST(Scheduler, CancelRunningStopsWithinASecond) {
  Blocking b;
  Scheduler s({2, 10}, b.work());
  s.enqueue("a", 0, 1, false);
  s.start();
  ASSERT_TRUE(b.wait_started(1));
  EXPECT_TRUE(s.is_running("a"));
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(s.cancel("a", StopReason::kUser));
  while (b.finished == 0 && std::chrono::steady_clock::now() - t0 < 2s) {
    std::this_thread::sleep_for(1ms);
  }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 1s);
  EXPECT_EQ(b.last_reason, StopReason::kUser);
  for (int i = 0; i < 200 && s.running() > 0; ++i) std::this_thread::sleep_for(1ms);
  EXPECT_FALSE(s.is_running("a"));
  s.shutdown(5s);
}

TEST(Scheduler, FirstStopReasonWins) {
  CancelToken t;
  t.request(StopReason::kWallTime);
  t.request(StopReason::kUser);
  EXPECT_TRUE(t.requested());
  EXPECT_EQ(t.reason(), StopReason::kWallTime);
}

TEST(Scheduler, ShutdownStopsRunningWorkAndDropsTheQueue) {
  Blocking b;
  Scheduler s({2, 10}, b.work());
  for (int i = 0; i < 5; ++i) s.enqueue(std::string("j").append(std::to_string(i)), 0, i, false);
  s.start();
  ASSERT_TRUE(b.wait_started(2));
  const auto stuck = s.shutdown(5s);
  EXPECT_TRUE(stuck.empty());
  EXPECT_EQ(b.finished, 2);
  EXPECT_EQ(b.last_reason, StopReason::kShutdown);
  EXPECT_FALSE(s.reserve()) << "no submissions after shutdown";
}

TEST(Scheduler, AThrowingJobDoesNotKillTheWorker) {
  std::atomic<int> ran{0};
  Scheduler s({1, 10}, [&](const std::string& id, CancelToken&) {
    ++ran;
    if (id == "bad") throw std::runtime_error("boom");
  });
  s.enqueue("bad", 1, 1, false);
  s.enqueue("good", 0, 2, false);
  s.start();
  for (int i = 0; i < 500 && ran < 2; ++i) std::this_thread::sleep_for(2ms);
  s.shutdown(5s);
  EXPECT_EQ(ran, 2);
}

}  // namespace
}  // namespace softshock::server
