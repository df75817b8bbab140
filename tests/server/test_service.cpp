// softshockd in-process over loopback gRPC: submit/watch/query/delete with tiny real runs,
// canonical error codes, auth, the bounded queue, cancellation, and requeue on shutdown.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "server/daemon.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/store/catalogue.hpp"
#include "softshock/v1/service.grpc.pb.h"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using grpc::StatusCode;

constexpr const char* kToken = "test-token-0123456789abcdef0123456789";  // >= 32 bytes

v1::RunSpec tiny_spec() {
  v1::RunSpec spec;
  spec.mutable_geometry()->set_target_elements(200);
  spec.mutable_run()->set_end_time(5e-9);
  spec.mutable_run()->set_output_interval(2.5e-9);
  return spec;
}

// Runs for a minute or more unless cancelled (8000 elements take ~5 s per 600 ns here).
v1::RunSpec long_spec() {
  v1::RunSpec spec;
  spec.mutable_geometry()->set_target_elements(8000);
  spec.mutable_run()->set_end_time(1e-5);
  spec.mutable_run()->set_output_interval(1e-6);
  spec.mutable_run()->set_history_interval(1e-8);
  return spec;
}

class ServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-service-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
    std::ofstream(dir_ / "token") << kToken << "\n";
    fs::permissions(dir_ / "token", fs::perms::owner_read | fs::perms::owner_write);
  }
  void TearDown() override {
    stub_.reset();
    daemon_.reset();
    fs::remove_all(dir_);
  }

  void start(int workers = 2, std::size_t max_queued = 100) {
    DaemonConfig c;
    c.data_dir = (dir_ / "data").string();
    c.listen = "127.0.0.1:0";
    c.port_file = (dir_ / "port").string();
    c.workers = workers;
    c.max_queued = max_queued;
    c.token_file = (dir_ / "token").string();
    daemon_ = std::make_unique<Daemon>(c);
    daemon_->start();
    auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(daemon_->port()),
                                       grpc::InsecureChannelCredentials());
    stub_ = v1::SimulationService::NewStub(channel);
  }

  std::unique_ptr<grpc::ClientContext> ctx(bool auth = true, std::chrono::seconds limit = 10s) {
    auto c = std::make_unique<grpc::ClientContext>();
    if (auth) c->AddMetadata("authorization", std::string("Bearer ") + kToken);
    c->set_deadline(std::chrono::system_clock::now() + limit);
    return c;
  }

  v1::Job submit(const v1::RunSpec& spec, const std::string& request_id = "",
                 grpc::Status* status = nullptr) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = spec;
    req.set_request_id(request_id);
    (*req.mutable_labels())["suite"] = "service";
    v1::Job job;
    grpc::Status s = stub_->SubmitJob(ctx().get(), req, &job);
    if (status) {
      *status = s;
    } else {
      EXPECT_TRUE(s.ok()) << s.error_message();
    }
    return job;
  }

  // Watches to the end; returns the last update and counts the messages.
  v1::Job watch(const std::string& id, int* messages = nullptr) {
    v1::WatchJobRequest req;
    req.set_id("jobs/" + id);
    auto c = ctx(true, 30s);
    auto reader = stub_->WatchJob(c.get(), req);
    v1::Job job, last;
    int n = 0;
    while (reader->Read(&job)) {
      last = job;
      ++n;
    }
    EXPECT_TRUE(reader->Finish().ok());
    if (messages) *messages = n;
    return last;
  }

  // Waits until the solver itself is stepping (meshing done): progress has steps.
  void wait_stepping(const std::string& id, std::chrono::seconds limit = 60s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      v1::GetJobRequest req;
      req.set_id(id);
      v1::Job job;
      EXPECT_TRUE(stub_->GetJob(ctx().get(), req, &job).ok());
      if (job.state() == v1::RUNNING && job.progress().steps() > 0) return;
      std::this_thread::sleep_for(20ms);
    }
    ADD_FAILURE() << "job " << id << " never started stepping";
  }

  v1::Job wait_state(const std::string& id, v1::JobState state, std::chrono::seconds limit = 20s) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    v1::Job job;
    while (std::chrono::steady_clock::now() < deadline) {
      v1::GetJobRequest req;
      req.set_id(id);
      EXPECT_TRUE(stub_->GetJob(ctx().get(), req, &job).ok());
      if (job.state() == state) return job;
      std::this_thread::sleep_for(20ms);
    }
    ADD_FAILURE() << "job " << id << " did not reach state " << state;
    return job;
  }

  fs::path dir_;
  std::unique_ptr<Daemon> daemon_;
  std::unique_ptr<v1::SimulationService::Stub> stub_;
};

