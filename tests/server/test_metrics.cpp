// The daemon's Prometheus metrics (server/metrics/): the text exposition format (HELP/TYPE lines,
// label escaping, cumulative histogram buckets), the bound on a family's series, and
// DaemonMetrics following a job's life through JobEvents as the runner reports it (queue wait,
// run time by state, element-steps live and from the summary, requeues), against a real catalogue.
#include <gtest/gtest.h>

#include <cctype>
#include <filesystem>
#include <random>
#include <string>

#include "server/jobs/job_events.hpp"
#include "server/metrics/daemon_metrics.hpp"
#include "server/metrics/registry.hpp"
#include "server/store/catalogue.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using metrics::Registry;

// The value of the sample line that starts with `series` ("name{labels}" or "name"), or NaN.
double sample(const std::string& text, const std::string& series) {
  std::size_t pos = 0;
  while ((pos = text.find(series + " ", pos)) != std::string::npos) {
    if (pos == 0 || text[pos - 1] == '\n') {
      const auto end = text.find('\n', pos);
      return std::stod(text.substr(pos + series.size() + 1, end - pos - series.size() - 1));
    }
    pos += series.size();
  }
  return std::nan("");
}

// A line of the text exposition format: "# HELP ..." / "# TYPE ...", or a metric name
// ([a-zA-Z_:][a-zA-Z0-9_:]*), optional {labels}, one space and a value without spaces. (Not
// std::regex: GCC 12 warns maybe-uninitialized inside it in the sanitizer build.)
bool exposition_line(const std::string& line) {
  if (line.rfind("# HELP ", 0) == 0 || line.rfind("# TYPE ", 0) == 0) return true;
  const auto space = line.rfind(' ');
  if (space == std::string::npos || space + 1 == line.size()) return false;
  const std::string head = line.substr(0, space), value = line.substr(space + 1);
  if (value.find_first_of(" \t") != std::string::npos) return false;
  const auto brace = head.find('{');
  const std::string name = head.substr(0, brace);
  if (brace != std::string::npos && head.back() != '}') return false;
  if (name.empty() || std::isdigit(static_cast<unsigned char>(name[0]))) return false;
  for (char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != ':') return false;
  return true;
}

TEST(MetricsRegistry, RendersCountersGaugesAndHistogramsInTheTextFormat) {
  Registry r;
  auto& calls = r.counter("calls_total", "Calls made.\nSecond line \\ here.", {"method", "code"});
  calls.with({"Get\"Job\"", "OK"}).inc();
  calls.with({"Get\"Job\"", "OK"}).inc(2);
  calls.with({"a\\b\nc", "NOT_FOUND"}).inc();
  calls.with({"x", "OK"}).inc(-5);  // ignored: counters only grow
  r.gauge("temperature", "Degrees.").with().set(-1.5);
  auto& h = r.histogram("wait_seconds", "Waits.", {}, {0.1, 1, 10});
  for (double v : {0.05, 0.1, 0.5, 5.0, 50.0}) h.with().observe(v);

  const std::string text = r.render();
  EXPECT_NE(text.find("# HELP calls_total Calls made.\\nSecond line \\\\ here.\n"
                      "# TYPE calls_total counter\n"),
            std::string::npos)
      << text;
  EXPECT_EQ(sample(text, R"(calls_total{method="Get\"Job\"",code="OK"})"), 3);
  EXPECT_EQ(sample(text, R"(calls_total{method="a\\b\nc",code="NOT_FOUND"})"), 1);
  EXPECT_EQ(sample(text, R"(calls_total{method="x",code="OK"})"), 0);
  EXPECT_NE(text.find("# TYPE temperature gauge\ntemperature -1.5\n"), std::string::npos) << text;
  // Buckets are cumulative and "less than or equal": 0.1 falls in le="0.1".
  EXPECT_NE(text.find("# TYPE wait_seconds histogram\n"
                      "wait_seconds_bucket{le=\"0.1\"} 2\n"
                      "wait_seconds_bucket{le=\"1\"} 3\n"
                      "wait_seconds_bucket{le=\"10\"} 4\n"
                      "wait_seconds_bucket{le=\"+Inf\"} 5\n"
                      "wait_seconds_sum 55.65\n"
                      "wait_seconds_count 5\n"),
            std::string::npos)
      << text;
  // Every line is a comment or `name{labels} value` (the checker refuses what is neither).
  for (const char* bad : {"1bad 3", "name", "name{a=\"b\" 3", "name 3 4", "name ", "# x"})
    EXPECT_FALSE(exposition_line(bad)) << bad;
  std::size_t start = 0;
  while (start < text.size()) {
    const auto end = text.find('\n', start);
    ASSERT_NE(end, std::string::npos) << "the text must end with a newline";
    EXPECT_TRUE(exposition_line(text.substr(start, end - start)))
        << text.substr(start, end - start);
    start = end + 1;
  }
}

