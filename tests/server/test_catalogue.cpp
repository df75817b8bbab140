// The job catalogue: migrations, transitions, request_id dedup, list filters and pagination,
// durability across reopen, and start-up recovery of interrupted jobs.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "server/catalogue.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

class CatalogueTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("softshock-catalogue-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
    path_ = (dir_ / "catalogue.sqlite").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  static NewJob job(const std::string& id, int priority = 0, int64_t create_us = 0,
                    std::map<std::string, std::string> labels = {}, std::string request_id = "") {
    NewJob j;
    j.id = id;
    j.spec_json = R"({"run":{"endTime":5e-09}})";
    j.spec_hash = "hash-" + id;
    j.priority = priority;
    j.create_us = create_us ? create_us : now_us();
    j.labels = std::move(labels);
    j.request_id = std::move(request_id);
    return j;
  }

  fs::path dir_;
  std::string path_;
};

TEST_F(CatalogueTest, MigrationsAreIdempotentAndDataSurvivesReopen) {
  {
    Catalogue c(path_);
    EXPECT_EQ(c.schema_version(), 1);
    c.insert(job("a", 3, 0, {{"study", "s1"}}));
  }
  for (int i = 0; i < 2; ++i) {
    Catalogue c(path_);
    EXPECT_EQ(c.schema_version(), 1);
    auto a = c.get("a");
    ASSERT_TRUE(a);
    EXPECT_EQ(a->state, JobState::kQueued);
    EXPECT_EQ(a->priority, 3);
    EXPECT_EQ(a->attempt, 1);
    EXPECT_EQ(a->labels.at("study"), "s1");
    EXPECT_EQ(a->spec_hash, "hash-a");
  }
}

TEST_F(CatalogueTest, RequestIdReturnsTheFirstJob) {
  Catalogue c(path_);
  auto first = c.insert(job("a", 0, 0, {}, "req-1"));
  EXPECT_TRUE(first.created);
  auto again = c.insert(job("b", 0, 0, {}, "req-1"));
  EXPECT_FALSE(again.created);
  EXPECT_EQ(again.job.id, "a");
  EXPECT_FALSE(c.get("b"));
  EXPECT_EQ(c.find_by_request_id("req-1")->id, "a");
  // Jobs without a request_id never collide with each other.
  EXPECT_TRUE(c.insert(job("c")).created);
  EXPECT_TRUE(c.insert(job("d")).created);
}

TEST_F(CatalogueTest, TransitionsAreConditional) {
  Catalogue c(path_);
  c.insert(job("a"));
  auto started = c.start("a", now_us());
  ASSERT_TRUE(started);
  EXPECT_EQ(started->state, JobState::kRunning);
  EXPECT_GT(started->start_us, 0);
  EXPECT_FALSE(c.start("a", now_us()));          // already running
  EXPECT_FALSE(c.cancel_queued("a", now_us()));  // not queued
  EXPECT_FALSE(c.finish("a", 2, JobState::kSucceeded, "", "", "", {}, nullptr, now_us()))
      << "a stale attempt must not finish the job";

  StoredSummary summary;
  summary.summary.elements = 200;
  summary.summary.max_abar = 0.25;
  summary.summary.rim_reflections_s = {1e-9, 2e-9};
  summary.mode_count = 3;
  summary.mode_times = {0, 4e-9};
  summary.mode_amplitudes = {1, 2, 3, 4, 5, 6};
  JobProgressRecord p;
  p.fraction = 1;
  p.steps = 42;
  ASSERT_TRUE(
      c.finish("a", 1, JobState::kSucceeded, "", "", "/r/result.h5", p, &summary, now_us()));
  auto done = c.get("a");
  EXPECT_EQ(done->state, JobState::kSucceeded);
  EXPECT_EQ(done->result_path, "/r/result.h5");
  EXPECT_EQ(done->progress.steps, 42);
  EXPECT_GT(done->finish_us, 0);
  // Terminal states never change.
  EXPECT_FALSE(c.finish("a", 1, JobState::kFailed, "X", "", "", {}, nullptr, now_us()));
  EXPECT_FALSE(c.requeue("a", 1, "SHUTDOWN", now_us()));

  auto stored = c.summary("a");
  ASSERT_TRUE(stored);
  EXPECT_EQ(stored->summary.elements, 200u);
  EXPECT_DOUBLE_EQ(stored->summary.max_abar, 0.25);
  EXPECT_EQ(stored->summary.rim_reflections_s, (std::vector<double>{1e-9, 2e-9}));
  EXPECT_EQ(stored->mode_count, 3);
  EXPECT_EQ(stored->mode_amplitudes, summary.mode_amplitudes);

  auto history = c.attempts("a");
  ASSERT_EQ(history.size(), 1u);
  EXPECT_EQ(history[0].outcome, "SUCCEEDED");

  c.insert(job("b"));
  EXPECT_TRUE(c.cancel_queued("b", now_us()));
  EXPECT_EQ(c.get("b")->state, JobState::kCancelled);
  EXPECT_EQ(c.get("b")->reason, reason::kCancelledByUser);
  EXPECT_FALSE(c.start("b", now_us()));

  EXPECT_TRUE(c.erase("a"));
  EXPECT_FALSE(c.get("a"));
  EXPECT_FALSE(c.summary("a"));
  EXPECT_TRUE(c.attempts("a").empty());
  EXPECT_FALSE(c.erase("a"));
}