TEST_F(ServiceTest, SubmitWatchQueryDelete) {
  start();
  const v1::Job job = submit(tiny_spec(), "req-a");
  EXPECT_EQ(job.name(), "jobs/" + job.id());
  EXPECT_EQ(job.state(), v1::QUEUED);
  EXPECT_EQ(job.spec_hash().size(), 64u);
  EXPECT_EQ(job.spec().geometry().target_elements(), 200);
  EXPECT_TRUE(job.spec().material().has_density()) << "the stored spec is normalised";
  EXPECT_EQ(submit(tiny_spec(), "req-a").id(), job.id()) << "request_id dedup";

  int messages = 0;
  const v1::Job done = watch(job.id(), &messages);
  ASSERT_EQ(done.state(), v1::SUCCEEDED) << done.error();
  EXPECT_GE(messages, 1);
  EXPECT_DOUBLE_EQ(done.progress().fraction(), 1.0);
  EXPECT_EQ(done.attempt(), 1);
  // Relative to the data folder: the server's absolute paths are its own business.
  EXPECT_EQ(done.result_path(), "jobs/" + job.id() + "/result.h5");
  EXPECT_TRUE(fs::exists(dir_ / "data" / done.result_path()));
  EXPECT_TRUE(done.has_finish_time());

  v1::GetJobSummaryRequest sreq;
  sreq.set_id(job.id());
  v1::JobSummary summary;
  ASSERT_TRUE(stub_->GetJobSummary(ctx().get(), sreq, &summary).ok());
  EXPECT_GT(summary.elements(), 100);
  EXPECT_GT(summary.steps(), 0);
  EXPECT_DOUBLE_EQ(summary.end_time_s(), 5e-9);

  v1::GetTimeSeriesRequest treq;
  treq.set_id(job.id());
  treq.add_names("abar");
  v1::TimeSeries ts;
  ASSERT_TRUE(stub_->GetTimeSeries(ctx().get(), treq, &ts).ok());
  ASSERT_EQ(ts.series_size(), 1);
  EXPECT_EQ(ts.series(0).values_size(), ts.time_size());
  EXPECT_GT(ts.time_size(), 1);
  treq.add_names("no_such_series");
  EXPECT_EQ(stub_->GetTimeSeries(ctx().get(), treq, &ts).error_code(),
            StatusCode::INVALID_ARGUMENT);

  v1::GetModesRequest mreq;
  mreq.set_id(job.id());
  mreq.set_mode_min(2);
  mreq.set_mode_max(4);
  v1::Modes modes;
  ASSERT_TRUE(stub_->GetModes(ctx().get(), mreq, &modes).ok());
  EXPECT_EQ(modes.mode_min(), 2);
  EXPECT_EQ(modes.mode_count(), 3);
  EXPECT_EQ(modes.amplitude_size(), modes.time_size() * 3);

  // Element field, every 2nd value.
  v1::GetFieldRequest freq;
  freq.set_id(job.id());
  freq.set_name("J");
  freq.set_every(2);
  {
    auto c = ctx();
    auto reader = stub_->GetField(c.get(), freq);
    v1::FieldChunk chunk;
    ASSERT_TRUE(reader->Read(&chunk));
    ASSERT_TRUE(chunk.has_header());
    EXPECT_EQ(chunk.header().location(), "element");
    const int64_t expected = (summary.elements() + 1) / 2;
    EXPECT_EQ(chunk.header().value_count(), expected);
    int64_t got = chunk.values_size();
    while (reader->Read(&chunk)) got += chunk.values_size();
    EXPECT_TRUE(reader->Finish().ok());
    EXPECT_EQ(got, expected);
  }
  // Node vector field on a raster: the disk fills ~pi/4 of its bounding box.
  freq.set_name("displacement");
  freq.mutable_raster()->set_nx(40);
  freq.mutable_raster()->set_ny(40);
  {
    auto c = ctx();
    auto reader = stub_->GetField(c.get(), freq);
    v1::FieldChunk chunk;
    std::vector<double> values;
    ASSERT_TRUE(reader->Read(&chunk));
    EXPECT_EQ(chunk.header().location(), "raster");
    EXPECT_EQ(chunk.header().components(), 2);
    EXPECT_LT(chunk.header().x_min(), chunk.header().x_max());
    while (reader->Read(&chunk))
      values.insert(values.end(), chunk.values().begin(), chunk.values().end());
    ASSERT_TRUE(reader->Finish().ok());
    ASSERT_EQ(values.size(), 40u * 40u * 2u);
    const auto inside =
        std::count_if(values.begin(), values.end(), [](double v) { return !std::isnan(v); });
    EXPECT_NEAR(static_cast<double>(inside) / values.size(), M_PI / 4, 0.08);
  }
  freq.mutable_raster()->set_nx(4096);
  {
    auto c = ctx();
    auto reader = stub_->GetField(c.get(), freq);
    v1::FieldChunk chunk;
    EXPECT_FALSE(reader->Read(&chunk));
    EXPECT_EQ(reader->Finish().error_code(), StatusCode::RESOURCE_EXHAUSTED);
  }

  v1::ListJobsRequest lreq;
  lreq.set_label("suite=service");
  v1::ListJobsResponse list;
  ASSERT_TRUE(stub_->ListJobs(ctx().get(), lreq, &list).ok());
  EXPECT_EQ(list.jobs_size(), 1);

  v1::DeleteJobRequest dreq;
  dreq.set_id(job.name());
  v1::DeleteJobResponse dresp;
  ASSERT_TRUE(stub_->DeleteJob(ctx().get(), dreq, &dresp).ok());
  EXPECT_FALSE(fs::exists((dir_ / "data" / done.result_path()).parent_path()));
  v1::GetJobRequest greq;
  greq.set_id(job.id());
  v1::Job gone;
  EXPECT_EQ(stub_->GetJob(ctx().get(), greq, &gone).error_code(), StatusCode::NOT_FOUND);
}