TEST(MetricsRegistry, RefusesBadNamesAndBoundsAndFoldsSeriesPastTheBound) {
  Registry r;
  EXPECT_THROW(r.counter("1bad", "x"), std::invalid_argument);
  EXPECT_THROW(r.counter("ok", "x", {"__reserved"}), std::invalid_argument);
  EXPECT_THROW(r.histogram("h", "x", {"le"}, {1}), std::invalid_argument);
  EXPECT_THROW(r.histogram("h2", "x", {}, {1, 1}), std::invalid_argument);
  auto& c = r.counter("ok", "x", {"k"});
  EXPECT_THROW(r.counter("ok", "again"), std::invalid_argument);
  EXPECT_THROW(c.with({}), std::invalid_argument);
  for (std::size_t i = 0; i < metrics::kMaxSeries + 10; ++i) c.with({std::to_string(i)}).inc();
  const std::string text = r.render();
  EXPECT_EQ(sample(text, R"(ok{k="overflow"})"), 10);
  EXPECT_EQ(sample(text, R"(ok{k="0"})"), 1);
  EXPECT_TRUE(std::isnan(sample(text, "ok{k=\"" + std::to_string(metrics::kMaxSeries) + "\"}")));
}

TEST(MetricsRegistry, FormatsValuesAsPrometheusReadsThem) {
  EXPECT_EQ(metrics::format_value(0.1), "0.1");
  EXPECT_EQ(metrics::format_value(1e21), "1e+21");
  EXPECT_EQ(metrics::format_value(3), "3");
  EXPECT_EQ(metrics::format_value(std::numeric_limits<double>::infinity()), "+Inf");
  EXPECT_EQ(metrics::format_value(-std::numeric_limits<double>::infinity()), "-Inf");
  EXPECT_EQ(metrics::format_value(std::nan("")), "NaN");
}

class DaemonMetricsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-metrics-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
    catalogue_ = std::make_unique<Catalogue>((dir_ / "catalogue.sqlite").string(), 0);
    metrics_ = std::make_unique<DaemonMetrics>(*catalogue_, dir_.string(), 5e8, "9.9.9",
                                               [](const std::string&, DiskSpace* d) {
                                                 d->total_bytes = 1000;
                                                 d->free_bytes = 400;
                                                 d->used_bytes = 550;
                                                 return true;
                                               });
    events_.set_observer([this](JobEventKind k, const std::string& id, const JobProgressRecord* p) {
      metrics_->on_job_event(k, id, p);
    });
  }
  void TearDown() override { fs::remove_all(dir_); }

  void insert(const std::string& id, int64_t create_us) {
    NewJob j;
    j.id = id;
    j.spec_json = "{}";
    j.spec_hash = "h-" + id;
    j.create_us = create_us;
    catalogue_->insert(j);
    events_.notify(id);
  }
  void progress(const std::string& id, int64_t steps, int64_t elements) {
    JobProgressRecord p;
    p.steps = steps;
    p.elements = elements;
    events_.set_progress(id, p);
  }

  fs::path dir_;
  std::unique_ptr<Catalogue> catalogue_;
  std::unique_ptr<DaemonMetrics> metrics_;
  JobEvents events_;
};

