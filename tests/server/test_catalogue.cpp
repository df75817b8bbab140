// The job catalogue: migrations, transitions, request_id dedup, list filters and pagination,
// durability across reopen, start-up recovery of interrupted jobs, grids, result reuse and
// QueryJobs' SQL.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <optional>
#include <random>

#include "server/store/catalogue.hpp"

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
    EXPECT_EQ(c.schema_version(), 10);
    c.insert(job("a", 3, 0, {{"study", "s1"}}));
  }
  for (int i = 0; i < 2; ++i) {
    Catalogue c(path_);
    EXPECT_EQ(c.schema_version(), 10);
    auto a = c.get("a");
    ASSERT_TRUE(a);
    EXPECT_EQ(a->state, JobState::kQueued);
    EXPECT_EQ(a->priority, 3);
    EXPECT_EQ(a->attempt, 1);
    EXPECT_EQ(a->labels.at("study"), "s1");
    EXPECT_EQ(a->spec_hash, "hash-a");
  }
}

// Every field of a StoredSummary, each with its own value (NaN where a figure may be NaN).
StoredSummary distinct_summary() {
  StoredSummary s;
  RunSummary& r = s.summary;
  r.elements = 101;
  r.nodes = 102;
  r.steps = 103;
  r.wall_time_s = 1.04;
  r.end_time_s = NAN;
  r.groups = {1.06, 1.07, 1.08, 1.09, 1.10, 1.11, 1.12};
  r.energy_injected_J_per_m = 1.13;
  r.energy_after_pulse_J_per_m = 1.14;
  r.max_abar_first_cycle = 1.15;
  r.max_abar = NAN;
  r.abar_end = 1.17;
  r.max_abar_filtered_first_cycle = 1.18;
  r.max_abar_filtered = 1.19;
  r.abar_filtered_end = NAN;  // a figure added by a migration: NaN survives too
  r.max_aspect_ratio = 1.21;
  r.aspect_ratio_above_10_s = 1.22;
  r.dominant_mode_end = 123;
  r.shock_at_center_s = 1.24;
  r.rim_reflections_s = {1.25, 1.26};
  r.min_dt_s = 1.27;
  r.max_dt_s = 1.28;
  r.status = "completed";
  r.error = "error text";
  r.kernel_time_s = 1.31;
  r.diagnostics_time_s = 1.42;
  r.output_time_s = 1.43;
  r.meshing_time_s = 1.32;
  r.mesh_cache = "hit";
  r.solver_revision = 133;
  s.mode_count = 2;
  s.mode_times = {1.34, 1.35};
  s.mode_amplitudes = {1.36, 1.37, 1.38, 1.39};
  s.abar_times = {1.40};
  s.abar_values = {1.41};
  return s;
}

// Equal, NaN included (EXPECT_EQ on doubles would fail NaN == NaN).
void expect_same(double a, double b, const char* what) {
  if (std::isnan(b)) {
    EXPECT_TRUE(std::isnan(a)) << what << " " << a;
  } else {
    EXPECT_EQ(a, b) << what;
  }
}