// A run with phase-field damage: its figures go from the solver's summary through the catalogue
// to GetJobSummary (the release tension damages the rim from ~10 ns: docs/verification.md).
TEST_F(ServiceTest, DamageFiguresReachTheSummary) {
  start();
  v1::RunSpec spec = tiny_spec();
  spec.mutable_geometry()->set_target_elements(400);
  spec.mutable_run()->set_end_time(2e-8);
  spec.mutable_damage()->set_model(v1::TALAMINI);
  const v1::Job done = watch(submit(spec).id());
  ASSERT_EQ(done.state(), v1::SUCCEEDED) << done.error();
  v1::GetJobSummaryRequest sreq;
  sreq.set_id(done.id());
  v1::JobSummary summary;
  ASSERT_TRUE(stub_->GetJobSummary(ctx().get(), sreq, &summary).ok());
  EXPECT_TRUE(summary.damage());
  EXPECT_GT(summary.damage_onset_s(), 0);
  EXPECT_LT(summary.damage_onset_s(), 2e-8);
  EXPECT_GT(summary.max_damaged_volume(), 0);
  EXPECT_GT(summary.max_damaged_radius_m(), 0);
  EXPECT_GT(summary.damage_dissipation_j_per_m(), 0);
  EXPECT_GT(summary.damage_solves(), 0);
  // The field d of the last frame, per node, on a raster: within [0, 1], damaged somewhere.
  v1::GetFieldRequest freq;
  freq.set_id(done.id());
  freq.set_name("damage");
  freq.mutable_raster()->set_nx(32);
  freq.mutable_raster()->set_ny(32);
  std::vector<double> d;
  {
    auto c = ctx();
    auto reader = stub_->GetField(c.get(), freq);
    v1::FieldChunk chunk;
    ASSERT_TRUE(reader->Read(&chunk));
    EXPECT_EQ(chunk.header().components(), 1);
    EXPECT_EQ(chunk.header().units(), "1");
    while (reader->Read(&chunk)) d.insert(d.end(), chunk.values().begin(), chunk.values().end());
    ASSERT_TRUE(reader->Finish().ok());
  }
  ASSERT_EQ(d.size(), 32u * 32u);
  double largest = 0;
  for (double v : d) {
    if (std::isnan(v)) continue;  // outside the disk
    EXPECT_GE(v, 0.0);
    EXPECT_LE(v, 1.0);
    largest = std::max(largest, v);
  }
  EXPECT_GT(largest, 0.0);
  // A run without damage says so, and has no damage field.
  const v1::Job plain = watch(submit(tiny_spec()).id());
  sreq.set_id(plain.id());
  ASSERT_TRUE(stub_->GetJobSummary(ctx().get(), sreq, &summary).ok());
  EXPECT_FALSE(summary.damage());
  EXPECT_EQ(summary.damage_solves(), 0);
  freq.set_id(plain.id());
  {
    auto c = ctx();
    auto reader = stub_->GetField(c.get(), freq);
    v1::FieldChunk chunk;
    EXPECT_FALSE(reader->Read(&chunk));
    EXPECT_EQ(reader->Finish().error_code(), StatusCode::FAILED_PRECONDITION);
  }
}