TEST_F(CatalogueTest, ShutdownRequeueKeepsTheAttempt) {
  Catalogue c(path_);
  c.insert(job("a"));
  c.start("a", now_us());
  EXPECT_TRUE(c.requeue("a", 1, reason::kShutdown, now_us()));
  auto a = c.get("a");
  EXPECT_EQ(a->state, JobState::kQueued);
  EXPECT_EQ(a->attempt, 1);
  ASSERT_TRUE(c.start("a", now_us()));
  auto history = c.attempts("a");
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[0].outcome, "REQUEUED");
  EXPECT_EQ(history[1].end_us, 0);  // the open one
}

TEST_F(CatalogueTest, QueuedJobsComeInRunOrder) {
  Catalogue c(path_);
  c.insert(job("a", 0));
  c.insert(job("b", 5));
  c.insert(job("c", 0));
  c.insert(job("d", 5));
  c.insert(job("e", -1));
  std::vector<std::string> order;
  for (const auto& q : c.queued_jobs()) order.push_back(q.id);
  EXPECT_EQ(order, (std::vector<std::string>{"b", "d", "a", "c", "e"}));
}

TEST_F(CatalogueTest, ListFiltersAndPaginates) {
  Catalogue c(path_);
  const int64_t t0 = 1'700'000'000'000'000;
  for (int i = 0; i < 10; ++i) {
    c.insert(job(std::string("j").append(std::to_string(i)), 0, t0 + i * 1000,
                 {{"study", i % 2 ? "odd" : "even"}, {"n", std::to_string(i)}}));
  }
  c.start("j3", now_us());

  ListFilter all;
  all.limit = 100;
  auto rows = c.list(all);
  ASSERT_EQ(rows.size(), 10u);
  EXPECT_EQ(rows.front().id, "j9");  // newest first
  EXPECT_EQ(rows.back().id, "j0");

  ListFilter running;
  running.state = JobState::kRunning;
  rows = c.list(running);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].id, "j3");

  ListFilter odd;
  odd.label_key = "study";
  odd.label_value = "odd";
  rows = c.list(odd);
  ASSERT_EQ(rows.size(), 5u);
  for (const auto& r : rows) EXPECT_EQ(r.labels.at("study"), "odd");

  ListFilter has_key;
  has_key.label_key = "n";
  EXPECT_EQ(c.list(has_key).size(), 10u);
  has_key.label_key = "missing";
  EXPECT_TRUE(c.list(has_key).empty());

  ListFilter window;
  window.created_after_us = t0 + 2000;   // exclusive
  window.created_before_us = t0 + 6000;  // exclusive
  rows = c.list(window);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].id, "j5");
  EXPECT_EQ(rows[2].id, "j3");

  // Pages of 4 through the cursor: every job exactly once, in order.
  std::vector<std::string> seen;
  ListFilter page;
  page.limit = 4;
  for (;;) {
    rows = c.list(page);
    for (const auto& r : rows) seen.push_back(r.id);
    if (rows.size() < 4u) break;
    page.before_seq = rows.back().seq;
  }
  ASSERT_EQ(seen.size(), 10u);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(seen[i], "j" + std::to_string(9 - i));
}

TEST_F(CatalogueTest, RecoveryRequeuesInterruptedJobsUpToMaxAttempts) {
  {
    Catalogue c(path_);
    c.insert(job("a"));
    c.insert(job("b"));
    c.start("a", now_us());
  }  // "crash": a stays RUNNING on disk
  {
    Catalogue c(path_);
    auto report = c.recover(2, now_us());
    EXPECT_EQ(report.requeued, (std::vector<std::string>{"a"}));
    EXPECT_TRUE(report.failed.empty());
    auto a = c.get("a");
    EXPECT_EQ(a->state, JobState::kQueued);
    EXPECT_EQ(a->attempt, 2);
    EXPECT_EQ(a->reason, reason::kInterrupted);
    EXPECT_EQ(c.get("b")->state, JobState::kQueued);
    EXPECT_EQ(c.get("b")->attempt, 1);
    auto history = c.attempts("a");
    ASSERT_EQ(history.size(), 1u);
    EXPECT_EQ(history[0].outcome, "INTERRUPTED");
    EXPECT_EQ(history[0].attempt, 1);
    // Recovery with nothing running changes nothing.
    EXPECT_TRUE(c.recover(2, now_us()).requeued.empty());
    ASSERT_TRUE(c.start("a", now_us()));
  }
  {
    Catalogue c(path_);
    auto report = c.recover(2, now_us());
    EXPECT_EQ(report.failed, (std::vector<std::string>{"a"}));
    auto a = c.get("a");
    EXPECT_EQ(a->state, JobState::kFailed);
    EXPECT_EQ(a->reason, reason::kMaxAttempts);
    EXPECT_EQ(c.attempts("a").size(), 2u);
  }
}

}  // namespace
}  // namespace softshock::server