void expect_same_figures(const RunSummary& a, const RunSummary& b) {
  EXPECT_EQ(a.elements, b.elements);
  EXPECT_EQ(a.nodes, b.nodes);
  EXPECT_EQ(a.steps, b.steps);
  expect_same(a.wall_time_s, b.wall_time_s, "wall_time_s");
  expect_same(a.end_time_s, b.end_time_s, "end_time_s");
  expect_same(a.groups.pbar, b.groups.pbar, "pbar");
  expect_same(a.groups.tbar_pulse, b.groups.tbar_pulse, "tbar_pulse");
  expect_same(a.groups.mubar, b.groups.mubar, "mubar");
  expect_same(a.groups.gamma, b.groups.gamma, "gamma");
  expect_same(a.groups.c1, b.groups.c1, "c1");
  expect_same(a.groups.c2, b.groups.c2, "c2");
  expect_same(a.groups.time_scale_s, b.groups.time_scale_s, "time_scale_s");
  expect_same(a.energy_injected_J_per_m, b.energy_injected_J_per_m, "energy_injected");
  expect_same(a.energy_after_pulse_J_per_m, b.energy_after_pulse_J_per_m, "energy_after_pulse");
  expect_same(a.max_abar_first_cycle, b.max_abar_first_cycle, "max_abar_first_cycle");
  expect_same(a.max_abar, b.max_abar, "max_abar");
  expect_same(a.abar_end, b.abar_end, "abar_end");
  expect_same(a.max_abar_filtered_first_cycle, b.max_abar_filtered_first_cycle,
              "max_abar_filtered_first_cycle");
  expect_same(a.max_abar_filtered, b.max_abar_filtered, "max_abar_filtered");
  expect_same(a.abar_filtered_end, b.abar_filtered_end, "abar_filtered_end");
  expect_same(a.max_aspect_ratio, b.max_aspect_ratio, "max_aspect_ratio");
  expect_same(a.aspect_ratio_above_10_s, b.aspect_ratio_above_10_s, "aspect_ratio_above_10_s");
  EXPECT_EQ(a.dominant_mode_end, b.dominant_mode_end);
  expect_same(a.shock_at_center_s, b.shock_at_center_s, "shock_at_center_s");
  EXPECT_EQ(a.rim_reflections_s, b.rim_reflections_s);
  expect_same(a.min_dt_s, b.min_dt_s, "min_dt_s");
  expect_same(a.max_dt_s, b.max_dt_s, "max_dt_s");
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.error, b.error);
  expect_same(a.kernel_time_s, b.kernel_time_s, "kernel_time_s");
  expect_same(a.diagnostics_time_s, b.diagnostics_time_s, "diagnostics_time_s");
  expect_same(a.output_time_s, b.output_time_s, "output_time_s");
  expect_same(a.meshing_time_s, b.meshing_time_s, "meshing_time_s");
  EXPECT_EQ(a.mesh_cache, b.mesh_cache);
  EXPECT_EQ(a.solver_revision, b.solver_revision);
}