TEST_F(ServiceTest, CanonicalErrors) {
  start();
  v1::RunSpec bad = tiny_spec();
  bad.mutable_geometry()->mutable_disk()->set_radius(-1);
  grpc::Status s;
  submit(bad, "", &s);
  EXPECT_EQ(s.error_code(), StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(s.error_message().find("geometry.disk.radius"), std::string::npos) << s.error_message();

  v1::RunSpec mesh = tiny_spec();
  mesh.mutable_geometry()->set_mesh_file("/etc/passwd");
  submit(mesh, "", &s);
  EXPECT_EQ(s.error_code(), StatusCode::INVALID_ARGUMENT);

  v1::GetJobRequest get;
  v1::Job job;
  get.set_id("0123456789abcdef");
  EXPECT_EQ(stub_->GetJob(ctx().get(), get, &job).error_code(), StatusCode::NOT_FOUND);
  get.set_id("jobs/../../etc");
  EXPECT_EQ(stub_->GetJob(ctx().get(), get, &job).error_code(), StatusCode::INVALID_ARGUMENT);

  v1::ListJobsRequest list;
  v1::ListJobsResponse resp;
  list.set_page_size(-1);
  EXPECT_EQ(stub_->ListJobs(ctx().get(), list, &resp).error_code(), StatusCode::INVALID_ARGUMENT);
  list.set_page_size(1);
  list.set_page_token("garbage!");
  EXPECT_EQ(stub_->ListJobs(ctx().get(), list, &resp).error_code(), StatusCode::INVALID_ARGUMENT);

  EXPECT_EQ(stub_->ListJobs(ctx(false).get(), v1::ListJobsRequest(), &resp).error_code(),
            StatusCode::UNAUTHENTICATED);
  auto wrong = ctx(false);
  wrong->AddMetadata("authorization", "Bearer nope");
  EXPECT_EQ(stub_->ListJobs(wrong.get(), v1::ListJobsRequest(), &resp).error_code(),
            StatusCode::UNAUTHENTICATED);
}

// Gmsh cannot be interrupted: a cancel during meshing is recorded at once and the worker drops
// the job when the mesher returns.
TEST_F(ServiceTest, CancelDuringMeshingTakesEffectWithinASecond) {
  start(/*workers=*/1, /*max_queued=*/4);
  v1::RunSpec spec = long_spec();
  spec.mutable_geometry()->set_target_elements(60000);  // ~1.5 s of meshing (more under ASan)
  const v1::Job job = submit(spec);
  wait_state(job.id(), v1::RUNNING);
  v1::CancelJobRequest creq;
  creq.set_id(job.id());
  v1::Job cancelled;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(stub_->CancelJob(ctx().get(), creq, &cancelled).ok());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 1s);
  EXPECT_EQ(cancelled.state(), v1::CANCELLED);
  EXPECT_EQ(cancelled.reason(), "CANCELLED_BY_USER");
  // The next job runs once the worker is free again.
  EXPECT_EQ(watch(submit(tiny_spec()).id()).state(), v1::SUCCEEDED);
}