TEST_F(DaemonMetricsTest, FollowsARunFromQueueToSuccess) {
  const int64_t t0 = now_us();
  insert("a", t0 - 3'000'000);  // submitted 3 s ago
  insert("b", t0);
  std::string text = metrics_->render();
  EXPECT_EQ(sample(text, R"(softshock_jobs{state="QUEUED"})"), 2);
  EXPECT_EQ(sample(text, R"(softshock_jobs{state="SUCCEEDED"})"), 0);
  EXPECT_EQ(sample(text, "softshock_job_queue_wait_seconds_count"), 0);
  EXPECT_EQ(sample(text, "softshock_data_disk_free_bytes"), 400);
  EXPECT_EQ(sample(text, "softshock_data_disk_total_bytes"), 1000);
  EXPECT_EQ(sample(text, "softshock_data_disk_used_bytes"), 550);
  EXPECT_EQ(sample(text, "softshock_data_disk_reserve_bytes"), 5e8);
  EXPECT_EQ(sample(text, R"(softshock_build_info{version="9.9.9"})"), 1);

  ASSERT_TRUE(catalogue_->start("a", t0));
  progress("a", 0, 100);  // the runner's first progress: the run started
  progress("a", 10, 100);
  progress("a", 25, 100);
  EXPECT_EQ(metrics_->tracked_runs(), 1u);
  text = metrics_->render();
  EXPECT_EQ(sample(text, R"(softshock_jobs{state="RUNNING"})"), 1);
  EXPECT_EQ(sample(text, "softshock_job_queue_wait_seconds_count"), 1);
  EXPECT_NEAR(sample(text, "softshock_job_queue_wait_seconds_sum"), 3.0, 1e-6);
  EXPECT_EQ(sample(text, R"(softshock_job_queue_wait_seconds_bucket{le="1"})"), 0);
  EXPECT_EQ(sample(text, R"(softshock_job_queue_wait_seconds_bucket{le="5"})"), 1);
  EXPECT_EQ(sample(text, "softshock_element_steps_total"), 2500);

  // The run ends with 40 steps of 100 elements in its summary: 15 more steps count.
  StoredSummary s;
  s.summary.elements = 100;
  s.summary.steps = 40;
  ASSERT_TRUE(
      catalogue_->finish("a", 1, JobState::kSucceeded, "", "", "r.h5", {}, &s, t0 + 2'000'000));
  events_.notify("a");
  events_.forget("a");
  events_.forget("a");  // told twice: counted once
  text = metrics_->render();
  EXPECT_EQ(metrics_->tracked_runs(), 0u);
  EXPECT_EQ(sample(text, "softshock_element_steps_total"), 4000);
  EXPECT_EQ(sample(text, R"(softshock_job_run_seconds_count{state="SUCCEEDED"})"), 1);
  EXPECT_NEAR(sample(text, R"(softshock_job_run_seconds_sum{state="SUCCEEDED"})"), 2.0, 1e-6);
  EXPECT_EQ(sample(text, R"(softshock_job_runs_finished_total{outcome="SUCCEEDED",reason="none"})"),
            1);
  EXPECT_EQ(sample(text, R"(softshock_jobs{state="SUCCEEDED"})"), 1);
  EXPECT_EQ(sample(text, R"(softshock_jobs{state="QUEUED"})"), 1);
}

TEST_F(DaemonMetricsTest, ARequeuedRunCountsAsRequeuedAndNotAsARunTime) {
  const int64_t t0 = now_us();
  insert("a", t0);
  ASSERT_TRUE(catalogue_->start("a", t0));
  progress("a", 0, 0);  // no element count (as on Slurm): nothing counted live
  progress("a", 7, 0);
  events_.forget("a");  // still RUNNING in the catalogue: not stopped yet
  EXPECT_EQ(metrics_->tracked_runs(), 1u);
  ASSERT_TRUE(catalogue_->requeue("a", 1, "SHUTDOWN", t0 + 1000));
  events_.forget("a");
  const std::string text = metrics_->render();
  EXPECT_EQ(metrics_->tracked_runs(), 0u);
  EXPECT_EQ(sample(text, "softshock_element_steps_total"), 0);
  EXPECT_EQ(
      sample(text, R"(softshock_job_runs_finished_total{outcome="REQUEUED",reason="SHUTDOWN"})"),
      1);
  EXPECT_TRUE(std::isnan(sample(text, R"(softshock_job_run_seconds_count{state="SUCCEEDED"})")));
  // A job never started under this daemon (its progress came first) is not tracked.
  progress("zzz", 3, 10);
  EXPECT_EQ(metrics_->tracked_runs(), 0u);
}

TEST_F(DaemonMetricsTest, CountsRpcsAndUploadsByTheirLabels) {
  metrics_->rpc_handled("softshock.v1.SimulationService", "GetJob", "unary", "OK", 0.002);
  metrics_->rpc_handled("softshock.v1.SimulationService", "GetJob", "unary", "NOT_FOUND", 0.2);
  metrics_->rpc_handled("softshock.v1.SimulationService", "GetJob", "unary", "OK", 0.003);
  metrics_->mesh_upload(true, 1200);
  metrics_->mesh_upload(false, 50);
  const std::string text = metrics_->render();
  const std::string ok =
      R"({grpc_service="softshock.v1.SimulationService",grpc_method="GetJob",grpc_type="unary",grpc_code="OK"})";
  EXPECT_EQ(sample(text, "grpc_server_handled_total" + ok), 2);
  EXPECT_EQ(sample(text, "grpc_server_handling_seconds_count" + ok), 2);
  EXPECT_NEAR(sample(text, "grpc_server_handling_seconds_sum" + ok), 0.005, 1e-12);
  EXPECT_EQ(
      sample(
          text,
          R"(grpc_server_handled_total{grpc_service="softshock.v1.SimulationService",grpc_method="GetJob",grpc_type="unary",grpc_code="NOT_FOUND"})"),
      1);
  EXPECT_EQ(sample(text, R"(softshock_mesh_uploads_total{outcome="stored"})"), 1);
  EXPECT_EQ(sample(text, R"(softshock_mesh_upload_bytes_total{outcome="rejected"})"), 50);
}

}  // namespace
}  // namespace softshock::server