// The summary columns are one table (store/summary_rows.cpp): every field goes in with
// finish() and comes back from summary(), from a reusing job's copy, from QueryJobs and from
// the grid reduction's read.
TEST_F(CatalogueTest, EverySummaryFieldRoundTripsThroughEveryRead) {
  Catalogue c(path_);
  c.insert(job("source"));
  ASSERT_TRUE(c.start("source", now_us()));
  const StoredSummary in = distinct_summary();
  ASSERT_TRUE(
      c.finish("source", 1, JobState::kSucceeded, "", "", "/r/result.h5", {}, &in, now_us()));
  auto expect_whole = [&](const std::optional<StoredSummary>& out, const char* where) {
    SCOPED_TRACE(where);
    ASSERT_TRUE(out);
    expect_same_figures(out->summary, in.summary);
    EXPECT_EQ(out->mode_count, in.mode_count);
    EXPECT_EQ(out->mode_times, in.mode_times);
    EXPECT_EQ(out->mode_amplitudes, in.mode_amplitudes);
    EXPECT_EQ(out->abar_times, in.abar_times);
    EXPECT_EQ(out->abar_values, in.abar_values);
  };
  expect_whole(c.summary("source"), "summary()");

  NewJob point = job("reuser");
  point.grid_id = "g";
  point.reused_from = "source";
  point.result_path = "/r/result.h5";
  NewGrid g;
  g.id = "g";
  g.create_us = now_us();
  g.definition = "{}";
  ASSERT_TRUE(c.insert_grid(g, {point}).created);
  expect_whole(c.summary("reuser"), "copied for a reusing job");

  JobQuery q;
  q.grid_id = "g";
  const auto rows = c.query(q);
  ASSERT_EQ(rows.size(), 1u);
  ASSERT_TRUE(rows[0].summary);
  expect_same_figures(*rows[0].summary, in.summary);
  // The jobs row's query figures: NaN becomes NULL (unknown), the rest are copied.
  EXPECT_DOUBLE_EQ(rows[0].groups.pbar, in.summary.groups.pbar);

  const auto points = c.grid_points("g");
  ASSERT_EQ(points.size(), 1u);
  ASSERT_TRUE(points[0].summary);
  expect_same_figures(points[0].summary->summary, in.summary);
  EXPECT_EQ(points[0].summary->abar_values, in.abar_values);
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
  summary.summary.abar_end = 0.125;
  summary.summary.max_abar_filtered = 0.2;
  summary.summary.abar_filtered_end = 0.1;
  summary.summary.max_abar_filtered_first_cycle = 0.05;
  summary.summary.max_aspect_ratio = 7.5;
  summary.summary.aspect_ratio_above_10_s = -1;
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
  EXPECT_DOUBLE_EQ(stored->summary.abar_end, 0.125);
  EXPECT_DOUBLE_EQ(stored->summary.max_abar_filtered, 0.2);
  EXPECT_DOUBLE_EQ(stored->summary.abar_filtered_end, 0.1);
  EXPECT_DOUBLE_EQ(stored->summary.max_abar_filtered_first_cycle, 0.05);
  EXPECT_DOUBLE_EQ(stored->summary.max_aspect_ratio, 7.5);
  EXPECT_DOUBLE_EQ(stored->summary.aspect_ratio_above_10_s, -1);
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

// A finished job with the given groups and summary figures (synthetic: no solver run).
void add_finished(Catalogue& c, const std::string& id, double pbar, double gamma,
                  double max_abar_first_cycle, const std::string& hash = "") {
  NewJob j;
  j.id = id;
  j.spec_json = "{}";
  j.spec_hash = hash.empty() ? "hash-" + id : hash;
  j.create_us = now_us();
  j.groups.pbar = pbar;
  j.groups.gamma = gamma;
  j.groups.tbar_pulse = 0.1257;
  j.groups.mubar = 2.5e-6;
  j.groups.c1 = 1;
  j.groups.c2 = 0.1;
  c.insert(j);
  ASSERT_TRUE(c.start(id, now_us()));
  StoredSummary s;
  s.summary.groups = j.groups;
  s.summary.groups.time_scale_s = 63.64e-9;
  s.summary.max_abar_first_cycle = max_abar_first_cycle;
  s.summary.max_abar = 2 * max_abar_first_cycle;
  s.abar_times = {0, 1e-7};
  s.abar_values = {0, max_abar_first_cycle};
  ASSERT_TRUE(c.finish(id, 1, JobState::kSucceeded, "", "", "/r/" + id + ".h5", {}, &s, now_us()));
}

TEST_F(CatalogueTest, QueryFiltersOnGroupsAndSummariesSortsAndPages) {
  Catalogue c(path_);
  for (int i = 0; i < 10; ++i) {
    std::string id = "j";  // appended, not "j" + ...: GCC 12 warns falsely (-Wrestrict) on that
    id += std::to_string(i);
    add_finished(c, id, 0.2 * i, i % 2 ? 7.0 : 5.0, 0.001 * i);
  }
  c.insert(job("queued"));  // no groups, no summary

  JobQuery q;
  RangeCondition pbar{"pbar"};
  pbar.ge = 0.5;
  pbar.le = 1.5;
  RangeCondition gamma{"gamma"};
  gamma.gt = 6;
  q.conditions = {pbar, gamma};
  auto rows = c.query(q);
  std::vector<std::string> ids;
  for (const auto& r : rows) ids.push_back(r.job.id);
  // pbar 0.6 (j3), 1.0 (j5), 1.4 (j7) with gamma 7; newest first by default.
  EXPECT_EQ(ids, (std::vector<std::string>{"j7", "j5", "j3"}));
  ASSERT_TRUE(rows[0].summary);
  EXPECT_DOUBLE_EQ(rows[0].summary->max_abar_first_cycle, 0.007);
  EXPECT_DOUBLE_EQ(rows[0].groups.gamma, 7.0);

  // A summary filter and an ascending sort; jobs without a summary never pass it.
  JobQuery by_abar;
  RangeCondition abar{"max_abar_first_cycle"};
  abar.gt = 0.0035;
  by_abar.conditions = {abar};
  by_abar.order_by = "max_abar_first_cycle";
  by_abar.descending = false;
  by_abar.limit = 3;
  ids.clear();
  for (;;) {
    auto page = c.query(by_abar);
    for (const auto& r : page) ids.push_back(r.job.id);
    if (static_cast<int>(page.size()) < by_abar.limit) break;
    by_abar.after_key = page.back().sort_key;
    by_abar.after_seq = page.back().job.seq;
  }
  EXPECT_EQ(ids, (std::vector<std::string>{"j4", "j5", "j6", "j7", "j8", "j9"}));

  // Descending on a column some rows lack: those come last, and paging still visits each once.
  JobQuery all;
  all.order_by = "max_abar";
  all.limit = 4;
  ids.clear();
  for (;;) {
    auto page = c.query(all);
    for (const auto& r : page) ids.push_back(r.job.id);
    if (static_cast<int>(page.size()) < all.limit) break;
    all.after_key = page.back().sort_key;
    all.after_seq = page.back().job.seq;
  }
  ASSERT_EQ(ids.size(), 11u);
  EXPECT_EQ(ids.front(), "j9");
  EXPECT_EQ(ids.back(), "queued");

  JobQuery unknown;
  unknown.conditions = {RangeCondition{"spec_json; DROP TABLE jobs"}};
  unknown.conditions[0].gt = 0;
  EXPECT_THROW(c.query(unknown), std::invalid_argument) << "names come from a fixed table";
}

TEST_F(CatalogueTest, GridsCountCancelAndReuse) {
  Catalogue c(path_);
  add_finished(c, "source", 1.0, 6.15, 0.02, "same-spec");
  EXPECT_EQ(c.find_reusable("same-spec")->id, "source");
  EXPECT_FALSE(c.find_reusable("same-spec", "source"));
  EXPECT_FALSE(c.find_reusable("other"));
  EXPECT_FALSE(c.find_reusable("same-spec", "", kSolverRevision + 1))
      << "a result of other numerics is not this solver's";

  NewGrid g;
  g.id = "g1";
  g.request_id = "req-1";
  g.definition = "{}";
  g.create_us = now_us();
  std::vector<NewJob> points;
  for (int i = 0; i < 4; ++i) {
    NewJob p = job("p" + std::to_string(i));
    p.grid_id = "g1";
    p.grid_index = i;
    p.reuse_result = true;
    points.push_back(p);
  }
  points[0].reused_from = "source";
  points[0].result_path = "/r/p0/result.h5";
  points[0].spec_hash = "same-spec";
  auto inserted = c.insert_grid(g, points);
  ASSERT_TRUE(inserted.created);
  EXPECT_EQ(inserted.grid.point_count, 4);
  EXPECT_EQ(inserted.point_seqs.size(), 4u);
  EXPECT_FALSE(c.insert_grid(g, points).created) << "same request_id: the first grid";
  EXPECT_EQ(c.find_grid_by_request_id("req-1")->id, "g1");

  auto p0 = c.get("p0");
  EXPECT_EQ(p0->state, JobState::kSucceeded);
  EXPECT_EQ(p0->reused_from, "source");
  EXPECT_EQ(p0->grid_id, "g1");
  ASSERT_TRUE(c.summary("p0"));
  EXPECT_DOUBLE_EQ(c.summary("p0")->summary.max_abar_first_cycle, 0.02);
  EXPECT_EQ(c.summary("p0")->abar_values.size(), 2u);
  EXPECT_EQ(c.find_reusable("same-spec")->id, "source") << "reusers are never sources";

  // A queued point reuses a result that appeared after submission.
  ASSERT_TRUE(c.complete_reused("p1", "source", "/r/p1/result.h5", now_us()));
  EXPECT_EQ(c.get("p1")->reused_from, "source");
  EXPECT_FALSE(c.complete_reused("p1", "source", "/r/p1/result.h5", now_us()));
  ASSERT_TRUE(c.start("p2", now_us()));

  GridCounts counts = c.grid_counts("g1");
  EXPECT_EQ(counts.by_state[JobState::kSucceeded], 2);
  EXPECT_EQ(counts.by_state[JobState::kRunning], 1);
  EXPECT_EQ(counts.by_state[JobState::kQueued], 1);
  EXPECT_EQ(counts.reused, 2);
  EXPECT_EQ(counts.running, (std::vector<std::string>{"p2"}));

  auto points_back = c.grid_points("g1");
  ASSERT_EQ(points_back.size(), 4u);
  EXPECT_EQ(points_back[3].index, 3);
  EXPECT_TRUE(points_back[0].summary);
  EXPECT_FALSE(points_back[3].summary);

  auto cancelled = c.cancel_grid("g1", now_us());
  EXPECT_EQ(cancelled.cancelled, (std::vector<std::string>{"p3"}));
  EXPECT_EQ(cancelled.running, (std::vector<std::string>{"p2"}));
  EXPECT_TRUE(c.get_grid("g1")->cancelled);
  EXPECT_EQ(c.get("p3")->state, JobState::kCancelled);

  JobQuery in_grid;
  in_grid.grid_id = "g1";
  in_grid.state = JobState::kSucceeded;
  EXPECT_EQ(c.query(in_grid).size(), 2u);
  EXPECT_EQ(c.list_grids(0, 10).size(), 1u);
}

}  // namespace
}  // namespace softshock::server