TEST_F(ServiceTest, BoundedQueueCancelAndPagination) {
  start(/*workers=*/1, /*max_queued=*/2);
  const v1::Job running = submit(long_spec());
  wait_stepping(running.id());

  // A running job's progress changes every step; the stream sends at most ~5 updates/s.
  {
    v1::WatchJobRequest wreq;
    wreq.set_id(running.id());
    grpc::ClientContext wctx;
    wctx.AddMetadata("authorization", std::string("Bearer ") + kToken);
    wctx.set_deadline(std::chrono::system_clock::now() + 1200ms);
    auto reader = stub_->WatchJob(&wctx, wreq);
    v1::Job update;
    int n = 0;
    while (reader->Read(&update)) ++n;
    EXPECT_EQ(reader->Finish().error_code(), StatusCode::DEADLINE_EXCEEDED);
    EXPECT_GE(n, 3);
    EXPECT_LE(n, 8);
  }

  const v1::Job q1 = submit(tiny_spec());
  const v1::Job q2 = submit(tiny_spec());
  grpc::Status s;
  submit(tiny_spec(), "", &s);
  EXPECT_EQ(s.error_code(), StatusCode::RESOURCE_EXHAUSTED);

  // Queries on unfinished jobs are a failed precondition.
  v1::GetJobSummaryRequest sreq;
  sreq.set_id(q1.id());
  v1::JobSummary summary;
  EXPECT_EQ(stub_->GetJobSummary(ctx().get(), sreq, &summary).error_code(),
            StatusCode::FAILED_PRECONDITION);

  v1::CancelJobRequest creq;
  v1::Job cancelled;
  creq.set_id(q1.id());
  ASSERT_TRUE(stub_->CancelJob(ctx().get(), creq, &cancelled).ok());
  EXPECT_EQ(cancelled.state(), v1::CANCELLED);
  EXPECT_EQ(stub_->CancelJob(ctx().get(), creq, &cancelled).error_code(),
            StatusCode::FAILED_PRECONDITION);

  creq.set_id(running.id());
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(stub_->CancelJob(ctx().get(), creq, &cancelled).ok());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 1s);
  EXPECT_EQ(cancelled.state(), v1::CANCELLED);
  EXPECT_EQ(cancelled.reason(), "CANCELLED_BY_USER");

  EXPECT_EQ(watch(q2.id()).state(), v1::SUCCEEDED);

  // Pages of one: every job exactly once, newest first.
  std::vector<std::string> ids;
  v1::ListJobsRequest lreq;
  lreq.set_page_size(1);
  for (;;) {
    v1::ListJobsResponse page;
    ASSERT_TRUE(stub_->ListJobs(ctx().get(), lreq, &page).ok());
    for (const auto& j : page.jobs()) ids.push_back(j.id());
    if (page.next_page_token().empty()) break;
    lreq.set_page_token(page.next_page_token());
  }
  EXPECT_EQ(ids, (std::vector<std::string>{q2.id(), q1.id(), running.id()}));
}

TEST_F(ServiceTest, ShutdownRequeuesRunningJobsAndRestartRunsThem) {
  start(1);
  const v1::Job job = submit(long_spec());
  wait_state(job.id(), v1::RUNNING);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(daemon_->stop());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 5s);
  stub_.reset();
  daemon_.reset();
  {
    Catalogue c((dir_ / "data" / "catalogue.sqlite").string());
    auto row = c.get(job.id());
    ASSERT_TRUE(row);
    EXPECT_EQ(row->state, JobState::kQueued);
    EXPECT_EQ(row->attempt, 1) << "an orderly shutdown is not the job's fault";
  }
  start(1);
  const v1::Job again = wait_state(job.id(), v1::RUNNING);
  EXPECT_EQ(again.attempt(), 1);
  v1::CancelJobRequest creq;
  creq.set_id(job.id());
  v1::Job cancelled;
  ASSERT_TRUE(stub_->CancelJob(ctx().get(), creq, &cancelled).ok());
  EXPECT_EQ(cancelled.state(), v1::CANCELLED);
}

TEST(JobRunner, MapsSolverFailuresToReasons) {
  EXPECT_EQ(failure_reason(FailureKind::kElementInversion), "ELEMENT_INVERSION");
  EXPECT_EQ(failure_reason(FailureKind::kNonFinite), "NON_FINITE");
  EXPECT_EQ(failure_reason(FailureKind::kTimeStepCollapse), "TIME_STEP_COLLAPSE");
  EXPECT_EQ(failure_reason(FailureKind::kMeshDistortion), "MESH_DISTORTION");
  EXPECT_EQ(failure_reason(FailureKind::kNone), "INTERNAL");
  // A cluster run's cause comes back by name (its result's summary): the same reasons.
  for (const FailureKind kind : {FailureKind::kElementInversion, FailureKind::kNonFinite,
                                 FailureKind::kTimeStepCollapse, FailureKind::kMeshDistortion})
    EXPECT_EQ(failure_reason(failure_name(kind)), failure_reason(kind));
  EXPECT_EQ(failure_reason(failure_name(FailureKind::kNone)), "");  // not a solver failure
  EXPECT_EQ(failure_reason("SOMETHING_NEWER"), "");  // a newer solver's cause: stays SLURM_FAILED
  EXPECT_EQ(failure_reason("INTERNAL"), "");
}

TEST(JobRunner, DecimatesModesForTheCatalogue) {
  History h;
  for (int k = 0; k <= 20; ++k) {
    h.time.push_back(k * 1e-9);
    h.modes.push_back(std::vector<double>(100, k));
  }
  const StoredSummary s = make_stored_summary(RunSummary{}, h, 4e-9, 65);
  EXPECT_EQ(s.mode_count, 65);
  ASSERT_EQ(s.mode_times.size(), 6u);  // samples 0, 4, 8, 12, 16, 20 (the last always kept)
  for (std::size_t r = 0; r < 6; ++r) EXPECT_NEAR(s.mode_times[r], 4e-9 * r, 1e-18);
  ASSERT_EQ(s.mode_amplitudes.size(), 6u * 65u);
  EXPECT_EQ(s.mode_amplitudes[65], 4);
  EXPECT_EQ(s.mode_amplitudes[5 * 65], 20);
}

}  // namespace
}  // namespace softshock::server
